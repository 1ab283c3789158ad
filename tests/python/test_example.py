"""The notebook-style example runs and says what it should (so it cannot rot)."""
import os
import subprocess
import sys

from conftest import SOURCE


def test_walk_angles_example_runs(synth_trial):
    script = os.path.join(SOURCE, "examples", "python", "walk_angles.py")
    for args in ([], [str(synth_trial)]):
        done = subprocess.run([sys.executable, script, *args], capture_output=True, text=True,
                              timeout=120, env=dict(os.environ))
        assert done.returncode == 0, done.stderr
        assert "occluded: ['RKNE']" in done.stdout
        assert "knee_angle_r" in done.stdout and "kept joints still finite: True" in done.stdout
