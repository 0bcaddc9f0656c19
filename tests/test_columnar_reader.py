"""The columnar (pyarrow) reader and the per-cell path agree: same values, same rows, same notes,
or the same DataError (message, row, column) — on generated tables full of nasty cells.

The fast path may only *accept* what the per-cell rules accept, with the same value; everything
else falls back to the per-cell path, which names the bad cell. ``table.COLUMNAR = False`` is the
per-cell path alone.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from robocal.data import load, read_canonical, read_ipa, table
from robocal.data import write_canonical
from robocal.data.dataset import Dataset
from robocal.exceptions import DataError

pytest.importorskip("pyarrow")

#: Cells the per-cell rules refuse or treat specially, each a trap for a lenient columnar parser.
NASTY = [
    "1_0",
    "0x10",
    "0b1",
    "1d5",
    "1f",
    " 1 ",
    "\t2\t",
    "1 2",
    "1e400",
    "-1e400",
    "1e-400",
    "NaN",
    "nan",
    "-nan",
    "inf",
    "-inf",
    "Infinity",
    "INF",
    "1,000",
    "1,5",
    "1.5.3",
    "١",
    "１",
    "\xa01",
    "1\u2003",
    "",
    " ",
    "1e",
    "e1",
    "+-1",
    "--1",
    "1-",
    ".",
    "+",
    "-",
    "+.5",
    "1.",
    ".5",
    "00012",
    "1E+5",
    "1e13",
    "-1e12",
    "1e12",
    "1000000000000.0001",
    "9" * 30,
    "0." + "0" * 30 + "1",
    "N/A",
    "NULL",
    "null",
    "NA",
    "#N/A",
    "true",
    "True",
    "1e+",
    "1E5e5",
    "2,02011E+13",
    "'1'",
    "1;2",
    "x",
]
QUOTED = ['"1"', '"1,5"', '"a,b"', '"', '""']


def _float_text(x: float, style: int) -> str:
    return [repr, lambda v: f"{v:.3f}", lambda v: f"{v:e}", lambda v: f"{v:+.6E}", lambda v: f" {v!r} ", lambda v: f"{v:.17g}"][style](x)


finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False)
number_cell = st.builds(_float_text, finite, st.integers(0, 5)) | st.integers(-(10**12), 10**12).map(str)
cell = st.one_of(
    number_cell, number_cell, number_cell, st.sampled_from(NASTY), st.sampled_from(QUOTED), st.text(alphabet=st.characters(codec="utf-8"), max_size=4)
)

HEADERS = [
    ["q1", "q2", "L"],
    ["q1", "q2", "q3", "L", "t", "temp"],
    ["q1", "q2", "x", "y", "z", "sample"],
    ["q1", "q2", "L", "operator"],
]


@st.composite
def tables(draw, clean: bool = False):
    header = list(draw(st.sampled_from(HEADERS)))
    if not clean and draw(st.integers(0, 20)) == 0:
        header.append(draw(st.sampled_from(["q1", "L", "", "q3"])))  # a duplicate or an extra name
    width = len(header)
    rows = []
    for _ in range(draw(st.integers(0, 12))):
        kind = 0 if clean else draw(st.integers(0, 30))
        if kind == 1:
            rows.append("")  # blank line
        elif kind == 2:
            rows.append(draw(st.sampled_from(["  ", "\t", ",,", ",," + "," * width, " , "])))
        else:
            n = width + (draw(st.sampled_from([-1, 1])) if kind == 3 else 0)
            cells = [draw(number_cell if clean else cell) for _ in range(max(n, 0))]
            line = ",".join(cells) + ("," if kind == 4 else "")
            rows.append(line)
    eol = "\n" if clean else draw(st.sampled_from(["\n", "\r\n", "\n", "\r", "\u2028"]))
    text = eol.join([",".join(header)] + rows)
    if not clean:
        text += draw(st.sampled_from(["", eol, eol + eol, "\n\n"]))
    bom = "\ufeff" if draw(st.booleans()) else ""
    return bom + text


def read_both(path, reader, **options):
    """(fast outcome, precise outcome): a Dataset or the DataError's (message, row, column)."""
    out = []
    for columnar in (True, False):
        table.COLUMNAR = columnar
        try:
            out.append(reader(path, **options))
        except DataError as exc:
            out.append((str(exc), exc.row, exc.column))
        finally:
            table.COLUMNAR = True
    return out


