"""Batch runs over a lab's archive: calibrate each subject, solve every trial, on Dask (docs/batch.md).

    python3 -m fabrik.batch ROOT --output OUT [--template T] [--scheduler ADDRESS]
                            [--workers N] [--fabrik PATH]

ROOT holds one folder per subject; each holds one static trial (a .trc/.c3d whose
name contains "static", any case) and its other trials (.trc/.c3d, subfolders
allowed). Per subject the static trial is calibrated once (`fabrik calibrate`), then
every trial is solved with that config (`fabrik solve`). The work is done by the
`fabrik` CLI in subprocesses, so a crash in one trial is a failed row, not a lost
worker, and a Dask worker needs the CLI but not this package's extension.
"""
import argparse
import csv
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
import uuid

TRIAL_SUFFIXES = (".trc", ".c3d")
STATIC_WORD = "static"
SUBJECT_FILE = "subject.json"
CONFIG_NAME = "calibrated.json"           # per subject, in OUT/SUBJECT
CALIBRATION_REPORT = "calibration.txt"    # calibrate's printed fit report, beside it
CALIBRATION_RECORD = "calibrated.record.json"  # what it was calibrated from (not a trial's suffix)
SUMMARY_NAME = "summary.csv"
# The outputs of one trial, by what they hold: suffixes appended to the trial's name.
# The report is renamed into place last, so its presence marks a complete trial. The record
# says what the outputs were solved from (the input file, the config): a rerun redoes them when
# either differs.
OUTPUT_SUFFIXES = {"joints": ".joints.trc", "angles": ".angles.mot", "record": ".batch.json",
                   "report": ".report.json"}

COLUMNS = ["subject", "trial", "kind", "status", "frames", "rms_mean_mm", "rms_max_mm", "max_mm",
           "max_marker", "quality_good", "quality_poor", "outlier_samples", "outlier_frames",
           "gap_runs", "gap_samples", "frames_without_markers", "markers_missing", "warnings",
           "solve_p50_us", "solve_p99_us", "wall_s", "error"]
# Columns that measure this machine, not the trial: they differ between two runs.
TIMING_COLUMNS = ("solve_p50_us", "solve_p99_us", "wall_s")

EXIT_OK, EXIT_TRIALS_FAILED, EXIT_SETUP = 0, 1, 2


class SetupError(Exception):
    """The batch cannot start (bad ROOT, OUT, template, CLI or cluster): exit code 2."""


# ---------------------------------------------------------------------------------------------
# The archive: subjects, their static trial and trials.

def _trial_files(folder):
    """Every .trc/.c3d under `folder` (hidden names skipped), as sorted relative POSIX paths."""
    found = []
    for dirpath, dirnames, filenames in os.walk(folder):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
        for name in filenames:
            if not name.startswith(".") and name.lower().endswith(TRIAL_SUFFIXES):
                found.append(os.path.relpath(os.path.join(dirpath, name), folder).replace(os.sep, "/"))
    return sorted(found)


def _trial_id(relpath):
    return os.path.splitext(relpath)[0]


def _subject_settings(folder):
    """The optional SUBJECT/subject.json: {"static": FILE, "template": FILE, "calibrate_args": [...]}."""
    path = os.path.join(folder, SUBJECT_FILE)
    if not os.path.exists(path):
        return {}
    try:
        with open(path) as f:
            settings = json.load(f)
    except (OSError, ValueError) as e:
        raise ValueError("%s: not readable as JSON (%s)" % (path, e))
    unknown = set(settings) - {"static", "template", "calibrate_args"} if isinstance(settings, dict) else None
    if unknown is None or unknown:
        raise ValueError('%s: expected an object with "static", "template" and/or "calibrate_args"%s'
                         % (path, "" if unknown is None else ", not " + ", ".join(sorted(unknown))))
    args = settings.get("calibrate_args", [])
    if not isinstance(args, list) or not all(isinstance(a, str) for a in args):
        raise ValueError('%s: "calibrate_args" must be a list of strings' % path)
    return settings


