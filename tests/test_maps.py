"""Joint error maps: a fine transmission error hidden in simulated data is found as a curve, clean
data get none, and the map carries through ``calibrate --causes``, ``verify`` and ``compensate``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy import sparse

import robocal
from robocal.cli import main
from robocal.data import write_canonical
from robocal.results import save_result
import robocal.exceptions
from robocal import _robocal
from robocal.kernels import factor_damped, fold_products, sparse_gram, stack_csr
from robocal.causes.candidates import MAP_REACH_SPACINGS, map_basis, map_coverage, map_curve, map_support
from robocal.diagnosis.validation import fold_causes
from robocal.physics import DEG
from robocal.diagnosis_file import Effect
from robocal.report.figures import map_figure
from robocal.simulation import simulate

#: A transmission error of joint 2 at 9 and 14 cycles per revolution: far beyond the harmonics
#: 1-3 of the named causes, as a harmonic drive's is.
GEAR = ["joint_periodic:joint=2,amplitude=0.01,harmonic=9", "joint_periodic:joint=2,amplitude=0.006,harmonic=14,phase=40"]


def true_error_deg(q2: np.ndarray) -> np.ndarray:
    return 0.01 * np.sin(9 * q2) + 0.006 * np.sin(14 * q2 + 40 * DEG)


@pytest.fixture(scope="module")
def geared():
    data, _ = simulate("ur10", "position", samples=800, seed=5, effects=GEAR)
    return data, robocal.diagnose(data)


def test_a_hidden_transmission_error_is_found_as_a_curve_within_its_band(geared):
    data, diagnosis = geared
    report = diagnosis.to_dict()
    maps = [e for e in report["effects"] if e["kind"] == "joint_map"]
    assert [e["joint"] for e in maps] == [2], [e["label"] for e in report["effects"]]
    assert report["final"]["rmse_heldout"] < 0.5 * report["baseline"]["rmse_heldout"]
    assert report["final"]["rmse_heldout_blocked"] < 0.5 * report["baseline"]["rmse_heldout_blocked"]
    curve = maps[0]["curve"]
    angle, value, std = (np.asarray(curve[k]) for k in ("angle_deg", "value_deg", "std_deg"))
    # The map's constant belongs to theta2: compare shapes, the offset removed.
    diff = value - true_error_deg(angle * DEG)
    diff -= np.mean(diff)
    assert np.sqrt(np.mean(diff**2)) < 0.2 * np.sqrt(np.mean(true_error_deg(angle * DEG) ** 2))
    assert np.mean(np.abs(diff) < 3.0 * std + 1e-4) > 0.9
    assert np.all(std > 0)


@pytest.mark.parametrize("robot, measurement, seed", [("ur10", "position", 11), ("abb-irb120", "cable", 12), ("hsr-jr680", "position", 13)])
def test_clean_data_get_no_map(robot, measurement, seed):
    data, _ = simulate(robot, measurement, samples=400, seed=seed)
    report = robocal.diagnose(data).to_dict()
    assert not [e for e in report["effects"] if e["kind"] == "joint_map"]


def test_maps_can_be_left_out(geared):
    data, _ = geared
    report = robocal.diagnose(data, maps=False).to_dict()
    assert not [e for e in report["effects"] + report["rejected"] if e["kind"] == "joint_map"]


def test_calibrate_verify_and_compensate_apply_the_map(geared, tmp_path):
    data, diagnosis = geared
    report = diagnosis.to_dict()
    label = next(e["label"] for e in report["effects"] if e["kind"] == "joint_map")
    geometric = robocal.calibrate(data)
    extended = robocal.calibrate(data, causes=report)
    assert label in [c["label"] for c in extended.to_dict()["causes"]]
    assert extended.metrics["test"]["rmse"] < 0.6 * geometric.metrics["test"]["rmse"]
    # another session of the same robot: the tracker elsewhere, a new path
    second, _ = simulate("ur10", "position", samples=800, seed=5, session=1, effects=GEAR)
    carried = robocal.verify(extended.to_dict(), second)
    plain = robocal.verify(geometric.to_dict(), second)
    assert label in carried["applied"]["causes"]
    assert carried["metrics"]["rmse"] < 0.6 * plain["metrics"]["rmse"]
    assert [c["label"] for c in carried["coverage"]] == [label]
    # compensation: the targets the calibrated model reaches, with the map in the joint angles
    targets = extended.robot.predict("position", data.q[:5])
    rows = robocal.compensate(extended.to_dict(), targets, frame="session")
    assert all(r["status"].startswith("ok") for r in rows)


def test_coverage_names_samples_beyond_the_fitted_range(geared, tmp_path, capsys):
    data, _ = geared
    narrow = data.subset(np.flatnonzero(np.abs(data.q[:, 1] - np.median(data.q[:, 1])) < 40 * DEG))
    fit = robocal.calibrate(narrow, causes=["joint_map joint 2 spacing=5.0 roughness=0.01"], test_fraction=0.0)
    result = fit.to_dict()
    (cause,) = [c for c in result["causes"] if c["kind"] == "joint_map"]
    second, _ = simulate("ur10", "position", samples=800, seed=5, session=1, effects=GEAR)
    inside = map_coverage(second.q[:, 1], cause["detail"])
    report = robocal.verify(result, second)
    (coverage,) = report["coverage"]
    assert coverage["outside"] == int(np.count_nonzero(~inside)) > 0
    assert coverage["rows"] == [int(r) for r in second.rows[~inside][:20]]
    # the metrics where the map applies are those of the covered samples alone
    covered = report["metrics_covered"]
    assert covered["n"] == int(np.count_nonzero(inside)) < report["metrics"]["n"]
    assert covered["rmse"] < report["metrics"]["rmse"]  # the map corrects the gear error there
    assert report["nominal"]["metrics_covered"]["n"] == covered["n"]
    # compensating a target beyond the range says so
    q = second.q[~inside][:1]
    (row,) = robocal.compensate(result, fit.robot.predict("position", q), frame="session")
    assert "beyond its map's data: joint 2 beyond" in row["status"]
    # and so does the command line
    save_result(result, tmp_path / "result.json")
    write_canonical(second, tmp_path / "second.csv")
    assert main(["verify", str(tmp_path / "result.json"), str(tmp_path / "second.csv")]) == 0
    out = capsys.readouterr().out
    assert f"beyond its map's data: {coverage['outside']} samples have joint 2 beyond" in out
    assert f"within the maps' ranges ({covered['n']} of {report['metrics']['n']} samples)" in out


@given(st.floats(-170, 0), st.floats(20, 300), st.sampled_from([2.0, 5.0, 15.0]))
@settings(max_examples=40, deadline=None)
def test_map_basis_has_no_constant_and_fades_beyond_its_range(lo, width, spacing):
    detail = {"lo": lo, "hi": lo + width, "spacing": spacing}
    q = np.radians(np.linspace(lo - 30, lo + width + 30, 301))
    B = map_basis(q, detail).toarray()
    # neither a constant nor a linear function of the angle is a map (they are theta's and
    # joint_scale's): no map fits a line over its range
    c = np.random.default_rng(0).normal(size=B.shape[1])
    inside_q = np.radians(np.linspace(lo, lo + width, 400))
    line = 1.0 + 0.3 * inside_q
    Bd = map_basis(inside_q, detail).toarray()
    assert np.std(line - Bd @ np.linalg.lstsq(Bd, line, rcond=None)[0]) > 1e-3 * np.std(line)
    inside = map_coverage(q, detail)
    assert np.all(inside == ((q >= np.radians(lo) - 1e-9) & (q <= np.radians(lo + width) + 1e-9)))
    # beyond the fitted range: the row of its nearer end, fading over MAP_REACH_SPACINGS spacings
    end = np.clip(q, np.radians(lo), np.radians(lo + width))
    fade = np.exp(-np.abs(q - end) / np.radians(MAP_REACH_SPACINGS * spacing))
    assert np.allclose(B[~inside], fade[~inside, None] * map_basis(end[~inside], detail).toarray())
    assert np.all(np.abs(B[inside]).sum(axis=1) > 0)
    curve = map_curve(detail, c)
    assert curve["angle_deg"][0] == lo and np.isclose(curve["angle_deg"][-1], lo + width)


@given(st.floats(-170, -60), st.floats(10, 60), st.floats(2.1, 6.0), st.sampled_from([2.0, 5.0]))
@settings(max_examples=40, deadline=None)
def test_a_map_covers_only_where_its_data_are(lo, band, gap_spacings, spacing):
    """Two bands of joint angles with a stretch of ``gap_spacings`` knot spacings between them:
    more than MAP_GAP_SPACINGS is a gap, where the map's correction fades from the nearer edge's;
    a narrower one is not a gap."""
    gap = gap_spacings * spacing
    angles = np.radians(np.concatenate([np.linspace(lo, lo + band, 200), np.linspace(lo + band + gap, lo + 2 * band + gap, 200)]))
    detail = {"spacing": spacing, **map_support(angles, spacing)}
    (a, b), middle = detail["gaps"][0], np.radians(lo + band + gap / 2)
    assert len(detail["gaps"]) == 1 and lo + band <= a < b <= lo + band + gap
    assert not map_coverage(np.array([middle]), detail)[0]
    nearer = np.radians(a if middle - np.radians(a) <= np.radians(b) - middle else b)
    fade = np.exp(-abs(middle - nearer) / np.radians(MAP_REACH_SPACINGS * spacing))
    assert np.allclose(map_basis(np.array([middle]), detail).toarray(), fade * map_basis(np.array([nearer]), detail).toarray())
    assert np.all(map_coverage(angles, detail))  # every angle it was fitted on
    curve = map_curve(detail, np.ones(map_basis(angles, detail).shape[1]))
    assert not np.any((curve["angle_deg"] > a) & (curve["angle_deg"] < b))  # the table leaves the gap out
    narrow = {"spacing": gap, **map_support(angles, gap)}  # the same stretch is one spacing of wider knots
    assert narrow["gaps"] == [] and map_coverage(np.array([middle]), narrow)[0]


def test_a_maps_correction_fades_beyond_its_data():
    """Beyond its range a map carries the correction of its end, fading as exp(-d / reach) with
    the distance d (reach: MAP_REACH_SPACINGS knot spacings): next to its data it still corrects,
    far from them it leaves the joint to the geometry's offset."""
    detail = {"lo": -60.0, "hi": 20.0, "spacing": 2.0}
    c = np.random.default_rng(1).normal(size=map_basis(np.zeros(1), detail).shape[1])
    reach = MAP_REACH_SPACINGS * detail["spacing"]

    def at(deg):
        return float((map_basis(np.radians([deg]), detail) @ c)[0])

    assert abs(at(20.0)) > 0 and abs(at(-60.0)) > 0
    assert np.isclose(at(20.0 + reach), np.exp(-1.0) * at(20.0))
    assert np.isclose(at(-60.0 - 2.0 * reach), np.exp(-2.0) * at(-60.0))
    assert abs(at(20.0 + 12.0 * reach)) < 1e-5 * abs(at(20.0))


