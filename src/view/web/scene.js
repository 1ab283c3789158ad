// The 3D scene: ground grid and the lab's up axis, model markers (occluded
// ones drawn differently), measured markers, residual lines, bones, segment
// frames, orbit/zoom/pan and a camera that can follow the subject. A pose
// that rests on no measurement is drawn dim and grey, with a note on the
// scene, so that a standing skeleton is not taken for a tracked one.

import * as THREE from 'three';
import {OrbitControls} from '/three/examples/jsm/controls/OrbitControls.js';

const AXES = {x: [1, 0, 0], y: [0, 1, 0], z: [0, 0, 1]};

// lab_axes.up / .forward: [x, y, z] or "+z", "-y", "x".
export function axisVector(v, fallback) {
  if (Array.isArray(v) && v.length === 3 && v.every(Number.isFinite)) return new THREE.Vector3(...v).normalize();
  const m = typeof v === 'string' && /^([+-]?)([xyz])$/i.exec(v.trim());
  if (m) return new THREE.Vector3(...AXES[m[2].toLowerCase()]).multiplyScalar(m[1] === '-' ? -1 : 1);
  return new THREE.Vector3(...fallback);
}

const finite3 = (p) => Array.isArray(p) && p.length === 3 && p.every(Number.isFinite);

const COLORS = {marker: 0x3fb8ff, occluded: 0xff9a2e, measured: 0xffffff, bone: 0xd8dde3,
                residual: 0xff4f6d, up: 0x7cff7c, untracked: 0x6b737c};
const UNTRACKED_OPACITY = 0.4;
const UNTRACKED_NOTE = 'NOT TRACKED: no measured marker in this pose';

// Removes a group's children and frees their GPU buffers (a new model rebuilds them all).
function disposeChildren(group) {
  group.traverse((o) => {
    if (o === group) return;
    if (o.geometry) o.geometry.dispose();
    for (const m of [].concat(o.material || [])) m.dispose();
  });
  group.remove(...group.children);
}

export class SkeletonScene {
  constructor(container) {
    this.container = container;
    this.scene = new THREE.Scene();
    this.scene.background = new THREE.Color(0x15181c);
    this.camera = new THREE.PerspectiveCamera(45, 1, 0.01, 200);
    this.renderer = null;
    try {
      this.renderer = new THREE.WebGLRenderer({antialias: true});
      this.renderer.setPixelRatio(window.devicePixelRatio || 1);
      container.appendChild(this.renderer.domElement);
    } catch (e) {
      this.webglError = String(e && e.message || e);  // the page still tracks and plots
    }
    // On the scene, where the user looks; text only (textContent).
    this.note = document.createElement('div');
    this.note.className = 'scene-note';
    this.note.hidden = true;
    this.note.textContent = UNTRACKED_NOTE;
    container.appendChild(this.note);
    this.controls = new OrbitControls(this.camera, this.renderer ? this.renderer.domElement : container);
    // Sky from the lab's up (set with the model): from the scene's y, a Z-up lab's markers
    // were lit from the side, dim, near the untracked grey.
    this.light = new THREE.HemisphereLight(0xffffff, 0x303030, 1.0);
    this.scene.add(this.light);
    this.options = {frames: true, measured: true, residuals: true, follow: false};
    this.world = new THREE.Group();   // the model's objects, rebuilt on each model
    this.scene.add(this.world);
    this.lab = new THREE.Group();     // grid and axes, turned to the lab's up axis
    this.scene.add(this.lab);
    // Grid and axes from the start (Y-up until a model says otherwise), seen from where the
    // first pose would be framed: a page waiting for poses shows a scene, not a black box.
    this.up = new THREE.Vector3(0, 1, 0);
    this.forward = new THREE.Vector3(1, 0, 0);
    this.buildLab();
    this.placeCamera(new THREE.Vector3().addScaledVector(this.up, 0.9));
    this.framed = false;
    this.resize();
    if (window.ResizeObserver) new ResizeObserver(() => this.resize()).observe(container);
    else window.addEventListener('resize', () => this.resize());
  }

  resize() {
    const w = Math.max(1, this.container.clientWidth), h = Math.max(1, this.container.clientHeight);
    this.camera.aspect = w / h;
    this.camera.updateProjectionMatrix();
    if (this.renderer) this.renderer.setSize(w, h, false);
    // setSize clears the canvas: draw again now, as no new pose may come (paused, stream stopped).
    this.render();
  }

