"""The probes in scripts/ that docs quote: each still runs, and says what the CLI says."""
import json
import os
import re
import subprocess
import sys

from conftest import SOURCE, fabrik_cli, shared_data


def test_carry_probe_reports_what_fabrik_solve_does(tmp_path):
    # docs/joint-limits.md quotes scripts/carry-probe (gait2354 on subject01_walk1 at carry 0).
    static, walk = shared_data("subject01_static.trc"), shared_data("subject01_walk1.trc")
    template = os.path.join(SOURCE, "config", "templates", "gait2354.json")
    probe = subprocess.run(
        [sys.executable, os.path.join(SOURCE, "scripts", "carry-probe"), "--carry", "0.25",
         "--template", template, "--static", static, "--trial", walk, "--cold-starts", "0"],
        capture_output=True, text=True, timeout=300, env=dict(os.environ))
    assert probe.returncode == 0, probe.stderr
    said = re.search(r"residual RMS ([\d.]+) mm \(mean over frames\), max ([\d.]+) mm \((\S+), "
                     r"frame index (\d+), file frame (\d+)\)", probe.stdout)
    assert said, probe.stdout
    cold = re.search(r"frame index +0: ([\d.]+) mm", probe.stdout)
    assert cold, probe.stdout
    config = tmp_path / "c.json"
    fabrik_cli("calibrate", "--template", template, "--static", static, "--output", config)
    edited = json.loads(config.read_text())
    edited["solver"]["subtree_carry"] = 0.25
    config.write_text(json.dumps(edited))
    report = tmp_path / "r.json"
    fabrik_cli("solve", "--config", config, "--input", walk, "--output", tmp_path / "j.trc",
               "--report", report, "--quiet")
    residual = json.loads(report.read_text())["residual_mm"]
    assert float(said.group(1)) == round(residual["rms_mean"], 2)
    assert float(said.group(2)) == round(residual["max"], 2)
    assert said.group(3) == residual["max_marker"]
    assert int(said.group(5)) == residual["max_frame"]
    # Cold from the first frame is the whole run's track: the same worst frame.
    assert float(cold.group(1)) == float(said.group(2))
