"""robocal against the tools a user would pick instead, on the same calibration problems.

Problems (each solver gets the same data, the same free parameters and the same start where
the model is robocal's):

* ``D1``: HSR-RobotCali (cable), the training split of ``bench_calibration.m9_setup``
  (1614 samples), HSR JR680.
* ``D3``: ipa-robot-accuracy UR10 Series B (laser-tracker position, 1495 samples).
* ``SIM``: ``robocal.simulate("hsr-jr680", "cable", samples=10000, seed=1)``.

Solvers:

* robocal's production LM (``robocal.calibration.lm.levenberg_marquardt``, Rust core);
* ``scipy.optimize.least_squares(method="lm")`` (MINPACK) on the pure-NumPy twin
  ``robocal.reference.residuals``, with finite differences (``jac="2-point"``) and with the
  analytic NumPy Jacobian ``robocal.reference.jacobian``;
* pybotics 3.1.2's calibration path (``OptimizationHandler`` + ``optimize_accuracy`` +
  ``least_squares(method="lm")``, its own MDH model) — position data only (D3);
* the UKF stage of M9: robocal's ``kalman.ukf`` (Rust sweep) vs filterpy's
  ``UnscentedKalmanFilter`` (``MerweScaledSigmaPoints``) and vs the NumPy twin of
  ``bench_calibration.numpy_ukf_vslm``; and the whole M9 cascade vs that twin.

Every solver runs in a fresh subprocess of this script (``--worker``), one after the other, so
peak memory is its own: the Linux peak RSS is reset (``/proc/self/clear_refs`` ← 5) after the
problem is built, and the solve's peak is ``VmHWM − VmRSS`` measured around it (all
allocations: NumPy, Rust, Python). A second run of the same solve under ``tracemalloc`` gives the
peak of the Python-visible allocations (NumPy buffers and Python objects; not Rust's), unless
the first run took longer than ``--tracemalloc-max-s``. Fast solves are timed best of
``--repeats``.

    python benches/bench_alternatives.py                 # full run (~5-10 min on 2 cores)
    python benches/bench_alternatives.py --quick         # small sizes, for development
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
import tracemalloc

from bench_calibration import D1_DEFAULT, UKF_OPTIONS, best_of, load_avg, m9_setup, numpy_twin, numpy_ukf_vslm, rmse
from machine import cpu_model
from record import add_argument, recording

D3_DEFAULT = D1_DEFAULT.parents[1] / "ipa-robot-accuracy-ur10" / "Series_B" / "measurements_joint_configurations.csv"
TOL = 1e-10


# ---------------------------------------------------------------------------------------------
# Memory
# ---------------------------------------------------------------------------------------------
def _status_kib(*keys: str) -> list[int]:
    with open("/proc/self/status") as f:
        d = dict(line.split(":", 1) for line in f)
    return [int(d[k].split()[0]) for k in keys]


def reset_peak_rss() -> int:
    """Reset the kernel's peak RSS of this process; return the current RSS (KiB)."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")
    return _status_kib("VmRSS")[0]


def peak_rss_kib() -> int:
    return _status_kib("VmHWM")[0]


# ---------------------------------------------------------------------------------------------
# Problems
# ---------------------------------------------------------------------------------------------
def build(name: str, args):
    """(robot, problem) of a benchmark problem."""
    import robocal
    from robocal.calibration.problem import Problem

    if name == "D1":
        r, _, _, problem, _ = m9_setup(args.d1, args.ukf_sweeps)
        return r, problem
    if name == "D3":
        r = robocal.robot("ur10")
        return r, Problem.build(r, robocal.load(args.d3, measurement="position", robot="ur10"))
    if name == "SIM":
        r = robocal.robot("hsr-jr680")
        data, _ = robocal.simulate("hsr-jr680", "cable", samples=args.sim_samples, seed=1)
        return r, Problem.build(r, data)
    raise ValueError(name)


# ---------------------------------------------------------------------------------------------
# Solvers: each returns (solve() -> dict, ) — the dict holds x (free parameters in robocal's
# layout, or None), rmse (mm, per residual component), and solver notes.
# ---------------------------------------------------------------------------------------------
def robocal_lm(r, problem, args):
    from robocal.calibration.lm import levenberg_marquardt

    def solve():
        res = levenberg_marquardt(problem, ftol=TOL, xtol=TOL, gtol=TOL)
        return dict(x=res.x, rmse=rmse(problem.residuals(res.x)), note=f"nit {res.nit}, nfev {res.nfev}; {res.message}")

    return solve


