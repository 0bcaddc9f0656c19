"""The parsed table every format reader stands on (``robocal.data.table``): one :class:`Table` from a
workbook or a delimited text, the same cells either way, and errors naming file, row and column.
That the table imports no format reader is the import-linter contract of ``pyproject.toml``
(tests/test_layers.py)."""

from __future__ import annotations

import numpy as np
import pytest
from robocal.data.table import Table, read_delimited, read_table
from robocal.exceptions import DataError

HEADER = ["q2", "L", "q1", "note"]
ROWS = [[10.5, 1200.25, -3.0, "a"], [11.0, 1201.5, -2.5, "b"], [12.25, 1199.0, -2.0, "c"]]


def _csv(path, delimiter=","):
    lines = [delimiter.join(HEADER)] + [delimiter.join(str(c) for c in row) for row in ROWS]
    path.write_text("\n".join(lines) + "\n")
    return path


def _workbook(path, second_sheet=False):
    openpyxl = pytest.importorskip("openpyxl")
    book = openpyxl.Workbook()
    sheet = book.active
    sheet.title = "data"
    for row in [HEADER, *ROWS]:
        sheet.append(row)
    if second_sheet:
        book.create_sheet("old").append(["x"])
        book["old"].append([1.0])
    book.save(path)
    return path


def test_a_workbook_and_its_csv_copy_give_the_same_table(tmp_path):
    # judged by content: the workbook is named .csv, the text file .xlsx
    book = read_table(_workbook(tmp_path / "book.csv"))
    text = read_table(_csv(tmp_path / "text.xlsx"))
    assert book.header == text.header == HEADER
    for table in (book, text):
        values, rows, excluded = table.numeric(["q1", "q2", "L"])
        np.testing.assert_array_equal(values, [[r[2], r[0], r[1]] for r in ROWS])
        assert rows.tolist() == [2, 3, 4] and excluded == []
        assert table.text("note", rows) == ["a", "b", "c"]
        assert table.joint_columns() == ["q1", "q2"]
        assert table.ignored_note(["q1", "q2", "L"]) == ["ignored columns ['note']"]
    assert book.notes == [] and text.notes == []


def test_the_path_is_kept_as_given_and_other_sheets_are_noted(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    _workbook(tmp_path / "two.xlsx", second_sheet=True)
    table = read_table("./two.xlsx")
    assert table.path == "./two.xlsx"  # the readers name the file as the user did
    assert table.notes[0] == "read sheet 'data'" and "sheet 'old' (1 rows, columns ['x']) not read" in table.notes[1]
    assert read_table("./two.xlsx", sheet="old").header == ["x"]
    with pytest.raises(DataError, match=r"no sheet 'nope'; the workbook has \['data', 'old'\]"):
        read_table("two.xlsx", sheet="nope")


def test_a_text_file_takes_no_sheet_and_its_delimiter_is_asked_for(tmp_path):
    path = _csv(tmp_path / "semi.csv", delimiter=";")
    with pytest.raises(DataError, match=r"`sheet` applies to .xlsx workbooks; this is a text file \(sheet='data'\)"):
        read_table(path, sheet="data")
    assert read_table(path, delimiter=";").header == read_delimited(path, ";").header == HEADER
    with pytest.raises(DataError, match="this file looks ';'-separated"):
        read_table(path)


def test_a_bad_cell_is_named_by_file_row_and_column(tmp_path):
    path = tmp_path / "bad.csv"
    path.write_text("q1,L\n1.0,2.0\n1.5,x\n")
    table = read_delimited(path)
    with pytest.raises(DataError) as error:
        table.numeric(["q1", "L"])
    assert (error.value.path, error.value.row, error.value.column, error.value.message) == (path, 3, "L", "expected a number; got 'x'")
    values, rows, excluded = table.numeric(["q1", "L"], exclude_bad_rows=True)
    assert values.tolist() == [[1.0, 2.0]] and rows.tolist() == [2] and excluded == [{"row": 3, "column": "L", "reason": "expected a number; got 'x'"}]


def test_joint_columns_are_in_joint_order():
    table = Table(["L", "q10", "q2", "x", "q1", "q", "q1a"], [], "in memory")
    assert table.joint_columns() == ["q1", "q2", "q10"]
    with pytest.raises(DataError, match=r"in memory, row 1: a file needs columns \['q1', 'y'\]; missing \['y'\]"):
        table.require(["q1", "y"], "a file")
