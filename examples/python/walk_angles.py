"""A notebook-style tour of the Python module `fabrik` (docs/python.md), cell by cell.

    PYTHONPATH=build/python /usr/bin/python3 examples/python/walk_angles.py [TRIAL.trc]

Without a trial it makes one: 2 s of the default model's markers on a smooth synthetic motion.
tests/python/test_example.py runs it, so it cannot rot."""
import sys

import numpy as np

import fabrik

# %% A config: the embedded default (the built-in 45-marker full-body model). A subject's own
# comes from fabrik.load_config("subject.json") or fabrik.calibrate(template, static_trc).
config = fabrik.load_config()
print(config)
print("tracked markers:", ", ".join(config.marker_names[:6]), "...")

# %% Frame by frame, as fabrikd tracks a stream: a (markers, 3) array in mm in the config's
# marker order, or a dict name -> (x, y, z) mm where a missing name is an occluded marker.
frames_mm = fabrik.synthetic_frames(config, frames=200, rate_hz=100.0)
tracker = fabrik.Tracker(config)
knee = []
for f, markers_mm in enumerate(frames_mm):
    pose = tracker.track(markers_mm, time_s=f / 100.0)
    knee.append(pose.angles_deg["knee_angle_r"])
print(pose)
print(f"right knee over 2 s: {min(knee):.1f} .. {max(knee):.1f} deg")
print(f"{tracker.joint_names[1]} at {np.round(pose.joints_mm[1], 1)} mm; pelvis frame "
      f"(w, x, y, z) {np.round(pose.segment_q_world[0], 3)}")

# %% An occluded marker: leave it out of the dict (or make its array row NaN).
markers = {name: tuple(xyz) for name, xyz in zip(tracker.marker_names, frames_mm[-1])}
del markers["RKNE"]
pose = tracker.track(markers, time_s=2.0)
print("occluded:", [n for n, o in zip(tracker.marker_names, pose.occluded) if o],
      "| status:", pose.status, f"| residual {pose.residual_rms_mm:.2f} mm RMS")

# %% A whole trial at once, as `fabrik solve` does it (gaps in the model's markers filled from
# both sides), from a file or from arrays.
if len(sys.argv) > 1:
    trial = fabrik.read_markers(sys.argv[1])
else:
    trial = fabrik.MarkerData(names=config.marker_names, positions_mm=frames_mm,
                              time_s=np.arange(len(frames_mm)) / 100.0, rate_hz=100.0)
solution = fabrik.solve(config, trial)
print(f"{len(solution.time_s)} frames, residual {np.mean(solution.residual_rms_mm):.2f} mm RMS "
      f"on average, statuses {sorted(set(solution.status))}")

# %% The angles as a pandas DataFrame (pandas is imported only here).
try:
    angles = solution.angles_dataframe()
    print(angles[["hip_flexion_r", "knee_angle_r", "ankle_angle_r"]].describe().round(1))
except ImportError as e:
    print(e)

# %% A pose is a snapshot: its arrays stay valid after the next track() and may be kept.
kept = pose.joints_mm
tracker.track(frames_mm[0], time_s=2.01)
print("kept joints still finite:", bool(np.isfinite(kept).all()), "| fabrik", fabrik.__version__)
