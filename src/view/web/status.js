// The status line (input rate, poses/s, latency, solve time, residual RMS,
// fit quality, gaps open, frames dropped, config, the vendor source), the
// error banner (also when the latest pose rests on no measured marker), and
// the lists of occluded markers and of sensors.

import {state, sourceOf, untrackedOf} from './state.js';

const STALL_MS = 2000;  // no pose for this long: the stream stopped
const GARBAGE_MS = 5000;  // an undecodable message keeps the banner this long
// fabrikd sends stats every interval_s (1 s by default). Older than 3 of
// them (and 3 s), they no longer show that fabrikd runs: a source they say is
// down is then not what to look at, and the stream's own banners speak.
const STATS_STALE_INTERVALS = 3;
const STATS_STALE_MIN_MS = 3000;

const fmt = (v, digits = 0, unit = '') => (Number.isFinite(v) ? v.toFixed(digits) + unit : '-');

// The source from the latest stats while they are fresh, else null.
function liveSource(now) {
  const interval = Number.isFinite(state.stats && state.stats.interval_s) ? state.stats.interval_s : 1;
  const staleMs = Math.max(STATS_STALE_MIN_MS, STATS_STALE_INTERVALS * interval * 1000);
  return state.stats && now - state.statsAtMs <= staleMs ? sourceOf(state.stats) : null;
}

// When QTM or Motive is down, fabrikd runs and the view waits for poses: the
// banner names the source and fabrikd's own reason, so the user looks at the
// mocap machine, not at fabrikd or the view.
function sourceBanner(src) {
  return `fabrikd is running; its source ${src.url} is not connected: ` +
    (src.last_error || 'no connection yet (no error reported so far)');
}

// The status line's part for the source, as `fabrik watch` words it.
function sourcePart(src) {
  return `source ${src.url} ${src.connected ? 'connected' : 'NOT connected'} ` +
    `(${src.frames} frames, ${src.reconnects} reconnects, ${src.errors} errors)`;
}

// Poses that rest on no measurement still carry a full posture (the last one,
// or the rest posture before any), which looks tracked: the banner says that
// fabrikd itself runs and what the skeleton shown is instead.
function untrackedBanner(u) {
  const counted = u.markers === 0 ? `no marker in the model, none of its ${u.sensors} orientation sensors measured`
    : u.occluded === u.markers ? `all ${u.markers} markers occluded`
    : u.occluded === 0 ? `${u.outliers} of ${u.markers} markers rejected as outliers`
    : `${u.occluded} of ${u.markers} markers occluded` + (u.outliers ? `, ${u.outliers} rejected as outliers` : '');
  const none = u.markers > 0 && u.occluded === u.markers;
  const head = none ? "fabrikd receives frames but none of the model's markers is measured"
                    : 'fabrikd receives frames but the solver has nothing measured to track (no_targets)';
  let shown = 'the skeleton shown is not tracked';
  if (u.no_targets) shown += ', it stands in its last posture';
  else if (u.held > 0) shown += `, it is pulled to the last measured positions of ${u.held} held markers`;
  else if (u.sensors > 0) shown += ' by markers, only orientation sensors turn it';
  return `${head}: ${shown} (${counted})`;
}

export class StatusView {
  constructor({line, banner, occludedList, sensorList}) {
    Object.assign(this, {line, banner, occludedList, sensorList});
    this.inputRate = null;
    this.prevStats = null;
    this.rateWindow = [];   // arrival times (ms) of poses in the last second
    this.garbageSeen = 0;
    this.garbageAt = -Infinity;
    this.shownOccluded = '';
  }

  onStats(stats) {
    const p = this.prevStats;
    if (p && stats.uptime_s > p.uptime_s && stats.frames_in >= p.frames_in)
      this.inputRate = (stats.frames_in - p.frames_in) / (stats.uptime_s - p.uptime_s);
    this.prevStats = stats;
  }

  onPose(arrivedAtMs) {
    this.rateWindow.push(arrivedAtMs);
    while (this.rateWindow.length && this.rateWindow[0] < arrivedAtMs - 1000) this.rateWindow.shift();
  }

  setSensors(names) {
    this.sensorList.replaceChildren(...(names.length ? names : ['none in this config']).map((n) => {
      const li = document.createElement('li');
      li.textContent = n;
      return li;
    }));
  }