class OverBudget(Exception):
    pass


class Tracked:
    """An objective wrapper: counts calls, remembers the best point, the time at which the
    residual norm first reached ``target`` (robocal's final RMSE) and stops the solver (raises
    :class:`OverBudget`) once ``budget`` seconds have passed."""

    def __init__(self, fun, rows: int, target: float, budget: float):
        import numpy as np

        self.fun, self.calls, self.t0 = fun, 0, time.perf_counter()
        self.target = None if not target else target * np.sqrt(rows) * (1 + 1e-6)  # "equal RMSE": 1e-6 relative
        self.budget, self.hit, self.best, self.best_x = budget, None, float("inf"), None

    def __call__(self, x, *extra):
        import numpy as np

        elapsed = time.perf_counter() - self.t0
        if self.budget and elapsed > self.budget:
            raise OverBudget
        v = self.fun(x, *extra)
        self.calls += 1
        norm = float(np.linalg.norm(v))
        if norm < self.best:
            self.best, self.best_x = norm, np.array(x, copy=True)
        if self.hit is None and self.target is not None and norm <= self.target:
            self.hit = time.perf_counter() - self.t0
        return v

    def run(self, solver):
        """``solver()`` → (its result or None when stopped by the budget, notes)."""
        self.t0 = time.perf_counter()
        try:
            return solver(), ""
        except OverBudget:
            return None, f"STOPPED at the {self.budget:g} s budget (best point so far reported); "


def _twin(r, problem):
    """(residuals, Jacobian) of ``problem`` over its free parameters in the NumPy twin."""
    conv, kinds = [j.convention for j in r.joints], [j.kind for j in r.joints]
    d = problem.data
    return numpy_twin(conv, kinds, d.measurement, problem.start, problem.free, d.q, d.y)[1:]


def scipy_lm(jac_kind: str):
    def make(r, problem, args):
        import scipy.optimize

        fun, jac = _twin(r, problem)
        rows = problem.residuals(problem.x0).size

        def solve():
            f = Tracked(fun, rows, args.target_rmse, args.budget_s)
            out, stop = f.run(
                lambda: scipy.optimize.least_squares(f, problem.x0, method="lm", jac=jac if jac_kind == "analytic" else "2-point", ftol=TOL, xtol=TOL, gtol=TOL)
            )
            x = f.best_x if out is None else out.x
            status = stop if out is None else (out.message if out.success else f"NOT CONVERGED: {out.message}")
            return dict(x=x, rmse=rmse(problem.residuals(x)), hit_s=f.hit, note=f"{f.calls} residual calls; {status}")

        return solve

    return make


def pybotics_lm(r, problem, args):
    """pybotics' own calibration path on position data: its UR10 MDH model, world frame from a
    Kabsch fit of its nominal flange points (as robocal's start does for the base), then
    ``least_squares(optimize_accuracy, method="lm")`` over all MDH parameters but the first
    link's, the tool position and the world frame (pybotics' documented example)."""
    import numpy as np
    import scipy.optimize
    from pybotics.optimization import OptimizationHandler, optimize_accuracy
    from pybotics.predefined_models import ur10
    from pybotics.robot import Robot as PyboticsRobot

    from robocal.geometry import kabsch

    if problem.data.measurement != "position":
        raise NotImplementedError("pybotics' calibration fits positions only (optimize_accuracy / compute_absolute_errors); it has no cable-length model")
    q, y = problem.data.q, problem.data.y
    pr = PyboticsRobot.from_parameters(ur10())
    flange = np.array([pr.fk(qi)[:3, 3] for qi in q])
    pr.world_frame = kabsch(flange, y)

    def solve():
        handler = OptimizationHandler(robot=pr, kinematic_chain_mask=[False] * 4 + [True] * 20, tool_mask=[True] * 3 + [False] * 3, world_mask=[True] * 6)
        x0 = handler.generate_optimization_vector()
        # pybotics' residual is the per-sample distance; robocal's rows are x, y, z: same sum of
        # squares, so its norm is compared with robocal's over 3 rows per sample
        f = Tracked(optimize_accuracy, 3 * len(q), args.target_rmse, args.pybotics_budget_s)
        out, stop = f.run(lambda: scipy.optimize.least_squares(f, x0, args=(handler, q, y), method="lm", ftol=TOL, xtol=TOL, gtol=TOL))
        e = f.best / np.sqrt(3 * len(q))
        status = stop if out is None else (out.message if out.success else f"NOT CONVERGED: {out.message}")
        return dict(x=None, rmse=e, hit_s=f.hit, note=f"{len(x0)} parameters (its MDH model), {f.calls} residual calls; {status}", nfev=f.calls)

    return solve


