"""Whole-trial solve: the same numbers as `fabrik solve`, from a file or from arrays; angles as a
pandas DataFrame."""
import dataclasses
import os

import numpy as np
import pytest

import fabrik
from conftest import DEFAULT_CONFIG, fabrik_cli


@pytest.fixture(scope="module")
def cli_outputs(synth_trial, tmp_path_factory):
    out = tmp_path_factory.mktemp("solve")
    fabrik_cli("solve", "--config", DEFAULT_CONFIG, "--input", synth_trial, "--output",
               out / "joints.trc", "--markers", out / "markers.trc", "--model-markers",
               out / "model_markers.trc", "--angles",
               out / "angles.mot", "--report", out / "report.json", "--quiet")
    return out


@pytest.fixture(scope="module")
def solution(synth_trial):
    return fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), synth_trial)


def test_solve_matches_the_cli(solution, cli_outputs, synth_trial):
    joints = fabrik.read_markers(cli_outputs / "joints.trc")
    markers = fabrik.read_markers(cli_outputs / "markers.trc")
    angles = fabrik.read_table(cli_outputs / "angles.mot")
    assert solution.joint_names == joints.names and solution.marker_names == markers.names
    np.testing.assert_allclose(solution.joints_mm, joints.positions_mm, rtol=0, atol=0.6e-6)
    # the filled model markers, NaN where the CLI wrote nothing
    np.testing.assert_allclose(solution.markers_mm, markers.positions_mm, rtol=0, atol=0.6e-6)
    model_markers = fabrik.read_markers(cli_outputs / "model_markers.trc")
    np.testing.assert_allclose(solution.model_markers_mm, model_markers.positions_mm, rtol=0,
                               atol=0.6e-6)
    # Measured samples are written as measured; the model's are the fit's.
    trial = fabrik.read_markers(synth_trial)
    columns = [trial.names.index(n) for n in solution.marker_names]
    measured = trial.positions_mm[:, columns]
    seen = np.isfinite(measured)
    np.testing.assert_allclose(solution.markers_mm[seen], measured[seen], rtol=0, atol=1e-9)
    assert np.nanmax(np.abs(solution.model_markers_mm[seen] - measured[seen])) > 0.1
    np.testing.assert_allclose(solution.time_s, angles.time_s, rtol=0, atol=1e-8)
    for i, name in enumerate(solution.angle_names):
        np.testing.assert_allclose(solution.angles_deg[:, i], angles.column(name), rtol=0,
                                   atol=0.6e-8)
    for i, name in enumerate(solution.translation_names):
        np.testing.assert_allclose(solution.translations_mm[:, i] / 1000, angles.column(name),
                                   rtol=0, atol=0.6e-8)
    import json
    report = json.loads((cli_outputs / "report.json").read_text())
    assert solution.summary["frames"] == report["frames"]
    assert solution.summary["residual_mm"]["rms_mean"] == pytest.approx(
        report["residual_mm"]["rms_mean"], abs=1e-9)
    assert set(solution.status) <= {"converged", "stalled", "max_iterations", "no_targets"}


def test_solve_from_arrays_equals_solve_from_file(solution, synth_trial):
    trial = fabrik.read_markers(synth_trial)
    mine = fabrik.MarkerData(names=trial.names, positions_mm=trial.positions_mm.copy(),
                             time_s=trial.time_s, rate_hz=trial.rate_hz,
                             first_frame=trial.first_frame)
    again = fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), mine)
    # the same to rounding: the file's metres went to mm and back
    np.testing.assert_allclose(again.joints_mm, solution.joints_mm, rtol=0, atol=1e-9)
    np.testing.assert_allclose(again.angles_deg, solution.angles_deg, rtol=0, atol=1e-9)
    assert again.status == solution.status
    np.testing.assert_array_equal(again.time_s, trial.time_s)


def test_solve_from_arrays_keeps_their_times(synth_trial):
    # Once the first time was taken as (first_frame - 1) / rate whatever time_s said: a
    # file starting at 0.23 s read into MarkerData came back starting at 0.22 s.
    trial = fabrik.read_markers(synth_trial)
    mine = fabrik.MarkerData(names=trial.names, positions_mm=trial.positions_mm[:20].copy(),
                             time_s=trial.time_s[:20] + 5.0, rate_hz=trial.rate_hz,
                             first_frame=23)
    solved = fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), mine)
    np.testing.assert_allclose(solved.time_s, mine.time_s, rtol=0, atol=1e-9)


