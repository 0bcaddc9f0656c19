"""Side-by-side benchmark of the Rust core against its pure-NumPy twin (``robocal.reference``).

Both run in this one process on the same inputs (the HSR JR680 of the paper, cable model, the
paper's 31-parameter set); each figure is the median of repeated calls. Prints a Markdown table
with absolute times, throughput and the Rust/NumPy ratio, plus the machine. The QR row's baseline is
LAPACK through SciPy, what a competent user would call.

    python benches/bench_core.py                 # all cores (rayon default)
    python benches/bench_core.py --threads 1     # single-core figures
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time

from machine import cpu_model
from record import add_argument, recording


def median_time(fn, min_total: float = 1.0, max_repeats: int = 100) -> float:
    """Median wall time of ``fn()`` over repeats lasting about ``min_total`` seconds (at least 5)."""
    fn()
    times: list = []
    while (sum(times) < min_total or len(times) < 5) and len(times) < max_repeats:
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--threads", type=int, default=None, help="rayon threads (default: all cores)")
    parser.add_argument("--sizes", type=int, nargs="+", default=[100, 1_000, 10_000])
    add_argument(parser)
    args = parser.parse_args()
    with recording(args.record):
        if args.threads:
            os.environ["RAYON_NUM_THREADS"] = str(args.threads)  # read when the core starts its pool

        import numpy as np
        import scipy.linalg

        import robocal
        from robocal import kernels
        from robocal import reference as ref

        r = robocal.robot("hsr-jr680")
        conv, kinds = [j.convention for j in r.joints], [j.kind for j in r.joints]
        params = r.with_params(tool_x=20.0, tool_y=-15.0, tool_z=60.0, anchor_x=1500.0, anchor_y=300.0, anchor_z=-200.0, cable_offset=950.0).params
        # A calibrated robot: every DH parameter off nominal (no zero link parameter left to skip).
        dh = np.flatnonzero([n.rstrip("0123456789") in ("alpha", "a", "d", "theta") for n in r.param_names])
        params[dh] += np.random.default_rng(1).normal(0.0, 1e-3, dh.size)
        cols = np.flatnonzero(r.default_mask("cable"))
        col_list = cols.tolist()
        rng = np.random.default_rng(0)
        threads = args.threads or os.cpu_count()

        print(f"machine: {cpu_model()}, {os.cpu_count()} cores; rayon threads: {threads}")
        print(f"python {sys.version.split()[0]}, numpy {np.__version__}, robocal {robocal.__version__}")
        print(f"cable model, HSR JR680 with calibrated-like parameters, {len(cols)} parameters; medians of repeats\n")
        print("| kernel | m | Rust | NumPy twin | NumPy / Rust | Rust throughput |")
        print("|---|---:|---:|---:|---:|---:|")

        def row(name, m, rust, numpy, unit_count, unit):
            tr, tn = median_time(rust), median_time(numpy)
            print(f"| {name} | {m:,} | {tr * 1e3:.3f} ms | {tn * 1e3:.3f} ms | {tn / tr:.1f}x | {unit_count / tr:,.0f} {unit}/s |")

        for m in args.sizes:
            q = np.radians([5.0, -60.0, 200.0, -160.0, 40.0, 60.0]) + rng.uniform(-0.6, 0.6, size=(m, 6))
            y = r.chain.predict("cable", params, q)
            row("fk (tool frame)", m, lambda: r.chain.fk(params, q, True), lambda: ref.fk(conv, kinds, params, q, True), m, "poses")
            row(
                "cable Jacobian (31 cols)",
                m,
                lambda: r.chain.jacobian("cable", params, q, None, col_list),
                lambda: ref.jacobian(conv, kinds, "cable", params, q, None, cols),
                m,
                "rows",
            )
            n = len(cols)
            sigmas, _, _ = kernels.merwe_sigma_points(params[cols], np.eye(n) * 1e-4, 1e-3, 2.0, 0.0)
            row(
                f"sigma residuals ({2 * n + 1} points)",
                m,
                lambda: r.chain.sigma_residuals("cable", params, col_list, sigmas, q, y),
                lambda: ref.sigma_residuals(conv, kinds, "cable", params, cols, sigmas, q, y),
                m * (2 * n + 1),
                "poses",
            )
            for n_par in (24, 31, 60):
                J = rng.standard_normal((m, n_par))
                res = rng.standard_normal(m)
                if m >= n_par:
                    # The LM's factorisation of an ill-conditioned Jacobian: R and Qᵀr. Its baseline is
                    # LAPACK (geqrf + ormqr) through SciPy, not the NumPy twin.
                    row(
                        f"QR and Qᵀr (n={n_par}; vs SciPy qr_multiply)",
                        m,
                        lambda: kernels.factor_damped(J).project(res),
                        lambda: scipy.linalg.qr_multiply(J, res[None, :], mode="right"),
                        1,
                        "factorisations",
                    )
                row(
                    f"damped solve (n={n_par})",
                    m,
                    lambda: kernels.solve_damped(J, res, 1e-3),
                    lambda: ref.solve_damped(J, res, 1e-3),
                    1,
                    "solves",
                )


if __name__ == "__main__":
    main()
