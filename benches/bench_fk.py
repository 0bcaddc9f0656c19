"""Forward kinematics: robocal's kernel against a straightforward vectorised NumPy FK, and
against another build of robocal (e.g. the kernel before a change), side by side.

The NumPy FK is what a user would write: per joint a (m, 4, 4) standard-DH matrix from
``np.cos``/``np.sin`` of the whole column, multiplied down the chain with ``@`` (batched
matmul), base and tool frames included. robocal's timing is ``Chain.fk(params, q, tool=True)``
from Python (conversion, allocation and the GIL release included). The D1 rows time one
residual evaluation of the calibration problem on the 2017 cable samples of HSR-RobotCali
(``Problem.residuals``, what the least-squares solvers call, and the bare ``Chain.residuals``).

``--baseline-so`` runs under a copy of this checkout's Python package (the .so must match its
bindings). Each build runs in its own subprocess; the builds alternate for ``--rounds`` rounds and every
figure is the median over rounds of per-round medians, so that a load change on the machine
hits both builds alike. Ratios are within one process (NumPy / robocal) or between the builds.

    python benches/bench_fk.py                                   # this build only
    python benches/bench_fk.py --baseline-so /path/to/_robocal.abi3.so --label-baseline main
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from record import add_argument, recording

D1 = "/work/shared/datasets/hsr-robotcali/HSR-RobotCali.xlsx"


def median_time(fn, repeats: int) -> float:
    fn()
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def numpy_dh_fk(params, q, n):
    """Standard-DH forward kinematics of a revolute chain with β = 0, base and tool frames."""
    import numpy as np

    from robocal.reference import frame_transform

    alpha, a, d, theta = params[: 5 * n].reshape(n, 5)[:, :4].T
    th = q + theta
    ct, st = np.cos(th), np.sin(th)
    ca, sa = np.cos(alpha), np.sin(alpha)
    A = np.zeros(q.shape + (4, 4))
    A[..., 0, 0], A[..., 0, 1], A[..., 0, 2], A[..., 0, 3] = ct, -st * ca, st * sa, a * ct
    A[..., 1, 0], A[..., 1, 1], A[..., 1, 2], A[..., 1, 3] = st, ct * ca, -ct * sa, a * st
    A[..., 2, 1], A[..., 2, 2], A[..., 2, 3], A[..., 3, 3] = sa, ca, d, 1.0
    T = frame_transform(params[5 * n : 5 * n + 6]) @ A[:, 0]
    for j in range(1, n):
        T = T @ A[:, j]
    return T @ frame_transform(params[5 * n + 6 : 5 * n + 12])


def worker(sizes, repeats: int, d1: str | None) -> dict:
    """Timings of the robocal build on ``sys.path`` (one round)."""
    import numpy as np

    import robocal

    r = robocal.robot("hsr-jr680")
    params = r.with_params(tool_x=20.0, tool_y=-15.0, tool_z=60.0).params
    # A calibrated robot: every DH parameter off nominal (no zero link parameter left to skip).
    dh = np.flatnonzero([n.rstrip("0123456789") in ("alpha", "a", "d", "theta") for n in r.param_names])
    params[dh] += np.random.default_rng(1).normal(0.0, 1e-3, dh.size)
    assert not params[4:30:5].any(), "the NumPy FK assumes beta = 0"
    rng = np.random.default_rng(0)
    out = {"module": robocal._robocal.__file__, "fk": {}}
    for m in sizes:
        q = np.radians([5.0, -60.0, 200.0, -160.0, 40.0, 60.0]) + rng.uniform(-0.6, 0.6, size=(m, 6))
        err = np.abs(r.chain.fk(params, q, True) - numpy_dh_fk(params, q, 6)).max()
        t_rust = median_time(lambda: r.chain.fk(params, q, True), repeats)
        t_numpy = median_time(lambda: numpy_dh_fk(params, q, 6), max(3, repeats // 10))
        out["fk"][m] = {"robocal": t_rust, "numpy": t_numpy, "max_abs_diff": float(err)}
    if d1:
        from robocal.calibration.problem import Problem
        from robocal.data import load

        data = load(d1)
        problem = Problem.build(r, data)
        x0 = problem.x0
        p = problem.full(x0)
        out["d1"] = {
            "samples": len(data),
            "problem": median_time(lambda: problem.residuals(x0), repeats),
            "chain": median_time(lambda: r.chain.residuals("cable", p, data.q, data.y), repeats),
        }
    return out


def build_tree(so: Path, tmp: Path) -> Path:
    """A copy of this checkout's Python package with ``so`` as its compiled core."""
    src = Path(__file__).resolve().parents[1] / "python" / "robocal"
    dst = tmp / "robocal"
    shutil.copytree(src, dst, ignore=shutil.ignore_patterns("*.so", "__pycache__"))
    shutil.copy2(so, dst / "_robocal.abi3.so")
    return tmp


