"""Shared test helpers: the pure-NumPy twin, random robots, observations and a comparison that
reports where and by how much two arrays differ."""

from __future__ import annotations

import importlib
import sys
import types
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from hypothesis import strategies as st


def _load_reference():
    """The twin from this checkout's ``python/robocal/reference.py`` with the pure-NumPy
    ``geometry.py`` beside it, loaded from their files as a package of their own: importing the
    ``robocal`` package needs the compiled core (and an installed copy may be stale). Falls back
    to ``robocal.reference`` without a checkout."""
    folder = Path(__file__).resolve().parents[1] / "python" / "robocal"
    if not (folder / "reference.py").exists():
        from robocal import reference

        return reference
    package = types.ModuleType("robocal_twin")
    package.__path__ = [str(folder)]  # submodules from the checkout; robocal/__init__.py never runs
    sys.modules.setdefault("robocal_twin", package)
    return importlib.import_module("robocal_twin.reference")


ref = _load_reference()

MEASUREMENTS = ("cable", "position", "pose")


@dataclass
class Case:
    """A random robot (chain and parameters) with a batch of joint vectors."""

    conventions: list
    kinds: list
    params: np.ndarray
    q: np.ndarray
    rng: np.random.Generator

    @property
    def n(self) -> int:
        return len(self.conventions)

    @property
    def chain(self) -> tuple:
        return self.conventions, self.kinds


def random_params(rng: np.random.Generator, n: int, nominal: bool = False) -> np.ndarray:
    """Realistic parameters: link lengths up to 1 m, any angles, small Hayati beta, a base up to
    2 m away, a tool up to 0.3 m, a cable anchor within 3 m. ``nominal``: beta = 0 and no base or
    tool, as on a robot's data sheet."""
    joints = np.column_stack(
        [
            rng.uniform(-np.pi, np.pi, n),  # alpha
            rng.choice([-1, 1], n) * rng.uniform(0, 1000, n),  # a
            rng.choice([-1, 1], n) * rng.uniform(0, 1000, n),  # d
            rng.uniform(-np.pi, np.pi, n),  # theta
            np.zeros(n) if nominal else rng.uniform(-0.05, 0.05, n),  # beta
        ]
    )
    base = np.concatenate([rng.uniform(-2000, 2000, 3), rng.uniform(-np.pi, np.pi, 3)])
    tool = np.concatenate([rng.uniform(-300, 300, 3), rng.uniform(-np.pi, np.pi, 3)])
    if nominal:
        base[:], tool[:] = 0.0, 0.0
    sensor = np.concatenate([rng.uniform(-3000, 3000, 3), [rng.uniform(0, 500), rng.uniform(0.98, 1.02)]])
    return np.concatenate([joints.ravel(), base, tool, sensor])


def random_q(rng: np.random.Generator, kinds, m: int) -> np.ndarray:
    prismatic = np.array([k == "prismatic" for k in kinds])
    return np.where(prismatic, rng.uniform(-500, 500, (m, len(kinds))), rng.uniform(-np.pi, np.pi, (m, len(kinds))))


@st.composite
def cases(draw, max_joints: int = 7, max_samples: int = 6, conventions=("dh", "mdh"), nominal=None) -> Case:
    """Random robots: 1..max_joints joints of mixed conventions and kinds, 1..max_samples configs."""
    n = draw(st.integers(1, max_joints))
    convs = draw(st.lists(st.sampled_from(conventions), min_size=n, max_size=n))
    kinds = draw(st.lists(st.sampled_from(["revolute", "revolute", "prismatic"]), min_size=n, max_size=n))
    m = draw(st.integers(1, max_samples))
    is_nominal = draw(st.booleans()) if nominal is None else nominal
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    params = random_params(rng, n, is_nominal)
    return Case(convs, kinds, params, random_q(rng, kinds, m), rng)