def test_a_folds_map_corrects_only_the_angles_it_was_fitted_on(geared):
    """Cross-validation credits a fold's map nothing beyond the joint angles of the fold's
    training samples (a new session gets its fading edge value: the folds do not count on it)."""
    data, diagnosis = geared
    model = diagnosis.model
    q2 = data.q[model.idx, 1]
    train = np.flatnonzero(q2 < np.median(q2))
    (fold_map,) = [c for c in fold_causes(model, train) if c.kind == "joint_map"]
    (full_map,) = [c for c in model.causes if c.kind == "joint_map"]
    beyond = model.idx[q2 > q2[train].max()]
    assert beyond.size and np.all(fold_map.basis.toarray()[beyond] == 0.0)
    assert np.allclose(fold_map.basis.toarray()[model.idx[train]], full_map.basis.toarray()[model.idx[train]])


def test_verify_names_the_samples_in_a_gap_of_the_maps_data(geared, tmp_path, capsys):
    data, _ = geared
    q2 = data.q[:, 1]
    hole = (q2 > np.percentile(q2, 40)) & (q2 < np.percentile(q2, 60))
    fit = robocal.calibrate(data.subset(np.flatnonzero(~hole)), causes=["joint_map joint 2 spacing=2.0 roughness=0.01"], test_fraction=0.0)
    result = fit.to_dict()
    (cause,) = [c for c in result["causes"] if c["kind"] == "joint_map"]
    assert len(cause["detail"]["gaps"]) == 1
    (coverage,) = robocal.verify(result, data)["coverage"]
    assert coverage["outside"] == int(np.count_nonzero(hole)) and coverage["gaps_deg"] == cause["detail"]["gaps"]
    save_result(result, tmp_path / "result.json")
    write_canonical(data, tmp_path / "data.csv")
    assert main(["verify", str(tmp_path / "result.json"), str(tmp_path / "data.csv")]) == 0
    assert f"{coverage['outside']} samples have joint 2 beyond the range" in (out := capsys.readouterr().out) and "or in the gaps" in out
    # the map's plot breaks its line at the gap
    curve = map_curve(cause["detail"], np.asarray(cause["coefficients"]))
    curve = {k: [float(v) for v in values] for k, values in curve.items()}  # as the report holds it
    effect = Effect(kind="joint_map", joint=2, label=cause["label"], curve=curve, rmse_heldout_after=0.0)
    assert map_figure(effect, tmp_path / "map.png").stat().st_size > 0


