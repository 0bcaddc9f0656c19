"""How robocal's calibrators scale with the number of samples M and of parameters n.

1. Samples: simulated HSR JR680 cable data (``robocal.simulate(..., seed=1)``), M = 100 … 100 000:
   * the production LM (``levenberg_marquardt``, run to its tolerances — its iteration count
     depends on the data, so the time per iteration is reported too);
   * the M9 cascade with FIXED work, as eq. (27) of the paper assumes: T3 = ``--sweeps`` UKF
     sweeps (``kalman.ukf``) then T9 = ``--vslm-iter`` VSLM iterations (``vslm``, ftol = xtol = 0
     so it never stops early), timed per stage; the cascade is the two calls ``ukf_vslm`` makes.
2. Parameters: M = ``--param-samples`` samples on robots with 3, 6 and 7 joints and on the
   6-joint robot with smaller masks: LM per iteration, one UKF sweep (per sample update), VSLM
   per iteration.

Exponents are least-squares slopes of log(time) on log(M) or log(n). The paper's eq. (27) is
Θ((T3 + T9)·M): slope 1 in M.

    python benches/bench_scaling.py            # full (~3-5 min on 2 cores)
    python benches/bench_scaling.py --quick
"""

from __future__ import annotations

import argparse
import os
import sys
import time

from bench_calibration import best_of, load_avg, rmse
from machine import cpu_model
from record import add_argument, recording

#: KUKA LBR iiwa 7-like standard-DH table (alpha deg, a mm, d mm, theta deg): a 7-joint arm.
IIWA_LIKE = [(-90, 0, 340, 0), (90, 0, 0, 0), (90, 0, 400, 0), (-90, 0, 0, 0), (-90, 0, 400, 0), (90, 0, 0, 0), (0, 0, 126, 0)]


def slope(x, t) -> float:
    import numpy as np

    return float(np.polyfit(np.log(x), np.log(t), 1)[0])


def hsr_rows():
    """The HSR JR680's nominal (alpha deg, a, d, theta deg) rows."""
    import numpy as np

    import robocal

    p = robocal.robot("hsr-jr680").params[:30].reshape(6, 5)[:, :4]
    return [(np.degrees(a), a_, d, np.degrees(th)) for a, a_, d, th in p]


def part_samples(args) -> None:
    import robocal
    from robocal.calibration.kalman import ukf
    from robocal.calibration.lm import levenberg_marquardt
    from robocal.calibration.problem import Problem
    from robocal.calibration.vslm import vslm

    r = robocal.robot("hsr-jr680")
    rows = []
    for m in args.samples:
        data, _ = robocal.simulate("hsr-jr680", "cable", samples=m, seed=1)
        problem = Problem.build(r, data)
        reps = args.repeats if m <= 10_000 else 1
        t_lm, res = best_of(lambda: levenberg_marquardt(problem), reps)
        t_ukf, first = best_of(lambda: ukf(problem, sweeps=args.sweeps), reps)
        t_vslm, second = best_of(lambda: vslm(problem, x0=first.x, max_iter=args.vslm_iter, ftol=0.0, xtol=0.0), reps)
        rows.append(
            (m, len(problem.free), t_lm, res.nit, res.nfev, rmse(problem.residuals(res.x)), t_ukf, t_vslm, second.nit, rmse(problem.residuals(second.x)))
        )
        print(f"  M={m}: LM {t_lm:.3f} s, UKF {t_ukf:.3f} s, VSLM {t_vslm:.3f} s", file=sys.stderr)

    print(f"## 1. Time against samples M (HSR JR680, cable, default mask)\n")
    print(
        f"LM: to its default tolerances (1e-10). M9: T3 = {args.sweeps} UKF sweeps, T9 = {args.vslm_iter} VSLM iterations (fixed). "
        f"Best of {args.repeats} up to M = 10 000, one run above.\n"
    )
    print(
        "| M | free params | LM time | LM iterations (nfev) | LM time / evaluation | LM RMSE (mm) | UKF stage | "
        "µs per sample update | VSLM stage | ms per VSLM iteration | M9 cascade (UKF + VSLM) | M9 RMSE (mm) |"
    )
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for m, n, t_lm, nit, nfev, e_lm, t_ukf, t_vslm, vnit, e_m9 in rows:
        print(
            f"| {m:,} | {n} | {t_lm:.4f} s | {nit} ({nfev}) | {t_lm / nfev * 1e3:.3f} ms | "
            f"{e_lm:.6f} | {t_ukf:.4f} s | {t_ukf / (args.sweeps * m) * 1e6:.2f} | "
            f"{t_vslm:.4f} s | {t_vslm / vnit * 1e3:.3f} | {t_ukf + t_vslm:.4f} s | {e_m9:.6f} |"
        )
    ms = [row[0] for row in rows]
    big = [i for i, m in enumerate(ms) if m >= 1000]
    series = {
        "LM, whole solve": [row[2] for row in rows],
        "LM, per evaluation (r + J + step)": [row[2] / row[4] for row in rows],
        "UKF stage (fixed T3)": [row[6] for row in rows],
        "VSLM stage (fixed T9)": [row[7] for row in rows],
        "M9 cascade (fixed T3 + T9)": [row[6] + row[7] for row in rows],
    }
    print("\n| quantity | exponent, all M | exponent, M ≥ 1 000 | complexity |")
    print("|---|---:|---:|---|")
    for name, t in series.items():
        a = slope(ms, t)
        b = slope([ms[i] for i in big], [t[i] for i in big]) if len(big) >= 2 else float("nan")
        complexity = "≈ linear, Θ(M)" if 0.85 <= b <= 1.15 else "sub-linear (fixed costs dominate)" if b < 0.85 else "super-linear"
        print(f"| {name} | {a:.2f} | {b:.2f} | {complexity} |")
    m9 = slope([ms[i] for i in big], [series["M9 cascade (fixed T3 + T9)"][i] for i in big]) if len(big) >= 2 else float("nan")
    ok = 0.85 <= m9 <= 1.15
    print(
        f"\n**Paper eq. (27), M9 = Θ((T3 + T9)·M), i.e. exponent 1 in M at fixed T3, T9: "
        f"{'CONSISTENT' if ok else 'NOT CONSISTENT'}** (fitted {m9:.2f} for M ≥ 1 000).\n"
    )


