// Wires the page together: messages from the connection go into the state
// and the history; each animation frame paints the pose to show (the newest,
// or the paused/scrubbed/trial one) once. window.fabrikView.state() is a
// read-only snapshot for tests.

import {state, snapshot, notePaint, untrackedOf} from './state.js';
import {connect} from './connection.js';
import {SkeletonScene} from './scene.js';
import {AnglePlots, WINDOW_S} from './plots.js';
import {StatusView} from './status.js';
import {History, bindTransport} from './history.js';

const $ = (id) => document.getElementById(id);

const scene = new SkeletonScene($('scene'));
const plots = new AnglePlots($('plots'), $('angle-pick'));
const status = new StatusView({line: $('status'), banner: $('banner'),
  occludedList: $('occluded-list'), sensorList: $('sensor-list')});
const history = new History(30);
const updateTransport = bindTransport(history, $('pause'), $('scrub'), $('scrub-label'));

for (const [id, option] of [['show-frames', 'frames'], ['show-measured', 'measured'],
                            ['show-residuals', 'residuals'], ['follow', 'follow']]) {
  const box = $(id);
  scene.options[option] = box.checked;
  box.addEventListener('change', () => { scene.options[option] = box.checked; dirty = true; });
}

let painted = null;   // the history entry on screen
let dirty = true;     // repaint even if the entry is the same (model, options, camera)
scene.controls.addEventListener('change', () => { dirty = true; });

let modelText = null;  // the model on screen, as text: a resent model is not rebuilt

function setModel(model) {
  const text = JSON.stringify(model);
  if (text === modelText) return;
  modelText = text;
  state.model = model;
  scene.setModel(model);
  state.labUp = scene.up.toArray();
  state.lightUp = scene.light.position.clone().normalize().toArray();
  plots.setCoordinates(model.coordinates || []);
  status.setSensors(model.sensors || []);
  dirty = true;
}

function onMessage(topic, data, arrivedAtMs, viewAtMs) {
  switch (topic) {
    case 'model': setModel(data); break;
    case 'pose':
      state.received++;
      state.latest = data;
      state.latestAtMs = arrivedAtMs;
      state.latestViewMs = viewAtMs;
      status.onPose(arrivedAtMs);
      history.push(data, arrivedAtMs, viewAtMs);
      break;
    case 'stats': state.stats = data; state.statsAtMs = arrivedAtMs; status.onStats(data); break;
    case 'status': state.status = data; break;
    case 'trial':
      if (data.model) setModel(data.model);
      history.setTrial(data.poses);
      state.trial = {poses: data.poses, index: 0,
                     file: typeof data.file === 'string' && data.file ? data.file.slice(0, 200) : null};
      break;
  }
}

connect(onMessage, () => { dirty = true; });

function paint(now) {
  requestAnimationFrame(paint);
  const entry = history.current(now);
  if (entry && (entry !== painted || dirty)) {
    // Dim per pose drawn (paused or scrubbed too); the banner speaks of the latest.
    state.drawn = scene.draw(entry.pose, untrackedOf(entry.pose, state.model) !== null);
    state.plots = plots.draw(history.window(entry, WINDOW_S));
    scene.render();
    if (entry !== painted && entry.arrivedAtMs !== null && !history.isPaused()) {
      state.painted++;
      const now = performance.now();
      notePaint(now - entry.arrivedAtMs, entry.viewAtMs !== null ? now - entry.viewAtMs : null);
    }
    painted = entry;
    dirty = false;
  } else if (dirty) {
    scene.render();
    dirty = false;
  }
  state.paused = history.isPaused();
  if (state.trial && entry) state.trial.index = history.indexOf(entry.seq);
  state.history = {size: history.entries.length, index: entry ? history.indexOf(entry.seq) : null};
  updateTransport(entry);
  status.update(now, entry ? entry.pose : null);
}
requestAnimationFrame(paint);

window.fabrikView = Object.freeze({
  state: snapshot,
  // For tests and the console: pause/resume and scrub like the controls do.
  togglePause: () => history.togglePause(),
  scrubTo: (i) => history.scrubTo(i),
  webglError: () => scene.webglError || null,
});
