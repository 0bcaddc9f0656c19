"""The diagnose report as a typed document (``robocal.load_diagnosis``): a report written by
``robocal diagnose --json`` reads back into the same model ``calibrate --causes`` fits, and a
malformed one is refused naming the file and the key — by the API, by ``calibrate --causes`` and
by ``report --diagnosis``, on the command line in one line without a traceback."""

from __future__ import annotations

import copy
import json

import numpy as np
import pytest

import robocal
from robocal.cli import main
from robocal.data import write_canonical
from robocal.diagnosis_file import DiagnosisReport, Quantity
from robocal.exceptions import InvalidParameterError
from robocal.report import report as html_report

EFFECT = "joint_periodic:joint=3,amplitude=0.02,harmonic=2"


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """A small simulated file, its report from the command line (JSON) and from the API (dict), and a result."""
    w = tmp_path_factory.mktemp("diagnosis")
    data, _ = robocal.simulate("abb-irb120", "position", samples=200, seed=3, effects=[EFFECT])
    csv = write_canonical(data, w / "d.csv")
    assert main(["diagnose", str(csv), "--robot", "abb-irb120", "--json", str(w / "report.json"), "--quiet"]) == 0
    assert main(["calibrate", str(csv), "--robot", "abb-irb120", "--out", str(w / "result.json"), "--quiet"]) == 0
    return w, csv, robocal.diagnose(str(csv), robot="abb-irb120").to_dict()


def test_a_report_reads_back_typed_and_fits_the_same_model(written):
    w, csv, doc = written
    path = w / "report.json"
    text = path.read_text()
    timeless = lambda d: {k: v for k, v in d.items() if k != "time_s"}  # noqa: E731
    assert timeless(json.loads(text)) == timeless(json.loads(json.dumps(doc)))  # the JSON is what to_dict() holds, written as before
    report = robocal.load_diagnosis(path)
    assert isinstance(report, DiagnosisReport) and report.model_dump(exclude={"time_s"}) == robocal.load_diagnosis(doc).model_dump(exclude={"time_s"})
    assert report.model.causes == doc["model"]["causes"] == ["joint_periodic joint 3 harmonic=2"]
    assert report.structure == [] and report.model.kinematic_prior is None and not report.several
    assert report.baseline.rmse_heldout == doc["baseline"]["rmse_heldout"] and report.final.rmse_heldout < report.baseline.rmse_heldout
    (effect,) = report.effects
    assert (effect.kind, effect.joint, effect.label) == ("joint_periodic", 3, "joint_periodic joint 3 harmonic=2")
    assert isinstance(effect.params["amplitude"], Quantity) and effect.params["amplitude"].unit == "deg"
    assert effect.rmse_after == doc["effects"][0]["rmse_heldout_after"] and len(report.rejected) == len(doc["rejected"])
    # calibrate --causes: the file, the dict and the typed report give one fit
    fits = [robocal.calibrate(str(csv), robot="abb-irb120", causes=c).to_dict() for c in (doc, path, report)]
    assert main(["calibrate", str(csv), "--robot", "abb-irb120", "--causes", str(path), "--out", str(w / "extended.json"), "--quiet"]) == 0
    fits.append(json.loads((w / "extended.json").read_text()))
    values = [[p["value"] for p in fit["parameters"]] + [v["value"] for c in fit["causes"] for v in c["params"].values()] for fit in fits]
    for other in values[1:]:
        np.testing.assert_array_equal(other, values[0])
    assert [c["label"] for c in fits[0]["causes"]] == report.model.causes


def test_reports_of_earlier_versions_and_extra_keys_read(written):
    """Keys added since (model.structure, model.kinematic_prior) default; keys no reader needs are kept."""
    _, _, doc = written
    old = copy.deepcopy(doc)
    del old["model"]["structure"], old["model"]["kinematic_prior"], old["final"]["residuals"]
    old["effects"][0]["something_new"] = {"a": [1, 2]}
    report = robocal.load_diagnosis(old)
    assert report.structure == [] and report.model.kinematic_prior is None and report.final.residuals is None
    assert report.effects[0].model_extra == {"something_new": {"a": [1, 2]}}


def _bad(doc: dict, edit) -> dict:
    doc = copy.deepcopy(doc)
    edit(doc)
    return doc


BAD = [
    (lambda d: d["effects"][0].pop("kind"), "effect 1 lacks kind"),
    (lambda d: d["effects"][0].update(joint="3"), "effect 1, key 'joint': input should be a valid integer; got '3'"),
    (lambda d: d["model"].update(causes="joint_periodic joint 3 harmonic=2"), "key 'model', key 'causes': input should be a valid list"),
    (lambda d: d["model"].update(kinematic_prior=[1.0]), "key 'model', key 'kinematic_prior'"),
    (lambda d: d["effects"][0]["params"]["amplitude"].update(value="big"), "effect 1, key 'params': parameter 'amplitude', key 'value'"),
]


@pytest.mark.parametrize("edit,words", BAD)
def test_a_malformed_report_is_refused_naming_the_file_and_the_key(written, edit, words):
    w, csv, doc = written
    path = w / "bad.json"
    path.write_text(json.dumps(_bad(doc, edit)))
    with pytest.raises(InvalidParameterError) as raised:
        robocal.load_diagnosis(path)
    assert str(raised.value).startswith(f"diagnose report {path}: ") and words in str(raised.value)
    with pytest.raises(InvalidParameterError, match="^diagnose report: "):  # a dict: named as a report
        robocal.load_diagnosis(_bad(doc, edit))
    for call in (
        lambda: robocal.calibrate(str(csv), robot="abb-irb120", causes=path),
        lambda: html_report(w / "result.json", w / "page", diagnosis=path),
    ):
        with pytest.raises(InvalidParameterError) as raised:
            call()
        assert str(path) in str(raised.value) and words in str(raised.value)
    assert not (w / "page").exists()


