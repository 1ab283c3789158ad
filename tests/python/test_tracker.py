"""Tracker from Python: the same poses as the C++ pipeline, dict and array inputs agree, wrong
input is a clear error, occlusion and convergence outcomes are values."""
import math

import numpy as np
import pytest

import fabrik
from conftest import DEFAULT_CONFIG, fabrik_cli


@pytest.fixture(scope="module")
def config():
    return fabrik.load_config()


@pytest.fixture(scope="module")
def frames(config):
    return fabrik.synthetic_frames(config, 20)


def test_dict_and_array_give_the_same_pose(config, frames):
    by_array, by_dict = fabrik.Tracker(config), fabrik.Tracker(config)
    names = by_array.marker_names
    for f, row in enumerate(frames):
        a = by_array.track(row, f / 100)
        d = by_dict.track({n: tuple(x) for n, x in zip(names, row)}, f / 100)
        assert a.status == d.status
        assert np.array_equal(a.joints_mm, d.joints_mm)
        assert np.array_equal(a.markers_mm, d.markers_mm)
        assert a.angles_deg == d.angles_deg
    # dict values may be lists or NumPy rows too, and names may come in any order
    shuffled = {n: list(x) for n, x in reversed(list(zip(names, frames[0])))}
    rows = {n: x for n, x in zip(names, frames[0])}
    first = fabrik.Tracker(config).track(shuffled, 0.0)
    again = fabrik.Tracker(config).track(rows, 0.0)
    assert np.array_equal(first.joints_mm, again.joints_mm)


def test_joints_match_fabrik_solve_frame_by_frame(config, synth_trial, tmp_path):
    """The trial through `fabrik solve` (C++) and through Tracker.track frame by frame give the
    same joint centres to the 6 decimals (mm) the TRC writer prints, and the same angles to
    the .mot's 8 decimals (degrees). The trial has gaps: offline the joints and angles are
    solved on the markers with their gaps filled (Solution.markers_mm), so those are what
    the Tracker is given."""
    joints_trc, mot = tmp_path / "joints.trc", tmp_path / "angles.mot"
    fabrik_cli("solve", "--config", DEFAULT_CONFIG, "--input", synth_trial, "--output",
               joints_trc, "--angles", mot, "--quiet")
    solution = fabrik.solve(fabrik.load_config(DEFAULT_CONFIG), synth_trial)
    assert solution.summary["solved_on_filled_markers"]  # the fixture's trial has gaps
    cli_joints = fabrik.read_markers(joints_trc)
    cli_angles = fabrik.read_table(mot)
    tracker = fabrik.Tracker(fabrik.load_config(DEFAULT_CONFIG))
    assert cli_joints.names == tracker.joint_names
    assert solution.marker_names == tracker.marker_names
    rate_hz = cli_joints.rate_hz
    for f in range(len(cli_joints.time_s)):
        pose = tracker.track(solution.markers_mm[f], f / rate_hz)
        np.testing.assert_allclose(pose.joints_mm, cli_joints.positions_mm[f], rtol=0,
                                   atol=0.5e-6 + 1e-9)
        for name, deg in pose.angles_deg.items():
            assert abs(deg - cli_angles.column(name)[f]) <= 0.5e-8 + 1e-10, (f, name)
        for name, mm in pose.translations_mm.items():
            assert abs(mm / 1000 - cli_angles.column(name)[f]) <= 0.5e-8 + 1e-10, (f, name)


def test_occluded_markers_absent_or_nan(config, frames):
    names = config.marker_names
    row = frames[0].copy()
    row[3] = np.nan
    pose = fabrik.Tracker(config).track(row, 0.0)
    assert pose.occluded[3] and pose.occluded.sum() == 1 and pose.occluded_count == 1
    assert math.isnan(pose.marker_residual_mm[3])
    missing = {n: tuple(x) for n, x in zip(names, frames[0]) if n != names[5]}
    pose = fabrik.Tracker(config).track(missing, 0.0)
    assert list(np.flatnonzero(pose.occluded)) == [5]
    assert pose.markers_mm[5].shape == (3,) and np.isfinite(pose.markers_mm[5]).all()


def test_no_markers_is_a_status_not_an_exception(config):
    tracker = fabrik.Tracker(config)
    pose = tracker.track({}, 0.0)
    assert pose.status == "no_targets"
    assert pose.occluded.all() and pose.worst_marker is None and pose.quality == "none"