@given(st.integers(0, 2**31 - 1), st.floats(1e-8, 1e2))
@settings(max_examples=30, deadline=None)
def test_the_sparse_damped_solve_matches_the_dense_qr(seed, lam):
    """The LM's damped steps of a sparse Jacobian (a model with joint maps), from its normal
    equations, are the dense QR's, with the same norm of the explained part."""
    from robocal.calibration.lm import _factor

    rng = np.random.default_rng(seed)
    J = rng.normal(size=(60, 8)) * rng.uniform(0.1, 10, size=8)
    b = rng.normal(size=60)
    gram = sparse_gram(sparse.csr_array(J))
    d = np.sqrt(np.diag(gram))
    dense, normal = factor_damped(J / d), _factor(sparse.csr_array(J), d, gram)
    assert np.isclose(np.linalg.norm(normal.project(b)), np.linalg.norm(dense.project(b)), rtol=1e-8)
    expected = np.linalg.solve((J / d).T @ (J / d) + lam * np.eye(8), (J / d).T @ b)
    assert np.allclose(normal.solve(normal.project(b), lam), expected, rtol=1e-7, atol=1e-10)
    assert np.allclose(dense.solve(dense.project(b), lam), expected, rtol=1e-7, atol=1e-10)


def test_a_map_found_in_sessions_carries_across_them():
    """Two sessions of one geared robot: the map fitted on one session lowers the other's
    held-out error (leave-one-session-out), one map per joint, with its curve."""
    first, _ = simulate("ur10", "position", samples=600, seed=5, effects=GEAR)
    second, _ = simulate("ur10", "position", samples=600, seed=5, session=1, effects=GEAR)
    report = robocal.diagnose([first, second]).to_dict()
    maps = [e for e in report["effects"] if e["kind"] == "joint_map"]
    assert [e["joint"] for e in maps] == [2], [e["label"] for e in report["effects"]]
    assert all(a < 0.8 * b for a, b in zip(report["final"]["per_session"], report["baseline"]["per_session"]))
    assert len(maps[0]["curve"]["std_deg"]) == len(maps[0]["curve"]["angle_deg"])
    # once a map of joint 2 is carried, no other map of joint 2 is tried
    tried = [r["label"] for r in report["rejected"] if r["kind"] == "joint_map" and r["joint"] == 2]
    assert not tried, tried
    # per session, the error where the map fitted on the other session applies
    covered = report["final"]["per_session_covered"]
    assert len(covered) == 2 and all(0 < c["samples"] <= 600 and c["rmse"] > 0 for c in covered)