def run_round(pythonpath: str | None, args) -> dict:
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    cmd = [sys.executable, __file__, "--worker", "--repeats", str(args.repeats), "--sizes", *map(str, args.sizes)]
    if args.d1:
        cmd += ["--d1", args.d1]
    done = subprocess.run(cmd, env=env, check=True, capture_output=True, text=True)
    return json.loads(done.stdout.splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[1_000, 10_000, 100_000])
    parser.add_argument("--repeats", type=int, default=51, help="timed calls per figure and round")
    parser.add_argument("--rounds", type=int, default=3, help="alternating rounds per build")
    parser.add_argument("--baseline-so", type=Path, help="another build of robocal._robocal to compare with")
    parser.add_argument("--label-baseline", default="baseline")
    parser.add_argument("--d1", default=D1 if Path(D1).exists() else None, help="HSR-RobotCali workbook (D1)")
    parser.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.worker:
            print(json.dumps(worker(args.sizes, args.repeats, args.d1)))
            return

        from machine import cpu_model, load_text

        with tempfile.TemporaryDirectory() as tmp:
            builds = {"this build": os.environ.get("PYTHONPATH")}
            if args.baseline_so:
                builds = {args.label_baseline: str(build_tree(args.baseline_so, Path(tmp))), **builds}
            load_start = load_text()
            rounds = {label: [] for label in builds}
            for _ in range(args.rounds):
                for label, path in builds.items():
                    rounds[label].append(run_round(path, args))
            load_end = load_text()

        threads = os.environ.get("RAYON_NUM_THREADS", "all")
        print(f"machine: {cpu_model()}, {os.cpu_count()} logical CPUs; load average {load_start} at the start, {load_end} at the end")
        print(f"rayon threads: {threads}; {args.rounds} alternating rounds per build, {args.repeats} calls per figure; medians\n")
        for label, rs in rounds.items():
            print(f"- {label}: {rs[0]['module']}")
        print()

        def med(label, *keys):
            values = []
            for r in rounds[label]:
                v = r
                for k in keys:
                    v = v[k]
                values.append(v)
            return statistics.median(values)

        labels = list(builds)
        head = "| poses | NumPy FK | " + " | ".join(f"robocal {lab}" for lab in labels) + " | " + " | ".join(f"NumPy / {lab}" for lab in labels)
        head += " | M poses/s (" + labels[-1] + ") |" + (f" {labels[-1]} vs {labels[0]} |" if len(labels) > 1 else "")
        print(head)
        print("|" + "---:|" * (head.count("|") - 1))
        for m in args.sizes:
            key = str(m)
            tn = med(labels[-1], "fk", key, "numpy")
            tr = [med(lab, "fk", key, "robocal") for lab in labels]
            ratios = [statistics.median(r["fk"][key]["numpy"] / r["fk"][key]["robocal"] for r in rounds[lab]) for lab in labels]
            row = f"| {m:,} | {tn * 1e3:.2f} ms | " + " | ".join(f"{t * 1e3:.3f} ms" for t in tr) + " | " + " | ".join(f"{x:.1f}x" for x in ratios)
            row += f" | {m / tr[-1] / 1e6:.1f} |" + (f" {tr[0] / tr[-1]:.2f}x |" if len(labels) > 1 else "")
            print(row)
        diff = max(r["fk"][str(m)]["max_abs_diff"] for rs in rounds.values() for r in rs for m in args.sizes)
        print(f"\nlargest |robocal − NumPy| over all poses and entries: {diff:.1e} (mm)")
        if args.d1:
            print(f"\nOne residual evaluation on D1 ({rounds[labels[-1]][0]['d1']['samples']} cable samples):\n")
            print("| call | " + " | ".join(labels) + " |" + (f" {labels[-1]} vs {labels[0]} |" if len(labels) > 1 else ""))
            print("|---|" + "---:|" * (len(labels) + (len(labels) > 1)))
            for name, key in (("`Problem.residuals(x0)`", "problem"), ("`Chain.residuals` (cable)", "chain")):
                ts = [med(lab, "d1", key) for lab in labels]
                print(f"| {name} | " + " | ".join(f"{t * 1e6:.1f} µs" for t in ts) + " |" + (f" {ts[0] / ts[-1]:.2f}x |" if len(labels) > 1 else ""))


if __name__ == "__main__":
    main()
