// The poses the page can show again: the last 30 s of the live stream (pause
// and scrub back through it) or, in trial mode, every pose of a solved trial
// (a time slider and play/pause). current() is the entry to paint.

export class History {
  constructor(seconds = 30) {
    this.seconds = seconds;
    this.entries = [];     // {seq, pose, t (s), arrivedAtMs, viewAtMs (when it reached fabrik view)}
    this.nextSeq = 0;
    this.paused = false;
    this.viewSeq = null;   // the entry shown while paused
    this.trial = null;     // {playing, startedAt, startT} in trial mode
  }

  get live() { return this.trial === null; }

  push(pose, arrivedAtMs, viewAtMs = null) {
    if (!this.live) return;
    this.entries.push({seq: this.nextSeq++, pose, t: arrivedAtMs / 1000, arrivedAtMs, viewAtMs});
    const oldest = arrivedAtMs / 1000 - this.seconds;
    let drop = 0;
    while (drop < this.entries.length - 1 && this.entries[drop].t < oldest) drop++;
    if (drop > 0) this.entries.splice(0, drop);
  }

  setTrial(poses) {
    const dt = 0.01;  // when a pose has no time
    this.entries = poses.map((pose, i) => ({seq: i, pose,
      t: Number.isFinite(pose.time) ? pose.time : i * dt, arrivedAtMs: null, viewAtMs: null}));
    this.nextSeq = poses.length;
    this.trial = {playing: true, startedAt: performance.now(), startT: this.entries.length ? this.entries[0].t : 0};
    this.paused = false;
    this.viewSeq = 0;
  }

  indexOf(seq) {
    if (this.entries.length === 0) return -1;
    const i = seq - this.entries[0].seq;
    return Math.max(0, Math.min(this.entries.length - 1, i));
  }

  // The entry to paint now.
  current(now = performance.now()) {
    if (this.entries.length === 0) return null;
    if (this.trial && this.trial.playing) {
      const first = this.entries[0].t, last = this.entries[this.entries.length - 1].t;
      const span = Math.max(last - first, 1e-9);
      const t = first + ((this.trial.startT - first + (now - this.trial.startedAt) / 1000) % span);
      let i = this.indexOf(this.viewSeq ?? 0);
      if (this.entries[i].t > t) i = 0;
      while (i + 1 < this.entries.length && this.entries[i + 1].t <= t) i++;
      this.viewSeq = this.entries[i].seq;
      return this.entries[i];
    }
    if (this.paused || this.trial) return this.entries[this.indexOf(this.viewSeq)];
    return this.entries[this.entries.length - 1];
  }

  // Entries within `seconds` before (and including) the given one.
  window(entry, seconds) {
    const end = this.indexOf(entry.seq);
    let start = end;
    while (start > 0 && this.entries[start - 1].t >= entry.t - seconds) start--;
    return this.entries.slice(start, end + 1);
  }

  // Pause (live: freeze on the newest; trial: stop playing) or go on.
  togglePause() {
    if (this.trial) {
      this.trial.playing = !this.trial.playing;
      if (this.trial.playing) {
        const e = this.entries[this.indexOf(this.viewSeq ?? 0)];
        this.trial.startedAt = performance.now();
        this.trial.startT = e ? e.t : 0;
      }
      return;
    }
    this.paused = !this.paused;
    this.viewSeq = this.paused && this.entries.length ? this.entries[this.entries.length - 1].seq : null;
  }

  // Show the entry at index i (0 = oldest held); pauses.
  scrubTo(i) {
    if (this.entries.length === 0) return;
    if (this.trial) this.trial.playing = false;
    else this.paused = true;
    this.viewSeq = this.entries[Math.max(0, Math.min(this.entries.length - 1, i))].seq;
  }

  isPaused() { return this.trial ? !this.trial.playing : this.paused; }
}

// The pause button and the slider, bound to a History.
export function bindTransport(history, button, slider, label) {
  button.addEventListener('click', () => history.togglePause());
  slider.addEventListener('input', () => history.scrubTo(Number(slider.value)));
  return function update(entry) {
    const n = history.entries.length;
    slider.max = String(Math.max(0, n - 1));
    slider.disabled = n === 0;
    const paused = history.isPaused();
    button.textContent = paused ? (history.trial ? 'Play' : 'Live') : 'Pause';
    if (entry) slider.value = String(history.indexOf(entry.seq));
    if (!entry) label.textContent = '';
    else if (history.trial) label.textContent = `trial ${entry.t.toFixed(2)} s, frame ${entry.pose.frame}`;
    else if (paused) label.textContent = `paused ${(history.entries[n - 1].t - entry.t).toFixed(1)} s back, frame ${entry.pose.frame}`;
    else label.textContent = `live, frame ${entry.pose.frame}`;
  };
}