def find_subjects(root, template=None):
    """The subjects of the archive at `root`, sorted by name: a list of dicts.

    Each: name, folder, template, calibrate_args, static (relative path or None),
    trials (relative paths, the static among them), statics (the trials taken for static
    ones: the summary's kind; several or a missing one is a problem), problem (None, or why the subject
    cannot be calibrated: its trials are then reported as failed with this text),
    calibration_problem (the problem is with the static or template alone: a calibration
    already on disk is reused instead).
    """
    subjects = []
    for name in sorted(os.listdir(root)):
        folder = os.path.join(root, name)
        if name.startswith(".") or not os.path.isdir(folder):
            continue
        s = {"name": name, "folder": folder, "template": template, "calibrate_args": [],
             "static": None, "statics": [], "trials": _trial_files(folder), "problem": None,
             "calibration_problem": False}
        subjects.append(s)
        try:
            settings = _subject_settings(folder)
        except ValueError as e:
            s["problem"] = str(e)
            continue
        s["calibrate_args"] = settings.get("calibrate_args", [])
        if "template" in settings:
            s["template"] = os.path.join(folder, settings["template"])
        if "static" in settings:
            static = str(settings["static"]).replace(os.sep, "/")
            if static not in s["trials"]:
                s["problem"] = ('%s names the static trial "%s", which is not among its trials (%s)'
                                % (os.path.join(folder, SUBJECT_FILE), static, _listing(s["trials"])))
            s["static"] = static
            s["statics"] = [static] if static in s["trials"] else []
        else:
            statics = [t for t in s["trials"] if STATIC_WORD in os.path.basename(t).lower()]
            # Static in the summary even when there are several: the user sees which were found.
            s["statics"] = statics
            if len(statics) == 1:
                s["static"] = statics[0]
            else:
                s["problem"] = (
                    "subject %s: %s static trial (a .trc/.c3d whose name contains \"%s\", any case)"
                    " among its trials (%s). Fix: keep one static trial, or name it in %s as "
                    '{"static": "FILE"}' % (name, "no" if not statics else "more than one",
                                            STATIC_WORD, _listing(statics or s["trials"]),
                                            os.path.join(folder, SUBJECT_FILE)))
        if s["problem"] is None and not s["template"]:
            s["problem"] = ("subject %s: no template to calibrate with. Fix: give --template, or "
                            '"template" in %s' % (name, os.path.join(folder, SUBJECT_FILE)))
        elif s["problem"] is None and not os.path.isfile(s["template"]):
            s["problem"] = "subject %s: template %s: no such file" % (name, s["template"])
        s["calibration_problem"] = s["problem"] is not None
        ids = [_trial_id(t) for t in s["trials"]]
        twins = sorted({i for i in ids if ids.count(i) > 1})
        if s["problem"] is None and twins:
            s["problem"] = ("subject %s: trials %s exist as both .trc and .c3d: their outputs would "
                            "collide. Fix: keep one of each" % (name, ", ".join(twins)))
    return subjects


def _listing(names, most=10):
    return "found %d: %s" % (len(names), _shown(names, most)) if names else "found none"


def _shown(names, most=10):
    return ", ".join(names[:most]) + (", ..." if len(names) > most else "")


# ---------------------------------------------------------------------------------------------
# The tasks. Plain functions of plain values (dicts, strings), so Dask can ship them to any
# worker; they never raise for a bad trial: failures are values (rows with an error).

def _cli_error(proc_or_text, limit=1000):
    """The CLI's message on one line: the last lines of its stderr."""
    text = proc_or_text if isinstance(proc_or_text, str) else (proc_or_text.stderr or "")
    lines = [ln.strip() for ln in text.replace("\r", "\n").splitlines() if ln.strip()]
    # The error starts at the last line the CLI prefixes ("fabrik solve: FILE: problem") that
    # is not a warning; its lists and its fix follow.
    starts = [k for k, ln in enumerate(lines)
              if ln.startswith("fabrik ") and ": warning: " not in ln]
    error = lines[starts[-1]:] if starts else lines[-4:]
    one = " | ".join(error)
    if len(one) <= limit:
        return one
    # The first line names the file and the problem, the last the fix: kept, the lists between
    # them left out, each cut at its end where they are still too long (a cut from the front
    # lost the file's name).
    half = (limit - len(" | ... | ")) // 2
    cut = lambda text: text if len(text) <= half else text[:half - 3] + "..."
    if len(error) == 1:
        return error[0][:limit - 3] + "..."
    return cut(error[0]) + " | ... | " + cut(error[-1])


