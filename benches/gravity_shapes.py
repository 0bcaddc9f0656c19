"""How much of a gravity deflection made by other masses robocal's compliance shape can follow
(issue 51): the groundwork for a compliance on the static gravity regressor.

    python benches/gravity_shapes.py [--files N] [--seed S]

For each robot and the first ``--files`` seeds, the mismatch simulator (``benches/mismatch.py``)
draws point masses placed otherwise than robocal's mass model (15-85 % along each link, up to
60 mm off it, ±30 % in mass, a payload of 10-50 % of the rated one) and computes the true gravity
torque of joints 2 and 3 along its path. Printed, per joint: the share of that torque's variation
(relative RMS of the least-squares leftover) that

- ``model``: robocal's compliance column leaves (the torque of its mass model);
- ``+payload``: that column and the torque of one kilogram at the tool point leave;
- ``regressor``: the static gravity regressor leaves — per link beyond the joint a mass at its
  frame's origin and three first moments along its frame's axes, the base parameters of static
  gravity (rank printed): any mass distribution and payload lies in its span.

A deflection ``c·τ`` whose shape the candidate leaves by a share ``s`` at ``k`` times its detection
limit leaves about ``s·k`` times the limit unexplained: what breeds the small false causes beside
a true compliance in the mismatch section.
"""

from __future__ import annotations

import argparse

import mismatch
import numpy as np
import robocal
from robocal.physics import gravity_torques, link_transforms
from robocal.simulation import setup

GRAVITY = np.array([0.0, 0.0, -9.80665])


def regressor(robot: robocal.Robot, q: np.ndarray, joint: int) -> np.ndarray:
    """The static gravity regressor of ``joint`` (0-based) on the nominal geometry, (m, 4·(N − joint)):
    per link beyond it, N·m per kg at its frame's origin and per kg·m along each of its frame's axes."""
    T = link_transforms(robot, q)
    origins, z = T[:, :, :3, 3] / 1000.0, T[:, :, :3, 2]
    columns = []
    for link in range(joint + 1, robot.n_joints + 1):
        columns.append(np.einsum("mk,mk->m", z[:, joint], np.cross(origins[:, link] - origins[:, joint], GRAVITY)))
        columns += [np.einsum("mk,mk->m", z[:, joint], np.cross(T[:, link, :3, a], GRAVITY)) for a in range(3)]
    return np.column_stack(columns)


def leftover(columns: np.ndarray, tau: np.ndarray) -> float:
    """Relative RMS of what the least-squares fit of ``columns`` and a constant (a joint's zero,
    which the geometry takes) leaves of ``tau``'s variation."""
    columns = np.column_stack([np.ones(len(tau)), columns])
    c, *_ = np.linalg.lstsq(columns, tau, rcond=None)
    return float(np.linalg.norm(tau - columns @ c) / np.linalg.norm(tau - tau.mean()))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--files", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    print("| robot | file | joint | model | +payload | regressor (rank) |\n|---|---|---|---|---|---|")
    for name in ("hsr-jr680", "abb-irb120", "ur10"):
        nominal = setup(robocal.robot(name), "position")
        for seed in range(args.files):
            acq = mismatch.acquisition(name, "position", 300, seed)
            keys = mismatch.draw("gravity", acq, rng)
            tau = mismatch.gravity_torques(acq, acq.q, np.array(keys["masses"]), np.array(keys["places"]), keys["payload"])
            model = gravity_torques(nominal, acq.q)
            per_kg = gravity_torques(nominal, acq.q, payload=1.0) - model
            for j in (1, 2):
                Y = regressor(nominal, acq.q, j)
                s = np.linalg.svd(Y, compute_uv=False)
                rank = int(np.sum(s > s[0] * 1e-8))
                shares = [leftover(model[:, j : j + 1], tau[:, j]), leftover(np.column_stack([model[:, j], per_kg[:, j]]), tau[:, j]), leftover(Y, tau[:, j])]
                print(f"| {name} | {seed} | {j + 1} | {shares[0]:.3f} | {shares[1]:.3f} | {shares[2]:.1e} ({rank} of {Y.shape[1]}) |")


if __name__ == "__main__":
    main()