def bits(a):
    return None if a is None else np.ascontiguousarray(a, dtype=np.float64).view(np.int64)


def assert_same(fast, precise):
    if isinstance(precise, tuple) or isinstance(fast, tuple):
        assert fast == precise
        return
    for name in ("q", "y", "t", "temp"):
        a, b = bits(getattr(fast, name)), bits(getattr(precise, name))
        assert (a is None) == (b is None), name
        if a is not None:
            np.testing.assert_array_equal(a, b, err_msg=name)  # bit for bit (-0.0 too)
    np.testing.assert_array_equal(fast.rows, precise.rows)
    assert fast.measurement == precise.measurement
    assert (fast.notes, fast.excluded) == (precise.notes, precise.excluded)


def write(tmp_path_factory, text: str):
    path = tmp_path_factory.mktemp("columnar") / "t.csv"
    path.write_bytes(text.encode("utf-8"))
    return path


@settings(max_examples=400, suppress_health_check=[HealthCheck.too_slow])
@given(tables(), st.booleans())
@example("q1,q2,L\n1_0,2,3\n", False)
@example("q1,q2,L\n0x10,2,3\n", False)
@example("q1,q2,L\n 1 ,2,3\n", False)
@example("q1,q2,L\n1e400,2,3\n", False)
@example("q1,q2,L\nNaN,2,3\n", False)
@example('q1,q2,L\n"1",2,3\n', False)
@example("q1,q2,L\n1,2,3,\n", False)
@example("q1,q2,L\n1,2,3\n\n\n4,5,6\n", True)
@example("q1,q2,L,t,temp\n1,2,3,4,\n", False)
@example("q1,q2,L,q1\n1,2,3,4\n", False)
@example("q1,q2,L\n1,2,1e13\n", False)
@example('q1,q2,L,operator\n1,2,3,"a\n4,5,6,b"\n', False)  # one record over two lines
@example("q1,q2,L\n1,2,3\x0b4,5,6\n", False)  # str.splitlines breaks at VT, FF, FS, GS, RS ...
@example("q1,q2,L\n1,2,3\u20284,5,6\n", False)  # ... and at U+2028, U+2029, U+0085
@example("q1,q2,L\n1,2,3\r4,5,6\n", False)  # a lone CR ends a line too
def test_fast_and_precise_paths_agree(tmp_path_factory, text, exclude):
    path = write(tmp_path_factory, text)
    fast, precise = read_both(path, read_canonical, exclude_bad_rows=exclude)
    assert_same(fast, precise)


@settings(max_examples=150, suppress_health_check=[HealthCheck.too_slow])
@given(tables(), st.sampled_from([None, "rad", "deg"]))
def test_load_agrees(tmp_path_factory, text, angle_unit):
    path = write(tmp_path_factory, text)
    fast, precise = read_both(path, load, angle_unit=angle_unit)
    assert_same(fast, precise)


IPA_HEADER = (
    "Timestamp;shoulder_pan_joint;shoulder_lift_joint;elbow_joint;wrist_1_joint;wrist_2_joint;wrist_3_joint;"
    "measurement_temperature;measurement_x;measurement_y;measurement_z;measurement_rx;measurement_ry;measurement_rz"
)
decimal_comma_cell = number_cell.map(lambda c: c.replace(".", ",")) | st.sampled_from(NASTY + ["1.5", "1,5,5", "1,e5", ",5", "5,"])


@settings(max_examples=200, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.lists(decimal_comma_cell, min_size=13, max_size=13), min_size=1, max_size=6), st.booleans(), st.booleans())
def test_decimal_comma_files_agree(tmp_path_factory, rows, crlf, clock):
    stamps = ["20200714163904", "2,02011E+13"]
    lines = [IPA_HEADER] + [";".join([stamps[0] if clock else stamps[1]] + r) for r in rows]
    path = write(tmp_path_factory, ("\r\n" if crlf else "\n").join(lines) + "\n")
    fast, precise = read_both(path, read_ipa, measurement="position")
    assert_same(fast, precise)


