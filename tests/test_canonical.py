"""The canonical CSV: round trip, and errors that name file, row and column."""

from __future__ import annotations

import numpy as np
import pytest

from robocal.data import Dataset, read_canonical, write_canonical
from robocal.exceptions import DataError


def sample(measurement="cable", m=5):
    rng = np.random.default_rng(2)
    width = {"cable": 1, "position": 3, "pose": 7}[measurement]
    y = rng.normal(500, 50, (m, width))
    if measurement == "pose":
        y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    return Dataset(q=rng.uniform(-3, 3, (m, 6)), y=y, measurement=measurement, t=np.arange(m) * 0.5, temp=20 + rng.random(m))


@pytest.mark.parametrize("measurement", ["cable", "position", "pose"])
@pytest.mark.parametrize("unit", ["deg", "rad"])
def test_round_trip_is_exact(tmp_path, measurement, unit):
    d = sample(measurement)
    back = read_canonical(write_canonical(d, tmp_path / "d.csv", angle_unit=unit), angle_unit=unit)
    assert back.measurement == measurement
    np.testing.assert_allclose(back.q, d.q, rtol=1e-15, atol=1e-15)
    np.testing.assert_array_equal(back.y, d.y)
    np.testing.assert_array_equal(back.t, d.t)
    np.testing.assert_array_equal(back.rows, np.arange(2, 7))


def write(tmp_path, text):
    path = tmp_path / "f.csv"
    path.write_text(text)
    return path


def test_text_in_a_numeric_cell_names_row_and_column(tmp_path):
    path = write(tmp_path, "q1,q2,L\n1,2,3\n4,five,6\n")
    with pytest.raises(DataError, match=r"f\.csv, row 3, column 'q2': expected a number; got 'five'") as err:
        read_canonical(path)
    assert (err.value.row, err.value.column) == (3, "q2")


@pytest.mark.parametrize(
    "text, message",
    [
        ("", "empty"),
        ("q1,q2,L\n", "no data rows"),
        ("q1;q2;L\n1;2;3\n", "containing ';'"),
        ("q1,q3,L\n1,2,3\n", "q1..qN without gaps"),
        ("q1,q2,x,y\n1,2,3,4\n", "no measurement columns"),
        ("q1,q2,L\n1,2\n", "row 2: expected 3 cells"),
        ("q1,q2,L\n1,2,nan\n", "row 2, column 'L': expected a finite number"),
    ],
)
def test_malformed_files(tmp_path, text, message):
    with pytest.raises(DataError, match=message):
        read_canonical(write(tmp_path, text))


def test_unknown_columns_are_reported_not_guessed(tmp_path):
    d = read_canonical(write(tmp_path, "q1,q2,L,operator\n1,2,3,ann\n"))
    assert d.notes == ["ignored unknown columns ['operator']"]


def test_missing_observation_columns_for_an_explicit_measurement(tmp_path):
    with pytest.raises(DataError, match=r"a pose file needs columns .*missing \['qw', 'qx', 'qy', 'qz'\]"):
        read_canonical(write(tmp_path, "q1,x,y,z\n1,2,3,4\n"), measurement="pose")


def test_missing_file():
    with pytest.raises(DataError, match="cannot read the file"):
        read_canonical("/nonexistent/data.csv")
