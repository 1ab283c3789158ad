"""Readers into NumPy: what the module reads is what the file says."""
import math

import numpy as np
import pytest

import fabrik
from conftest import DEFAULT_CONFIG, fabrik_cli, shared_data


def parse_trc(path):
    """The TRC's labels and numbers read by hand (tab-separated; empty field = missing)."""
    lines = open(path).read().split("\n")
    rate = float(lines[2].split("\t")[0])
    labels = [x for x in lines[3].split("\t")[2:] if x]
    rows = [line.split("\t") for line in lines[5:] if line.strip()]
    times = [float(r[1]) for r in rows]
    values = np.array([[float(v) if v else math.nan for v in (r[2:] + [""] * (3 * len(labels)))
                        [:3 * len(labels)]] for r in rows])
    return labels, rate, times, values.reshape(len(rows), len(labels), 3)


def test_trc_equals_the_file(synth_trial):
    labels, rate, times, values = parse_trc(synth_trial)
    trial = fabrik.read_markers(synth_trial)
    assert trial.names == labels and trial.rate_hz == rate
    assert trial.file_units == "mm" and trial.format == "TRC"
    np.testing.assert_allclose(trial.time_s, times, rtol=0, atol=1e-12)
    assert np.array_equal(np.isnan(trial.positions_mm), np.isnan(values))
    assert np.isnan(values).any()  # the synthetic gaps
    np.testing.assert_allclose(trial.positions_mm, values, rtol=0, atol=1e-9)
    assert trial.positions_mm.base is not None  # the reader's memory, viewed
    np.testing.assert_allclose(trial.marker(labels[1]), values[:, 1], rtol=0, atol=1e-9)
    frame = trial.frame(0)
    assert set(frame) == {n for n, p in zip(labels, values[0]) if not np.isnan(p).any()}


def test_metres_files_are_read_in_mm(synth_trial, tmp_path):
    labels, _, _, values = parse_trc(synth_trial)
    text = open(synth_trial).read().split("\n")
    header = text[2].split("\t")
    header[4] = "m"
    text[2] = "\t".join(header)
    for i in range(5, len(text)):
        fields = text[i].split("\t")
        if len(fields) > 2:
            fields[2:] = [repr(float(v) / 1000) if v else "" for v in fields[2:]]
            text[i] = "\t".join(fields)
    path = tmp_path / "metres.trc"
    path.write_text("\n".join(text))
    trial = fabrik.read_markers(path)
    assert trial.file_units == "m"
    np.testing.assert_allclose(trial.positions_mm, values, rtol=1e-12, atol=1e-9)


def test_mot_equals_the_file(synth_trial, tmp_path):
    mot = tmp_path / "angles.mot"
    fabrik_cli("solve", "--config", DEFAULT_CONFIG, "--input", synth_trial, "--output",
               tmp_path / "j.trc", "--angles", mot, "--quiet")
    lines = mot.read_text().split("\n")
    start = lines.index("endheader") + 1
    columns = lines[start].split("\t")
    rows = np.array([[float(v) for v in line.split("\t")] for line in lines[start + 1:]
                     if line.strip()])
    table = fabrik.read_table(mot)
    assert table.names == columns[1:] and table.in_degrees
    assert table.header["inDegrees"] == "yes"
    assert np.array_equal(table.time_s, rows[:, 0])
    assert np.array_equal(table.data, rows[:, 1:])


def test_quaternion_sto_cells():
    table = fabrik.read_table(shared_data("opensense_placement_orientations.sto"))
    assert table.data.ndim == 3 and table.data.shape[2] == 4
    norms = np.linalg.norm(table.data, axis=2)
    np.testing.assert_allclose(norms[~np.isnan(norms)], 1, atol=1e-3)


def test_c3d():
    trial = fabrik.read_markers(shared_data("Vicon.c3d"))
    assert trial.format == "C3D" and trial.positions_mm.shape[1:] == (len(trial.names), 3)
    assert trial.rate_hz > 0 and np.isfinite(trial.positions_mm).any()


def test_reader_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="absent.trc"):
        fabrik.read_markers(tmp_path / "absent.trc")
    bad = tmp_path / "bad.trc"
    bad.write_text("not a trc\n")
    with pytest.raises(fabrik.FormatError, match="bad.trc"):
        fabrik.read_markers(bad)
    assert issubclass(fabrik.FormatError, ValueError)
    other = tmp_path / "x.csv"
    other.write_text("a,b\n")
    with pytest.raises(ValueError, match="x.csv"):
        fabrik.read_markers(other)