def robocal_ukf(r, problem, args):
    from robocal.calibration.kalman import ukf

    opts = _ukf_opts(args)

    def solve():
        res = ukf(problem, **opts)
        return dict(x=res.x, rmse=rmse(problem.residuals(res.x)), note=f"{opts['sweeps']} sweeps × {len(problem.data)} samples")

    return solve


def _ukf_opts(args):
    _, _, _, _, opts = m9_setup(args.d1, args.ukf_sweeps)
    return {k: opts[k] for k in UKF_OPTIONS}


def filterpy_ukf(r, problem, args):
    """filterpy's UKF with the same sigma points, P0, Q, R, reset of P at each sweep; the state is
    the free parameters, ``fx`` the identity, ``hx`` the NumPy twin's prediction of one sample."""
    import numpy as np
    from filterpy.kalman import MerweScaledSigmaPoints, UnscentedKalmanFilter

    from robocal import reference as ref

    conv, kinds = [j.convention for j in r.joints], [j.kind for j in r.joints]
    meas, q, y = problem.data.measurement, problem.data.q, problem.data.y
    start, free = problem.start, problem.free
    opts = _ukf_opts(args)
    n = len(free)

    def hx(x, qi):
        p = start.copy()
        p[free] = x
        return ref.predict(conv, kinds, meas, p, qi).ravel()

    def solve():
        points = MerweScaledSigmaPoints(n, alpha=opts["alpha"], beta=opts["beta"], kappa=opts["kappa"])
        kf = UnscentedKalmanFilter(dim_x=n, dim_z=y.shape[1], dt=1.0, hx=hx, fx=lambda x, dt: x, points=points)
        kf.x, kf.Q, kf.R = problem.x0.copy(), opts["Q"], opts["R"]
        for _ in range(opts["sweeps"]):
            kf.P = opts["P0"].copy()
            for i in range(len(q)):
                kf.predict()
                kf.update(y[i], qi=q[i : i + 1])
        return dict(x=kf.x.copy(), rmse=rmse(problem.residuals(kf.x)), note=f"{opts['sweeps']} sweeps × {len(q)} samples")

    return solve


def numpy_ukf(r, problem, args):
    """The UKF stage of ``bench_calibration.numpy_ukf_vslm`` (its VSLM loop skipped: max_iter=0)."""
    return _numpy_m9(r, problem, args, max_iter=0)


def _numpy_m9(r, problem, args, max_iter=None):
    conv, kinds = [j.convention for j in r.joints], [j.kind for j in r.joints]
    _, _, _, _, opts = m9_setup(args.d1, args.ukf_sweeps)
    if max_iter is not None:
        opts["max_iter"] = max_iter

    def solve():
        _, x, _, nit, t_ukf, t_vslm = numpy_ukf_vslm(conv, kinds, problem.data.measurement, problem.start, problem.free, problem.data.q, problem.data.y, **opts)
        return dict(x=x, rmse=rmse(problem.residuals(x)), note=f"{opts['sweeps']} sweeps, {nit} VSLM iterations (UKF {t_ukf:.2f} s, VSLM {t_vslm:.2f} s)")

    return solve


def numpy_m9(r, problem, args):
    return _numpy_m9(r, problem, args)


def robocal_m9(r, problem, args):
    from robocal.calibration.cascade import ukf_vslm

    _, _, _, _, opts = m9_setup(args.d1, args.ukf_sweeps)

    def solve():
        res = ukf_vslm(problem, **opts)
        return dict(x=res.x, rmse=rmse(problem.residuals(res.x)), note=res.message)

    return solve


