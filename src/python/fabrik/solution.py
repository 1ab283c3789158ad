"""A whole trial through the offline pipeline of `fabrik solve`, as NumPy arrays (and a pandas
DataFrame of angles where pandas is installed)."""
import json
import os
import warnings
from dataclasses import dataclass, field
from typing import List

import numpy as np

from . import _fabrik
from .recordings import MarkerData


@dataclass
class Solution:
    """Per frame f: joints_mm[f] (joints, 3), markers_mm[f] (markers, 3: the tracked markers as
    measured, gaps filled from both sides, NaN for a marker never measured, as `fabrik solve
    --markers` writes them) and model_markers_mm[f] (the model's fitted markers, as fabrikd
    publishes them live; `--model-markers`) in mm; angles_deg[f] (degrees, angle_names order, continuous
    over frames) and translations_mm[f] (mm), solved on markers_mm where gaps were filled
    (summary["solved_on_filled_markers"]); residual RMS/max (mm), status and quality: the causal
    pass's (fabrikd's) against the measured markers (the solver's stop reason is a value, never
    an exception). time_s and frame_numbers are the source's own. summary: what `fabrik solve
    --report` writes."""
    time_s: np.ndarray
    frame_numbers: np.ndarray
    rate_hz: float
    joint_names: List[str]
    joints_mm: np.ndarray
    marker_names: List[str]
    markers_mm: np.ndarray
    angle_names: List[str]
    angles_deg: np.ndarray
    translation_names: List[str]
    translations_mm: np.ndarray
    residual_rms_mm: np.ndarray
    residual_max_mm: np.ndarray
    solve_us: np.ndarray
    iterations: np.ndarray
    measured: np.ndarray
    outlier_count: np.ndarray
    status: List[str]
    quality: List[str]
    summary: dict
    missing_in_trial: List[str] = field(default_factory=list)
    ignored_in_trial: List[str] = field(default_factory=list)
    mostly_missing: List[str] = field(default_factory=list)
    model_markers_mm: np.ndarray = None
    # Every coordinate in the model's order (the columns of `fabrik solve --angles`).
    coordinate_names: List[str] = field(default_factory=list)

    def angles_dataframe(self, translations=False):
        """The angles (degrees) as a pandas DataFrame indexed by time_s, one column per angle
        (angle_names): the rotational coordinates only, so every column is in degrees. The
        translations (pelvis_tx, ...) are in translations_mm (mm, translation_names).

        translations=True: every coordinate, as the .mot of `fabrik solve --angles` has them:
        its columns in its order (coordinate_names), angles in degrees and translations in
        metres, as OpenSim's Coordinates files have them. Every frame is a row: frames before
        the first measured one and after the last are NaN (the .mot leaves them out). Needs pandas (imported here,
        not at `import fabrik`)."""
        try:
            import pandas as pd
        except ImportError as e:
            raise ImportError("Solution.angles_dataframe needs pandas "
                              "(Debian: python3-pandas); the arrays need nothing") from e
        index = pd.Index(self.time_s, name="time_s")
        if not translations:
            return pd.DataFrame(self.angles_deg, index=index, columns=self.angle_names)
        columns = {name: self.angles_deg[:, i] for i, name in enumerate(self.angle_names)}
        for i, name in enumerate(self.translation_names):
            columns[name] = self.translations_mm[:, i] / 1000.0  # mm -> m, as in the .mot
        # The .mot's order; a Solution made without coordinate_names: angles, then translations.
        order = self.coordinate_names or list(columns)
        return pd.DataFrame({name: columns[name] for name in order}, index=index)