@settings(max_examples=100)
@given(tables(clean=True))
def test_clean_tables_take_the_columnar_path(tmp_path_factory, text):
    """On a clean table the fast path answers without splitting a single row in Python."""
    path = write(tmp_path_factory, text)
    body = table.split_delimited(table.read_text(path), ",", path)[1]
    assert isinstance(body, table.DelimitedBody)
    if len(body.rows):
        header = table.split_delimited(table.read_text(path), ",", path)[0]
        values = body.numeric([i for i, h in enumerate(header) if h != "sample"])
        assert values is not None and "records" not in vars(body)


@given(st.lists(finite, min_size=1, max_size=50))
def test_values_are_bit_identical_to_float(tmp_path_factory, xs):
    """pyarrow's float parser rounds every written number as Python's ``float`` does."""
    texts = [_float_text(x, k % 6) for k, x in enumerate(xs)]
    path = write(tmp_path_factory, "q1,L\n" + "\n".join(f"{t},{t}" for t in texts) + "\n")
    header, body = table.split_delimited(table.read_text(path), ",", path)
    values = body.numeric([0, 1])
    assert values is not None
    np.testing.assert_array_equal(values[:, 0].view(np.int64), np.array([float(t) for t in texts]).view(np.int64))


def test_large_file_round_trip_through_the_fast_path(tmp_path, monkeypatch):
    rng = np.random.default_rng(3)
    d = Dataset(q=rng.uniform(-3, 3, (3000, 6)), y=rng.normal(900, 100, 3000), measurement="cable", t=np.arange(3000.0))
    path = write_canonical(d, tmp_path / "big.csv")
    monkeypatch.setattr(table, "_records", lambda *a: pytest.fail("the per-cell path ran on a clean file"))
    back = read_canonical(path)
    np.testing.assert_allclose(back.q, d.q, rtol=1e-15, atol=1e-15)
    np.testing.assert_array_equal(back.y, d.y)
    np.testing.assert_array_equal(back.rows, np.arange(2, 3002))


@pytest.mark.parametrize(
    "text, message",
    [
        ("q1,q2,L\n1,2,3\n1_0,2,3\n", r"row 3, column 'q1': expected a number; got '1_0'"),
        ("q1,q2,L\n1,2,3\n1,0x10,3\n", r"row 3, column 'q2': expected a number; got '0x10'"),
        ("q1,q2,L\n1,2,3\n1,2,NaN\n", r"row 3, column 'L': expected a finite number; got 'NaN'"),
        ("q1,q2,L\n1,2,3\n1,2,1e400\n", r"row 3, column 'L': expected a finite number; got '1e400'"),
        ("q1,q2,L\n1,2,3\n1,2,2e12\n", r"row 3, column 'L': 2e\+12 is beyond"),
        ("q1,q2,L\n1,2,3\n\n1,2\n", r"row 4: expected 3 cells like the header; got 2"),
        ("q1,q2,L\n1,2,3\n1,2,3,\n", r"row 3: expected 3 cells like the header; got 4"),
        ("q1,q2,L\n1,2,3\n1,,3\n", r"row 3, column 'q2': expected a number; the cell is empty"),
        ("q1,q2,L\n1,2,3\n1,\u0661,3\n", r"row 3, column 'q2': expected a number; got '\u0661'"),
        ("q1,q2,L\n1,2,3\n1,1\u00a0000,3\n", r"row 3, column 'q2': expected a number"),
    ],
)
def test_bad_cells_are_named_by_the_per_cell_path(tmp_path, text, message):
    path = tmp_path / "f.csv"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(DataError, match=message):
        read_canonical(path)


def test_blank_and_padded_lines_keep_their_row_numbers(tmp_path):
    path = tmp_path / "f.csv"
    path.write_bytes(b"\xef\xbb\xbfq1,q2,L\r\n1,2,3\r\n\r\n 4 ,\t5,6\r\n\r\n")
    d = read_canonical(path, angle_unit="rad")
    np.testing.assert_array_equal(d.rows, [2, 4])
    np.testing.assert_array_equal(d.q, [[1, 2], [4, 5]])


digits14 = st.text(alphabet="0123456789", min_size=14, max_size=14)
stamp = st.datetimes(min_value=__import__("datetime").datetime(1971, 1, 2), max_value=__import__("datetime").datetime(2099, 12, 30)).map(
    lambda d: d.strftime("%Y%m%d%H%M%S")
)