SOLVERS = {
    "robocal-lm": ("robocal `levenberg_marquardt` (Rust core, analytic J)", robocal_lm),
    "scipy-lm-fd": ("scipy `least_squares(method='lm')`, NumPy twin, 2-point finite differences", scipy_lm("2-point")),
    "scipy-lm-jac": ("scipy `least_squares(method='lm')`, NumPy twin, analytic NumPy J", scipy_lm("analytic")),
    "pybotics-lm": ("pybotics 3.1.2 `optimize_accuracy` + scipy `least_squares(method='lm')`, its MDH model", pybotics_lm),
    "robocal-ukf": ("robocal `kalman.ukf` (Rust sweep)", robocal_ukf),
    "filterpy-ukf": ("filterpy `UnscentedKalmanFilter` + NumPy twin `predict`", filterpy_ukf),
    "numpy-ukf": ("NumPy twin UKF (`bench_calibration.numpy_ukf_vslm`, UKF stage)", numpy_ukf),
    "robocal-m9": ("robocal `cascade.ukf_vslm` (M9)", robocal_m9),
    "numpy-m9": ("NumPy twin M9 (`bench_calibration.numpy_ukf_vslm`)", numpy_m9),
}


def worker(args) -> None:
    import gc

    import numpy as np

    r, problem = build(args.problem, args)
    solve = SOLVERS[args.solver][1](r, problem, args)
    gc.collect()
    rss0 = reset_peak_rss()
    t = time.perf_counter()
    out = solve()
    first = time.perf_counter() - t
    peak = peak_rss_kib() - rss0
    best = first
    if first < args.repeat_below_s and args.repeats > 1:
        best, _ = best_of(solve, args.repeats - 1)
        best = min(best, first)
    traced = None
    if first <= args.tracemalloc_max_s:
        tracemalloc.start()
        solve()
        traced = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
    x = out.pop("x")
    if "nfev" in out:
        out["note"] += f"{best / out['nfev']:.3f} s per residual evaluation"
    print(
        json.dumps(
            dict(
                out,
                time_s=best,
                first_s=first,
                rss_peak_kib=peak,
                traced_peak_b=traced,
                n_free=len(problem.free),
                samples=len(problem.data),
                x=None if x is None else np.asarray(x).tolist(),
            )
        )
    )


def run_case(problem: str, solver: str, args, extra=()) -> dict:
    cmd = [sys.executable, __file__, "--worker", "--problem", problem, "--solver", solver] + args.passthrough + list(extra)
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        lines = [line for line in proc.stderr.strip().splitlines() if line.strip()]
        return dict(error=lines[-1] if lines else f"exit status {proc.returncode}")
    return json.loads(proc.stdout.strip().splitlines()[-1])


def mib(kib) -> str:
    return "n/a" if kib is None else f"{kib / 1024:.1f} MiB"


def table(title: str, intro: str, problem: str, solvers: list[str], args, reference: str, extra=()) -> dict:
    """Runs ``solvers`` (``reference`` first, whose final RMSE the others' time-to-RMSE uses)."""
    import numpy as np

    print(f"### {title}\n\n{intro}\n")
    print(
        "| solver | wall time | × robocal | time to robocal's final RMSE | × robocal | "
        "final RMSE (mm) | max abs(x − x_robocal) | peak RSS of the solve | tracemalloc peak | notes |"
    )
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|---|")
    ref = run_case(problem, reference, args, extra)
    hit = [f"--target-rmse={ref['rmse']!r}"] if "rmse" in ref else []
    results = {s: ref if s == reference else run_case(problem, s, args, [*extra, *hit]) for s in solvers}
    for s in solvers:
        out = results[s]
        label = SOLVERS[s][0]
        if "error" in out:
            print(f"| {label} | — | — | — | — | — | — | — | — | **fails**: `{out['error']}` |")
            continue
        ratio = out["time_s"] / ref["time_s"] if "time_s" in ref else float("nan")
        dx = "—" if out["x"] is None or ref.get("x") is None else f"{np.max(np.abs(np.subtract(out['x'], ref['x']))):.2e}"
        traced = "n/a (not rerun)" if out["traced_peak_b"] is None else mib(out["traced_peak_b"] / 1024)
        if s == reference:
            reach = "—", "—"
        elif out.get("hit_s") is None:
            reach = ("not reached", "—") if "hit_s" in out else ("n/a", "—")
        else:
            reach = f"{out['hit_s']:.3f} s", f"{out['hit_s'] / ref['time_s']:.1f}×"
        print(
            f"| {label} | {out['time_s']:.3f} s | {ratio:.1f}× | {reach[0]} | {reach[1]} | "
            f"{out['rmse']:.6f} | {dx} | {mib(out['rss_peak_kib'])} | {traced} | {out['note']} |"
        )
    print()
    return results