def test_solution_arrays_own_their_memory(solution):
    # moved from C++, not copied: the array's base is the capsule that owns the vector
    assert solution.joints_mm.base is not None
    assert solution.joints_mm.shape == (len(solution.time_s), len(solution.joint_names), 3)
    assert solution.angles_deg.shape == (len(solution.time_s), len(solution.angle_names))


def test_angles_dataframe(solution):
    pd = pytest.importorskip("pandas")
    df = solution.angles_dataframe()
    assert isinstance(df, pd.DataFrame)
    assert list(df.columns) == solution.angle_names and df.index.name == "time_s"
    assert np.array_equal(df.to_numpy(), solution.angles_deg)
    # angles only: the pelvis translations are not angles (they are in translations_mm)
    assert not set(solution.translation_names) & set(df.columns)


def test_angles_dataframe_with_translations_is_the_mot(solution, cli_outputs):
    # `fabrik solve --angles` writes every coordinate; angles_dataframe() left out the three
    # pelvis translations. translations=True gives the .mot's columns, in its order and units.
    pytest.importorskip("pandas")
    mot = fabrik.read_table(cli_outputs / "angles.mot")
    df = solution.angles_dataframe(translations=True)
    assert solution.translation_names == ["pelvis_tx", "pelvis_ty", "pelvis_tz"]
    assert list(df.columns) == mot.names == solution.coordinate_names
    assert len(df.columns) == len(solution.angle_names) + 3
    for name in mot.names:
        np.testing.assert_allclose(df[name].to_numpy(), mot.column(name), rtol=0, atol=0.6e-8)
    # metres, as the .mot: mm / 1000
    np.testing.assert_array_equal(df["pelvis_ty"].to_numpy(),
                                  solution.translations_mm[:, 1] / 1000.0)


def test_a_trial_sharing_no_marker_is_refused(tmp_path):
    data = fabrik.MarkerData(names=["A", "B"], positions_mm=np.zeros((3, 2, 3)),
                             time_s=np.arange(3) / 100, rate_hz=100)
    with pytest.raises(RuntimeError, match="none of"):
        fabrik.solve(fabrik.load_config(), data)
    with pytest.raises(FileNotFoundError, match="nothing.trc"):
        fabrik.solve(fabrik.load_config(), tmp_path / "nothing.trc")