@given(st.integers(0, 2**31 - 1), st.integers(1, 40), st.integers(1, 15), st.floats(0.05, 0.9))
@settings(max_examples=40, deadline=None)
def test_the_rust_gram_of_a_sparse_jacobian_is_the_dense_product(seed, m, n, density):
    J = sparse.random_array((m, n), density=density, format="csr", random_state=np.random.default_rng(seed))
    assert np.allclose(sparse_gram(J), J.toarray().T @ J.toarray(), rtol=1e-12, atol=1e-14)
    # scipy stores small matrices' indices as int32, large ones' as int64: both are read
    J64 = sparse.csr_array((J.data, J.indices.astype(np.int64), J.indptr.astype(np.int64)), shape=J.shape)
    assert np.array_equal(sparse_gram(J64), sparse_gram(J))


@given(st.integers(0, 2**31 - 1), st.integers(1, 40), st.integers(1, 6), st.integers(1, 9), st.integers(1, 4))
@settings(max_examples=40, deadline=None)
def test_the_rust_fold_products_are_the_dense_products_of_each_folds_rows(seed, m, nc, p, folds):
    """A screening's per-fold blocks (the Rust core, one pass over the rows) are NumPy's products
    of each fold's rows, for every labelling."""
    rng = np.random.default_rng(seed)
    C = sparse.random_array((m, nc), density=0.4, format="csr", random_state=rng)
    J = sparse.random_array((m, p), density=0.6, format="csr", random_state=rng)
    r = rng.normal(size=m)
    labels = [rng.integers(0, folds, size=m), np.arange(m) % 2]
    Cd, Jd = C.toarray(), J.toarray()
    for (CtJ, Ctr, CtC), label, count in zip(fold_products(C, J, r, labels, [folds, 2]), labels, [folds, 2]):
        assert CtJ.shape == (count, nc, p) and Ctr.shape == (count, nc) and CtC.shape == (count, nc, nc)
        for f in range(count):
            rows = label == f
            assert np.allclose(CtJ[f], Cd[rows].T @ Jd[rows], rtol=1e-12, atol=1e-14)
            assert np.allclose(Ctr[f], Cd[rows].T @ r[rows], rtol=1e-12, atol=1e-14)
            assert np.allclose(CtC[f], Cd[rows].T @ Cd[rows], rtol=1e-12, atol=1e-14)