def target(name: str, results: dict, fast: str, slow: str, factor: float) -> None:
    """MET when ``slow`` needs ≥ ``factor`` × ``fast``'s time to reach ``fast``'s final RMSE."""
    a, b = results.get(fast, {}), results.get(slow, {})
    if "time_s" not in a or "time_s" not in b:
        print(f"**Target {name}: NOT MEASURED** (a run failed).\n")
        return
    if b.get("hit_s") is None:
        # Only a lower bound on the ratio: it decides the target only if it already reaches it.
        bound = b["time_s"] / a["time_s"]
        verdict = "MET" if bound >= factor else f"NOT SHOWN (the lower bound {bound:.0f}× is below {factor:g}×)"
        print(
            f"**Target {name}: {verdict}** — {slow} never reached robocal's final RMSE {a['rmse']:.6f} mm "
            f"within {b['time_s']:.1f} s (≥ {bound:.0f}× robocal's {a['time_s']:.3f} s); its best {b['rmse']:.6f} mm.\n"
        )
        return
    ratio = b["hit_s"] / a["time_s"]
    met = ratio >= factor
    print(
        f"**Target {name}: {'MET' if met else 'MISSED'}** — scipy reaches robocal's final RMSE ({a['rmse']:.6f} mm) after "
        f"{b['hit_s']:.3f} s vs robocal's {a['time_s']:.3f} s for its whole solve = {ratio:.1f}× (target ≥ {factor:g}×: "
        f"{'exceeded by ' + format(ratio / factor, '.2f') + '×' if met else 'short by ' + format(factor / ratio, '.2f') + '×'}). "
        f"Run to its own stop, scipy ends at {b['rmse']:.6f} mm after {b['time_s']:.3f} s ({b['time_s'] / a['time_s']:.1f}×); "
        f"{'equal final RMSE to 1e-6 relative' if abs(a['rmse'] - b['rmse']) <= 1e-6 * a['rmse'] else 'the final RMSEs differ (see the notes)'}.\n"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="development sizes: 2000 simulated samples, 1 UKF sweep")
    parser.add_argument("--sim-samples", type=int, default=10_000)
    parser.add_argument("--ukf-sweeps", type=int, default=5, help="UKF sweeps (M9's T3)")
    parser.add_argument("--repeats", type=int, default=3, help="best of this many runs for solves under --repeat-below-s")
    parser.add_argument("--repeat-below-s", type=float, default=2.0)
    parser.add_argument("--tracemalloc-max-s", type=float, default=10.0, help="rerun under tracemalloc only solves faster than this")
    parser.add_argument("--budget-s", type=float, default=150.0, help="wall-time budget of each scipy solve (0: none)")
    parser.add_argument("--pybotics-budget-s", type=float, default=60.0, help="wall-time budget of pybotics' solve (~1 s per residual evaluation on D3)")
    parser.add_argument("--ukf-stage-sweeps", type=int, default=1, help="sweeps in the UKF-stage table (filterpy takes ~40 s per sweep of D1)")
    parser.add_argument("--target-rmse", type=float, default=0.0, help=argparse.SUPPRESS)
    parser.add_argument("--blas-threads", type=int, default=1)
    parser.add_argument("--d1", default=str(D1_DEFAULT))
    parser.add_argument("--d3", default=str(D3_DEFAULT))
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--problem", help=argparse.SUPPRESS)
    parser.add_argument("--solver", help=argparse.SUPPRESS)
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.quick:
            args.sim_samples, args.ukf_sweeps = min(args.sim_samples, 2000), 1
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = str(args.blas_threads)
        if args.worker:
            worker(args)
            return
        args.passthrough = [
            f"--sim-samples={args.sim_samples}",
            f"--ukf-sweeps={args.ukf_sweeps}",
            f"--repeats={args.repeats}",
            f"--repeat-below-s={args.repeat_below_s}",
            f"--tracemalloc-max-s={args.tracemalloc_max_s}",
            f"--budget-s={args.budget_s}",
            f"--pybotics-budget-s={args.pybotics_budget_s}",
            f"--blas-threads={args.blas_threads}",
            f"--d1={args.d1}",
            f"--d3={args.d3}",
        ]

        import filterpy
        import numpy as np
        import scipy

        import robocal

        try:
            from importlib.metadata import version

            pyb = version("pybotics")
        except Exception:  # noqa: BLE001 - not installed
            pyb = "not installed"
        print("## robocal vs the alternatives\n")
        print(
            f"* machine: {cpu_model()}, {os.cpu_count()} cores; rayon threads: {os.environ.get('RAYON_NUM_THREADS', 'all')}; "
            f"NumPy BLAS threads: {args.blas_threads}; load average at start: {load_avg()}"
        )
        print(
            f"* python {sys.version.split()[0]}, numpy {np.__version__}, scipy {scipy.__version__}, "
            f"filterpy {filterpy.__version__}, pybotics {pyb}, robocal {robocal.__version__}"
        )
        print(f"* command: `python benches/bench_alternatives.py {' '.join(sys.argv[1:])}`".rstrip())
        print(
            "* each solver in a fresh subprocess, one after another; wall time of the solve only (best of "
            f"{args.repeats} when under {args.repeat_below_s:g} s); ftol = xtol = gtol = {TOL:g} for every least-squares solver; "
            "peak RSS = VmHWM − VmRSS around the solve after resetting the peak (all allocations); tracemalloc peak = "
            "Python-visible allocations of a second run (NumPy buffers, Python objects; not Rust's)\n"
        )
        start = time.perf_counter()
        lm = ["robocal-lm", "scipy-lm-fd", "scipy-lm-jac", "pybotics-lm"]
        d1 = table(
            "D1 (HSR-RobotCali, cable), least squares",
            "HSR JR680, D1 training split (1614 samples), robocal's default mask → 24 free parameters, start `problem.x0`.",
            "D1",
            lm,
            args,
            "robocal-lm",
        )
        target("robocal's production LM ≥ 100× faster than scipy with finite differences on D1, at equal final RMSE", d1, "robocal-lm", "scipy-lm-fd", 100)
        table(
            "D3 (UR10 Series B, laser-tracker position), least squares",
            "UR10, 1495 samples, default mask → 27 free parameters; pybotics fits its own MDH model "
            "(20 link + 3 tool + 6 world = 29 parameters, redundant ones included) from its own start; "
            "its solve is stopped at a wall-time budget (`--pybotics-budget-s`), so its row is a time per evaluation "
            "and the RMSE reached by then, not a converged fit.",
            "D3",
            lm,
            args,
            "robocal-lm",
        )
        table(
            f"Simulated HSR JR680 cable, {args.sim_samples:,} samples, least squares",
            f"`robocal.simulate('hsr-jr680', 'cable', samples={args.sim_samples}, seed=1)`, default mask → 25 free parameters.",
            "SIM",
            lm,
            args,
            "robocal-lm",
        )
        table(
            f"D1, the UKF stage of M9 ({args.ukf_stage_sweeps} sweep{'s' if args.ukf_stage_sweeps > 1 else ''}, the same for each implementation)",
            "Same P0, Q, R, Merwe sigma points (alpha 0.1, beta 2, kappa 0), P reset to P0 at each sweep (Algorithm 1).",
            "D1",
            ["robocal-ukf", "filterpy-ukf", "numpy-ukf"],
            args,
            "robocal-ukf",
            [f"--ukf-sweeps={args.ukf_stage_sweeps}"],
        )
        m9 = table(
            f"D1, the whole M9 cascade ({args.ukf_sweeps} UKF sweeps + VSLM ≤ 200 iterations)",
            "As in `bench_calibration.py` part 2 (the VSLM stage diverges on D1 with the default damping: compare speed, not RMSE).",
            "D1",
            ["robocal-m9", "numpy-m9"],
            args,
            "robocal-m9",
        )
        if "time_s" in m9.get("robocal-m9", {}) and "time_s" in m9.get("numpy-m9", {}):
            ratio = m9["numpy-m9"]["time_s"] / m9["robocal-m9"]["time_s"]
            print(
                f"**Target M9 ≥ 20× faster than its NumPy twin: {'MET' if ratio >= 20 else 'MISSED'}** — "
                f"{m9['numpy-m9']['time_s']:.3f} s / {m9['robocal-m9']['time_s']:.3f} s = {ratio:.1f}× "
                f"({'by ' + format(ratio / 20, '.2f') + '×' if ratio >= 20 else 'short by ' + format(20 / ratio, '.2f') + '×'}).\n"
            )
        print(f"total {time.perf_counter() - start:.1f} s; load average at end: {load_avg()}\n")


if __name__ == "__main__":
    main()
