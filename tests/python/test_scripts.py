"""The probes in scripts/ that docs quote: each still runs, and says what the CLI says."""
import json
import os
import re
import subprocess
import sys

from conftest import SOURCE, fabrik_cli, shared_data


def test_carry_probe_reports_what_fabrik_solve_does(tmp_path):
    # docs/joint-limits.md quotes scripts/carry-probe: gait2354 on subject01_walk1 at carry 0,
    # whose worst frame is its own fit, the same from any cold start before it.
    static, walk = shared_data("subject01_static.trc"), shared_data("subject01_walk1.trc")
    template = os.path.join(SOURCE, "config", "templates", "gait2354.json")
    probe = subprocess.run(
        [sys.executable, os.path.join(SOURCE, "scripts", "carry-probe"), "--carry", "0",
         "--template", template, "--static", static, "--trial", walk,
         "--cold-starts", "0", "40", "52"],
        capture_output=True, text=True, timeout=300, env=dict(os.environ))
    assert probe.returncode == 0, probe.stderr
    said = re.search(r"residual RMS ([\d.]+) mm \(mean over frames\), max ([\d.]+) mm \((\S+), "
                     r"file frame (\d+), frame index (\d+)\)", probe.stdout)
    assert said, probe.stdout
    cold = [float(mm) for mm in re.findall(r"frame index +\d+: ([\d.]+) mm", probe.stdout)]
    assert len(cold) == 3, probe.stdout
    config = tmp_path / "c.json"
    fabrik_cli("calibrate", "--template", template, "--static", static, "--output", config)
    edited = json.loads(config.read_text())
    edited["solver"]["subtree_carry"] = 0
    config.write_text(json.dumps(edited))
    report = tmp_path / "r.json"
    fabrik_cli("solve", "--config", config, "--input", walk, "--output", tmp_path / "j.trc",
               "--report", report, "--quiet")
    residual = json.loads(report.read_text())["residual_mm"]
    assert float(said.group(1)) == round(residual["rms_mean"], 2)
    assert float(said.group(2)) == round(residual["max"], 2)
    assert said.group(3) == residual["max_marker"]
    assert int(said.group(4)) == residual["max_frame"]
    # The docs' claim: from every cold start, the worst frame comes out the same to 0.1 mm.
    assert all(abs(mm - residual["max"]) <= 0.1 for mm in cold), (cold, residual["max"])
