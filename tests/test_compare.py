"""The comparison harness (``robocal.compare``): same splits for all methods, every file
written, tables consistent with the JSON, failures recorded rather than fatal, the CLI."""

from __future__ import annotations

import csv
import json
import re
import warnings

import numpy as np
import pytest

from robocal.calibration import api
from robocal.cli import main
from robocal.compare import compare, default_methods, method_label, wilcoxon_row
from robocal.data import write_canonical
from robocal.exceptions import InvalidParameterError
from robocal.simulation import simulate

FAST = ["lm", "lm-paper", "vslm", "ukf", "ukf-vslm", "rbf"]
FILES = [f"table_{n}.{ext}" for n in ("VIII", "IX", "X", "XI", "XII", "XIII") for ext in ("md", "csv")]
FILES += ["tables.md", "fig5_metrics.png", "fig6_convergence.png", "fig7_errors.png", "comparison.json"]


@pytest.fixture(scope="module")
def data():
    dataset, _ = simulate("hsr-jr680", "cable", samples=140, seed=5)
    return dataset


@pytest.fixture(scope="module")
def paper_run(data, tmp_path_factory):
    # An unknown option makes vslm raise on every split: it must be recorded, not fatal.
    result = compare(data, methods=FAST, protocol="paper", repeats=3, method_options={"vslm": {"no_such_option": 1}})
    out = tmp_path_factory.mktemp("paper")
    result.write(out)
    return result, out


def _markdown_rows(path) -> list[list[str]]:
    lines = [line for line in path.read_text().splitlines() if line.startswith("|")]
    return [[cell.strip() for cell in line.strip("|").split("|")] for line in lines[2:]]


def test_default_methods_are_m1_to_m9_then_lm():
    methods = default_methods()
    assert [api.METHODS[m][0] for m in methods] == [f"M{i}" for i in range(1, 10)] + ["-"]
    assert method_label("ekf") == "M1 EKF" and method_label("ukf-vslm") == "M9 UKF-VSLM"
    assert method_label("lm-paper") == "M6 LM" and method_label("lm") == "robocal LM"


def test_all_files_are_written_and_tables_have_a_row_per_method(paper_run):
    result, out = paper_run
    for name in FILES:
        assert (out / name).stat().st_size > 0, name
    labels = ["Before (start)"] + [method_label(m) for m in FAST]
    assert [row[0] for row in _markdown_rows(out / "table_VIII.md")] == labels
    assert [row[0] for row in _markdown_rows(out / "table_IX.md")] == labels[1:]
    with open(out / "table_VIII.csv") as f:
        assert [row["method"] for row in csv.DictReader(f)] == labels
    assert len(_markdown_rows(out / "table_XII.md")) == 6  # one row per joint
    assert len(_markdown_rows(out / "table_X.md")) == 3 * (len(FAST) - 1)


def test_markdown_numbers_match_the_json_and_the_runs(paper_run):
    result, out = paper_run
    doc = json.loads((out / "comparison.json").read_text())
    rows = {row["name"]: row for row in doc["tables"]["table_VIII"]["rows"]}
    for cells in _markdown_rows(out / "table_VIII.md"):
        row = next(r for r in rows.values() if r["method"] == cells[0])
        for cell, metric in zip(cells[2:5], ("rmse", "mae", "max")):
            if row[f"{metric}_mean"] is None:
                assert cell == "—"
                continue
            mean, std = (float(v) for v in cell.split(" ± "))
            assert mean == pytest.approx(row[f"{metric}_mean"], rel=1e-3)
            assert std == pytest.approx(row[f"{metric}_std"], rel=1e-3)
    lm_rmse = [r["test"]["rmse"] for r in doc["runs"] if r["method"] == "lm"]
    assert len(lm_rmse) == 3 and rows["lm"]["rmse_mean"] == pytest.approx(np.mean(lm_rmse))
    assert rows["lm"]["rmse_std"] == pytest.approx(np.std(lm_rmse, ddof=1))


