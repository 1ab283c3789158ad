"""fabrik.batch (docs/batch.md) on a synthetic archive: a two-worker Dask cluster gives what one
process gives, bad files fail alone, a rerun skips what is done and redoes what is not."""
import concurrent.futures
import csv
import json
import os
import re
import shutil
import subprocess
import sys

import pytest

SOURCE = os.environ["FABRIK_SOURCE_DIR"]
FABRIK = os.environ["FABRIK_BIN"]
TEMPLATE = os.path.join(SOURCE, "config", "templates", "plugin_gait_lower_body.json")
TIMING = ("solve_p50_us", "solve_p99_us", "wall_s")
RUN_TIMEOUT_S = 180      # one batch of a few dozen 1-2 s trials takes seconds
CLUSTER_TIMEOUT_S = 60   # starting two local worker processes takes a few seconds

SUBJECTS, TRIALS = 3, 8
BAD = {("subj01", "walk_truncated"), ("subj02", "walk_unreadable"), ("subj03", "walk_wrong_markers")}
NO_STATIC = "subj04"


def synth_archive(root, subjects, trials, seconds):
    subprocess.run([sys.executable, os.path.join(SOURCE, "scripts", "synth-archive"), str(root),
                    "--subjects", str(subjects), "--trials", str(trials), "--seconds", str(seconds),
                    "--fabrik", FABRIK], check=True, timeout=RUN_TIMEOUT_S, capture_output=True)


def batch(root, out, *args, template=TEMPLATE):
    """`python3 -m fabrik.batch` as a user runs it: (exit code, stderr)."""
    given = ["--template", template] if template else []
    p = subprocess.run([sys.executable, "-m", "fabrik.batch", str(root), "--output", str(out),
                        *given, "--fabrik", FABRIK, *args],
                       capture_output=True, text=True, timeout=RUN_TIMEOUT_S)
    return p.returncode, p.stderr


def summary(out):
    with open(os.path.join(out, "summary.csv"), newline="") as f:
        return list(csv.DictReader(f))


def without_timings(rows, out):
    """Rows minus the columns that time this machine, with OUT's path (in error texts) as 'OUT'."""
    return [{k: v.replace(str(out), "OUT") for k, v in r.items() if k not in TIMING} for r in rows]


def output_files(out):
    return sorted(os.path.relpath(os.path.join(d, n), out)
                  for d, _, names in os.walk(out) for n in names)


def numbers_of(path, out):
    """A file's content as compared between runs: a report without its solve times; text with
    OUT's path as 'OUT' (calibrate names its output) and its numbers parsed."""
    with open(path) as f:
        text = f.read().replace(str(out), "OUT")
    if path.endswith(".report.json"):
        report = json.loads(text)
        del report["solve_us"]
        return report
    return [float(t) if re.fullmatch(r"[-+0-9.eE]+", t) and re.search(r"[0-9]", t) else t
            for t in re.split(r"[\s,]+", text)]


@pytest.fixture(scope="module")
def archive(tmp_path_factory):
    """3 subjects x (1 static + 8 walks of 1.5 s), three bad files, a subject with no static trial."""
    root = tmp_path_factory.mktemp("archive")
    synth_archive(root, SUBJECTS, TRIALS, 1.5)
    walk = os.path.join(root, "subj01", "walk01.trc")
    with open(walk) as f:
        lines = f.read().splitlines(keepends=True)
    with open(os.path.join(root, "subj01", "walk_truncated.trc"), "w") as f:
        f.writelines(lines[:3])  # cut inside the header: no marker names
    with open(os.path.join(root, "subj02", "walk_unreadable.c3d"), "wb") as f:
        f.write(b"not a C3D file")
    labels = lines[3].rstrip("\n").split("\t")  # Frame#, Time, then each name and two blanks
    lines[3] = "\t".join(labels[:2] + [("M%d" % i if name else name)
                                       for i, name in enumerate(labels[2:])]) + "\n"
    with open(os.path.join(root, "subj03", "walk_wrong_markers.trc"), "w") as f:
        f.writelines(lines)
    os.makedirs(os.path.join(root, NO_STATIC))
    for name in ("walk01.trc", "walk02.trc"):
        shutil.copy(os.path.join(root, "subj02", name), os.path.join(root, NO_STATIC, name))
    return root