def test_wrong_input_gives_clear_errors(config, frames):
    tracker = fabrik.Tracker(config)
    n = len(config.marker_names)
    with pytest.raises(ValueError, match=rf"shape \({n}, 3\).*got shape \({n - 1}, 3\)"):
        tracker.track(frames[0][:-1], 0.0)
    with pytest.raises(ValueError, match=r"got shape \(20, 45, 3\)"):
        tracker.track(frames, 0.0)
    with pytest.raises(KeyError, match="'NOSE' is not a marker of this tracker"):
        tracker.track({"NOSE": (0, 0, 0)}, 0.0)
    with pytest.raises(ValueError, match="LASI: give x, y, z"):
        tracker.track({"LASI": (1, 2)}, 0.0)
    with pytest.raises(ValueError, match="coordinates must be numbers"):
        tracker.track({"LASI": (1, "a", 2)}, 0.0)
    # True is an int to Python: it was read as 1 mm.
    with pytest.raises(ValueError, match="coordinates must be numbers.*got True"):
        tracker.track({"LASI": (1, True, 2)}, 0.0)
    with pytest.raises(TypeError, match="give a dict"):
        tracker.track(object(), 0.0)
    # None and a number became 0-d arrays and were refused for their shape (a ValueError).
    for wrong in (None, 5, 2.5):
        with pytest.raises(TypeError, match="give a dict"):
            tracker.track(wrong, 0.0)
    # A coordinate that is not a number in a list or an array is a ValueError too, as in a dict
    # (before: a TypeError that said "not list", though a list of numbers is taken).
    rows = frames[0].tolist()
    rows[0][0] = "x"
    for markers in (rows, np.array(rows, dtype=object)):
        with pytest.raises(ValueError, match="coordinates must be numbers"):
            tracker.track(markers, 0.0)
    assert tracker.track(frames[0].tolist(), 0.0).status != "no_targets"  # numbers: taken
    for t in (float("nan"), float("inf")):  # a NaN once stayed in the tracker's clock
        with pytest.raises(ValueError, match="time_s must be a finite number"):
            tracker.track(frames[0], t)
    with pytest.raises(ValueError, match="rate_hz must be a positive number"):
        fabrik.synthetic_frames(config, 3, rate_hz=0.0)  # once 405 NaNs
    # unknown names may be skipped on request
    skipped = {"NOSE": (0, 0, 0), "LASI": tuple(frames[0][0])}
    pose = tracker.track(skipped, 0.0, ignore_unknown=True)
    assert pose.occluded_count == n - 1
    # ... on request only: the same dict again without it is refused again
    with pytest.raises(KeyError, match="'NOSE'"):
        tracker.track(skipped, 0.01)


def test_a_pose_is_a_snapshot_and_its_arrays_keep_it_alive(config, frames):
    tracker = fabrik.Tracker(config)
    first = tracker.track(frames[0], 0.0)
    joints = first.joints_mm
    kept = joints.copy()
    del first
    for f in range(1, 5):
        tracker.track(frames[f], f / 100)
    assert np.array_equal(joints, kept)  # not overwritten by later frames, not freed
    assert joints.base is not None  # a view, not a copy


def test_shapes_units_and_reset(config, frames):
    tracker = fabrik.Tracker(config)
    pose = tracker.track(frames[0], 0.0)
    assert pose.cold_start
    assert pose.joints_mm.shape == (len(tracker.joint_names), 3)
    assert pose.segment_q_world.shape == (len(tracker.segment_names), 4)
    np.testing.assert_allclose(np.linalg.norm(pose.segment_q_world, axis=1), 1, atol=1e-9)
    # mm: the model markers lie within a few mm of the measured (mm) markers
    assert pose.residual_rms_mm < 5 and np.nanmax(pose.marker_residual_mm) < 20
    assert set(pose.angles_deg) | set(pose.translations_mm) == set(tracker.coordinate_names)
    assert not tracker.track(frames[1], 0.01).cold_start
    tracker.reset()
    assert tracker.track(frames[2], 0.02).cold_start


