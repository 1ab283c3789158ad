"""What a track() call costs from Python over the same call from C++ (docs/python.md).

    PYTHONPATH=build/python /usr/bin/python3 -m fabrik.bench [--config FILE] [--frames N]

The same synthetic frames (synthetic_frames: the config's model on a smooth motion, 0.5 mm
noise) go, each from a cold start, interleaved, `--repeats` times, through
  C++        a C++ loop over Tracker::track (_bench_track_cpp; input already in metres),
  array      Tracker.track with a (markers, 3) array,
  dict       Tracker.track with a dict of tuples whose keys are the same str objects every
             frame (built from one list of names),
  dict-new   the same with new str keys every frame (e.g. parsed from JSON per frame).
The dicts are built beforehand: the caller's cost, not the module's.

Two figures per input, both medians over the frames (robust to the scheduler's preemptions on a
loaded machine). "difference": the median wall time of a Python track() call minus the median
of the C++ loop's calls (each frame timed alone in both): what a caller sees, including the
solve's own variation between runs. "edge": the Python edge alone, within the same calls: each
call's wall time minus Pose.track_us (the C++ Tracker::track inside it). Figures, not a
pass/fail test."""
import argparse
import statistics
import time

from . import _fabrik
from .config import load_config


def run(track, inputs, rate_hz):
    """Per call: wall us and the edge (wall - track_us) in us."""
    clock = time.perf_counter_ns
    walls, edges = [], []
    for f, markers in enumerate(inputs):
        t0 = clock()
        pose = track(markers, f / rate_hz)
        wall = (clock() - t0) / 1e3
        walls.append(wall)
        edges.append(wall - pose.track_us)
    return walls, edges


def quantile(values, q):
    ordered = sorted(values)
    return ordered[int(q * (len(ordered) - 1))]


def _at_least_one(text):
    n = int(text)
    if n < 1:
        raise argparse.ArgumentTypeError("must be 1 or more, not %s" % text)
    return n


def main(argv=None):
    p = argparse.ArgumentParser(prog="python3 -m fabrik.bench",
                                description=__doc__.split("\n")[0])
    p.add_argument("--config", help="daemon config (default: the embedded default)")
    p.add_argument("--frames", type=_at_least_one, default=2000)
    p.add_argument("--rate", type=float, default=100.0, help="frame rate (Hz)")
    p.add_argument("--repeats", type=_at_least_one, default=3)
    a = p.parse_args(argv)
    if not a.rate > 0:
        p.error("--rate must be more than 0")
    config = load_config(a.config)
    frames = _fabrik.synthetic_frames(config, a.frames, a.rate)
    names = config.marker_names
    inputs = {
        "array": list(frames),
        "dict": [{n: tuple(map(float, x)) for n, x in zip(names, row)} for row in frames],
        "dict-new": [{"".join(n): tuple(map(float, x)) for n, x in zip(names, row)}
                     for row in frames],
    }
    print(f"config {config.file}: model '{config.model_name}', {len(names)} markers, "
          f"{a.frames} frames at {a.rate:g} Hz, {a.repeats} repeats")
    print(f"{'repeat':>6} {'input':>9} {'Python p50 us':>14} {'C++ p50 us':>11} "
          f"{'difference':>11} {'edge p50 us':>12} {'edge p90 us':>12}")
    diffs = {k: [] for k in inputs}
    medians = {k: [] for k in inputs}
    for r in range(a.repeats):
        for kind, data in inputs.items():
            cpp = statistics.median(_fabrik._bench_track_cpp(config, frames, a.rate))
            walls, edges = run(_fabrik.Tracker(config).track, data, a.rate)
            wall, p50 = statistics.median(walls), statistics.median(edges)
            diffs[kind].append(wall - cpp)
            medians[kind].append(p50)
            print(f"{r + 1:>6} {kind:>9} {wall:14.2f} {cpp:11.2f} {wall - cpp:11.2f} "
                  f"{p50:12.2f} {quantile(edges, 0.9):12.2f}")
    for kind in inputs:
        print(f"{kind:>9}: Python edge p50 {min(medians[kind]):.2f}..{max(medians[kind]):.2f} us; "
              f"median call minus the C++ median {min(diffs[kind]):.2f}..{max(diffs[kind]):.2f} us "
              f"(ranges over repeats)")


if __name__ == "__main__":
    main()