def test_a_slice_of_a_trial_keeps_its_frame_numbers_and_times(synth_trial):
    # A slice's first_frame field stays the file's: its frame numbers came back from 1.
    trial = fabrik.read_markers(synth_trial)
    part = dataclasses.replace(trial, positions_mm=trial.positions_mm[40:60],
                               time_s=trial.time_s[40:60], frame_numbers=trial.frame_numbers[40:60])
    solved = fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), part)
    np.testing.assert_array_equal(solved.frame_numbers, trial.frame_numbers[40:60])
    np.testing.assert_allclose(solved.time_s, trial.time_s[40:60], rtol=0, atol=1e-9)
    # Every other frame would be numbered and timed as consecutive ones: refused.
    with pytest.raises(ValueError, match="frame_numbers must run on by one"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), dataclasses.replace(
            trial, positions_mm=trial.positions_mm[::2], time_s=trial.time_s[::2],
            frame_numbers=trial.frame_numbers[::2]))
    # Positions sliced alone were numbered from 1 and timed from 0 s; another rate drifted.
    with pytest.raises(ValueError, match="frame_numbers has 100 entries for 20 frames"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG),
                     dataclasses.replace(trial, positions_mm=trial.positions_mm[40:60]))
    with pytest.raises(ValueError, match="is rate_hz right"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), dataclasses.replace(trial, rate_hz=120))
    twice = list(trial.names)
    twice[1] = twice[0]
    with pytest.raises(ValueError, match="holds '%s' twice" % twice[0]):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), dataclasses.replace(trial, names=twice))
    with pytest.raises(ValueError, match="time_s must step by 1/rate_hz"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), dataclasses.replace(
            trial, positions_mm=trial.positions_mm[::2], time_s=trial.time_s[::2],
            frame_numbers=None))
    # A NaN time was taken (its frame's time came out made up), a zero rate divided by zero.
    times = trial.time_s.copy()
    times[5] = np.nan
    with pytest.raises(ValueError, match="time_s must be finite seconds, but entry 5 is nan"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), dataclasses.replace(trial, time_s=times))
    with pytest.raises(ValueError, match="rate_hz must be a positive number"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), dataclasses.replace(trial, rate_hz=0.0))
    # MarkerData.frames keeps positions, times and numbers together: the same solve as above.
    again = fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), trial.frames(40, 60))
    np.testing.assert_array_equal(again.frame_numbers, solved.frame_numbers)
    np.testing.assert_array_equal(again.joints_mm, solved.joints_mm)
    # Without times (made by hand), frame n at (n - 1) / rate (an IndexError before).
    untimed = dataclasses.replace(trial, time_s=None).frames(40, 60)
    np.testing.assert_allclose(untimed.time_s, (trial.frame_numbers[40:60] - 1) / trial.rate_hz)
    # No tracked marker measured at all: refused, as fabrik solve refuses it (an all-NaN
    # Solution before), and samples 1000 times too far are dropped as fabrikd drops them.
    empty = dataclasses.replace(trial, positions_mm=np.full_like(trial.positions_mm, np.nan))
    with pytest.raises(RuntimeError, match="no tracked marker is measured in any of the"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), empty)
    far = dataclasses.replace(trial, positions_mm=trial.positions_mm * 1e6)
    with pytest.raises(RuntimeError, match="farther than input.max_abs_coordinate_mm"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), far)
    # A few such samples: dropped, said (the CLI says it; Python was silent).
    glitch = trial.positions_mm.copy()
    glitch[10:20, 0] = 1e9
    with pytest.warns(UserWarning, match="10 samples farther than input.max_abs_coordinate_mm"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG),
                     dataclasses.replace(trial, positions_mm=glitch))
    # Exact zeros everywhere: the refusal names keep_zeros (it said "every sample is empty").
    zeros = dataclasses.replace(trial, positions_mm=np.zeros_like(trial.positions_mm))
    with pytest.raises(RuntimeError, match="exactly \\(0, 0, 0\\).*give keep_zeros=True"):
        fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), zeros)


def test_keep_zeros_holds_for_arrays_as_for_files(synth_trial):
    # An exact (0, 0, 0) is missing unless keep_zeros: it was taken as a position from arrays.
    trial = fabrik.read_markers(synth_trial)
    zeroed = trial.positions_mm.copy()
    zeroed[30:40, 0] = 0.0
    mine = dataclasses.replace(trial, positions_mm=zeroed)
    config = fabrik.load_config(DEFAULT_CONFIG)
    seen = int(np.sum(~np.isnan(trial.positions_mm[30, :, 0])))
    assert not np.isnan(trial.positions_mm[30:40, 0]).any()
    dropped = fabrik.solve(config, mine)
    np.testing.assert_array_equal(dropped.measured[30:40], seen - 1)
    kept = fabrik.solve(config, mine, keep_zeros=True)
    np.testing.assert_array_equal(kept.measured[30:40], seen)
    assert np.array_equal(mine.positions_mm, zeroed, equal_nan=True)  # the caller's, untouched


def _prefixed_file(path, subject, out):
    """A copy of a TRC with its labels (its fourth line) as `subject`:MARKER."""
    lines = open(path).read().split("\n")
    lines[3] = "\t".join(c if i < 2 or not c else subject + ":" + c
                         for i, c in enumerate(lines[3].split("\t")))
    out.write_text("\n".join(lines))
    return out


def _prefixed(trial, subject, shift_mm=0.0):
    return [subject + ":" + n for n in trial.names], trial.positions_mm + shift_mm