def _run_cli(cmd, timeout_s):
    """(returncode, error text or None) of one CLI run, bounded by `timeout_s`."""
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return None, "timed out after %g s: %s" % (timeout_s, " ".join(cmd[:2]))
    except OSError as e:
        return None, "cannot run %s: %s" % (cmd[0], e)
    if p.returncode != 0:
        what = "exit %d" % p.returncode if p.returncode > 0 else "killed by signal %d" % -p.returncode
        return p, "%s (%s)" % (_cli_error(p) or "no message", what)
    return p, None


def _partial(path):
    """The temporary name `path` is written under before its rename: hidden, same folder and suffix."""
    folder, name = os.path.split(path)
    stem, suffix = os.path.splitext(name)
    return os.path.join(folder, "." + stem + ".partial" + suffix)


def _remove(paths):
    for p in paths:
        try:
            os.remove(p)
        except FileNotFoundError:
            pass


# What produced an output: files are known by their stat and their content's hash. Only equality
# is tested, never "newer than": a clock that is off, or `cp -p` giving a new file an old mtime,
# cannot make a changed file pass for the old one.

def _stat_key(st):
    # ctime cannot be set by a user or `cp -p`: any write, replacement or copy changes it.
    return [st.st_size, st.st_mtime_ns, st.st_ctime_ns, st.st_ino]


def _sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def file_identity(path):
    """{"stat": [size, mtime_ns, ctime_ns, inode], "sha256": ...} of the file at `path`."""
    key = _stat_key(os.stat(path))  # before the hash: a write in between makes the next check hash
    return {"stat": key, "sha256": _sha256(path)}


def same_file(path, identity):
    """Whether `path` holds the content `identity` describes. The same stat is taken as the same
    file, unread (cheap for a big archive); a different size is a different file; anything else
    (a copy, a move, a touch, a chmod) is settled by reading the file and comparing its hash.
    Returns (same, identity now): the caller may record the new stat to skip the hash next time."""
    try:
        st = os.stat(path)
        if identity["stat"] == _stat_key(st):
            return True, identity
        if identity["stat"][0] != st.st_size:
            return False, None
        now = file_identity(path)
        return now["sha256"] == identity["sha256"], now
    except (OSError, KeyError, TypeError, IndexError):
        return False, None


def _read_record(path):
    try:
        with open(path) as f:
            record = json.load(f)
        return record if isinstance(record, dict) else None
    except (OSError, ValueError):
        return None


def _write_json(path, value):
    partial = _partial(path)
    with open(partial, "w") as f:
        json.dump(value, f, indent=1, sort_keys=True)
        f.write("\n")
    os.replace(partial, path)


def calibrate_subject(job):
    """Calibrate one subject (once): {"config": path, "sha256": its hash} or {"error": text}.

    job: fabrik, template, static (path), config (path to write), calibrate_args,
    timeout_s, recalibrate (why the config on disk is stale, or absent). An existing config
    (a previous run's, or put there by hand) is reused unless `recalibrate` says why not.
    """
    try:
        return _calibrate_subject(job)
    except Exception as e:  # e.g. OUT not writable: the subject's trials fail, the batch goes on
        return {"error": "calibration from %s failed: %s: %s" % (job["static"], type(e).__name__, e)}


def _calibrate_subject(job):
    config = job["config"]
    if os.path.isfile(config) and not job.get("recalibrate"):
        return {"config": config, "sha256": _sha256(config), "reused": True}
    os.makedirs(os.path.dirname(config), exist_ok=True)
    partial = _partial(config)
    # Taken before calibrate reads them: a file changed meanwhile is seen as changed next time.
    record = {"static": file_identity(job["static"]), "template": file_identity(job["template"]),
              "calibrate_args": list(job["calibrate_args"])}
    cmd = [job["fabrik"], "calibrate", "--template", job["template"], "--static", job["static"],
           "--output", partial] + list(job["calibrate_args"])
    p, error = _run_cli(cmd, job["timeout_s"])
    if error:
        _remove([partial])
        return {"error": "calibration from %s failed: %s" % (job["static"], error)}
    with open(os.path.join(os.path.dirname(config), CALIBRATION_REPORT), "w") as f:
        f.write(p.stdout.replace(partial, config))
    record["config_sha256"] = _sha256(partial)
    _write_json(os.path.join(os.path.dirname(config), CALIBRATION_RECORD), record)
    os.replace(partial, config)
    return {"config": config, "sha256": record["config_sha256"], "reused": False}