@pytest.fixture(scope="module")
def scheduler_address():
    """A local Dask cluster of two single-threaded worker processes, reached by its address."""
    distributed = pytest.importorskip("distributed")
    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        cluster = pool.submit(distributed.LocalCluster, n_workers=2, threads_per_worker=1,
                              processes=True, dashboard_address=None).result(CLUSTER_TIMEOUT_S)
    try:
        with distributed.Client(cluster.scheduler_address, timeout=CLUSTER_TIMEOUT_S) as client:
            client.wait_for_workers(2, timeout=CLUSTER_TIMEOUT_S)
        yield cluster.scheduler_address
    finally:
        cluster.close(timeout=CLUSTER_TIMEOUT_S)


@pytest.fixture(scope="module")
def runs(archive, scheduler_address, tmp_path_factory):
    """The archive once sequentially and once on the two-worker cluster."""
    seq, dask = tmp_path_factory.mktemp("sequential"), tmp_path_factory.mktemp("dask")
    return {"sequential": (seq, *batch(archive, seq, "--workers", "1")),
            "dask": (dask, *batch(archive, dask, "--scheduler", scheduler_address))}


def test_the_dask_run_equals_the_sequential_run(runs):
    (seq, _, seq_log), (dask, _, dask_log) = runs["sequential"], runs["dask"]
    assert "on the cluster at tcp://" in dask_log and "on this process" in seq_log
    rows = summary(seq)
    assert len(rows) == SUBJECTS * (1 + TRIALS) + len(BAD) + 2
    assert without_timings(summary(dask), dask) == without_timings(rows, seq)
    files = output_files(seq)
    assert files == output_files(dask)
    assert len([f for f in files if f.endswith(".angles.mot")]) == SUBJECTS * (1 + TRIALS)
    for f in files:
        if f == "summary.csv":
            continue  # compared above, without its timings
        assert numbers_of(os.path.join(dask, f), dask) == numbers_of(os.path.join(seq, f), seq), f


def test_bad_files_fail_alone_and_the_exit_code_says_so(runs):
    for out, code, _ in runs.values():
        assert code == 1
        rows = summary(out)
        failed = {(r["subject"], r["trial"]) for r in rows if r["status"] == "failed"}
        assert failed == BAD | {(NO_STATIC, "walk01"), (NO_STATIC, "walk02")}
        for r in rows:
            if r["status"] == "failed":
                assert r["error"] and r["frames"] == ""
            else:
                assert r["status"] == "ok" and r["error"] == ""
                assert int(r["frames"]) > 0 and 0 < float(r["rms_mean_mm"]) < 5
        by_trial = {(r["subject"], r["trial"]): r["error"] for r in rows}
        assert "walk_unreadable.c3d" in by_trial[("subj02", "walk_unreadable")]
        # The refusal whole enough to act on: the file, the problem and the fix (a cut from
        # the front kept only the lists and the fix).
        wrong = by_trial[("subj03", "walk_wrong_markers")]
        assert "walk_wrong_markers.trc: shares none" in wrong and "Fix: " in wrong, wrong
        # The subject without a static trial: what was found, and the fix.
        assert "no static trial" in by_trial[(NO_STATIC, "walk01")]
        assert "found 2: walk01.trc, walk02.trc" in by_trial[(NO_STATIC, "walk01")]
        assert [f for f in output_files(out) if ".partial" in f or "walk_" in f] == []
        # Each TRC names its own file (as OpenSim and Mokka show it), not the staging name.
        for f in output_files(out):
            if f.endswith(".joints.trc"):
                with open(os.path.join(out, f)) as trc:
                    assert trc.readline().rstrip("\r\n").endswith("\t" + os.path.basename(f)), f
        statics = [r for r in rows if r["kind"] == "static"]
        assert len(statics) == SUBJECTS and all("static" in r["trial"] for r in statics)