@given(st.integers(0, 2**31 - 1), st.integers(1, 30), st.integers(1, 5), st.integers(0, 3), st.integers(0, 4))
@settings(max_examples=40, deadline=None)
def test_the_rust_stacked_jacobian_is_scipys_stack_of_its_blocks(seed, m, nd, n_thin, n_extra):
    """A sparse Jacobian laid out by the Rust core from its blocks (dense columns first in every
    row, then each thin block's entries, weighted rows, then the extra rows) is scipy's stack."""
    rng = np.random.default_rng(seed)
    dense = rng.normal(size=(m, nd))
    thin = [sparse.random_array((m, 4), density=0.5, format="csr", random_state=rng) for _ in range(n_thin)]
    n = nd + 4 * n_thin
    extra = sparse.random_array((n_extra, n), density=0.5, format="csr", random_state=rng)
    w = rng.uniform(0.5, 2.0, size=m)
    indptr, indices, data = stack_csr(dense, np.arange(nd), [(b, nd + 4 * t) for t, b in enumerate(thin)], w, extra)
    got = sparse.csr_array((data, indices, indptr), shape=(m + n_extra, n)).toarray()
    expected = np.vstack([np.hstack([dense] + [b.toarray() for b in thin]) * w[:, None], extra.toarray()])
    assert np.array_equal(got, expected)
    assert stack_csr(dense, np.arange(nd), [(b, nd + 4 * t) for t, b in enumerate(thin)], w, extra, pattern=False)[:2] == (None, None)


