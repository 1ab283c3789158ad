// The page's state: what arrived (model, poses, stats, status) and what was
// drawn. One object, written by the modules that own each part; the test
// reads it through snapshot() (window.fabrikView.state()).

export const state = {
  connected: false,
  model: null,           // the last `model` message's data
  labUp: null,           // the scene's up axis, from model.lab_axes
  lightUp: null,         // where the sky light comes from (the lab's up)
  latest: null,          // newest live pose (newest wins)
  latestAtMs: 0,         // performance.now() when it arrived
  latestViewMs: null,    // its arrival at fabrik view (view_ms, page clock), when stamped
  stats: null,           // last `stats` data
  statsAtMs: 0,          // performance.now() when it arrived
  status: null,          // last `status` data (from fabrik view)
  received: 0,           // pose messages received (live)
  messages: 0,           // all messages received
  garbage: 0,            // messages the page could not use
  lastGarbage: null,     // what was wrong with the last one
  painted: 0,            // frames painted with a pose not painted before
  drawn: {frame: null, bones: 0, markers: 0, occluded: [], measured: 0, residual_lines: 0, frames: 0,
          untracked: false},
  paintMs: [],           // recent arrival -> painted latencies (ms)
  viewPaintMs: [],       // recent arrival at fabrik view -> painted latencies (ms)
  lastPaintMs: null,
  banner: null,          // banner text, null when none
  bannerKind: null,      // 'error', or 'info' (the view's word while no pose has come)
  statusStale: false,    // the status line's figures are of a stream that stopped
  paused: false,
  trial: null,           // {poses: [...], index, file} in trial mode
  plots: {},             // coordinate -> samples held
  history: {size: 0, index: null},
};

const PAINT_KEEP = 600;

function keep(values, v) {
  values.push(v);
  if (values.length > PAINT_KEEP) values.splice(0, values.length - PAINT_KEEP);
}

export function notePaint(ms, viewMs) {
  state.lastPaintMs = ms;
  keep(state.paintMs, ms);
  if (viewMs !== null) keep(state.viewPaintMs, viewMs);
}

const SOURCE_TEXT_CHARS = 300;  // a longer url or error is cut: the banner stays one or two lines
const count = (v) => (Number.isInteger(v) && v >= 0 ? v : 0);
const text = (v) => (typeof v === 'string' && v !== '' ? v.slice(0, SOURCE_TEXT_CHARS) : null);

// The vendor source fabrikd reads itself (stats.source, docs/vendor-sources.md;
// QTM or Motive), checked field by field as the page trusts nothing it is sent,
// or null: stats without it come from a daemon on plain ZeroMQ input.
export function sourceOf(stats) {
  const s = stats && stats.source;
  if (s === null || typeof s !== 'object' || Array.isArray(s)) return null;
  return {url: text(s.url) || '(source)', connected: s.connected === true, server: text(s.server),
          frames: count(s.frames), reconnects: count(s.reconnects), errors: count(s.errors),
          bad_packets: count(s.bad_packets), last_error: text(s.last_error)};
}

// Whether a pose rests on no measurement, as the pose itself says (proto/pose.schema.json):
// solver.status `no_targets` (nothing visible to track: fabrikd left the posture
// as it was) or every tracked marker (the keys of `markers`) in `occluded`
// (none measured: at most held last positions or orientation sensors move
// it). Either alone is enough: a frame whose visible markers were all
// rejected as outliers is no_targets with markers not occluded, and held
// markers or sensors give a status other than no_targets with all occluded.
// Null when the pose is tracked, else what to say about it.
export function untrackedOf(pose, model) {
  if (pose === null || typeof pose !== 'object') return null;
  const noTargets = !!pose.solver && pose.solver.status === 'no_targets';
  const names = pose.markers && typeof pose.markers === 'object' ? Object.keys(pose.markers) : [];
  const occluded = new Set(Array.isArray(pose.occluded) ? pose.occluded : []);
  const occludedN = names.filter((n) => occluded.has(n)).length;
  if (!noTargets && !(names.length > 0 && occludedN === names.length)) return null;
  const listed = (v) => (Array.isArray(v) ? v.length : 0);
  return {no_targets: noTargets, markers: names.length, occluded: occludedN,
          held: Array.isArray(pose.held) ? pose.held.filter((n) => occluded.has(n)).length : 0,
          outliers: listed(pose.outliers), sensors: listed(model && model.sensors)};
}

function quantile(values, q) {
  if (values.length === 0) return null;
  const s = [...values].sort((a, b) => a - b);
  return s[Math.min(s.length - 1, Math.floor(q * s.length))];
}

// A deep copy, so a caller cannot change the page through it.
export function snapshot() {
  const m = state.model;
  return JSON.parse(JSON.stringify({
    connected: state.connected,
    model: m ? {config: m.config ?? null, bones: (m.bones || []).length,
                markers: (m.markers || []).length, joints: (m.joints || []).length,
                segments: (m.segments || []).length, coordinates: (m.coordinates || []).length,
                sensors: (m.sensors || []).length} : null,
    lab_up: state.labUp,
    light_up: state.lightUp,
    drawn: state.drawn,
    received: state.received,
    latest_view_ms: state.latestViewMs,
    messages: state.messages,
    garbage: state.garbage,
    painted: state.painted,
    plots: state.plots,
    banner: state.banner,
    banner_kind: state.bannerKind,
    status_stale: state.statusStale,
    untracked: untrackedOf(state.latest, m),
    paused: state.paused,
    trial: state.trial ? {poses: state.trial.poses.length, index: state.trial.index, file: state.trial.file} : null,
    history: state.history,
    source: sourceOf(state.stats),
    stream: state.status ? state.status.stream : null,
    last_paint_ms: state.lastPaintMs,
    paint_ms: {n: state.paintMs.length, p50: quantile(state.paintMs, 0.5),
               p95: quantile(state.paintMs, 0.95), max: quantile(state.paintMs, 1)},
    view_to_paint_ms: {n: state.viewPaintMs.length, p50: quantile(state.viewPaintMs, 0.5),
                       p95: quantile(state.viewPaintMs, 0.95), max: quantile(state.viewPaintMs, 1)},
  }));
}