def test_dicts_whose_keys_change_between_frames(config, frames):
    """The dict path remembers the last dict's keys by position (tracker.cpp): reordered,
    missing and new keys on the same tracker must still land on their markers."""
    names = list(config.marker_names)
    by_dict, by_array = fabrik.Tracker(config), fabrik.Tracker(config)
    rng = np.random.default_rng(3)
    for f, row in enumerate(frames):
        order = rng.permutation(len(names)) if f % 3 else np.arange(len(names))
        keep = order[: len(names) - (f % 4)]  # some frames lack a few markers
        masked = np.full_like(row, np.nan)
        masked[keep] = row[keep]
        d = by_dict.track({names[i]: tuple(row[i]) for i in keep}, f / 100)
        a = by_array.track(masked, f / 100)
        assert np.array_equal(d.occluded, a.occluded), f
        assert np.array_equal(d.joints_mm, a.joints_mm), f


def test_a_fourth_value_is_the_markers_confidence(config, frames):
    """As on the daemon's wire: x, y, z, confidence; below confidence.threshold (0.3 by default)
    the marker is occluded, a confidence of 1 (or more: clamped) is a 3-value marker."""
    names = config.marker_names
    n = len(names)
    three = {nm: tuple(x) for nm, x in zip(names, frames[0])}
    plain = fabrik.Tracker(config).track(three, 0.0)
    assert plain.low_confidence_count == 0
    sure = fabrik.Tracker(config).track({nm: (*x, 1.5) for nm, x in three.items()}, 0.0)
    assert np.array_equal(sure.joints_mm, plain.joints_mm) and sure.occluded_count == 0
    # a low confidence occludes the marker as an absent name does
    doubtful = dict(three, **{names[5]: (*three[names[5]], 0.1)})
    low = fabrik.Tracker(config).track(doubtful, 0.0)
    absent = fabrik.Tracker(config).track({k: v for k, v in three.items() if k != names[5]}, 0.0)
    assert list(np.flatnonzero(low.occluded)) == [5]
    assert low.occluded_count == 1 and low.low_confidence_count == 1
    assert np.array_equal(low.joints_mm, absent.joints_mm)
    # above the threshold the marker is tracked
    kept = fabrik.Tracker(config).track(dict(three, **{names[5]: (*three[names[5]], 0.5)}), 0.0)
    assert not kept.occluded[5] and kept.low_confidence_count == 0
    # a confidence that is not a number's value says nothing: occluded (as the wire's)
    nan = fabrik.Tracker(config).track(dict(three, **{names[5]: [*three[names[5]], np.nan]}), 0.0)
    assert nan.occluded[5] and nan.occluded_count == 1
    # the (markers, 4) array: the same
    with_ones = np.hstack([frames[0], np.ones((n, 1))])
    assert np.array_equal(fabrik.Tracker(config).track(with_ones, 0.0).joints_mm, plain.joints_mm)
    with_low = with_ones.copy()
    with_low[5, 3] = 0.1
    by_array = fabrik.Tracker(config).track(with_low, 0.0)
    assert list(np.flatnonzero(by_array.occluded)) == [5] and by_array.low_confidence_count == 1
    assert np.array_equal(by_array.joints_mm, low.joints_mm)
    # a NumPy row of 4 as a dict value
    row4 = fabrik.Tracker(config).track({nm: with_low[i] for i, nm in enumerate(names)}, 0.0)
    assert np.array_equal(row4.joints_mm, low.joints_mm)


def test_confidence_input_errors(config, frames):
    tracker = fabrik.Tracker(config)
    n = len(config.marker_names)
    with pytest.raises(ValueError, match=rf"shape \({n}, 3\) or \({n}, 4\).*got shape \({n}, 5\)"):
        tracker.track(np.zeros((n, 5)), 0.0)
    with pytest.raises(ValueError, match=r"LASI: give x, y, z \(3 numbers, mm\) or x, y, z, "
                                         r"confidence \(0-1\)"):
        tracker.track({"LASI": (1, 2, 3, 0.5, 9)}, 0.0)
    with pytest.raises(ValueError, match="as must a confidence, got 'high'"):
        tracker.track({"LASI": (1, 2, 3, "high")}, 0.0)
    # a frame without confidences after one with them: every marker at 1 again
    names = config.marker_names
    three = {nm: tuple(x) for nm, x in zip(names, frames[0])}
    tracker.track({nm: (*x, 0.0) for nm, x in three.items()}, 0.0)
    assert tracker.track(three, 0.01).occluded_count == 0