def _has_coordinates(config_path):
    """Whether the calibrated model names coordinates (else `fabrik solve` refuses --angles)."""
    with open(config_path) as f:
        model = json.load(f).get("model", {})
    return isinstance(model, dict) and bool(model.get("coordinates"))


def _blank_row(trial):
    row = dict.fromkeys(COLUMNS, "")
    row.update(subject=trial["subject"], trial=trial["trial"], kind=trial["kind"])
    return row


def calibration_notes(report_path):
    """The notes `fabrik calibrate` printed (its "note: ..." lines in calibration.txt): a
    subject who moved in the static window, a lab axis far from the pose's, ..."""
    try:
        with open(report_path) as f:
            return [ln[len("note: "):].strip() for ln in f if ln.startswith("note: ")]
    except OSError:
        return []


def row_from_report(trial, report, status, wall_s=""):
    """A summary row from `fabrik solve --report` JSON (docs/batch.md lists the columns); a
    static trial's warnings count its calibration's notes too (trial["calibration_report"])."""
    row = _blank_row(trial)
    r = report["residual_mm"]
    filled = report.get("filled", {})
    row.update(
        status=status, frames=report["frames"],
        rms_mean_mm=round(r["rms_mean"], 4), rms_max_mm=round(r["rms_max"], 4),
        max_mm=round(r["max"], 4), max_marker=r.get("max_marker", ""),
        quality_good=report.get("quality", {}).get("good", 0),
        quality_poor=report.get("quality", {}).get("poor", 0),
        outlier_samples=report["outliers"]["samples"], outlier_frames=report["outliers"]["frames"],
        gap_runs=sum(len(runs) for runs in filled.values()),
        gap_samples=sum(last - first + 1 for runs in filled.values() for first, last in runs),
        frames_without_markers=report["frames_without_markers"],
        markers_missing=len(report.get("markers_missing_in_trial", [])),
        warnings=len(report.get("warnings", [])) + (
            len(calibration_notes(trial["calibration_report"]))
            if trial.get("kind") == "static" and trial.get("calibration_report") else 0),
        solve_p50_us=round(report["solve_us"]["p50"], 2),
        solve_p99_us=round(report["solve_us"]["p99"], 2),
        wall_s=wall_s)
    return row


def trial_outputs(out_dir, trial_id):
    """The output paths of one trial, by kind (OUTPUT_SUFFIXES)."""
    base = os.path.join(out_dir, *trial_id.split("/"))
    return {k: base + suffix for k, suffix in OUTPUT_SUFFIXES.items()}


def done_report(outputs, input_path, config_sha256, want_angles=True):
    """The report of a trial done from this input and config (all its outputs present, its record
    naming the same input content and config), else None."""
    needed = [k for k in outputs if want_angles or k != "angles"]
    if not all(os.path.isfile(outputs[k]) for k in needed):
        return None
    record = _read_record(outputs["record"])
    if record is None or record.get("config_sha256") != config_sha256:
        return None
    same, now = same_file(input_path, record.get("input"))
    if not same:
        return None
    try:
        with open(outputs["report"]) as f:
            report = json.load(f)
    except (OSError, ValueError):
        return None
    if now is not record.get("input"):  # the same content under a new stat (copied, moved):
        try:                             # record it, so that the next run need not read it
            _write_json(outputs["record"], dict(record, input=now))
        except OSError:
            pass
    return report


def solve_trial(job, calibration):
    """Solve one trial with its subject's calibration: a summary row (never raises for a bad file).

    job: fabrik, subject, trial (id), kind, input (path), outputs (kind -> path),
    timeout_s. calibration: calibrate_subject's result (Dask passes the finished task's).
    """
    started = time.monotonic()
    try:
        return _solve_trial(job, calibration, started)
    except Exception as e:  # e.g. a full disk, an unexpected report: this trial fails, not the batch
        return dict(_blank_row(job), status="failed", wall_s=round(time.monotonic() - started, 3),
                    error="%s: %s" % (type(e).__name__, e))