def test_splits_are_identical_across_methods_and_follow_the_paper_protocol(paper_run):
    result, _ = paper_run
    assert len(result.splits) == 3
    for split in result.splits:
        assert len(split["train"]) == 100 and len(split["test"]) == 20
        assert not set(split["train"]) & set(split["test"])
        runs = [r for r in result.runs if r["split"] == split["index"]]
        assert sorted(r["method"] for r in runs) == sorted(FAST)
        assert all(r["test_rows"] == split["test_rows"] for r in runs)
        assert all(len(r["test_errors"]) == 20 for r in runs if r["status"] == "ok")
    assert result.splits[0]["test"] != result.splits[1]["test"]


def test_a_failing_method_is_recorded_not_fatal(paper_run):
    result, out = paper_run
    failed = result.runs_of("vslm")
    assert [r["status"] for r in failed] == ["failed"] * 3
    assert "no_such_option" in failed[0]["error"]
    assert all(r["status"] == "ok" for m in FAST if m != "vslm" for r in result.runs_of(m))
    row = next(r for r in _markdown_rows(out / "table_VIII.md") if r[0] == "M8 VSLM")
    assert row[1] == "0/3" and "no_such_option" in row[-1]


def test_a_method_raising_is_recorded(data, monkeypatch):
    def broken(problem, **options):
        raise RuntimeError("diverged")

    monkeypatch.setitem(api.METHODS, "rbf", ("M5", "broken", broken))
    result = compare(data, methods=["lm", "rbf"], protocol="chronological", repeats=2)
    assert len(result.splits) == 1 and any("deterministic" in note for note in result.config["notes"])
    assert result.runs_of("rbf")[0]["error"] == "RuntimeError: diverged"
    assert result.runs_of("lm")[0]["status"] == "ok"


def test_kfold_holds_out_every_sample_once(data, tmp_path):
    result = compare(data, methods=["lm", "rbf"], protocol="kfold", repeats=3)
    tests = np.concatenate([s["test"] for s in result.splits])
    assert sorted(tests.tolist()) == list(range(len(data)))
    result.write(tmp_path)
    assert (tmp_path / "comparison.json").exists()


def test_subset_is_drawn_before_splitting(data):
    result = compare(data, methods=["lm"], protocol="80-20", repeats=2, subset=60)
    assert result.config["samples"] == 60
    assert all(len(s["train"]) + len(s["test"]) == 60 for s in result.splits)


def test_wilcoxon_rows():
    better = wilcoxon_row([1.0, 1.0, 1.0, 1.0, 1.0, 1.0], [2.0, 3.0, 4.0, 5.0, 6.0, 7.0])
    assert better["r_plus"] == 21 and better["r_minus"] == 0 and better["better"] == "reference"
    assert better["p_value"] == pytest.approx(0.03125) and better["note"] == ""
    few = wilcoxon_row([1.0, 2.0], [2.0, 1.5])
    assert few["n"] == 2 and "too few pairs" in few["note"]
    assert wilcoxon_row([1.0, 2.0], [1.0, 2.0 + 1e-14])["note"] == "all paired differences are zero"


def test_cli_end_to_end(data, tmp_path, capsys):
    path = tmp_path / "sim.csv"
    write_canonical(data, path)
    out = tmp_path / "out"
    code = main(
        [
            "compare",
            str(path),
            "--robot",
            "hsr-jr680",
            "--protocol",
            "paper",
            "--repeats",
            "2",
            "--methods",
            "lm",
            "ukf-vslm",
            "rbf",
            "--seed",
            "3",
            "--out",
            str(out),
        ]
    )
    assert code == 0
    assert "Table VIII" in capsys.readouterr().out
    for name in FILES:
        assert (out / name).exists(), name
    doc = json.loads((out / "comparison.json").read_text())
    assert doc["config"]["seed"] == 3 and [m["name"] for m in doc["methods"]] == ["lm", "ukf-vslm", "rbf"]


def test_cli_exits_1_when_every_run_failed_and_draws_without_warnings(data, tmp_path, capsys):
    """Issue 52 #21: every run failing (4 training samples cannot place the cable) exited 0, and
    the convergence figure's legend of no line made matplotlib warn on the terminal."""
    path = tmp_path / "sim.csv"
    write_canonical(data, path)
    argv = ["compare", path, "--robot", "hsr-jr680", "--protocol", "80-20", "--repeats", "2", "--methods", "lm", "--subset", "5", "--out", tmp_path / "c"]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        code = main([str(a) for a in argv])
    assert code == 1
    assert "2 of 2 runs failed" in capsys.readouterr().out
    assert all((tmp_path / "c" / name).exists() for name in FILES)  # the failures are written all the same
    assert [str(w.message) for w in caught if issubclass(w.category, UserWarning)] == []


