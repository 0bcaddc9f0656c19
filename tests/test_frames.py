"""pandas interop: ``robocal.load(DataFrame)`` reads a frame as the canonical CSV with the same
content (same Dataset, same DataErrors naming column and row — the frame's position),
``Dataset.to_frame`` round-trips, and results give their parameters as a DataFrame."""

from __future__ import annotations

import numpy as np
import pytest

import robocal
from robocal.data import Dataset, load, read_canonical, write_canonical
from robocal.exceptions import DataError

pd = pytest.importorskip("pandas")


def sample(measurement="pose", m=6, robot=None):
    rng = np.random.default_rng(7)
    width = {"cable": 1, "position": 3, "pose": 7}[measurement]
    y = rng.normal(500, 50, (m, width))
    if measurement == "pose":
        y[:, 3:] /= np.linalg.norm(y[:, 3:], axis=1, keepdims=True)
    return Dataset(q=rng.uniform(-3, 3, (m, 6)), y=y, measurement=measurement, robot=robot, t=np.arange(m) * 0.5, temp=20 + rng.random(m))


def same_data(a, b):
    for name in ("q", "y", "t", "temp"):
        x, y = getattr(a, name), getattr(b, name)
        assert (x is None) == (y is None), name
        if x is not None:
            np.testing.assert_array_equal(x, y, err_msg=name)
    assert (a.measurement, a.robot, a.notes, a.excluded) == (b.measurement, b.robot, b.notes, b.excluded)


@pytest.mark.parametrize("measurement", ["cable", "position", "pose"])
def test_frame_and_csv_give_the_same_dataset(tmp_path, measurement):
    d = sample(measurement)
    path = write_canonical(d, tmp_path / "d.csv")
    from_csv = load(path)
    from_frame = load(pd.read_csv(path))
    same_data(from_frame, from_csv)
    np.testing.assert_array_equal(from_frame.rows, np.arange(len(d)))  # positions in the frame
    assert from_frame.source == "DataFrame"


@pytest.mark.parametrize("measurement", ["cable", "position", "pose"])
def test_round_trip(measurement):
    d = sample(measurement, robot="ur10")
    back = robocal.load(d.to_frame())
    same_data(back, d)  # bit for bit: the frame holds radians and says so in attrs
    again = robocal.load(back.to_frame())
    same_data(again, back)
    np.testing.assert_array_equal(again.rows, back.rows)
    deg = d.to_frame(angle_unit="deg")  # the values of a canonical file, read back through degrees
    np.testing.assert_allclose(robocal.load(deg).q, d.q, rtol=1e-15, atol=1e-15)
    deg.attrs.clear()  # a frame that does not say its unit is read in degrees, like a file
    np.testing.assert_allclose(robocal.load(deg).q, d.q, rtol=1e-15, atol=1e-15)


def test_to_frame_columns():
    f = sample("cable", m=3).to_frame(angle_unit="deg")
    assert f.attrs == {"angle_unit": "deg"}
    assert list(f.columns) == ["q1", "q2", "q3", "q4", "q5", "q6", "L", "t", "temp"]
    assert f.shape == (3, 9)


def test_text_cells_read_like_csv_cells(tmp_path):
    """A frame of strings (e.g. ``read_csv(dtype=str)``) is checked cell by cell like the file."""
    text = "q1,q2,L\n1,2,3\n 4 ,5.5e1,6\n"
    (tmp_path / "f.csv").write_text(text)
    from_csv = read_canonical(tmp_path / "f.csv")
    from_frame = load(pd.read_csv(tmp_path / "f.csv", dtype=str), check_units=False)
    np.testing.assert_array_equal(from_frame.q, from_csv.q)
    np.testing.assert_array_equal(from_frame.y, from_csv.y)