def _solve_trial(job, calibration, started):
    row = _blank_row(job)
    if "error" in calibration:
        row.update(status="failed", error=calibration["error"])
        return row
    try:
        angles = _has_coordinates(calibration["config"])
    except (OSError, ValueError) as e:
        row.update(status="failed", error="%s: %s" % (calibration["config"], e))
        return row
    outputs = job["outputs"]
    kinds = [k for k in ("joints", "angles", "record", "report") if angles or k != "angles"]
    # Written under their own names in a hidden folder, not under hidden names: a TRC's header
    # names its file, and must name the one the user gets.
    staging = os.path.join(os.path.dirname(outputs["report"]),
                           "." + os.path.basename(job["trial"]) + ".partial")
    partial = {k: os.path.join(staging, os.path.basename(outputs[k])) for k in kinds}
    # A half-written trial starts over, hidden names beside its outputs included (where batches
    # before the staging folder wrote them).
    _remove(list(outputs.values()) + [_partial(p) for p in outputs.values()])
    shutil.rmtree(staging, ignore_errors=True)
    os.makedirs(staging)
    # Before the solve reads the input: a file changed meanwhile is seen as changed next time.
    try:
        record = {"input": file_identity(job["input"]),
                  "config_sha256": calibration.get("sha256") or _sha256(calibration["config"])}
    except OSError as e:
        shutil.rmtree(staging, ignore_errors=True)
        row.update(status="failed", error=str(e), wall_s=round(time.monotonic() - started, 3))
        return row
    cmd = [job["fabrik"], "solve", "--config", calibration["config"], "--input", job["input"],
           "--output", partial["joints"], "--report", partial["report"], "--quiet"]
    if angles:
        cmd += ["--angles", partial["angles"]]
    _, error = _run_cli(cmd, job["timeout_s"])
    report = None
    if error is None:
        try:
            with open(partial["report"]) as f:
                report = json.load(f)
        except (OSError, ValueError) as e:
            error = "the report: %s" % e
    if error is not None:
        shutil.rmtree(staging, ignore_errors=True)
        row.update(status="failed", error=error, wall_s=round(time.monotonic() - started, 3))
        return row
    row = row_from_report(job, report, "ok", round(time.monotonic() - started, 3))
    _write_json(partial["record"], record)
    for k in kinds:  # the report last: it marks the trial complete
        os.replace(partial[k], outputs[k])
    shutil.rmtree(staging, ignore_errors=True)  # the trial is done: a leftover must not fail it
    return row


def check_cli(fabrik, timeout_s=60):
    """`fabrik --version` (the version line), or an error text: run where the trials will run."""
    p, error = _run_cli([fabrik, "--version"], timeout_s)
    return {"error": error} if error else {"version": p.stdout.strip()}


# ---------------------------------------------------------------------------------------------
# The plan: what to calibrate and solve, what is done already.

def stale_calibration(s, config, config_sha256):
    """Why the subject's config on disk must be calibrated again (a text), or None: it is kept.

    Only a config this batch calibrated is redone (its record holds the config's hash): one put
    there by hand, or by a batch before the records, is kept. Only what can be calibrated from
    now is compared: without a template, or with the static trial gone, the config is kept.
    """
    if s["problem"]:
        return None
    record = _read_record(os.path.join(os.path.dirname(config), CALIBRATION_RECORD))
    if record is None or record.get("config_sha256") != config_sha256:
        return None
    static = os.path.join(s["folder"], *s["static"].split("/"))
    if not same_file(static, record.get("static"))[0]:
        return "its static trial %s changed" % s["static"]
    if not same_file(s["template"], record.get("template"))[0]:
        return "its template %s changed" % s["template"]
    if list(s["calibrate_args"]) != record.get("calibrate_args"):
        return "its calibrate_args changed"
    return None


def orphan_outputs(out, subjects):
    """The trials (SUBJECT/TRIAL) whose outputs are in `out` but which are not in the archive."""
    known = {(s["name"], _trial_id(rel)) for s in subjects for rel in s["trials"]}
    found = set()
    for name in sorted(os.listdir(out)):
        folder = os.path.join(out, name)
        if name.startswith(".") or not os.path.isdir(folder):
            continue
        for dirpath, dirnames, filenames in os.walk(folder):
            dirnames[:] = [d for d in dirnames if not d.startswith(".")]  # staging folders
            for f in filenames:
                suffix = next((x for x in OUTPUT_SUFFIXES.values() if f.endswith(x)), None)
                if suffix and not f.startswith("."):
                    rel = os.path.relpath(os.path.join(dirpath, f[:-len(suffix)]), folder)
                    if (name, rel.replace(os.sep, "/")) not in known:
                        found.add(name + "/" + rel.replace(os.sep, "/"))
    return sorted(found)