@pytest.mark.parametrize("quiet", [False, True])
def test_cli_prints_stage_lines_where_no_bar_is_drawn(data, tmp_path, capsys, quiet):
    """Issue 52: off a terminal (here: captured), a long command printed nothing for minutes. Each
    stage now ends with one line on stderr with its elapsed time; --quiet silences it, and called
    from Python afterwards robocal prints none."""
    path = tmp_path / "sim.csv"
    write_canonical(data, path)
    argv = ["compare", str(path), "--robot", "hsr-jr680", "--protocol", "80-20", "--repeats", "2", "--methods", "lm", "--out", str(tmp_path / "c")]
    assert main(argv + (["--quiet"] if quiet else [])) == 0
    lines = capsys.readouterr().err.splitlines()
    assert lines == [] if quiet else [line for line in lines if re.fullmatch(r"robocal: compare: splits: 2 splits in \d+\.\d s", line)] == lines != []
    compare(data, methods=["lm"], protocol="80-20", repeats=2)
    assert capsys.readouterr().err == ""


def test_cli_refusals_name_the_options_and_the_paper_s_labels(data, tmp_path, capsys):
    """The tables say "M1 EKF": a method asked by its label is refused naming each method's label;
    more folds than samples named `k`, an argument of the library, not --repeats."""
    path = tmp_path / "sim.csv"
    write_canonical(data, path)
    argv = ["compare", str(path), "--robot", "hsr-jr680", "--out", str(tmp_path / "c")]
    assert main(argv + ["--methods", "M1"]) == 2
    assert "unknown methods ['M1']; choose from bas (M2), de (M7), ekf (M1), lm, " in capsys.readouterr().err
    assert main(argv + ["--protocol", "kfold", "--repeats", "500"]) == 2
    assert "`--repeats` must be an integer in [2, m=140]; got 500" in capsys.readouterr().err
    with pytest.raises(InvalidParameterError, match="no method given; choose from bas"):
        compare(data, methods=[])


@pytest.mark.parametrize(
    "bad, message",
    [
        ({"kinematic_prior": (-1, 1)}, "`kinematic_prior` must be"),  # was: every run a failure, exit 1
        ({"seed": "a"}, "`seed` must be None or an integer"),  # was: TypeError from the split
        ({"subset": 130.5}, r"`subset` must lie in \[2, 140\]"),  # was: TypeError from NumPy
        ({"method_options": {"ekff": {}}}, r"`method_options` names unknown methods \['ekff'\]"),  # was: ignored
    ],
)
def test_arguments_are_refused_before_any_run(data, bad, message):
    with pytest.raises(InvalidParameterError, match=message):
        compare(data, methods=["lm"], repeats=1, **bad)


def test_one_method_may_be_named_by_a_string_and_numpy_integers_count(data):
    result = compare(data, methods="lm", repeats=np.int64(1))  # was: "unknown methods ['l', 'm']"
    assert result.methods == ["lm"] and result.config["repeats"] == 1


def test_the_data_s_notes_are_the_tables_notes(data, tmp_path):
    """Degrees read as radians, as asked, gave a table of 221 mm errors without the reader's word why."""
    path = tmp_path / "sim.csv"
    write_canonical(data, path)
    result = compare(str(path), robot="hsr-jr680", methods="lm", repeats=1, angle_unit="rad")
    assert any("look like degrees" in note and "kept in rad as asked" in note for note in result.table_viii().notes)


def test_a_split_without_degrees_of_freedom_fails_as_calibrate_refuses_it(data):
    """8 configurations of 3 visits each left 8 residuals for 8 parameters: every method "succeeded"
    with a training RMSE of 0.006 mm, where calibrate refuses the same training set."""
    few = data.subset(np.repeat(np.arange(10), 3))
    result = compare(few, methods=["lm", "ekf"], protocol="kfold", repeats=5)
    assert all(r["status"] == "failed" and "0 degrees of freedom" in r["error"] for r in result.runs)