def test_each_reader_says_what_it_needs(written):
    """No key is required of every report: calibrate --causes (and plan) need the model, the page
    the held-out figures; each names the file and the key it lacks."""
    w, csv, doc = written
    path = w / "no_model.json"
    path.write_text(json.dumps(_bad(doc, lambda d: d.pop("model"))))
    assert robocal.load_diagnosis(path).model is None
    html_report(w / "result.json", w / "page_without_model", diagnosis=path)  # the page needs no model
    with pytest.raises(InvalidParameterError, match=f"diagnose report {path} lacks key 'model'"):
        robocal.calibrate(str(csv), robot="abb-irb120", causes=path)
    for edit, key in [
        (lambda d: d["baseline"].pop("rmse_heldout"), "key 'baseline', key 'rmse_heldout'"),
        (lambda d: d.pop("effects"), "key 'effects'"),
        (lambda d: d["effects"][0].pop("rmse_heldout_after"), "effect 1, key 'rmse_heldout_after'"),
    ]:
        path.write_text(json.dumps(_bad(doc, edit)))
        robocal.calibrate(str(csv), robot="abb-irb120", causes=path)  # the model is all a fit needs
        with pytest.raises(InvalidParameterError, match=f"diagnose report {path} lacks {key}: report --diagnosis takes the held-out figures"):
            html_report(w / "result.json", w / "page", diagnosis=path)
    assert not (w / "page").exists()


@pytest.mark.parametrize(
    "text,words",
    [("{not json", "not a diagnose report (invalid JSON"), ("[1, 2]", "the top level: input should be a valid dictionary"), ('{"a": 1, "a": 2}', "'a'")],
)
def test_the_command_line_refuses_a_bad_report_in_one_line(written, capsys, text, words):
    w, csv, doc = written
    path = w / "broken.json"
    path.write_text(text)
    for argv in (
        ["calibrate", str(csv), "--robot", "abb-irb120", "--causes", str(path)],
        ["report", str(w / "result.json"), "--diagnosis", str(path), "--out", str(w / "p")],
    ):
        assert main(argv) == 2
        out, err = capsys.readouterr()
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("robocal: error: ") and str(path) in lines[0] and words in lines[0], err
        assert "Traceback" not in err and out == ""
    path.write_text(json.dumps(_bad(doc, BAD[0][0])))
    assert main(["calibrate", str(csv), "--robot", "abb-irb120", "--causes", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err == f"robocal: error: diagnose report {path}: effect 1 lacks kind"


def test_a_report_of_another_robot_is_refused_by_every_reader(written, tmp_path, capsys):
    """Issue 52 #6: an abb-irb120 report was fitted to ur10 data, planned for and shown beside a ur10 result (a result of another robot was refused)."""
    w = written[0]
    data, _ = robocal.simulate("ur10", "position", samples=60, seed=2)
    csv = write_canonical(data, tmp_path / "p.csv")
    assert main(["calibrate", str(csv), "--robot", "ur10", "--out", str(tmp_path / "rp.json"), "--quiet"]) == 0
    report = w / "report.json"
    for argv in (
        ["calibrate", str(csv), "--robot", "ur10", "--causes", str(report), "--out", str(tmp_path / "x.json")],
        ["plan", "--robot", "ur10", "--from", str(report), "--poses", "10", "--candidates", "100", "--out", str(tmp_path / "x.csv")],
        ["plan", "--robot", "ur10", "--from", str(report), "--data", str(csv), "--poses", "10", "--candidates", "100", "--out", str(tmp_path / "x.csv")],
        ["report", str(tmp_path / "rp.json"), "--diagnosis", str(report), "--out", str(tmp_path / "page")],
    ):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert err == f"robocal: error: diagnose report {report} is a diagnosis of robot 'abb-irb120', not of 'ur10': pass a diagnose report of 'ur10'"
    assert sorted(f.name for f in tmp_path.iterdir()) == ["p.csv", "rp.json"]
    with pytest.raises(InvalidParameterError, match="is a diagnosis of robot 'abb-irb120', not of 'ur10'"):
        robocal.calibrate(str(csv), robot="ur10", causes=written[2])


def test_a_multi_session_report_reads_typed(tmp_path):
    """Several sessions: the leave-one-session-out figures, each session's own report and own terms."""
    sessions = [robocal.simulate("abb-irb120", "position", samples=150, seed=2, session=s)[0] for s in range(2)]
    doc = robocal.diagnose(sessions).to_dict()
    report = robocal.load_diagnosis(doc)
    assert report.several and report.held_key == "rmse_loso" and report.baseline.rmse_loso == doc["baseline"]["rmse_loso"]
    assert [s.diagnosis.baseline.rmse_heldout for s in report.sessions] == [s["diagnosis"]["baseline"]["rmse_heldout"] for s in doc["sessions"]]
    assert [s.causes for s in report.model.sessions] == [s["causes"] for s in doc["model"]["sessions"]]
    three = [*sessions, robocal.simulate("abb-irb120", "position", samples=150, seed=2, session=2)[0]]
    with pytest.raises(InvalidParameterError, match="key 'model', key 'sessions' lists 2 sessions; .* 3 sessions"):
        robocal.calibrate(three, causes=doc)
    bad = _bad(doc, lambda d: d["sessions"][1]["diagnosis"]["effects"].append({"label": "x"}))
    with pytest.raises(InvalidParameterError, match=r"session 2, key 'diagnosis', effect \d+ lacks kind"):
        robocal.load_diagnosis(bad)