def plan(root, out, template, fabrik, timeout_s, log=None):
    """(subjects' calibration jobs, trial jobs to run, rows of trials already done or unrunnable).

    A calibration job is only planned for a subject with a trial left to run.
    """
    calibrations, pending, rows = {}, [], []
    subjects = find_subjects(root, template)
    for s in subjects:
        out_dir = os.path.join(out, s["name"])
        config = os.path.join(out_dir, CONFIG_NAME)
        want_angles, config_sha256, stale = True, None, None
        if os.path.isfile(config):
            try:
                want_angles = _has_coordinates(config)
                config_sha256 = _sha256(config)
            except (OSError, ValueError):
                os.remove(config)  # unreadable: calibrate again
            else:
                stale = stale_calibration(s, config, config_sha256)
        if stale and log:
            print("batch: subject %s: %s since its calibration: calibrating again and solving all "
                  "its trials again" % (s["name"], stale), file=log)
        for rel in s["trials"]:
            trial = {"fabrik": fabrik, "subject": s["name"], "trial": _trial_id(rel),
                     "kind": "static" if rel in s["statics"] else "dynamic",
                     "input": os.path.join(s["folder"], *rel.split("/")),
                     "outputs": trial_outputs(out_dir, _trial_id(rel)), "timeout_s": timeout_s,
                     "calibration_report": os.path.join(out_dir, CALIBRATION_REPORT)}
            # A done trial is kept, and a calibration on disk used, even where the subject
            # could not be calibrated now (a rerun without --template after one with it).
            # Other problems (trials that collide, a broken subject.json) fail every trial.
            usable = not s["problem"] or s["calibration_problem"]
            report = (done_report(trial["outputs"], trial["input"], config_sha256, want_angles)
                      if usable and not stale and os.path.isfile(config) else None)
            if report is not None:
                try:
                    rows.append(row_from_report(trial, report, "skipped"))
                    continue
                except (KeyError, TypeError, ValueError):
                    pass  # an unexpected report: solve again
            if s["problem"] and not (s["calibration_problem"] and os.path.isfile(config)):
                rows.append(dict(_blank_row(trial), status="failed", error=s["problem"]))
                continue
            pending.append(trial)
            calibrations.setdefault(s["name"], {
                "fabrik": fabrik, "template": s["template"], "config": config,
                "static": (os.path.join(s["folder"], *s["static"].split("/"))
                           if s["static"] else None),  # None: the calibration on disk is used
                "calibrate_args": s["calibrate_args"], "timeout_s": timeout_s, "recalibrate": stale})
    orphans = orphan_outputs(out, subjects)
    if orphans and log:
        # Kept: they may be the user's to keep (a trial moved out of ROOT on purpose).
        print("batch: the outputs of %d trial%s in %s belong to no trial of ROOT (kept, not in the "
              "summary; delete them if unwanted): %s"
              % (len(orphans), "s" if len(orphans) > 1 else "", out, _shown(orphans)), file=log)
    return calibrations, pending, rows


# ---------------------------------------------------------------------------------------------
# Running the plan: in this process (--workers 1), or on a Dask cluster.

def run_sequential(calibrations, pending, on_row):
    results = {}
    for job in pending:
        if job["subject"] not in results:
            results[job["subject"]] = calibrate_subject(calibrations[job["subject"]])
        on_row(solve_trial(job, results[job["subject"]]))


def run_dask(client, calibrations, pending, on_row, idle_timeout_s):
    """Submit every calibration and trial to `client`'s cluster; rows as they finish.

    Each trial task takes its subject's calibration future as an argument: Dask runs
    the calibration first, once, and feeds its result to every trial of the subject.
    """
    import distributed

    token = uuid.uuid4().hex[:8]
    cal = {name: client.submit(calibrate_subject, job, key="calibrate-%s-%s" % (name, token),
                               priority=1)
           for name, job in calibrations.items()}
    futures = {}
    for job in pending:
        key = "solve-%s/%s-%s" % (job["subject"], job["trial"], token)
        futures[client.submit(solve_trial, job, cal[job["subject"]], key=key)] = job
    waiting = set(futures)
    while waiting:
        try:
            done = distributed.wait(list(waiting), timeout=idle_timeout_s,
                                    return_when="FIRST_COMPLETED").done
        except distributed.TimeoutError:
            # No task finished for idle_timeout_s: the cluster lost its workers or hangs.
            for f in sorted(waiting, key=lambda f: (futures[f]["subject"], futures[f]["trial"])):
                on_row(dict(_blank_row(futures[f]), status="failed",
                            error="no result from the cluster within %g s" % idle_timeout_s))
                f.cancel()
            return
        for f in done:
            waiting.discard(f)
            try:
                on_row(f.result())
            except Exception as e:  # the task itself was lost (e.g. KilledWorker)
                on_row(dict(_blank_row(futures[f]), status="failed",
                            error="task failed on the cluster: %s: %s" % (type(e).__name__, e)))