  // The camera beside the subject at `c`, a little ahead and above, looking at it.
  placeCamera(c) {
    const side = new THREE.Vector3().crossVectors(this.forward, this.up).normalize();
    this.controls.target.copy(c);
    this.camera.position.copy(c).addScaledVector(side, 3.2).addScaledVector(this.forward, 1.2)
      .addScaledVector(this.up, 1.0);
    this.controls.update();
  }

  setModel(model) {
    this.model = model;
    this.k = model.units === 'm' ? 1 : 0.001;   // the scene is in metres
    this.up = axisVector(model.lab_axes && model.lab_axes.up, [0, 1, 0]);
    this.forward = axisVector(model.lab_axes && model.lab_axes.forward, [1, 0, 0]);
    this.camera.up.copy(this.up);
    this.light.position.copy(this.up);
    this.buildLab();
    disposeChildren(this.world);

    const sphere = new THREE.SphereBufferGeometry(1, 12, 8);
    this.materials = {
      marker: new THREE.MeshLambertMaterial({color: COLORS.marker}),
      occluded: new THREE.MeshBasicMaterial({color: COLORS.occluded, wireframe: true}),
      measured: new THREE.MeshBasicMaterial({color: COLORS.measured}),
      bone: new THREE.MeshLambertMaterial({color: COLORS.bone}),
      // An untracked pose: the same shapes, grey and see-through.
      untrackedMarker: new THREE.MeshLambertMaterial({color: COLORS.untracked, transparent: true,
                                                      opacity: UNTRACKED_OPACITY}),
      untrackedOccluded: new THREE.MeshBasicMaterial({color: COLORS.untracked, wireframe: true,
                                                      transparent: true, opacity: UNTRACKED_OPACITY}),
      untrackedBone: new THREE.MeshLambertMaterial({color: COLORS.untracked, transparent: true,
                                                    opacity: UNTRACKED_OPACITY}),
    };
    this.markers = new Map();
    this.measured = new Map();
    for (const m of model.markers) {
      const name = typeof m === 'string' ? m : m.name;
      const mesh = new THREE.Mesh(sphere, this.materials.marker);
      mesh.scale.setScalar(0.014);
      mesh.userData.name = name;
      mesh.visible = false;
      this.markers.set(name, mesh);
      this.world.add(mesh);
      const dot = new THREE.Mesh(sphere, this.materials.measured);
      dot.scale.setScalar(0.006);
      dot.visible = false;
      this.measured.set(name, dot);
      this.world.add(dot);
    }
    const cylinder = new THREE.CylinderBufferGeometry(1, 1, 1, 8, 1);
    this.bones = model.bones.map(([a, b]) => {
      const mesh = new THREE.Mesh(cylinder, this.materials.bone);
      mesh.userData = {a, b};
      mesh.visible = false;
      this.world.add(mesh);
      return mesh;
    });
    this.frames = new Map();
    for (const s of model.segments || []) {
      const axes = new THREE.AxesHelper(0.12);
      axes.userData = s;
      axes.visible = false;
      this.frames.set(s.name, axes);
      this.world.add(axes);
    }
    const n = Math.max(1, model.markers.length);
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array(n * 6), 3));
    this.residuals = new THREE.LineSegments(geometry, new THREE.LineBasicMaterial({color: COLORS.residual}));
    this.residuals.frustumCulled = false;
    this.world.add(this.residuals);
    if (!this.framed) this.placeCamera(new THREE.Vector3().addScaledVector(this.up, 0.9));
    this.framed = false;  // framed again on its first pose
  }

  buildLab() {
    disposeChildren(this.lab);
    const grid = new THREE.GridHelper(10, 20, 0x4a5460, 0x2c323a);
    grid.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), this.up);
    this.lab.add(grid);
    this.lab.add(new THREE.AxesHelper(0.3));  // lab x red, y green, z blue
    this.lab.add(new THREE.ArrowHelper(this.up, new THREE.Vector3(), 0.6, COLORS.up, 0.1, 0.05));
  }

  vec(p) { return new THREE.Vector3(p[0] * this.k, p[1] * this.k, p[2] * this.k); }

  // Draws one pose, dim when it is untracked (state.js untrackedOf); returns
  // what is in the scene now (counted from the scene's objects, not from the pose).
  draw(pose, untracked = false) {
    if (!this.model) {
      this.note.hidden = true;  // nothing drawn: no note, as `untracked: false` says
      return {frame: pose.frame, bones: 0, markers: 0, occluded: [], measured: 0, residual_lines: 0, frames: 0,
              untracked: false};
    }
    this.note.hidden = !untracked;
    const occluded = new Set(pose.occluded);
    const occludedMaterial = untracked ? this.materials.untrackedOccluded : this.materials.occluded;
    const markerMaterial = untracked ? this.materials.untrackedMarker : this.materials.marker;
    const boneMaterial = untracked ? this.materials.untrackedBone : this.materials.bone;
    for (const [name, mesh] of this.markers) {
      const p = pose.markers[name];
      mesh.visible = finite3(p);
      if (!mesh.visible) continue;
      mesh.position.copy(this.vec(p));
      mesh.material = occluded.has(name) ? occludedMaterial : markerMaterial;
      mesh.scale.setScalar(occluded.has(name) ? 0.022 : 0.014);
    }
    const measured = pose.measured || {};
    const line = this.residuals.geometry.attributes.position;
    let lines = 0;
    for (const [name, dot] of this.measured) {
      const p = measured[name];
      dot.visible = this.options.measured && finite3(p);
      if (!finite3(p)) continue;
      dot.position.copy(this.vec(p));
      const model = pose.markers[name];
      if (this.options.residuals && finite3(model)) {
        const a = this.vec(p), b = this.vec(model);
        line.setXYZ(2 * lines, a.x, a.y, a.z);
        line.setXYZ(2 * lines + 1, b.x, b.y, b.z);
        lines++;
      }
    }
    line.needsUpdate = true;
    this.residuals.geometry.setDrawRange(0, 2 * lines);
    const Y = new THREE.Vector3(0, 1, 0);
    for (const bone of this.bones) {
      const pa = pose.joints[bone.userData.a], pb = pose.joints[bone.userData.b];
      bone.visible = finite3(pa) && finite3(pb);
      if (!bone.visible) continue;
      bone.material = boneMaterial;
      const a = this.vec(pa), b = this.vec(pb), d = b.clone().sub(a);
      const length = d.length();
      bone.position.copy(a).addScaledVector(d, 0.5);
      if (length > 0) bone.quaternion.setFromUnitVectors(Y, d.divideScalar(length));
      bone.scale.set(0.007, Math.max(length, 1e-6), 0.007);
    }
    const segments = pose.segments || {};
    for (const [name, axes] of this.frames) {
      const s = segments[name];
      const origin = s && finite3(s.origin) ? s.origin : pose.joints[axes.userData.origin];
      axes.visible = this.options.frames && !!s && Array.isArray(s.q) && finite3(origin);
      if (!axes.visible) continue;
      axes.position.copy(this.vec(origin));
      axes.quaternion.set(s.q[1], s.q[2], s.q[3], s.q[0]).normalize();  // [w, x, y, z]
    }
    this.aim(pose);
    return this.inventory(pose.frame);
  }

  inventory(frame) {
    const shown = (o) => o.visible && o.parent === this.world;
    const markers = [...this.markers.values()].filter(shown);
    const {occluded, untrackedOccluded} = this.materials;
    return {frame, bones: this.bones.filter(shown).length, markers: markers.length,
            occluded: markers.filter((m) => m.material === occluded || m.material === untrackedOccluded)
              .map((m) => m.userData.name),
            measured: [...this.measured.values()].filter(shown).length,
            residual_lines: this.residuals.geometry.drawRange.count / 2,
            frames: [...this.frames.values()].filter(shown).length,
            // The note on and no bone or marker drawn in a tracked pose's colours.
            untracked: !this.note.hidden && ![...this.bones, ...markers].some((o) => shown(o) &&
              [this.materials.bone, this.materials.marker, occluded].includes(o.material))};
  }

  // Frames the subject on its first pose; with follow on, keeps it centred.
  aim(pose) {
    const root = this.model.segments && this.model.segments[0] && pose.joints[this.model.segments[0].origin];
    const points = finite3(root) ? [root] : Object.values(pose.joints).filter(finite3);
    if (points.length === 0) return;
    const c = new THREE.Vector3();
    for (const p of points) c.add(this.vec(p));
    c.divideScalar(points.length);
    if (!this.framed) {
      this.placeCamera(c);
      this.framed = true;
    } else if (this.options.follow) {
      const shift = c.clone().sub(this.controls.target).multiplyScalar(0.2);
      this.controls.target.add(shift);
      this.camera.position.add(shift);
    }
    this.controls.update();
  }

  render() {
    if (this.renderer) this.renderer.render(this.scene, this.camera);
  }
}