def stamps(out):
    return {f: os.stat(os.path.join(out, f)).st_mtime_ns for f in output_files(out)
            if f != "summary.csv"}


def test_a_rerun_skips_what_is_done_and_redoes_what_is_not(tmp_path):
    root, out = tmp_path / "archive", tmp_path / "out"
    synth_archive(root, 2, 3, 1.0)
    code, _ = batch(root, out, "--workers", "1")
    assert code == 0  # no trial failed
    first, before = summary(out), stamps(out)
    assert {r["status"] for r in first} == {"ok"} and len(first) == 2 * 4

    code, log = batch(root, out, "--workers", "1")
    assert code == 0 and "8 done already (skipped), 0 to run" in log
    rows = summary(out)
    assert {r["status"] for r in rows} == {"skipped"}
    assert stamps(out) == before  # nothing rewritten
    strip = lambda rs: [dict(r, status="", **dict.fromkeys(TIMING, "")) for r in rs]
    assert strip(rows) == strip(first)  # the skipped rows carry the done trials' numbers

    # One output gone, one trial half-written (its report renamed last, so missing).
    os.remove(out / "subj02" / "walk03.angles.mot")
    os.mkdir(out / "subj01" / ".walk01.partial")
    os.replace(out / "subj01" / "walk01.report.json", out / "subj01" / ".walk01.partial" / "walk01.report.json")
    # A trial half-written under hidden names beside its outputs (as batches wrote before the
    # staging folder) leaves none of them once it runs again.
    (out / "subj01" / ".walk01.joints.partial.trc").write_text("a half-written joints file\n")
    code, log = batch(root, out, "--workers", "1")
    assert code == 0 and "6 done already (skipped), 2 to run" in log
    rows = summary(out)
    assert {(r["subject"], r["trial"]) for r in rows if r["status"] == "ok"} == {
        ("subj01", "walk01"), ("subj02", "walk03")}
    after = stamps(out)
    rerun = {f for f in before if after.get(f) != before[f]}
    assert rerun == {"subj01/walk01.joints.trc", "subj01/walk01.angles.mot",
                     "subj01/walk01.report.json", "subj01/walk01.batch.json",
                     "subj02/walk03.joints.trc", "subj02/walk03.angles.mot",
                     "subj02/walk03.report.json", "subj02/walk03.batch.json"}
    assert strip(rows) == strip(first)
    assert [f for f in after if ".partial" in f] == []


def test_a_rerun_without_the_template_uses_the_calibrations_on_disk(tmp_path):
    root, out = tmp_path / "archive", tmp_path / "out"
    synth_archive(root, 1, 2, 1.0)
    code, _ = batch(root, out, "--workers", "1")
    assert code == 0 and {r["status"] for r in summary(out)} == {"ok"}
    before = stamps(out)

    code, log = batch(root, out, "--workers", "1", template=None)
    assert code == 0, log  # was: every done trial failed "no template to calibrate with"
    assert {r["status"] for r in summary(out)} == {"skipped"}
    assert stamps(out) == before

    os.remove(out / "subj01" / "walk01.joints.trc")
    code, log = batch(root, out, "--workers", "1", template=None)
    assert code == 0, log
    assert {(r["trial"], r["status"]) for r in summary(out)} >= {("walk01", "ok")}

    os.remove(out / "subj01" / "calibrated.json")  # nothing to reuse: the template is needed
    code, _ = batch(root, out, "--workers", "1", template=None)
    assert code == 1
    assert {r["error"] for r in summary(out)} == {
        'subject subj01: no template to calibrate with. Fix: give --template, or "template" in %s'
        % os.path.join(root, "subj01", "subject.json")}