@settings(max_examples=300)
@given(st.lists(stamp | digits14, min_size=1, max_size=20))
def test_clock_matches_strptime(stamps):
    """The UR10 ``Timestamp`` clock read by array arithmetic equals strptime's, or defers."""
    from datetime import datetime

    from robocal.data.formats.ipa import _clock

    fast = _clock(stamps)
    try:
        slow = np.array([datetime.strptime(s, "%Y%m%d%H%M%S").timestamp() for s in stamps])
    except ValueError:
        assert fast is None
        return
    if fast is not None:
        np.testing.assert_array_equal(fast, slow)


def test_without_pyarrow_every_cell_takes_the_per_cell_path(tmp_path, monkeypatch):
    d = Dataset(q=np.ones((4, 2)), y=np.arange(4.0), measurement="cable")
    path = write_canonical(d, tmp_path / "d.csv", angle_unit="rad")
    monkeypatch.setattr(table, "_arrow", lambda: None)
    back = read_canonical(path, angle_unit="rad")
    np.testing.assert_array_equal(back.y[:, 0], d.y[:, 0])
    (tmp_path / "ipa.csv").write_text(IPA_HEADER + "\n" + ";".join(["20200714163904"] + ["1,5"] * 13) + "\n")
    assert read_ipa(tmp_path / "ipa.csv", measurement="position").t.tolist() == [0.0]


def test_decimal_comma_files_take_the_columnar_path(tmp_path, monkeypatch):
    rows = [";".join([f"2020071416390{k}"] + [f"{k},{j}5" for j in range(13)]) for k in range(5)]
    (tmp_path / "ipa.csv").write_text(IPA_HEADER + "\r\n" + "\r\n".join(rows) + "\r\n")
    monkeypatch.setattr(table, "_records", lambda *a: pytest.fail("the per-cell path ran on a clean file"))
    d = read_ipa(tmp_path / "ipa.csv", measurement="position")
    np.testing.assert_array_equal(d.q[:, 0], [0.05, 1.05, 2.05, 3.05, 4.05])
    np.testing.assert_array_equal(d.t, np.arange(5.0))


def test_reading_a_file_does_not_import_pandas(tmp_path):
    """pyarrow's ``to_numpy`` imports pandas when installed (~0.4 s): the reader must not call it."""
    import subprocess
    import sys

    (tmp_path / "a.csv").write_text("q1,q2,L\n10,20,30\n40,50,60\n")
    (tmp_path / "b.csv").write_text("q1,q2,L,operator\n 10 ,20,30,ann\n40,50,60,bob\n")  # text column, padded cells
    (tmp_path / "c.csv").write_text(IPA_HEADER + "\n" + ";".join(["20200714163904"] + ["1,5"] * 13) + "\n")
    code = (
        "import sys, robocal.data as d; d.table.COLUMNAR_MIN_BYTES = 0; d.load(sys.argv[1]); d.load(sys.argv[2]); "
        "d.read_ipa(sys.argv[3], measurement='position'); print('pyarrow' in sys.modules, 'pandas' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code, *(str(tmp_path / n) for n in ("a.csv", "b.csv", "c.csv"))], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["True", "False"]


def test_small_files_do_not_pay_for_importing_pyarrow(tmp_path):
    """A fresh process reading a small file stays on the per-cell path (importing pyarrow would
    cost more); a file past COLUMNAR_MIN_BYTES loads pyarrow."""
    import subprocess
    import sys

    (tmp_path / "small.csv").write_text("q1,q2,L\n10,20,30\n40,50,60\n")
    rng = np.random.default_rng(0)
    write_canonical(Dataset(q=rng.uniform(-3, 3, (12000, 6)), y=rng.normal(900, 9, 12000), measurement="cable"), tmp_path / "big.csv")
    assert (tmp_path / "big.csv").stat().st_size > table.COLUMNAR_MIN_BYTES
    code = "import sys, robocal.data as d; d.load(sys.argv[1]); print('pyarrow' in sys.modules)"
    seen = [
        subprocess.run([sys.executable, "-c", code, str(tmp_path / n)], capture_output=True, text=True, check=True).stdout.strip()
        for n in ("small.csv", "big.csv")
    ]
    assert seen == ["False", "True"]