def part_params(args) -> None:
    import robocal
    from robocal import Robot
    from robocal.calibration.kalman import ukf
    from robocal.calibration.lm import levenberg_marquardt
    from robocal.calibration.problem import Problem
    from robocal.calibration.vslm import vslm

    hsr = robocal.robot("hsr-jr680")
    cases = [("3-joint (HSR JR680's first 3 links)", Robot.from_dh("hsr-3", hsr_rows()[:3]), None)]
    data6, _ = robocal.simulate(hsr, "cable", samples=args.param_samples, seed=1)
    full_free = [hsr.param_names[k] for k in Problem.build(hsr, data6).free]
    setup = [n for n in full_free if n.startswith(("anchor", "cable"))]
    kin = [n for n in full_free if n not in setup]
    for k in (4, 12):
        cases.append((f"6-joint HSR JR680, mask: set-up + first {k} kinematic", hsr, setup + kin[:k]))
    cases.append(("6-joint HSR JR680, default mask", hsr, None))
    cases.append(("7-joint (iiwa-like DH)", Robot.from_dh("iiwa-like-7", IIWA_LIKE), None))
    rows = []
    for label, r, mask in cases:
        data = data6 if r is hsr else robocal.simulate(r, "cable", samples=args.param_samples, seed=1)[0]
        problem = Problem.build(r, data, mask=mask)
        t_lm, res = best_of(lambda: levenberg_marquardt(problem), args.repeats)
        t_ukf, first = best_of(lambda: ukf(problem, sweeps=1), args.repeats)
        t_vslm, second = best_of(lambda: vslm(problem, x0=first.x, max_iter=args.vslm_iter, ftol=0.0, xtol=0.0), args.repeats)
        rows.append((label, r.n_joints, len(problem.free), t_lm, res.nit, res.nfev, t_ukf, t_vslm / second.nit))
        print(f"  {label}: n={len(problem.free)}", file=sys.stderr)

    m = args.param_samples
    print(f"## 2. Time against parameter count n (simulated cable, M = {m:,})\n")
    lm_columns = "LM time | LM iterations (nfev) | LM per evaluation"
    print(f"| robot / mask | joints | free params n | {lm_columns} | UKF sweep | µs per sample update | VSLM per iteration |")
    print("|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for label, j, n, t_lm, nit, nfev, t_ukf, t_it in rows:
        print(
            f"| {label} | {j} | {n} | {t_lm:.4f} s | {nit} ({nfev}) | {t_lm / nfev * 1e3:.3f} ms | "
            f"{t_ukf:.4f} s | {t_ukf / m * 1e6:.2f} | {t_it * 1e3:.3f} ms |"
        )
    ns = [row[2] for row in rows]
    print("\n| quantity | exponent in n | expected |")
    print("|---|---:|---|")
    print(
        f"| LM per evaluation | {slope(ns, [row[3] / row[5] for row in rows]):.2f} | J: M·n, JᵀJ: M·n², "
        "solve: n³ — 1 to 2 once those dominate; per-sample kinematics (joints, not n) and call overheads lower it |"
    )
    print(
        f"| UKF per sample update | {slope(ns, [row[6] for row in rows]):.2f} | 2n+1 sigma points × a kinematic chain, "
        "plus n×n covariance updates: between 1 and 2 (n³ Cholesky negligible at n ≤ 30) |"
    )
    print(f"| VSLM per iteration | {slope(ns, [row[7] for row in rows]):.2f} | as LM per evaluation |")
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, nargs="+", default=[100, 1_000, 10_000, 100_000])
    parser.add_argument("--param-samples", type=int, default=5_000)
    parser.add_argument("--sweeps", type=int, default=5, help="T3: UKF sweeps")
    parser.add_argument("--vslm-iter", type=int, default=20, help="T9: VSLM iterations")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--threads", type=int, default=None, help="rayon threads (default: all cores)")
    parser.add_argument("--quick", action="store_true", help="M up to 3000, 1000 samples for the parameter sweep")
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.quick:
            args.samples, args.param_samples, args.repeats = [100, 1000, 3000], 1000, 1
        if args.threads:
            os.environ["RAYON_NUM_THREADS"] = str(args.threads)
        for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
            os.environ[var] = "1"

        import numpy as np

        import robocal

        print("## Scaling\n")
        print(f"* machine: {cpu_model()}, {os.cpu_count()} cores; rayon threads: {args.threads or os.cpu_count()}; load average at start: {load_avg()}")
        print(f"* python {sys.version.split()[0]}, numpy {np.__version__}, robocal {robocal.__version__}")
        print(f"* command: `python benches/bench_scaling.py {' '.join(sys.argv[1:])}`".rstrip() + "\n")
        start = time.perf_counter()
        part_samples(args)
        part_params(args)
        print(f"total {time.perf_counter() - start:.1f} s; load average at end: {load_avg()}\n")


if __name__ == "__main__":
    main()