def test_a_done_trial_does_not_hide_a_problem_that_is_not_calibration(tmp_path):
    root, out = tmp_path / "archive", tmp_path / "out"
    synth_archive(root, 1, 1, 1.0)
    code, _ = batch(root, out, "--workers", "1")
    assert code == 0
    (root / "subj01" / "walk01.c3d").write_bytes(b"")  # walk01 now twice: outputs would collide
    code, _ = batch(root, out, "--workers", "1")
    assert code == 1
    rows = summary(out)
    assert {r["status"] for r in rows} == {"failed"}
    assert all("exist as both .trc and .c3d" in r["error"] for r in rows)


@pytest.mark.parametrize("option", ["--trial-timeout", "--connect-timeout"])
@pytest.mark.parametrize("value", ["-1", "0", "nan", "inf"])
def test_a_timeout_that_is_not_a_positive_number_of_seconds_stops_the_batch(tmp_path, option, value):
    # Negative or 0 would fail every trial as "timed out"; NaN or inf would never time out.
    root = tmp_path / "archive"
    (root / "subj01").mkdir(parents=True)
    code, err = batch(root, tmp_path / "out", "--workers", "1", option, value)
    assert code == 2
    assert option in err and "(0, 1e9]" in err
    assert not (tmp_path / "out").exists()


def test_two_static_trials_are_named_as_what_was_found(tmp_path):
    root, out = tmp_path / "archive", tmp_path / "out"
    (root / "s").mkdir(parents=True)
    for name in ("a_static.trc", "b_STATIC.trc", "walk01.trc"):
        (root / "s" / name).write_text("")  # refused at planning, before any file is read
    code, _ = batch(root, out, "--workers", "1")
    assert code == 1
    errors = {r["error"] for r in summary(out)}
    assert len(errors) == 1
    error = errors.pop()
    assert "more than one static trial" in error
    assert "found 2: a_static.trc, b_STATIC.trc)" in error
    # Both are static trials (the cause of the failure), in the summary as in the message.
    assert {r["trial"]: r["kind"] for r in summary(out)} == {
        "a_static": "static", "b_STATIC": "static", "walk01": "dynamic"}


def replace_keeping_mtime(path, data):
    """Write `data` to `path`, then give it its old mtime back (as `cp -p` of an older export, or a
    tool that preserves times, would): only its size, ctime or content tell it changed."""
    st = os.stat(path)
    with open(path, "wb") as f:
        f.write(data)
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns))


def test_a_rerun_redoes_a_trial_whose_input_changed_and_no_other(tmp_path):
    root, out, shorter = tmp_path / "archive", tmp_path / "out", tmp_path / "shorter"
    synth_archive(root, 1, 2, 1.0)
    synth_archive(shorter, 1, 1, 0.5)
    code, _ = batch(root, out, "--workers", "1")
    assert code == 0
    frames = {r["trial"]: int(r["frames"]) for r in summary(out)}

    # walk01 re-exported shorter (another size), walk02 edited in place (the same size): both
    # with their old mtimes.
    replace_keeping_mtime(root / "subj01" / "walk01.trc",
                          (shorter / "subj01" / "walk01.trc").read_bytes())
    text = (root / "subj01" / "walk02.trc").read_bytes()
    last = text.rstrip().rfind(b"\t") + 1  # a digit of the last sample's last coordinate
    replace_keeping_mtime(root / "subj01" / "walk02.trc",
                          text[:last] + (b"8" if text[last:last + 1] == b"9" else b"9") + text[last + 1:])
    code, log = batch(root, out, "--workers", "1")
    assert code == 0 and "1 done already (skipped), 2 to run" in log, log
    rows = {r["trial"]: r for r in summary(out)}
    assert {t: r["status"] for t, r in rows.items()} == {
        "subj01_static": "skipped", "walk01": "ok", "walk02": "ok"}
    assert int(rows["walk01"]["frames"]) < frames["walk01"]  # was: the 1 s trial's frames, skipped
    assert int(rows["walk02"]["frames"]) == frames["walk02"]

    # The archive copied with its times (cp -p): the same content, so nothing is redone; the
    # records take the copies' stats, so the next run does not read the trials again.
    copy = tmp_path / "copy"
    shutil.copytree(root, copy, copy_function=shutil.copy2)
    before = stamps(out)
    code, log = batch(copy, out, "--workers", "1")
    assert code == 0 and "3 done already (skipped), 0 to run" in log, log
    after = stamps(out)
    assert {f for f in before if after[f] != before[f]} == {
        "subj01/subj01_static.batch.json", "subj01/walk01.batch.json", "subj01/walk02.batch.json"}
    code, log = batch(copy, out, "--workers", "1")
    assert code == 0 and "3 done already (skipped), 0 to run" in log, log
    assert stamps(out) == after