def test_the_rust_stacked_jacobian_refuses_a_block_of_another_row_count():
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="a block has 2 rows; the dense block 3"):
        stack_csr(np.ones((3, 2)), np.arange(2), [(sparse.csr_array(np.ones((2, 1))), 2)], np.ones(3), sparse.csr_array((0, 3)))
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="column index 4 is not below the column count 3"):
        stack_csr(np.ones((3, 2)), np.array([0, 4]), [], np.ones(3), sparse.csr_array((0, 3)))


def test_the_rust_fold_products_refuse_a_label_beyond_the_folds():
    C = sparse.csr_array(np.eye(3))
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="row 2 fold 5 of 2"):
        fold_products(C, C, np.ones(3), [np.array([0, 1, 5])], [2])
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="C has 3 rows but J has 2"):
        fold_products(C, C[:2], np.ones(3), [np.zeros(3)], [1])


def test_the_rust_gram_refuses_malformed_input():
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="column index 5"):
        _robocal.sparse_gram(np.array([0, 1]), np.array([5]), np.array([1.0]), 3)
    with pytest.raises(robocal.exceptions.RobocalError, match="J"):
        _robocal.sparse_gram(np.array([0, 1]), np.array([0]), np.array([np.nan]), 3)
    with pytest.raises(robocal.exceptions.InvalidParameterError, match="int32 or int64"):
        _robocal.sparse_gram(np.array([0.0, 1.0]), np.array([0]), np.array([1.0]), 3)


def test_a_result_cause_needs_a_list_of_coefficients():
    """A result file whose joint cause holds a bare number is refused by name (it once reached
    the matrix product of the compensation)."""
    from robocal.causes.candidates import joint_offsets

    with pytest.raises(robocal.exceptions.InvalidParameterError, match="joint_scale.*list of 1 finite coefficients"):
        joint_offsets(robocal.robot("ur10"), [{"kind": "joint_scale", "joint": 2, "detail": {}, "coefficients": 0.0}])


def test_a_map_takes_the_place_of_its_joints_harmonic():
    """A transmission error with a strong second harmonic: the named stage finds the harmonic,
    the map of the same joint then follows the whole error and replaces it (a harmonic claims a
    shape beyond the range it saw; the map does not). The report says so."""
    effects = ["joint_periodic:joint=2,amplitude=0.03,harmonic=2,phase=20", *GEAR]
    data, _ = simulate("ur10", "position", samples=800, seed=7, effects=effects)
    report = robocal.diagnose(data).to_dict()
    causes = report["model"]["causes"]
    assert any(c.startswith("joint_map joint 2 ") for c in causes), causes
    assert not any(c.startswith("joint_periodic joint 2 ") for c in causes), causes
    replaced = [r for r in report["rejected"] if r["kind"] == "joint_periodic" and r["joint"] == 2 and r["reason"].startswith("replaced by joint_map joint 2")]
    assert replaced, [(r["label"], r["reason"]) for r in report["rejected"]]
    assert report["final"]["rmse_heldout"] < 0.5 * report["baseline"]["rmse_heldout"]