def _ship_by_value():
    """Pickle this module's functions by value: workers then need no `fabrik` package installed."""
    import cloudpickle

    module = sys.modules[__name__]
    if module.__name__ != "__main__":  # __main__'s functions go by value already
        cloudpickle.register_pickle_by_value(module)


def connect(scheduler, workers, connect_timeout_s):
    """A distributed.Client: to `scheduler`, or to a LocalCluster of `workers` processes."""
    import distributed

    _ship_by_value()
    try:
        if scheduler:
            client = distributed.Client(scheduler, timeout=connect_timeout_s)
            client.wait_for_workers(1, timeout=connect_timeout_s)
            return client, None
        # One single-threaded worker process per core: the same path as a remote cluster
        # (tasks pickled to other processes); each task waits on its `fabrik` subprocess.
        cluster = distributed.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                           dashboard_address=None)
        client = distributed.Client(cluster, timeout=connect_timeout_s)
        client.wait_for_workers(workers, timeout=connect_timeout_s)
        return client, cluster
    except (OSError, distributed.TimeoutError) as e:
        raise SetupError("Dask: cannot reach %s: %s" % (scheduler or "a local cluster", e))


# ---------------------------------------------------------------------------------------------
# The summary and the command.

def write_summary(path, rows):
    """OUT/summary.csv, one row per trial sorted by subject and trial, written then renamed."""
    rows = sorted(rows, key=lambda r: (r["subject"], r["trial"]))
    partial = _partial(path)
    with open(partial, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=COLUMNS)
        w.writeheader()
        w.writerows(rows)
    os.replace(partial, path)
    return rows


def _check_paths(root, out):
    if not os.path.isdir(root):
        raise SetupError("%s: not a folder (ROOT: one folder per subject)" % root)
    r, o = os.path.realpath(root), os.path.realpath(out)
    if o == r or o.startswith(r + os.sep):
        raise SetupError("--output %s is inside ROOT %s: its outputs would be read as trials. "
                         "Fix: write outside ROOT" % (out, root))
    os.makedirs(out, exist_ok=True)


def _template_problem(path):
    """Why `path` cannot be the template, or None."""
    if os.path.isfile(path):
        return None
    return "not a file" if os.path.exists(path) else "no such file"


