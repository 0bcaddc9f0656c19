"""The robot type: a serial chain, its nominal parameter vector, joint limits, its masses and
the masks of what a calibration estimates.

The bottom of the model layer: it knows no file format. Robots are read and written by the
formats above it (:mod:`robocal.robot_file`, :mod:`robocal.robot_table`, :mod:`robocal.urdf`,
:mod:`robocal.rtb`), which :func:`robocal.robot.robot` dispatches to.

Units inside are mm and radians; degrees appear only where a table is read or written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterable, Optional, Sequence

import numpy as np

from . import _robocal
from .kernels import MAX_ABS, as_float, as_float_array, as_str, identifiability
from .exceptions import InvalidParameterError, NonFiniteError, ShapeError
from .geometry import frame_params, frame_transform, rotation

MEASUREMENTS = ("cable", "position", "pose")

#: Residual rows per sample: the cable length; x, y, z; x, y, z and the rotation vector.
RESIDUAL_WIDTH = {"cable": 1, "position": 3, "pose": 6}


def setup_names(robot: "Robot", measurement: str) -> list[str]:
    """The set-up a new session places anew: the tracker's base frame and the tool point
    (position; pose adds the tool's orientation), the cable's anchor and zero (cable: the hook
    on the tool stays)."""
    if measurement == "cable":
        names = ["anchor_x", "anchor_y", "anchor_z", "cable_offset"]
    else:
        names = [f"base_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")] + ["tool_x", "tool_y", "tool_z"]
        if measurement == "pose":
            names += ["tool_rx", "tool_ry", "tool_rz"]
    return [n for n in names if n in robot.param_names]


def zero_names(robot: "Robot") -> list[str]:
    """Each joint's zero offset, the parameter a re-mastering moves: ``theta{j}`` of a revolute
    joint, ``d{j}`` of a prismatic one (1-based)."""
    return [f"theta{j}" if joint.kind == "revolute" else f"d{j}" for j, joint in enumerate(robot.joints, start=1)]


def _chain(joints: Sequence["Joint"]):
    """The core's compiled chain of ``joints`` (their conventions and kinds are all it holds)."""
    return _robocal.Chain([j.convention for j in joints], [j.kind for j in joints])


@dataclass(frozen=True)
class Joint:
    """One joint of a serial chain.

    Attributes
    ----------
    convention : {"dh", "mdh"}
        Standard DH (the paper's eq. 1) or modified DH (Craig).
    kind : {"revolute", "prismatic"}
        Whether the joint variable adds to ``theta`` (rad) or to ``d`` (mm).
    hayati : bool
        The link's axes are nominally parallel: calibration estimates Hayati's ``beta`` and holds
        ``d`` fixed (``d`` is ill-conditioned there).
    limits : tuple of float
        Joint range ``(lower, upper)`` in rad (mm for prismatic joints).
    """

    convention: str = "dh"
    kind: str = "revolute"
    hayati: bool = False
    limits: tuple[float, float] = (-math.pi, math.pi)


@dataclass(frozen=True)
class MassModel:
    """The masses of a robot's links for gravity torques.

    Attributes
    ----------
    link_masses : tuple of float
        Mass of link j (moved by joint j) in kg, one per joint.
    rated_payload : float
        The robot's rated payload in kg (for reference; the effect's payload defaults to 0).
    compliance : float or None
        Default joint compliance in rad/(N·m) (the simulator's ``joint_compliance`` default);
        None: none known, the effect must be given one.
    centres_of_mass : tuple or None
        Per link, its centre of mass ``(x, y, z)`` in mm in the link's own DH frame j, or None:
        lumped at the midpoint of DH frame origins ``o_{j-1}`` and ``o_j`` (the default for
        every link when the tuple is None).
    """

    link_masses: tuple
    rated_payload: float = 0.0
    compliance: Optional[float] = None
    centres_of_mass: Optional[tuple] = None

    def __post_init__(self):  # plain tuples of floats, so that equal models compare equal
        masses = tuple(float(m) for m in self.link_masses)
        centres = self.centres_of_mass
        if centres is not None:
            if len(centres) != len(masses):
                raise InvalidParameterError(f"centres_of_mass has {len(centres)} entries; expected one per link ({len(masses)})")
            centres = tuple(None if c is None else tuple(float(v) for v in c) for c in centres)
            if any(c is not None and len(c) != 3 for c in centres):
                raise InvalidParameterError(f"each centre of mass must be (x, y, z) in mm or None; got {self.centres_of_mass!r}")
        object.__setattr__(self, "link_masses", masses)
        object.__setattr__(self, "centres_of_mass", centres)


class Robot:
    """A serial robot: joints, nominal parameters (mm, rad) and its compiled chain.

    Parameters
    ----------
    name : str
    joints : sequence of Joint
    params : array_like, shape (5N + 17,)
        Nominal parameter vector in the order of :attr:`param_names`.
    mass_model : MassModel, optional
        The robot's own masses and centres of mass (a robot file's ``masses``), one link per
        joint; :func:`robocal.physics.mass_model` prefers it to the built-in model of the name.

    Examples
    --------
    >>> import numpy as np, robocal
    >>> r = robocal.robot("hsr-jr680")
    >>> T = r.fkine(np.zeros((1, 6)))
    >>> T.shape
    (1, 4, 4)
    """

    def __init__(self, name: str, joints: Sequence[Joint], params: np.ndarray, mass_model: Optional["MassModel"] = None):
        self.name = name
        self.joints = tuple(joints)
        if not self.joints:
            raise ShapeError(f"robot {name!r} needs at least one joint; got none")
        for i, joint in enumerate(self.joints, start=1):
            as_str(joint.convention, f"joint {i} convention"), as_str(joint.kind, f"joint {i} kind")  # their values: checked by the core
            limits = as_float_array(joint.limits, f"joint {i} limits")
            if limits.shape != (2,) or not (np.all(np.isfinite(limits)) and limits[0] < limits[1]):
                raise InvalidParameterError(f"joint {i} limits must be finite (lower, upper) with lower < upper; got {joint.limits!r}")
        self.chain = _chain(self.joints)
        self.param_names: list[str] = self.chain.param_names()
        self.param_units: list[str] = self.chain.param_units()
        self.params = self._check_params(params, "params")
        if mass_model is not None and len(mass_model.link_masses) != self.n_joints:
            raise ShapeError(f"robot {name!r}: the mass model has {len(mass_model.link_masses)} links; expected one per joint ({self.n_joints})")
        self.mass_model = mass_model

    # -- construction -------------------------------------------------------------------------
    @classmethod
    def from_dh(
        cls,
        name: str,
        rows: Iterable[Sequence],
        convention: str = "dh",
        degrees: bool = True,
    ) -> "Robot":
        """Builds a robot from rows ``(alpha, a, d, theta[, (lower, upper)[, hayati[, kind]]])``.

        Angles are in degrees when ``degrees`` (the way DH tables are published), lengths in mm;
        ``kind`` is ``"revolute"`` (default) or ``"prismatic"``, whose limits are in mm.
        """
        to_rad = math.radians if degrees else float
        joints, values = [], []
        for i, row in enumerate(rows, start=1):
            if isinstance(row, (str, bytes)) or not isinstance(row, Sequence) or len(row) < 4:
                raise ShapeError(f"DH row {i} must hold at least (alpha, a, d, theta); got {row!r}")
            alpha, a, d, theta = (as_float(v, f"DH row {i} {key}") for key, v in zip(("alpha", "a", "d", "theta"), row))
            kind = row[6] if len(row) > 6 else "revolute"
            limits = as_float_array(row[4], f"DH row {i} limits") if len(row) > 4 else np.array([-180.0, 180.0] if degrees else [-math.pi, math.pi])
            limits = tuple((np.radians(limits) if degrees and kind == "revolute" else limits).tolist())  # its shape is checked by Robot()
            hayati = bool(row[5]) if len(row) > 5 else False
            joints.append(Joint(convention=convention, kind=kind, limits=limits, hayati=hayati))
            values.append((to_rad(alpha), a, d, to_rad(theta), 0.0))
        params = np.zeros(5 * len(joints) + 17)
        params[: 5 * len(joints)] = np.ravel(values)
        params[-1] = 1.0  # cable_scale
        return cls(name, joints, params)

    # -- the vector ---------------------------------------------------------------------------
    @property
    def n_joints(self) -> int:
        return len(self.joints)

    @property
    def prismatic(self) -> tuple[int, ...]:
        """Indices (0-based) of the prismatic joints, whose values are mm rather than angles."""
        return tuple(j for j, joint in enumerate(self.joints) if joint.kind == "prismatic")

    @property
    def n_params(self) -> int:
        return len(self.param_names)

    def index(self, name: str) -> int:
        """Position of parameter ``name`` in the vector."""
        try:
            return self.param_names.index(name)
        except ValueError:
            raise InvalidParameterError(f"unknown parameter {name!r}; robot {self.name!r} has {self.param_names}") from None

    def with_params(self, **values: float) -> "Robot":
        """A copy with some parameters replaced (by name, in mm / rad)."""
        params = self.params.copy()
        for name, value in values.items():
            params[self.index(name)] = as_float(value, name)
        return self.with_vector(params)

    def with_vector(self, params) -> "Robot":
        """A copy with the parameter vector ``params`` (:attr:`param_names`' order; a fit's)."""
        return Robot(self.name, self.joints, params, self.mass_model)

    def _check_params(self, params, arg: str) -> np.ndarray:
        p = as_float_array(params, arg)
        if p.shape != (self.n_params,):
            raise ShapeError(f"`{arg}` must have shape ({self.n_params},); got {p.shape}")
        if (np.abs(p) <= MAX_ABS).all():  # the common case in one pass (NaN fails the test too)
            return p
        bad = np.flatnonzero(~np.isfinite(p))
        if bad.size:
            raise NonFiniteError(f"`{arg}` must be finite; got {p[bad[0]]} at index {bad[0]} ({self.param_names[bad[0]]})")
        huge = np.flatnonzero(np.abs(p) > MAX_ABS)
        if huge.size:  # the core would refuse it by index only
            k = huge[0]
            raise InvalidParameterError(f"{self.param_names[k]} must lie within ±{MAX_ABS:.0e} {self.param_units[k]}; got {p[k]:.4g} (`{arg}` index {k})")
        return p

    def columns(self, selection, arg: str = "mask") -> np.ndarray:
        """Parameter indices of ``selection``: a boolean mask of length :attr:`n_params`, integer
        indices or parameter names; an error naming ``arg`` otherwise."""
        try:
            c = np.asarray(selection)
        except ValueError:  # ragged nesting
            c = np.asarray(selection, dtype=object)
        if c.ndim != 1:
            raise ShapeError(f"`{arg}` must be a 1-D mask, index list or list of names; got {selection!r}")
        if c.dtype.kind == "b":
            if c.shape != (self.n_params,):
                raise ShapeError(f"`{arg}` as a boolean mask must have shape ({self.n_params},); got {c.shape}")
            return np.flatnonzero(c)
        if c.dtype.kind in "US":
            return np.array([self.index(str(name)) for name in c], dtype=np.int64)
        if c.size and c.dtype.kind not in "iu":
            raise InvalidParameterError(f"`{arg}` must hold booleans, integer indices or parameter names; got dtype {c.dtype}")
        return c.astype(np.int64)  # the range is checked by the core

    def default_mask(self, measurement: str) -> np.ndarray:
        """Parameters a calibration with ``measurement`` data estimates by default.

        Every DH parameter (``beta`` instead of ``d`` on Hayati joints), and what the measurement
        needs: ``cable`` the tool point, anchor and sensor zero; ``position`` the base frame and
        tool point; ``pose`` the base and tool frames. The identifiable subset of this set is
        decided from the data (``robocal.identifiability``).
        """
        if measurement not in MEASUREMENTS:
            raise InvalidParameterError(f"`measurement` must be one of {MEASUREMENTS}; got {measurement!r}")
        mask = np.zeros(self.n_params, dtype=bool)
        for j, joint in enumerate(self.joints, start=1):
            for p in ("alpha", "a", "theta"):
                mask[self.index(f"{p}{j}")] = True
            mask[self.index(f"beta{j}" if joint.hayati else f"d{j}")] = True
        tool = ["tool_x", "tool_y", "tool_z"]
        extra = {
            "cable": tool + ["anchor_x", "anchor_y", "anchor_z", "cable_offset"],
            "position": tool + [f"base_{c}" for c in ("x", "y", "z", "rx", "ry", "rz")],
            "pose": tool + [f"{f}_{c}" for f in ("base", "tool") for c in ("x", "y", "z", "rx", "ry", "rz")],
        }[measurement]
        for name in extra:
            mask[self.index(name)] = True
        return mask

    # -- kinematics ---------------------------------------------------------------------------
    def _joints_array(self, q) -> np.ndarray:
        qa = as_float_array(q, "q")
        if qa.ndim == 1:
            qa = qa[None, :]
        if qa.ndim != 2 or qa.shape[1] != self.n_joints:
            raise ShapeError(f"`q` must have shape (m, {self.n_joints}); got {np.shape(q)}")
        return np.ascontiguousarray(qa)

    def fkine(self, q, params=None, tool: bool = False) -> np.ndarray:
        """Forward kinematics.

        Parameters
        ----------
        q : array_like, shape (m, N) or (N,)
            Joint values in rad (mm for prismatic joints).
        params : array_like, shape (5N + 17,), optional
            Parameter vector; the nominal one by default.
        tool : bool
            Pose of the tool frame instead of the flange.

        Returns
        -------
        ndarray, shape (m, 4, 4)
            Homogeneous transforms in the base frame, translations in mm.
        """
        p = self.params if params is None else self._check_params(params, "params")
        return self.chain.fk(p, self._joints_array(q), tool)

    def _measurement_inputs(self, measurement: str, q, y, params):
        if measurement not in MEASUREMENTS:
            raise InvalidParameterError(f"`measurement` must be one of {MEASUREMENTS}; got {measurement!r}")
        p = self.params if params is None else self._check_params(params, "params")
        qa = self._joints_array(q)
        if y is None:
            return p, qa, None
        ya = as_float_array(y, "y")
        if ya.ndim == 1 and measurement == "cable":
            ya = ya[:, None]
        return p, qa, np.ascontiguousarray(ya)

    def predict(self, measurement: str, q, params=None) -> np.ndarray:
        """Model prediction ``h`` per sample, shape (m, 1 | 3 | 7) for cable | position | pose."""
        p, qa, _ = self._measurement_inputs(measurement, q, None, params)
        return self.chain.predict(measurement, p, qa)

    def residuals(self, measurement: str, q, y, params=None) -> np.ndarray:
        """Residuals ``y − h``, shape (m, 1 | 3 | 6) (pose: position then rotation vector)."""
        p, qa, ya = self._measurement_inputs(measurement, q, y, params)
        return self.chain.residuals(measurement, p, qa, ya)

    def residuals_at(self, measurement: str, q, y, cols, values, params=None) -> np.ndarray:
        """Residuals for many parameter sets in one call: ``params[cols] = values[s]`` for each row
        ``s`` of ``values`` (S, len(cols)); shape (S, m·k). Population methods evaluate with it."""
        p, qa, ya = self._measurement_inputs(measurement, q, y, params)
        vals = np.ascontiguousarray(as_float_array(values, "values"))
        return self.chain.sigma_residuals(measurement, p, [int(c) for c in cols], vals, qa, ya)

    def identifiability(self, measurement: str, J, cols, tol: float = 1e-9) -> dict:
        """:func:`robocal.kernels.identifiability` of ``J``, the Jacobian of ``measurement``
        residuals in the parameters ``cols`` (indices, J's columns in order), with the set-up a
        session places anew (:func:`setup_names`) kept first where it and the robot's own
        parameters explain the same: ``tool_x``/``tool_y`` rather than ``theta6``, ``base_rz``
        rather than ``theta1``. A redundant robot parameter then stays at its nominal value, and
        what a start's set-up error does is absorbed by the set-up, not by an implausible link
        parameter. Indices in the result are positions in ``cols``."""
        setup = {self.index(name) for name in setup_names(self, measurement)}
        return identifiability(J, tol, first=[int(c) in setup for c in cols])

    def jacobian(self, measurement: str, q, y=None, params=None, cols=None) -> np.ndarray:
        """Identification Jacobian ``∂h/∂params[cols]``, shape (m·k, len(cols)), rows sample-major.

        ``cols`` is an index list or boolean mask over the parameter vector (default: all).
        ``y`` is needed for ``pose`` only.
        """
        p, qa, ya = self._measurement_inputs(measurement, q, y, params)
        return self.chain.jacobian(measurement, p, qa, ya, None if cols is None else self.columns(cols, "cols").tolist())

    def residuals_and_jacobian(self, measurement: str, q, y, params=None, cols=None) -> tuple[np.ndarray, np.ndarray]:
        """:meth:`residuals` and :meth:`jacobian` at the same parameters from one pass over the
        samples (the residuals bit for bit :meth:`residuals`'): a Gauss–Newton step needs both,
        and the Jacobian's forward kinematics already gives the residuals' tool frames."""
        p, qa, ya = self._measurement_inputs(measurement, q, y, params)
        return self.chain.residuals_and_jacobian(measurement, p, qa, ya, None if cols is None else self.columns(cols, "cols").tolist())

    def to_mdh(self) -> "Robot":
        """The same robot in modified DH, with identical tool-frame kinematics.

        Standard DH regroups as ``Rz Tz · [Tx Rx Ry · Rz Tz] · … · Tx Rx Ry``: joint i of the MDH
        chain takes ``alpha, a, beta`` of DH link i-1, and the last link's ``Tx(a_N) Rx(alpha_N)
        Ry(beta_N)`` moves into the tool frame. The flange frame therefore differs; the tool frame
        does not.
        """
        if any(j.convention != "dh" for j in self.joints):
            raise InvalidParameterError("to_mdh converts a chain whose joints are all standard DH")
        n = self.n_joints
        dh = self.params[: 5 * n].reshape(n, 5)  # alpha, a, d, theta, beta
        mdh = dh.copy()
        mdh[0, [0, 1, 4]] = 0.0
        mdh[1:, [0, 1, 4]] = dh[:-1, [0, 1, 4]]
        alpha_n, a_n, _, _, beta_n = dh[-1]
        last = np.eye(4)  # Tx(a_N) · Rx(alpha_N) · Ry(beta_N)
        last[:3, :3] = rotation(0, alpha_n) @ rotation(1, beta_n)
        last[0, 3] = a_n
        tool = frame_params(last @ frame_transform(self.params[self.index("tool_x") : self.index("tool_x") + 6]))
        params = self.params.copy()
        params[: 5 * n] = mdh.ravel()
        params[self.index("tool_x") : self.index("tool_x") + 6] = tool
        joints = [Joint("mdh", j.kind, j.hayati, j.limits) for j in self.joints]
        return Robot(self.name, joints, params)  # no mass model: its centres of mass are in the DH frames

    def __repr__(self) -> str:
        return f"Robot({self.name!r}, {self.n_joints} joints, {self.n_params} parameters)"

    # -- pickling (process pools, copy.deepcopy) ----------------------------------------------
    def __getstate__(self) -> dict:
        # The compiled chain cannot be pickled; it is made of the joints alone and rebuilt from them.
        state = self.__dict__.copy()
        del state["chain"]
        return state

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        self.chain = _chain(self.joints)
