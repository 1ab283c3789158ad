"""Recordings as NumPy arrays: marker trials (TRC, C3D) and OpenSim tables (MOT, STO)."""
import os
import dataclasses
from dataclasses import dataclass, field
from typing import Dict, List

import numpy as np

from . import _fabrik


@dataclass
class MarkerData:
    """A marker trial. positions_mm: (frames, markers, 3) float64 in mm in the file's lab
    frame, NaN where a marker is missing; names: the markers; time_s: each frame's time as the
    file counts it; frame_numbers: as the file numbers them. file_units: the unit the file was
    written in (positions are converted to mm whatever it was)."""
    names: List[str]
    positions_mm: np.ndarray
    time_s: np.ndarray
    rate_hz: float
    first_frame: int = 1
    frame_numbers: np.ndarray = None
    file_units: str = "mm"
    format: str = ""
    warnings: List[str] = field(default_factory=list)

    def marker(self, name):
        """(frames, 3) mm of one marker (a view)."""
        return self.positions_mm[:, self.names.index(name), :]

    def frames(self, start, stop):
        """Frames [start, stop) (indices, as a Python slice takes them) as a MarkerData whose
        positions, times and frame numbers stay together (what solve needs of a part)."""
        part = slice(start, stop)
        frames = np.shape(self.positions_mm)[0]
        numbers = self.frame_numbers
        if numbers is None or not len(numbers):
            numbers = self.first_frame + np.arange(frames)
        times = self.time_s
        if times is None or not len(times):  # frame n at (n - 1) / rate, as solve takes it
            times = (np.asarray(numbers, dtype=np.float64) - 1.0) / float(self.rate_hz)
        return dataclasses.replace(self, positions_mm=self.positions_mm[part],
                                   time_s=np.asarray(times)[part],
                                   frame_numbers=np.asarray(numbers)[part],
                                   warnings=list(self.warnings))

    def frame(self, index):
        """{name: (x, y, z) mm} of one frame, the dict Tracker.track takes (missing markers
        left out)."""
        row = self.positions_mm[index]
        return {n: tuple(p) for n, p in zip(self.names, row) if not np.isnan(p).any()}


@dataclass
class Table:
    """An OpenSim table (.mot, .sto). data: (rows, columns) values as the file has them
    (in_degrees says whether rotational columns are degrees), or (rows, columns, k) when cells
    are k-tuples such as quaternions (w, x, y, z); names: the columns after time."""
    names: List[str]
    time_s: np.ndarray
    data: np.ndarray
    rate_hz: float
    in_degrees: bool
    cell_kind: str
    header: Dict[str, str]
    name: str = ""
    warnings: List[str] = field(default_factory=list)

    def column(self, name):
        """One column's values (a view)."""
        return self.data[:, self.names.index(name)]


def read_markers(path, keep_zeros=False):
    """A .trc or .c3d file as MarkerData (mm). Exact (0, 0, 0) samples are missing (NaN) unless
    keep_zeros. Raises FileNotFoundError, or FormatError (a ValueError) saying what is wrong."""
    return MarkerData(**_fabrik._read_markers(os.fspath(path), keep_zeros))


def read_table(path):
    """A .mot or .sto file as a Table. Raises FileNotFoundError or FormatError."""
    return Table(**_fabrik._read_table(os.fspath(path)))