def test_a_rerun_recalibrates_when_the_static_template_or_settings_changed(tmp_path):
    root, out = tmp_path / "archive", tmp_path / "out"
    synth_archive(root, 2, 1, 1.0)
    template = tmp_path / "template.json"
    shutil.copy(TEMPLATE, template)
    code, _ = batch(root, out, "--workers", "1", template=str(template))
    assert code == 0
    config = out / "subj01" / "calibrated.json"

    def rerun(expect_recalibrated):
        before = config.read_bytes()
        code, log = batch(root, out, "--workers", "1", template=str(template))
        assert code == 0, log
        status = {(r["subject"], r["trial"]): r["status"] for r in summary(out)}
        if expect_recalibrated:
            assert "subject subj01: %s" % expect_recalibrated in log, log
            assert status[("subj01", "subj01_static")] == status[("subj01", "walk01")] == "ok"
        else:
            assert "calibrating again" not in log and config.read_bytes() == before, log
            assert set(status.values()) == {"skipped"}
        assert status[("subj02", "subj02_static")] == status[("subj02", "walk01")] == "skipped"
        return before

    static = root / "subj01" / "subj01_static.trc"
    os.utime(static, ns=(0, 0))  # touched (to another clock's time), not changed: kept
    rerun(None)
    # Another static trial under the same name, with the old one's mtime.
    replace_keeping_mtime(static, (root / "subj02" / "subj02_static.trc").read_bytes())
    old = rerun("its static trial subj01_static.trc changed")
    assert config.read_bytes() != old  # calibrated from the new static trial
    (root / "subj01" / "subject.json").write_text('{"calibrate_args": ["--frames", "10"]}')
    rerun("its calibrate_args changed")
    rerun(None)
    template.write_text(template.read_text() + "\n")  # any change to the template's file counts
    code, log = batch(root, out, "--workers", "1", template=str(template))
    assert code == 0 and "subject subj01: its template" in log and "subject subj02: its template" in log
    assert {r["status"] for r in summary(out)} == {"ok"}

    # A config edited by hand is kept (not calibrated over), and the trials solved with it again.
    config.write_text(config.read_text() + "\n")
    edited = config.read_bytes()
    code, log = batch(root, out, "--workers", "1", template=str(template))
    assert code == 0 and "calibrating again" not in log and config.read_bytes() == edited, log
    assert {(r["subject"], r["status"]) for r in summary(out)} == {("subj01", "ok"), ("subj02", "skipped")}


def test_outputs_of_trials_gone_from_root_are_kept_and_named(tmp_path):
    root, out = tmp_path / "archive", tmp_path / "out"
    synth_archive(root, 2, 2, 1.0)
    code, _ = batch(root, out, "--workers", "1")
    assert code == 0
    os.remove(root / "subj01" / "walk02.trc")
    shutil.rmtree(root / "subj02")
    before = output_files(out)
    code, log = batch(root, out, "--workers", "1")
    assert code == 0
    assert ("the outputs of 4 trials in %s belong to no trial of ROOT (kept, not in the summary; "
            "delete them if unwanted): subj01/walk02, subj02/subj02_static, subj02/walk01, "
            "subj02/walk02" % out) in log, log
    assert output_files(out) == before  # nothing deleted
    assert [(r["subject"], r["trial"]) for r in summary(out)] == [
        ("subj01", "subj01_static"), ("subj01", "walk01")]
    os.remove(out / "subj01" / "walk02.report.json")  # one output left of it: still named
    shutil.rmtree(out / "subj02")
    code, log = batch(root, out, "--workers", "1")
    assert "the outputs of 1 trial in %s belong to no trial of ROOT" % out in log, log
    assert "subj01/walk02\n" in log


