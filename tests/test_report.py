"""robocal report: the HTML page and its figures from a result file, with and without the data."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import numpy as np
import pytest

import robocal
from robocal.report import figures as report_figures
from robocal.report import page as report_page
from robocal.cli import report as report_cli
from robocal.data import write_canonical
from robocal.exceptions import InvalidParameterError
from robocal.report import report
from robocal.results import load_result

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def calibrated(tmp_path_factory):
    """A position calibration of a simulated IRB 120: (result file, document, data file)."""
    where = tmp_path_factory.mktemp("report")
    data, _ = robocal.simulate("abb-irb120", "position", samples=200, seed=1)
    csv_path = write_canonical(data, where / "d.csv")
    result = robocal.calibrate(str(csv_path), robot="abb-irb120")
    doc = result.to_dict()
    assert doc["dataset"]["source"] == str(csv_path)
    path = where / "result.json"
    path.write_text(json.dumps(doc))
    return path, doc, csv_path


def images(page: Path) -> list[Path]:
    """The figures a page references, each checked to be a non-empty PNG beside it."""
    names = re.findall(r'<img src="([^"]+)"', page.read_text())
    paths = [page.parent / n for n in names]
    for p in paths:
        assert p.is_file(), p
        assert p.stat().st_size > 1000 and p.read_bytes()[:8] == PNG, p
    return paths


def test_report_has_header_metrics_tables_and_all_figures(calibrated, tmp_path):
    path, doc, csv_path = calibrated
    page = report(path, tmp_path / "out")
    assert page == tmp_path / "out" / "index.html"
    text = page.read_text()
    assert "abb-irb120" in text and doc["method"] in text and doc["dataset"]["sha256"] in text
    for split in ("train", "test"):
        for key in ("rmse", "mae", "max"):
            assert f"{doc['metrics'][split][key]:.4f}" in text, (split, key)
    # Every fixed parameter with its reason; every parameter in the table.
    for name, why in doc["fixed"].items():
        assert f"<code>{name}</code>" in text and why.replace("'", "&#x27;") in text
    assert all(f"<code>{p['name']}</code>" in text for p in doc["parameters"])
    # Angles are shown in degrees: alpha1 of the IRB 120 is nominally -90 deg.
    assert "-90.0000" in text
    names = {p.name for p in images(page)}
    assert names == {"residuals_histogram.png", "residuals_samples.png", "parameters.png", "convergence.png", "identifiability.png", "acceptance.png"}
    # the acceptance figures of the held-out samples: one visit per target, so AP is the held-out error
    assert "<h2>Acceptance (ISO 9283)</h2>" in text and f"on the {doc['metrics']['test']['n']} held-out samples" in text
    assert f"RMS {doc['metrics']['test']['rmse']:.4f}  max {doc['metrics']['test']['max']:.4f} mm over {doc['metrics']['test']['n']} targets" in text
    # Self-contained: no scripts, no external resources.
    assert "<script" not in text and "http://" not in text and "https://" not in text


def test_evaluation_reproduces_the_recorded_metrics(calibrated):
    """The calibrated robot on the named file's training rows gives the recorded training RMSE,
    the held-out rows are the recorded ones, and the nominal model is worse."""
    path, doc, csv_path = calibrated
    robot, doc = load_result(path)
    d = report_page._load_data(doc, None)
    assert d.same_file and len(d.dataset) == 200
    ev = report_page._evaluate(robot, doc, d.dataset, d.same_file)
    assert ev.held_out.sum() == len(doc["dataset"]["rows_held_out"]) == doc["metrics"]["test"]["n"]
    train = ev.after[~ev.held_out]
    assert np.sqrt(np.mean(train**2)) == pytest.approx(doc["metrics"]["train"]["rmse"], rel=1e-6)
    assert np.sqrt(np.mean(ev.after[ev.held_out] ** 2)) == pytest.approx(doc["metrics"]["test"]["rmse"], rel=1e-6)
    assert np.sqrt(np.mean(ev.before**2)) > 5 * np.sqrt(np.mean(ev.after**2))
    # One singular value per estimated parameter, all positive: the free set is identifiable.
    assert ev.n_cols == len(doc["free"]) and ev.singular.shape == (len(doc["free"]),) and ev.singular.min() > 0


def test_cli_with_a_diagnosis(calibrated, tmp_path, capsys):
    path, doc, _ = calibrated
    diagnosis = {
        "robot": "abb-irb120",
        "measurement": "position",
        "samples": 200,
        "source": None,
        "baseline": {"rmse_heldout": 0.05, "rmse_heldout_blocked": 0.06, "n_params": 27, "folds": 5, "implausible": []},
        "effects": [
            {
                "kind": "outliers",
                "joint": None,
                "label": "outliers",
                "params": {"rows": [7, 9], "samples": [5, 7], "threshold_sigma": 5.0},
                "rmse_heldout_before": 0.09,
                "rmse_heldout_after": 0.05,
            },
            {
                "kind": "joint_periodic",
                "joint": 2,
                "label": "joint_periodic joint 2 <harmonic=1>",
                "params": {"amplitude": {"value": 0.01, "std": 0.001, "unit": "deg"}},
                "rmse_heldout_before": 0.05,
                "rmse_heldout_after": 0.03,
            },
        ],
        "rejected": [],
        "final": {"rmse_heldout": 0.03, "rmse_heldout_blocked": 0.035, "n_params": 29},
    }
    diag_path = tmp_path / "diag.json"
    diag_path.write_text(json.dumps(diagnosis))
    parser = argparse.ArgumentParser()
    report_cli.add_arguments(parser)
    args = parser.parse_args([str(path), "--out", str(tmp_path / "html"), "--diagnosis", str(diag_path)])
    assert report_cli.run(args) == 0
    page = tmp_path / "html" / "index.html"
    assert capsys.readouterr().out.strip() == f"wrote {page}"
    text = page.read_text()
    assert "diagnosis.png" in {p.name for p in images(page)}
    # Labels are escaped, the cause's parameters shown.
    assert "joint_periodic joint 2 &lt;harmonic=1&gt;" in text and "<harmonic=1>" not in text
    assert "amplitude 0.01 ± 0.001 deg" in text
    assert [s[0] for s in report_figures._diagnosis_steps(diagnosis)] == [
        "geometric, outliers kept",
        "geometric baseline (outliers removed)",
        "+ joint_periodic joint 2 <harmonic=1>",
    ]
    with pytest.raises(SystemExit):
        parser.parse_args([str(path)])  # --out is required


def test_missing_source_gives_a_page_without_the_data_figures(calibrated, tmp_path):
    path, doc, csv_path = calibrated
    moved = json.loads(path.read_text())
    moved["dataset"]["source"] = str(tmp_path / "gone.csv")
    moved_path = tmp_path / "moved.json"
    moved_path.write_text(json.dumps(moved))
    page = report(moved_path, tmp_path / "nodata")
    text = page.read_text()
    assert "is not on this machine" in text and "--data FILE" in text
    assert {p.name for p in images(page)} == {"parameters.png", "convergence.png"}
    assert f"{doc['metrics']['train']['rmse']:.4f}" in text
    # --data brings the data figures back; the same content is recognised by its sha256.
    page = report(moved_path, tmp_path / "withdata", data=csv_path)
    names = {p.name for p in images(page)}
    assert {"residuals_histogram.png", "identifiability.png"} <= names
    assert "sha256 matches" in page.read_text()
    # No source recorded at all: said so.
    moved["dataset"]["source"] = None
    page = report(moved, tmp_path / "nosource")
    assert "names no measurement file" in page.read_text()


def test_bad_result_files_raise(calibrated, tmp_path):
    path, doc, _ = calibrated
    corrupt = tmp_path / "corrupt.json"
    corrupt.write_text(path.read_text()[: len(path.read_text()) // 2])
    with pytest.raises(InvalidParameterError, match="not a robocal result file"):
        report(corrupt, tmp_path / "a")
    other = tmp_path / "other.json"
    other.write_text(json.dumps({**doc, "schema": "something/2"}))
    with pytest.raises(InvalidParameterError, match="schema"):
        report(other, tmp_path / "b")
    with pytest.raises(InvalidParameterError, match="cannot read"):
        report(tmp_path / "missing.json", tmp_path / "c")
    assert not (tmp_path / "a").exists()  # nothing written for a bad input
    bad_diag = tmp_path / "diag.json"
    bad_diag.write_text("{}")
    with pytest.raises(InvalidParameterError, match="diagnose"):
        report(path, tmp_path / "d", diagnosis=bad_diag)


def test_diagnosis_section_shows_structure_budget_and_sessions(calibrated, tmp_path):
    """A diagnosis that found a reading convention: the page names it with its alternatives, the
    error budget (final held-out RMSE beside the floor of the data's resolution) and, for several
    sessions, what each session keeps."""
    path, _, _ = calibrated
    data, _ = robocal.simulate("abb-irb120", "position", samples=300, seed=2)
    flipped = data.q.copy()
    flipped[:, 2] *= -1.0
    from dataclasses import replace

    diagnosis = robocal.diagnose(replace(data, q=flipped)).to_dict()
    assert diagnosis["effects"][0]["label"] == "joint_sign joint 3"
    text = report(path, tmp_path / "one", diagnosis=diagnosis).read_text()
    assert "<h3>Structure</h3>" in text and "joint_sign joint 3" in text
    assert "<h3>Error budget</h3>" in text and f"{diagnosis['final']['floor_mm']:.4f}" in text
    # two compliances: how well the data split them, beside their stiffness
    both = {"kind": "joint_compliance", "rmse_heldout_before": 0.5, "rmse_heldout_after": 0.4, "params": {}}
    diagnosis["effects"] += [
        {**both, "joint": 2, "label": "joint_compliance joint 2", "correlation": {"joint_compliance joint 3": -0.87}},
        {**both, "joint": 3, "label": "joint_compliance joint 3", "correlation": {"joint_compliance joint 2": "<b>"}},
    ]
    # one joint's harmonics, one claim: the others shown beside the first, with their sizes
    harmonic = {"kind": "joint_periodic", "joint": 4, "rmse_heldout_before": 0.4, "rmse_heldout_after": 0.3}
    third = {**harmonic, "label": "joint_periodic joint 4 harmonic=3", "params": {"amplitude": {"value": 0.00123, "std": 0.0001, "unit": "deg"}}}
    diagnosis["effects"].append({**harmonic, "label": "joint_periodic joint 4 harmonic=1", "params": {}, "with_harmonics": [third]})
    text = report(path, tmp_path / "corr", diagnosis=diagnosis).read_text()
    assert "correlation with joint_compliance joint 3 -0.87" in text and "<b>" not in text
    assert "beside its joint_periodic joint 4 harmonic=3 (amplitude 0.00123" in text
    sessions = robocal.diagnose([robocal.simulate("abb-irb120", "position", samples=200, seed=2, session=s)[0] for s in range(2)]).to_dict()
    text = report(path, tmp_path / "two", diagnosis=sessions).read_text()
    assert "<h3>Sessions</h3>" in text and "sessions it was not fitted on" in text


def test_an_extended_result_is_reported_with_its_causes(tmp_path):
    """The figures of an extended result (a UR10 with a gear error on joint 2, diagnosed and
    calibrated with its cause) come from the model verify applies: the report's "after" RMSE on
    the calibration's file is verify's on the same file (which re-fits only the set-up), and the
    metrics the report recomputes from it are the result file's."""
    data, _ = robocal.simulate("ur10", "position", samples=400, seed=3, effects=["joint_periodic:joint=2,amplitude=0.02,harmonic=2"])
    csv_path = write_canonical(data, tmp_path / "d.csv")
    diagnosis = robocal.diagnose(str(csv_path), robot="ur10").to_dict()
    assert diagnosis["model"]["causes"] == ["joint_periodic joint 2 harmonic=2"]
    doc = robocal.calibrate(str(csv_path), robot="ur10", causes=diagnosis).to_dict()
    result = tmp_path / "result.json"
    result.write_text(json.dumps(doc))
    text = report(result, tmp_path / "out", diagnosis=diagnosis).read_text()
    after = float(re.search(r"RMSE [0-9.]+ mm with the nominal kinematics \(measurement set-up refitted\) and ([0-9.]+) mm calibrated", text).group(1))
    verified = robocal.verify(str(result), str(csv_path))
    assert after == pytest.approx(verified["metrics"]["rmse"], rel=2e-3)
    assert "they match the result file" in text and "not in the result file" not in text
    # the geometry alone is far off: the figures are not its
    geometric = np.sqrt(np.mean(np.sum(load_result(doc)[0].residuals("position", data.q, data.y) ** 2, axis=1)))
    assert geometric > 2 * after


def test_every_figure_keeps_its_text_inside(calibrated, tmp_path, monkeypatch):
    """Titles, labels and annotations of every figure lie within its canvas, long cause labels
    included (the diagnosis chart's title ran off its right edge)."""
    path, _, _ = calibrated
    save, outside = report_figures._save, []

    def checked(fig, where):
        fig.canvas.draw()
        drawn = fig.get_tightbbox(fig.canvas.get_renderer())  # inches, of everything drawn
        width, height = fig.get_size_inches()
        if drawn.x0 < -0.01 or drawn.y0 < -0.01 or drawn.x1 > width + 0.01 or drawn.y1 > height + 0.01:
            outside.append((where.name, drawn.bounds))
        return save(fig, where)

    monkeypatch.setattr(report_figures, "_save", checked)
    long = "joint_map joint 3 spacing=5 roughness=0.01 beside joint_coupling joint 3 source=2"
    diagnosis = _diagnosis({"kind": "joint_map", "joint": 3, "label": long, "params": {}, "rmse_heldout_before": 0.05, "rmse_heldout_after": 0.03})
    report(path, tmp_path / "out", diagnosis=diagnosis)
    assert outside == []


def test_the_shapes_a_joint_error_could_not_be_told_from_are_words_and_hand_edits_are_left_out():
    """A cause's ``undetermined_between`` is shown beside it, on the command line and the page;
    what a hand-edited file puts there other than a list of labels is not echoed."""
    from robocal.report.text import alike_words

    assert alike_words({"undetermined_between": ["joint_scale joint 6", "joint_periodic joint 6 harmonic=2"]}) == (
        "; the data cannot tell it from joint_scale joint 6, joint_periodic joint 6 harmonic=2"
    )
    for edited in (None, {}, {"undetermined_between": []}, {"undetermined_between": "joint_scale"}, {"undetermined_between": [1, 2]}, "x"):
        assert alike_words(edited) == ""


def test_a_conventions_alternatives_are_shown_once_on_the_page(calibrated, tmp_path):
    """The alternatives the data cannot tell from a reading convention stand in the structure
    section's column, not a second time beside it in the table of effects; a joint shape's stand
    beside it (it has no other place)."""
    path, _, _ = calibrated
    convention = {"kind": "joint_zero", "joint": 2, "label": "joint_zero joint 2 offset=90", "params": {}, "rmse_heldout_before": 0.05}
    scale = {"kind": "joint_scale", "joint": 6, "label": "joint_scale joint 6", "params": {}, "rmse_heldout_before": 0.04}
    diagnosis = _diagnosis(
        {**convention, "rmse_heldout_after": 0.04, "significance": {"undetermined_between": ["joint_zero joint 2 offset=270 and joint_sign joint 2"]}},
        {**scale, "rmse_heldout_after": 0.03, "significance": {"undetermined_between": ["joint_periodic joint 6 harmonic=1"]}},
    )
    page = report(path, tmp_path / "out", diagnosis=diagnosis).read_text()
    assert page.count("joint_zero joint 2 offset=270 and joint_sign joint 2") == 1
    assert page.count("joint_periodic joint 6 harmonic=1") == 1


def _diagnosis(*effects) -> dict:
    """A diagnosis report of a simulated IRB 120 position file naming ``effects``."""
    return {
        "robot": "abb-irb120",
        "measurement": "position",
        "samples": 200,
        "source": None,
        "baseline": {"rmse_heldout": 0.05, "folds": 5},
        "rejected": [],
        "final": {"rmse_heldout": 0.03},
        "effects": list(effects),
    }


def test_a_result_the_monitor_updated_is_not_called_corrupt(calibrated, tmp_path):
    """``robocal monitor --out`` applies what changed to the values: on the data calibrated on they
    no longer reproduce the calibration's metrics, and the report says why, lists the changes and
    draws no figure of the old data under the new values."""
    from robocal.monitoring import Monitor

    path, doc, _ = calibrated
    stream, _ = robocal.simulate("abb-irb120", "position", samples=700, seed=1)
    q = stream.q.copy()
    q[400:, 1] -= np.radians(0.2)  # joint 2's zero moves at sample 400
    monitor = Monitor(str(path))
    monitor.update(q, stream.y)
    assert [a.kind for a in monitor.alarms] == ["joint_zero"]
    page = report(monitor.result_document(), tmp_path / "page").read_text()
    assert "edited or is corrupt" not in page
    assert "<h2>Monitoring</h2>" in page and "joint_zero of joint 2" in page and "robocal monitor has applied changes" in page
    assert "figures that need the data are left out" in page