  // The banner's text, or null: what is wrong, most serious first. Sets this.kind: 'info'
  // for the server's word while no pose has come yet (not an error), else 'error'.
  bannerText(now) {
    if (state.garbage > this.garbageSeen) { this.garbageSeen = state.garbage; this.garbageAt = now; }
    const st = state.status;
    this.kind = 'error';
    // One page too many: the view said why before it closed; the page retries.
    if (st && st.stream === 'rejected') return `${st.message || 'fabrik view has too many viewers'}`;
    if (!state.connected) return state.messages ? 'Disconnected from fabrik view: reconnecting...' : null;
    if (state.trial) return null;
    if (st && st.stream === 'garbage') return `Garbage on the pose stream: ${st.message || 'undecodable poses'}`;
    // Before the stalled stream and the watchdog: a source down is their cause.
    const src = liveSource(now);
    if (src && !src.connected) return sourceBanner(src);
    // No pose yet: what the view waits for (a wrong --pose, subjects on pose/NAME).
    if (state.received === 0 && st && st.stream === 'waiting' && st.message) {
      this.kind = 'info';
      return st.message;
    }
    if (st && st.stream === 'stalled') return `The pose stream stopped: ${st.message || 'no pose from fabrikd'}`;
    if (state.received > 0 && now - state.latestAtMs > STALL_MS)
      return `The pose stream stopped: no pose for ${((now - state.latestAtMs) / 1000).toFixed(0)} s`;
    // After the stream's own banners: with no new pose the latest says nothing of now.
    const untracked = untrackedOf(state.latest, state.model);
    if (untracked) return untrackedBanner(untracked);
    if (now - this.garbageAt < GARBAGE_MS) return `Undecodable message from fabrik view: ${state.lastGarbage}`;
    return null;
  }

  update(now, pose) {
    state.banner = this.bannerText(now);
    state.bannerKind = state.banner === null ? null : this.kind;
    this.banner.hidden = state.banner === null;
    this.banner.classList.toggle('info', state.bannerKind === 'info');
    if (state.banner !== null) this.banner.textContent = state.banner;

    const s = state.stats || {}, st = state.status || {};
    const r = pose && pose.residual ? pose.residual : {};
    const units = pose && pose.units ? pose.units : 'mm';
    while (this.rateWindow.length && this.rateWindow[0] < now - 1000) this.rateWindow.shift();
    // No marker measured: no residual (0.00 would read as a perfect fit), as `fabrik watch` says.
    const residual = pose && (r.count === 0 || r.quality === 'none') ? 'none (no marker measured)'
      : fmt(r.rms, 2, ' ' + units);
    const fit = [
      `residual RMS ${residual}`,
      `fit ${r.quality || '-'}`,
      `gaps open ${pose ? pose.occluded.length : '-'}`,
    ];
    const config = `config ${s.config || (state.model && state.model.config) || '-'}`;
    let parts;
    if (state.trial) {
      // Only what a recording has: the live stream's rates, latency and drops are not its.
      parts = [`trial ${state.trial.file || '(unnamed)'}`, `paint ${fmt(state.lastPaintMs, 1, ' ms')}`,
               ...fit, config];
    } else {
      parts = [
        `input ${fmt(this.inputRate, 0, ' Hz')}`,
        `fabrikd ${fmt(s.pose_rate_hz, 0, ' poses/s')}`,
        `view ${fmt(st.poses_per_s, 0, ' poses/s')}`,
        `page ${this.rateWindow.length} poses/s`,
        `latency ${fmt(s.queue_latency_us && s.queue_latency_us.p50, 0)}/${fmt(s.queue_latency_us && s.queue_latency_us.p99, 0, ' us')} (p50/p99), paint ${fmt(state.lastPaintMs, 1, ' ms')}`,
        `solve ${fmt(s.solve_us && s.solve_us.p50, 1, ' us')}`,
        ...fit,
        `dropped ${fmt(s.frames_dropped)}`,
        config,
        `stream ${st.stream || (state.connected ? 'connected' : 'connecting')}`,
      ];
      const src = sourceOf(state.stats);
      if (src) parts.push(sourcePart(src));
    }
    // A stream that stopped (or a lost connection) leaves the last figures: say they are old.
    const lastPoseS = (now - state.latestAtMs) / 1000;
    state.statusStale = !state.trial && state.received > 0 &&
      (!state.connected || st.stream === 'stalled' || now - state.latestAtMs > STALL_MS);
    if (state.statusStale) parts.unshift(`STALE: last pose ${lastPoseS.toFixed(0)} s ago, figures as then`);
    this.line.classList.toggle('stale', state.statusStale);
    this.line.textContent = parts.join(' | ');

    const occluded = (pose ? pose.occluded.join(',') : '') + '@' + Math.floor(now / 250);
    if (occluded !== this.shownOccluded) {
      this.shownOccluded = occluded;
      const gaps = (pose && pose.gap_s) || {};
      const held = new Set((pose && pose.held) || []);
      this.occludedList.replaceChildren(...(pose ? pose.occluded : []).map((n) => {
        const li = document.createElement('li');
        li.textContent = n + (held.has(n) ? ' (held)' : '') +
          (Number.isFinite(gaps[n]) ? ` for ${gaps[n].toFixed(1)} s` : '');
        return li;
      }));
    }
  }
}