@pytest.mark.parametrize("missing", ["nowhere.json", "."])
def test_a_missing_template_stops_the_batch(tmp_path, missing):
    root = tmp_path / "archive"
    synth_archive(root, 1, 1, 1.0)
    template = str(tmp_path / missing)
    code, err = batch(root, tmp_path / "out", "--workers", "1", template=template)
    assert code == 2, err  # was: 1, every trial failed with "template ...: no such file"
    assert "usage:" in err and "--template %s: %s" % (template, "no such file" if missing != "."
                                                      else "not a file") in err
    assert not (tmp_path / "out").exists()


def test_a_row_counts_the_reports_warnings():
    from fabrik.batch import row_from_report
    report = {"frames": 10, "residual_mm": {"rms_mean": 1.0, "rms_max": 2.0, "max": 3.0},
              "outliers": {"samples": 0, "frames": 0}, "frames_without_markers": 0,
              "solve_us": {"p50": 10.0, "p99": 20.0},
              "warnings": ["walk.trc: the Time column runs at 30 Hz ...", "walk.trc: ..."]}
    trial = {"subject": "s", "trial": "walk", "kind": "dynamic"}
    assert row_from_report(trial, report, "ok")["warnings"] == 2
    del report["warnings"]  # a report written before the column: none said
    assert row_from_report(trial, report, "ok")["warnings"] == 0


def test_a_static_row_counts_its_calibrations_notes(tmp_path):
    # A subject who moved in the static window was said in calibration.txt only: the static
    # row read "warnings 0" and 300 good frames.
    from fabrik.batch import row_from_report
    report = {"frames": 10, "residual_mm": {"rms_mean": 1.0, "rms_max": 2.0, "max": 3.0},
              "outliers": {"samples": 0, "frames": 0}, "frames_without_markers": 0,
              "solve_us": {"p50": 10.0, "p99": 20.0}, "warnings": ["static.trc: ..."]}
    notes = tmp_path / "calibration.txt"
    notes.write_text("segments\n  pelvis ...\nnote: the subject moved in the static window: ...\n"
                     "note: marker 'RTHI' is missing in 2 of the 300 frames ...\n")
    static = {"subject": "s", "trial": "static", "kind": "static",
              "calibration_report": str(notes)}
    assert row_from_report(static, report, "ok")["warnings"] == 3
    dynamic = dict(static, kind="dynamic", trial="walk")
    assert row_from_report(dynamic, report, "ok")["warnings"] == 1  # the subject's notes once
    gone = dict(static, calibration_report=str(tmp_path / "none.txt"))
    assert row_from_report(gone, report, "ok")["warnings"] == 1


def test_a_long_error_keeps_its_file_problem_and_fix():
    # A refusal whose first line and fix were together over the limit was cut from the
    # front: the row began "...ll)) (fewer than half)", without the file.
    from fabrik.batch import _cli_error
    path = "/lab/" + "long_folder_name/" * 20 + "walk_blank25.trc"
    text = ("fabrik solve: warning: " + path + ": a reader's warning\n"
            "fabrik solve: " + path + ": has only 16 of the 41 marker names" + " x" * 200 + "\n"
            "  config: LASI, ...\n  file:   A, ...\nFix: check the trial" + " y" * 200 + "\n")
    error = _cli_error(text)
    assert len(error) <= 1000, len(error)
    assert error.startswith("fabrik solve: " + path + ": has only 16"), error[:120]
    assert " | ... | Fix: check the trial" in error