def test_subject_solves_one_person_of_a_prefixed_recording(solution, synth_trial, tmp_path):
    trial = fabrik.read_markers(synth_trial)
    anna_names, anna_mm = _prefixed(trial, "Anna")
    ben_names, ben_mm = _prefixed(trial, "Ben", shift_mm=1000.0)
    both = fabrik.MarkerData(names=ben_names + anna_names,
                             positions_mm=np.concatenate([ben_mm, anna_mm], axis=1),
                             time_s=trial.time_s, rate_hz=trial.rate_hz,
                             first_frame=trial.first_frame)
    config = fabrik.load_config(DEFAULT_CONFIG)
    anna = fabrik.solve(config, both, subject="Anna")
    np.testing.assert_allclose(anna.joints_mm, solution.joints_mm, rtol=0, atol=1e-9)
    assert anna.marker_names == solution.marker_names  # without the prefix
    ben = fabrik.solve(config, both, subject="Ben")
    np.testing.assert_allclose(ben.joints_mm, solution.joints_mm + 1000.0, rtol=0, atol=1e-6)
    # Without a subject the config shares no name: the hint names the keyword, not a CLI option.
    with pytest.raises(RuntimeError, match=r"give subject='(Ben|Anna)'"):
        fabrik.solve(config, both)
    with pytest.raises(RuntimeError, match=r"subject='Carl': .*subjects: Ben, Anna"):
        fabrik.solve(config, both, subject="Carl")
    for bad in ("", "Anna:LASI", 3):
        with pytest.raises(ValueError, match="subject must be"):
            fabrik.solve(config, both, subject=bad)
    # A file's labels too.
    prefixed = _prefixed_file(synth_trial, "Anna", tmp_path / "anna.trc")
    from_file = fabrik.solve(config, prefixed, subject="Anna")
    np.testing.assert_allclose(from_file.joints_mm, solution.joints_mm, rtol=0, atol=1e-9)
    with pytest.raises(RuntimeError, match="leave out subject"):
        fabrik.solve(config, synth_trial, subject="Anna")


def test_a_trial_with_fewer_than_half_of_the_names_needs_allow_missing_markers(synth_trial):
    trial = fabrik.read_markers(synth_trial)
    keep = len(trial.names) // 2 - 1  # fewer than half
    names = trial.names[:keep] + [n + "_" for n in trial.names[keep:]]
    data = fabrik.MarkerData(names=names, positions_mm=trial.positions_mm, time_s=trial.time_s,
                             rate_hz=trial.rate_hz, first_frame=trial.first_frame)
    config = fabrik.load_config(DEFAULT_CONFIG)
    with pytest.raises(RuntimeError, match=r"(?s)has only %d of the \d+ marker names.*"
                       r"give allow_missing_markers=True" % keep):
        fabrik.solve(config, data)
    solution = fabrik.solve(config, data, allow_missing_markers=True)
    assert solution.summary["frames"] == len(trial.time_s)
    assert len(solution.missing_in_trial) == len(trial.names) - keep


def test_subject_of_a_multi_subject_config_tracks_with_that_subjects_config(synth_trial, tmp_path):
    import json
    alice = json.load(open(DEFAULT_CONFIG))
    alice["model"] = os.path.join(os.path.dirname(DEFAULT_CONFIG), alice["model"])
    bob = json.loads(json.dumps(alice))
    bob.setdefault("solver", {}).update(max_iterations=1, segment_fit="paper")  # tracks apart
    for name, c in (("alice", alice), ("bob", bob)):
        (tmp_path / (name + ".json")).write_text(json.dumps(c))
    two = tmp_path / "two.json"
    two.write_text(json.dumps({"format": "fabrikd-config/1", "subjects": [
        {"name": "Alice", "config": "alice.json"}, {"name": "Bob", "config": "bob.json"}]}))
    trial = _prefixed_file(synth_trial, "Bob", tmp_path / "bob.trc")
    fabrik_cli("solve", "--config", two, "--input", trial, "--subject", "Bob", "--output",
               tmp_path / "cli.trc", "--quiet")
    cli = fabrik.read_markers(tmp_path / "cli.trc")
    config = fabrik.load_config(two)
    mine = fabrik.solve(config, trial, subject="Bob")
    np.testing.assert_allclose(mine.joints_mm, cli.positions_mm, rtol=0, atol=0.6e-6)
    as_alice = fabrik.solve(fabrik.load_config(tmp_path / "alice.json"), trial, subject="Bob")
    assert np.nanmax(np.abs(as_alice.joints_mm - mine.joints_mm)) > 1.0  # Bob's config mattered
    with pytest.raises(RuntimeError, match="lists subjects: give subject with one of them"):
        fabrik.solve(config, trial)
