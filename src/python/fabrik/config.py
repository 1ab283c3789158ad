"""Loading a daemon config or model, and calibrating a subject (the compiled code; paths may
be str or os.PathLike)."""
import numbers
import os
import re

from . import _fabrik


def load_config(path=None):
    """A fabrikd-config/1 file, or a fabrikd-model/1 file tracked with the embedded default
    config's settings; no path: the embedded default (the built-in full-body model).

    Raises FileNotFoundError, or ConfigError (a ValueError) whose message names the file, the
    JSON pointer and the fix."""
    return _fabrik.load_config(None if path is None else os.fspath(path))


def calibrate(template, static, output=None, *, first_frame=-1, frames=-1, auto_window=-1,
              lab_up="", lab_forward="", keep_zeros=False):
    """A subject's Config from a model template (fabrikd-template/1) and a static trial (.trc or
    .c3d): the same code as `fabrik calibrate`. The config is usable at once (Tracker(config),
    solve(config, ...)); with `output` it is also written there. Its calibration_report is the
    summary `fabrik calibrate` prints.

    first_frame (the file's frame number) and frames choose the averaging window; auto_window=N
    the stillest N frames instead. lab_up/lab_forward ("+z", "+x") declare the lab's axes.
    Marker templates only: a keypoint template ("kind": "keypoints") is a CalibrationError, as
    the module has no keypoint calibration: run `fabrik calibrate --template T --trial
    MOVEMENT.trc --output subject.json` and load_config("subject.json"). A template's
    orientation sensors are left out of the config (the module does not calibrate sensors):
    said in calibration_report's notes and as a UserWarning.

    Releases the GIL. Raises FileNotFoundError, ConfigError/FormatError (ValueErrors) or
    CalibrationError (a RuntimeError: the trial cannot support the template)."""
    # -1 is "not set"; any other value below the least was once taken as not set too, or
    # refused in the command line's words ("--frames 0 ... runs past the last frame"); a float
    # was cut to a whole number (2.7 read as frame 2).
    for name, value, least in (("first_frame", first_frame, 0), ("frames", frames, 1),
                               ("auto_window", auto_window, 1)):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral):
            raise TypeError("%s must be a whole number (or -1: not set), not %r" % (name, value))
        if value != -1 and value < least:
            raise ValueError("%s must be %d or more (or -1: not set), not %r" % (name, least, value))
    try:
        return _fabrik.calibrate(os.fspath(template), os.fspath(static),
                                 None if output is None else os.fspath(output),
                                 first_frame=first_frame, frames=frames, auto_window=auto_window,
                                 lab_up=lab_up, lab_forward=lab_forward, keep_zeros=keep_zeros)
    except _fabrik.CalibrationError as e:
        # The compiled code speaks the command line's options: a Python caller gave keywords.
        said = str(e)
        text = re.sub(r"--(first-frame|frames|auto-window|lab-up|lab-forward)\b",
                      lambda m: m.group(1).replace("-", "_"), said)
        if text == said:
            raise
        raise _fabrik.CalibrationError(text) from None
