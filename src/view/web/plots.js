// Rolling plots (canvas 2D) of the joint angles the user picks: the last
// 10 s before the pose on screen, with the coordinate's range of motion
// (model.coordinates min_deg/max_deg) drawn as a band.

const DEFAULT_PICKS = ['hip_flexion_r', 'knee_angle_r', 'ankle_angle_r'];
export const WINDOW_S = 10;
// The user's picks outlive a reload (localStorage; a browser that refuses it: the defaults).
const PICKS_KEY = 'fabrikView.plotPicks';

function storedPicks() {
  try {
    const v = JSON.parse(localStorage.getItem(PICKS_KEY) || '[]');
    return Array.isArray(v) ? v.filter((n) => typeof n === 'string') : [];
  } catch (e) {
    return [];
  }
}

function storePicks(names) {
  try { localStorage.setItem(PICKS_KEY, JSON.stringify(names)); } catch (e) { /* not kept */ }
}

export class AnglePlots {
  constructor(container, select) {
    this.container = container;
    this.select = select;
    this.coordinates = new Map();  // name -> {min_deg, max_deg}
    this.plots = new Map();        // name -> {canvas, label}
    select.addEventListener('change', () => this.pick([...select.selectedOptions].map((o) => o.value)));
  }

  setCoordinates(coordinates) {
    this.coordinates = new Map(coordinates.map((c) => [c.name, c]));
    const previous = new Set(this.plots.keys());
    this.select.replaceChildren(...coordinates.map((c) => {
      const o = document.createElement('option');
      o.value = o.textContent = c.name;
      return o;
    }));
    let picks = [...previous].filter((n) => this.coordinates.has(n));
    if (picks.length === 0) picks = storedPicks().filter((n) => this.coordinates.has(n));
    if (picks.length === 0) picks = DEFAULT_PICKS.filter((n) => this.coordinates.has(n));
    if (picks.length === 0) picks = coordinates.slice(0, 3).map((c) => c.name);
    this.pick(picks, false);  // only the user's own choice is kept
  }

  pick(names, remember = true) {
    if (remember) storePicks(names);
    for (const o of this.select.options) o.selected = names.includes(o.value);
    this.plots = new Map(names.map((name) => {
      const div = document.createElement('div');
      div.className = 'plot';
      const label = document.createElement('div');
      label.className = 'name';
      const canvas = document.createElement('canvas');
      div.append(label, canvas);
      return [name, {div, label, canvas}];
    }));
    this.container.replaceChildren(...[...this.plots.values()].map((p) => p.div));
  }

  // Draws each picked angle over `entries` (oldest first, each {pose, t});
  // returns the number of samples each plot holds.
  draw(entries) {
    const held = {};
    const end = entries.length ? entries[entries.length - 1].t : 0;
    for (const [name, plot] of this.plots) {
      const samples = [];
      for (const e of entries) {
        const v = e.pose.angles && e.pose.angles[name];
        if (Number.isFinite(v)) samples.push([e.t, v]);
      }
      held[name] = samples.length;
      const c = this.coordinates.get(name) || {};
      const rom = Number.isFinite(c.min_deg) && Number.isFinite(c.max_deg) ? [c.min_deg, c.max_deg] : null;
      const last = samples.length ? samples[samples.length - 1][1] : null;
      plot.label.textContent = `${name}  ${last === null ? '-' : last.toFixed(1) + '°'}` +
        (rom ? `  (ROM ${rom[0]}..${rom[1]}°)` : '');
      this.paint(plot.canvas, samples, rom, end);
    }
    return held;
  }

  paint(canvas, samples, rom, end) {
    const dpr = window.devicePixelRatio || 1;
    const w = Math.max(1, Math.round(canvas.clientWidth * dpr)), h = Math.max(1, Math.round(canvas.clientHeight * dpr));
    if (canvas.width !== w || canvas.height !== h) { canvas.width = w; canvas.height = h; }
    const g = canvas.getContext('2d');
    g.clearRect(0, 0, w, h);
    let lo = Infinity, hi = -Infinity;
    for (const [, v] of samples) { lo = Math.min(lo, v); hi = Math.max(hi, v); }
    if (rom) { lo = Math.min(lo, rom[0]); hi = Math.max(hi, rom[1]); }
    if (!Number.isFinite(lo)) { lo = -1; hi = 1; }
    const pad = Math.max(1, (hi - lo) * 0.08);
    lo -= pad; hi += pad;
    const x = (t) => w - ((end - t) / WINDOW_S) * w;
    const y = (v) => h - ((v - lo) / (hi - lo)) * h;
    if (rom) {
      g.fillStyle = 'rgba(90, 200, 120, 0.18)';
      g.fillRect(0, y(rom[1]), w, y(rom[0]) - y(rom[1]));
    }
    if (lo < 0 && hi > 0) {
      g.strokeStyle = '#3a424c';
      g.lineWidth = dpr;
      g.beginPath(); g.moveTo(0, y(0)); g.lineTo(w, y(0)); g.stroke();
    }
    g.strokeStyle = '#3fb8ff';
    g.lineWidth = 1.5 * dpr;
    g.beginPath();
    samples.forEach(([t, v], i) => (i ? g.lineTo(x(t), y(v)) : g.moveTo(x(t), y(v))));
    g.stroke();
  }
}