def run_batch(root, out, template=None, scheduler=None, workers=None, fabrik=None,
              timeout_s=3600.0, connect_timeout_s=60.0, log=sys.stderr):
    """Run the batch; returns the summary rows (sorted). Raises SetupError when it cannot start."""
    fabrik = fabrik or os.environ.get("FABRIK_BIN") or "fabrik"
    root, out = os.path.abspath(root), os.path.abspath(out)
    template = os.path.abspath(template) if template else None
    if template and _template_problem(template):
        raise SetupError("--template %s: %s" % (template, _template_problem(template)))
    _check_paths(root, out)
    started = time.monotonic()
    calibrations, pending, rows = plan(root, out, template, fabrik, timeout_s, log)
    skipped = sum(r["status"] == "skipped" for r in rows)
    unrunnable = len(rows) - skipped
    if not rows and not pending:
        raise SetupError("%s: no trials found (expected ROOT/SUBJECT/*.trc|*.c3d)" % root)
    seen_problems = set()
    for r in rows:
        if r["status"] == "failed" and r["error"] not in seen_problems:
            seen_problems.add(r["error"])
            print("batch: %s" % r["error"], file=log)
    total = len(pending)
    mode = ("the cluster at %s" % scheduler if scheduler else "this process" if workers == 1
            else "a local Dask cluster of %d workers" % (workers or os.cpu_count() or 1))
    print("batch: %d trials of %d subjects: %d done already (skipped), %d to run on %s%s"
          % (len(rows) + total, len({r["subject"] for r in rows} | set(calibrations)), skipped,
             total, mode, ", %d failed before running (above)" % unrunnable if unrunnable else ""),
          file=log)

    def on_row(row):
        rows.append(row)
        n = len(rows) - skipped - unrunnable
        print("batch: [%d/%d] %s/%s %s%s" % (n, total, row["subject"], row["trial"], row["status"],
                                            ": " + row["error"] if row["error"] else ""),
              file=log, flush=True)

    if pending and workers == 1 and not scheduler:
        cli = check_cli(fabrik, connect_timeout_s)
        if "error" in cli:
            raise SetupError("the fabrik CLI: %s. Fix: give --fabrik PATH" % cli["error"])
        run_sequential(calibrations, pending, on_row)
    elif pending:
        client, cluster = connect(scheduler, workers or os.cpu_count() or 1, connect_timeout_s)
        try:
            cli = client.submit(check_cli, fabrik, pure=False).result(timeout=connect_timeout_s)
            if "error" in cli:
                raise SetupError("the fabrik CLI on the workers: %s. Fix: install it there, or give "
                                 "--fabrik PATH valid on every worker" % cli["error"])
            run_dask(client, calibrations, pending, on_row, idle_timeout_s=timeout_s + 60.0)
        finally:
            client.close()
            if cluster is not None:
                cluster.close()
    rows = write_summary(os.path.join(out, SUMMARY_NAME), rows)
    failed = sum(r["status"] == "failed" for r in rows)
    print("batch: %d ok, %d skipped (done before), %d failed in %.1f s; summary: %s"
          % (sum(r["status"] == "ok" for r in rows), skipped, failed, time.monotonic() - started,
             os.path.join(out, SUMMARY_NAME)), file=log)
    return rows


def main(argv=None):
    p = argparse.ArgumentParser(
        prog="python3 -m fabrik.batch",
        description="Calibrate each subject of an archive from its static trial and solve every "
                    "trial with the fabrik CLI, in parallel on Dask; write the outputs and "
                    "OUT/summary.csv. Exit 0: no trial failed; 1: some trial failed (see the "
                    "summary); 2: the batch could not start. docs/batch.md")
    p.add_argument("root", help="the archive: ROOT/SUBJECT/{*static*.trc|c3d, trials}")
    p.add_argument("--output", "-o", required=True, help="output folder (outside ROOT)")
    p.add_argument("--template", help="calibration template (fabrikd-template/1), unless each "
                                      "subject's subject.json names one")
    p.add_argument("--scheduler", help="a Dask scheduler's address (e.g. tcp://host:8786): run "
                                       "on that cluster's workers")
    p.add_argument("--workers", type=int, help="local Dask worker processes (default: one per "
                                               "core); 1: sequentially in this process, no Dask")
    p.add_argument("--fabrik", help="the fabrik CLI (default: $FABRIK_BIN, else fabrik on PATH; "
                                    "resolved on each worker)")
    p.add_argument("--trial-timeout", type=float, default=3600.0,
                   help="seconds one calibration or trial may take before it fails (default 3600)")
    p.add_argument("--connect-timeout", type=float, default=60.0,
                   help="seconds to reach the cluster and its workers (default 60)")
    a = p.parse_args(argv)
    if a.scheduler and a.workers:
        p.error("--workers sizes a local cluster: not with --scheduler (the cluster has its own)")
    if a.workers is not None and a.workers < 1:
        p.error("--workers must be at least 1")
    for option, value in (("--trial-timeout", a.trial_timeout),
                          ("--connect-timeout", a.connect_timeout)):
        # NaN fails both comparisons, so it is refused too.
        if not 0 < value <= 1e9:
            p.error("%s must be a number of seconds in (0, 1e9], not %g" % (option, value))
    if a.template and _template_problem(a.template):
        # Else every subject it calibrates would fail with it: a bad option, as above.
        p.error("--template %s: %s" % (a.template, _template_problem(a.template)))
    try:
        rows = run_batch(a.root, a.output, a.template, a.scheduler, a.workers, a.fabrik,
                         a.trial_timeout, a.connect_timeout)
    except SetupError as e:
        print("batch: %s" % e, file=sys.stderr)
        return EXIT_SETUP
    return EXIT_TRIALS_FAILED if any(r["status"] == "failed" for r in rows) else EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
