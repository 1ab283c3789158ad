// The WebSocket to `fabrik view` (/ws): JSON text messages
// {"topic": "model"|"pose"|"stats"|"status"|"trial", "data": ...}.
// Checks each message's shape, hands good ones to onMessage(topic, data,
// arrivedAtMs) and counts the rest as garbage. Reconnects with a backoff.

import {state} from './state.js';

const isObject = (v) => v !== null && typeof v === 'object' && !Array.isArray(v);
const isVec3 = (v) => Array.isArray(v) && v.length === 3 && v.every(Number.isFinite);

// What is wrong with a message, or null when it can be used.
export function problem(topic, data) {
  switch (topic) {
    case 'pose':
      if (!isObject(data)) return 'pose is not an object';
      if (!Number.isFinite(data.frame)) return 'pose without a frame number';
      if (!isObject(data.joints) || !isObject(data.markers)) return 'pose without joints or markers';
      if (!Array.isArray(data.occluded)) return 'pose without an occluded list';
      for (const [k, v] of Object.entries(data.joints)) if (!isVec3(v)) return `joint ${k} is not [x, y, z]`;
      for (const [k, v] of Object.entries(data.markers)) if (!isVec3(v)) return `marker ${k} is not [x, y, z]`;
      return null;
    case 'model':
      if (!isObject(data) || !Array.isArray(data.joints) || !Array.isArray(data.bones) ||
          !Array.isArray(data.markers)) return 'model without joints, bones or markers';
      if (!data.bones.every((b) => Array.isArray(b) && b.length === 2)) return 'model bone is not a pair';
      return null;
    case 'trial':
      if (!isObject(data) || !Array.isArray(data.poses)) return 'trial without poses';
      if (data.model && problem('model', data.model)) return problem('model', data.model);
      return data.poses.map((p) => problem('pose', p)).find((p) => p) || null;
    case 'stats':
    case 'status':
      return isObject(data) ? null : `${topic} is not an object`;
    default:
      return `unknown topic ${JSON.stringify(String(topic)).slice(0, 40)}`;
  }
}

export function connect(onMessage, onChange) {
  const url = `${location.protocol === 'https:' ? 'wss' : 'ws'}://${location.host}/ws`;
  let delayMs = 250;

  function open() {
    const ws = new WebSocket(url);
    ws.onopen = () => { state.connected = true; onChange(); };
    ws.onclose = () => {
      state.connected = false;
      onChange();
      setTimeout(open, delayMs);
      delayMs = Math.min(delayMs * 2, 4000);
    };
    ws.onmessage = (event) => {
      const arrivedAtMs = performance.now();
      state.messages++;
      let msg = null;
      try { msg = JSON.parse(event.data); } catch (e) { /* counted below */ }
      const why = !isObject(msg) ? 'a message that is not a JSON object'
                                 : problem(msg.topic, msg.data);
      if (why) {
        state.garbage++;
        state.lastGarbage = why;
        onChange();
        return;
      }
      // Back to quick retries only once let in: a page turned away (too many viewers) is
      // opened and closed at once, and retried every 250 ms it kept the server busy.
      if (!(msg.topic === 'status' && msg.data.stream === 'rejected')) delayMs = 250;
      // view_ms: when the pose reached `fabrik view` (wall clock, this machine), on this page's clock.
      const viewAtMs = Number.isFinite(msg.view_ms) ? msg.view_ms - performance.timeOrigin : null;
      onMessage(msg.topic, msg.data, arrivedAtMs, viewAtMs);
    };
  }
  open();
}