def _first_frame_and_time(markers):
    """The first frame's number and time of a MarkerData, from its frame_numbers and time_s where
    it has them (a slice of a trial keeps its own), checked to run on one frame at a time: the
    solve numbers and times frames first + index."""
    first_frame = int(markers.first_frame)
    frames = np.shape(markers.positions_mm)[0] if np.ndim(markers.positions_mm) else 0
    for name in ("frame_numbers", "time_s"):
        given = getattr(markers, name)
        if given is not None and len(given) and len(given) != frames:
            raise ValueError("markers.%s has %d entries for %d frames of positions_mm: slice "
                             "them together" % (name, len(given), frames))
    numbers = markers.frame_numbers
    if numbers is not None and len(numbers):
        numbers = np.asarray(numbers)
        steps = np.flatnonzero(np.diff(numbers) != 1)
        if steps.size:
            k = int(steps[0])
            raise ValueError("markers.frame_numbers must run on by one (the solve numbers frames "
                             "first + index), but %d follows %d" % (numbers[k + 1], numbers[k]))
        first_frame = int(numbers[0])
    times = markers.time_s
    if times is None or not len(times):
        return first_frame, float("nan")
    times = np.asarray(times, dtype=np.float64)
    if not np.all(np.isfinite(times)):
        k = int(np.flatnonzero(~np.isfinite(times))[0])
        raise ValueError("markers.time_s must be finite seconds, but entry %d is %g" % (k, times[k]))
    rate_hz = float(markers.rate_hz)
    if not (np.isfinite(rate_hz) and rate_hz > 0.0):
        raise ValueError("rate_hz must be a positive number of frames per second (got %g)" % rate_hz)
    period_s = 1.0 / rate_hz
    # Half a period, step by step and over the whole: a file's Time column rounded to 3
    # decimals is off by far less; another rate (100 Hz data said to be 120) drifts past it.
    off = np.flatnonzero(np.abs(np.diff(times) - period_s) > 0.5 * period_s)
    if off.size:
        k = int(off[0])
        raise ValueError("markers.time_s must step by 1/rate_hz (%g s), but %g s follows %g s"
                         % (period_s, times[k + 1], times[k]))
    drift_s = (times[-1] - times[0]) - (len(times) - 1) * period_s
    if abs(drift_s) > 0.5 * period_s:
        raise ValueError("markers.time_s must step by 1/rate_hz (%g s), but spans %g s over %d "
                         "frames (%g Hz): is rate_hz right?" % (
                             period_s, times[-1] - times[0], len(times),
                             (len(times) - 1) / (times[-1] - times[0])))
    return first_frame, float(times[0])


def solve(config, markers, keep_zeros=False, subject=None, allow_missing_markers=False):
    """Track a whole trial as `fabrik solve` does (the daemon's Tracker; markers_mm the
    measured markers with their gaps filled from both sides, model_markers_mm the fit's). markers: a .trc/.c3d path, or MarkerData (e.g. from
    read_markers, or made from your own (frames, markers, 3) mm array; a slice keeps its
    frame_numbers and time_s, which must be as long as positions_mm and step by one frame, of
    1/rate_hz). keep_zeros=False takes an exact (0, 0, 0) as missing, for a path and a
    MarkerData alike. subject: one subject of a recording whose markers are labelled
    `Subject:Marker` (Vicon, QTM and Motive label several people so), as `fabrik solve
    --subject`: only its markers are solved, under their names without the prefix.
    allow_missing_markers: track a trial that has fewer than half of the config's marker names
    (refused by default, a RuntimeError naming them: most often another marker set). Releases
    the GIL while it solves. Raises FileNotFoundError/FormatError, ValueError for such frame
    numbers or times (or a name given twice), or RuntimeError when the trial shares no marker
    name with the config, has fewer than half of them with a sample, has no tracked marker
    measured at all, or names no such subject. Samples past input.max_abs_coordinate_mm are
    taken as missing, with a UserWarning."""
    if subject is not None and (not isinstance(subject, str) or not subject or ":" in subject):
        raise ValueError("subject must be a subject's name, the part of a label before ':' "
                         "(got %r)" % (subject,))
    subject = subject or ""
    if isinstance(markers, MarkerData):
        # As the TRC reader refuses a label on two markers: which one the config means is
        # ambiguous (the second was taken silently).
        seen = set()
        for name in markers.names:
            if name in seen:
                raise ValueError("markers.names holds %r twice: which one the config's marker "
                                 "is, is ambiguous; rename one" % name)
            seen.add(name)
        first_frame, first_time_s = _first_frame_and_time(markers)
        positions_mm = np.asarray(markers.positions_mm, dtype=np.float64)
        zero_samples = 0
        if not keep_zeros:
            # As read_markers does: an exact (0, 0, 0) is a system's way to say "missing".
            zeros = np.all(positions_mm == 0.0, axis=-1)
            if zeros.any():
                positions_mm = positions_mm.copy()
                positions_mm[zeros] = np.nan
                zero_samples = int(zeros.sum())
        d = _fabrik._solve_arrays(config, list(markers.names), positions_mm,
                                  float(markers.rate_hz), first_frame, first_time_s, subject,
                                  bool(allow_missing_markers), zero_samples)
    else:
        d = _fabrik._solve_file(config, os.fspath(markers), keep_zeros, subject,
                                bool(allow_missing_markers))
    d["summary"] = json.loads(d.pop("summary_json"))
    dropped = d.pop("dropped_samples")
    if dropped:  # as fabrik solve warns
        warnings.warn("%d samples farther than input.max_abs_coordinate_mm from the origin are "
                      "taken as missing, as fabrikd takes them" % dropped, UserWarning,
                      stacklevel=2)
    return Solution(**d)