@pytest.mark.parametrize(
    "frame, message, row, column",
    [
        (pd.DataFrame({"q1": [1.0, 2.0, 3.0], "q2": [1.0, np.nan, 3.0], "L": [1.0, 2.0, 3.0]}), "expected a finite number; got nan", 1, "q2"),
        (pd.DataFrame({"q1": [1.0, 2.0], "q2": [1.0, 2.0], "L": [1.0, np.inf]}), "expected a finite number; got inf", 1, "L"),
        (pd.DataFrame({"q1": ["1", "1_0"], "q2": [1, 2], "L": [1, 2]}), "expected a number; got '1_0'", 1, "q1"),
        (pd.DataFrame({"q1": ["0x10", "1"], "q2": [1, 2], "L": [1, 2]}), "expected a number; got '0x10'", 0, "q1"),
        (pd.DataFrame({"q1": [1, 2], "q2": [1, 2], "L": [3e12, 2]}), "3e\\+12 is beyond", 0, "L"),
        (pd.DataFrame({"q1": [1, 2], "q2": [True, False], "L": [1, 2]}), "expected a number; got True \\(bool\\)", 0, "q2"),
        (pd.DataFrame({"q1": [1, None], "q2": ["a", "b"], "L": [1, 2]}), "expected a number; got 'a'", 0, "q2"),
        (pd.DataFrame({"q1": pd.array([1, None], dtype="Int64"), "q2": [1, 2], "L": [1, 2]}), "the cell is empty", 1, "q1"),
        (pd.DataFrame({"q1": [1.0], "q2": [2.0], "x": [1.0]}), "no measurement columns", None, None),
        (pd.DataFrame({"q1": [1.0], "q3": [2.0], "L": [1.0]}), "q1..qN without gaps", None, None),
        (pd.DataFrame({"q1": [], "q2": [], "L": []}), "the DataFrame has no rows", None, None),
        (pd.DataFrame([[1.0, 2.0, 3.0]], columns=["q1", "L", "L"]), "appears more than once", None, None),
    ],
)
def test_bad_frames_name_column_and_row(frame, message, row, column):
    with pytest.raises(DataError, match=message) as err:
        load(frame, check_units=False)
    assert str(err.value).startswith("DataFrame")
    if row is not None:
        assert (err.value.row, err.value.column) == (row, column)
        assert f"row {row}, column {column!r}" in str(err.value)


def test_bad_frame_errors_match_the_csv_errors(tmp_path):
    """The same bad cell in a file and in a frame: the same message, the row told as a line
    number in the file and as a position in the frame."""
    text = "q1,q2,L\n1,2,3\n4,nan,6\n"
    (tmp_path / "f.csv").write_text(text)
    with pytest.raises(DataError) as from_csv:
        read_canonical(tmp_path / "f.csv")
    with pytest.raises(DataError) as from_frame:
        load(pd.read_csv(tmp_path / "f.csv", dtype=str, keep_default_na=False))
    assert from_frame.value.message == from_csv.value.message
    assert (from_frame.value.row, from_csv.value.row, from_frame.value.column) == (1, 3, "q2")


def test_excluded_rows_and_a_nan_temperature():
    frame = pd.DataFrame({"q1": [10.0, 20.0, 30.0], "q2": [10.0, "x", 30.0], "L": [1.0, 2.0, 3.0], "temp": [20.0, 21.0, np.nan]})
    d = load(frame, exclude_bad_rows=True)
    np.testing.assert_array_equal(d.rows, [0, 2])
    assert d.excluded == [{"row": 1, "column": "q2", "reason": "expected a number; got 'x'"}]
    assert np.isnan(d.temp[1])


def test_load_options_and_calibrate_take_frames(tmp_path):
    data, _ = robocal.simulate("hsr-jr680", "cable", samples=300, seed=2)
    frame = data.to_frame()
    assert frame.attrs["robot"] == "hsr-jr680"
    with pytest.raises(DataError, match="DataFrame is read as a canonical table"):
        load(frame, format="ipa")
    with pytest.raises(DataError, match="robot 'ur10' has 6 joints|this is"):
        load(frame.drop(columns=["q6"]), robot="ur10")
    result = robocal.calibrate(frame, test_fraction=0.2)
    assert result.success and result.problem.data.source == "DataFrame"
    table = result.parameters_frame()
    assert list(table.columns) == ["name", "value", "nominal", "deviation", "std", "unit", "estimated"]
    assert len(table) == len(result.parameters())
    np.testing.assert_allclose(table["deviation"], table["value"] - table["nominal"])
    assert table["estimated"].sum() == len(result.x)
    assert table.loc[table["estimated"], "std"].notna().all() and table.loc[~table["estimated"], "std"].isna().all()
    assert set(table["unit"]) <= {"mm", "rad", "1"}


def test_not_a_path_nor_a_frame():
    with pytest.raises(DataError, match="a file path \\(str or Path\\) or a pandas DataFrame; got dict"):
        load({"q1": [1]})