def observations(case: Case, measurement: str, position_noise: float = 1.0, max_angle: float = 0.3) -> np.ndarray:
    """Observations near the model's predictions: positions within ``position_noise`` mm (cable
    lengths likewise), orientations rotated by up to ``max_angle`` rad; pose quaternions get a
    random sign (q and -q are the same rotation)."""
    rng = case.rng
    h = ref.predict(*case.chain, measurement, case.params, case.q)
    m = h.shape[0]
    if measurement != "pose":
        return h + rng.normal(0, position_noise, h.shape)
    axis = rng.normal(size=(m, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    phi = axis * rng.uniform(0, max_angle, (m, 1))
    R = ref.so3_exp(phi) @ ref.matrix_from_quaternion(h[:, 3:])
    quat = ref.quaternion_from_matrix(R) * rng.choice([-1.0, 1.0], (m, 1))
    return np.column_stack([h[:, :3] + rng.normal(0, position_noise, (m, 3)), quat])


def assert_close(got, want, rtol: float = 1e-10, per_column: bool = False, what: str = "") -> None:
    """``|got - want| <= rtol * scale`` elementwise, ``scale = max(1, max|want|)`` over the whole
    array (or over each column). The failure message gives the worst entry and both values."""
    got, want = np.atleast_1d(np.asarray(got, dtype=float)), np.atleast_1d(np.asarray(want, dtype=float))
    assert got.shape == want.shape, f"{what}: shape {got.shape} != expected {want.shape}"
    if want.size == 0:
        return
    if per_column:
        scale = np.maximum(1.0, np.abs(want).max(axis=0, keepdims=True))
    else:
        scale = np.full_like(want, max(1.0, np.abs(want).max()))
    scale = np.broadcast_to(scale, want.shape)
    excess = np.abs(got - want) - rtol * scale
    excess[np.isnan(excess)] = np.inf
    worst = np.unravel_index(np.argmax(excess), excess.shape)
    assert excess[worst] <= 0.0, (
        f"{what}: at index {tuple(int(i) for i in worst)} got {got[worst]!r}, expected {want[worst]!r} "
        f"(|diff| = {abs(got[worst] - want[worst]):.3e} > {rtol:.0e} x scale {scale[worst]:.3e})"
    )


def assert_jacobian_close(got, want, measurement: str, rtol: float = 1e-10, what: str = "") -> None:
    """Jacobians (m·k, n): position and rotation rows compared apart, each column on its scale."""
    k = ref.MEASUREMENTS[measurement][1]
    assert got.shape == want.shape, f"{what}: shape {got.shape} != expected {want.shape}"
    shape = (want.shape[0] // k, k, want.shape[1])
    g, w = got.reshape(shape), want.reshape(shape)
    flat = lambda a: a.reshape(a.shape[0] * a.shape[1], a.shape[2])  # noqa: E731
    for rows, name in ((slice(0, min(k, 3)), "position rows"), (slice(3, k), "rotation rows")):
        assert_close(flat(g[:, rows]), flat(w[:, rows]), rtol, per_column=True, what=f"{what} {name}")


def random_spd(rng: np.random.Generator, n: int, scales=None) -> np.ndarray:
    """A random symmetric positive definite matrix (condition number ~ 10-100 before scaling)."""
    A = rng.normal(size=(n, n))
    P = A @ A.T + n * np.eye(n)
    if scales is not None:
        P = P * np.outer(scales, scales)
    return (P + P.T) / 2


def three_joint_robot(conventions, kinds, beta: bool = True, name: str = "custom"):
    """A 3-joint robot off every default: skew links, base and tool frames, Hayati ``beta`` on
    joints 2 and 3 unless ``beta`` is False; revolute limits ±3 rad, prismatic 0–400 mm."""
    from robocal.serial_robot import Joint, Robot

    limits = {"revolute": (-3.0, 3.0), "prismatic": (0.0, 400.0)}
    params = np.zeros(5 * 3 + 17)
    params[:15] = [0.3, 120.0, 400.0, 0.2, 0.0, -1.2, 35.0, 80.0, 0.1, 0.01 * beta, 0.4, 20.0, 60.0, -0.3, 0.02 * beta]
    params[15:27] = [10.0, -5.0, 3.0, 0.01, -0.02, 0.3, 1.0, 2.0, 90.0, 0.1, 0.2, -0.3]
    params[-1] = 1.0
    return Robot(name, [Joint(c, k, False, limits[k]) for c, k in zip(conventions, kinds)], params)


def with_sensor_error(data, amplitude: float, period: float):
    """``data`` whose sensor errs by ``amplitude`` (mm), periodically in what it reads with
    ``period`` (mm): a drawstring's error along its length, or a tracker's across its field (each
    axis periodic in another one, so no rigid frame absorbs it)."""
    from dataclasses import replace

    y = data.y.copy()
    if data.measurement == "cable":
        y[:, 0] += amplitude * np.sin(2.0 * np.pi * y[:, 0] / period)
    else:
        y[:, :3] += amplitude * np.sin(2.0 * np.pi * data.y[:, [1, 2, 0]] / period)
    return replace(data, y=y)
