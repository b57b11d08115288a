"""Leg-tip trajectories and joint trajectories (Brodoline et al. 2024, Methods and Fig. 7C).

The tip path of one leg, as a function of its leg phase ``phi`` (0 = touchdown):

* stance, ``0 <= phi < beta``: a straight line at ground height, from ``+L/2`` to ``-L/2`` along
  the forward axis at constant speed ``L / (beta T)`` (the body moves forward by one step);
* swing, ``beta <= phi < 1``: back to ``+L/2``, lifted by the step height ``h``. Each coordinate
  is a cubic spline in the swing fraction ``s = (phi - beta) / (1 - beta)`` with knots
  ``s = 0, 1/4, 1/2, 3/4, 1``: fixed values at ``0, 1/2, 1`` (``-L/2, 0, +L/2`` forward,
  ``0, h, 0`` up), first derivatives clamped to the stance velocity at both ends, and the two free
  knot values at ``1/4`` and ``3/4`` solved so that the second derivative is zero at both ends.
  Position, velocity and acceleration are therefore continuous at lift-off and touchdown.

Joint trajectories follow through the analytic inverse kinematics:
``q = IK(p)``, ``qd = J^-1 pd``, ``qdd = J^-1 (pdd - dJ/dt qd)``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.interpolate import CubicSpline

from .errors import InvalidGaitError
from .gait import GaitPattern, _times
from .kinematics import Branch, LegKinematics
from .legs import leg_side

__all__ = [
    'ANTBOT_NEUTRAL_TIP_M',
    'TipPath',
    'SwingSpline',
    'swing_splines',
    'tip_path',
    'default_forward_axis',
    'LegTrajectory',
]

# Stance midpoint of an AntBot leg in its base frame [m]: 140 mm out, 120 mm below the coxa.
# Every tip of a 100-140 mm step and a 40 mm lift stays well inside the reach [0.063, 0.229] m
# with the knee up.
ANTBOT_NEUTRAL_TIP_M: tuple[float, float, float] = (0.14, 0.0, -0.12)

_KNOTS = np.array([0.0, 0.25, 0.5, 0.75, 1.0])


def _c2_spline(y0: float, y2: float, y4: float, g0: float, g1: float) -> CubicSpline:
    """Cubic spline on ``_KNOTS`` with end slopes ``g0, g1`` and zero end curvature.

    The interior values at ``s = 1/4, 3/4`` are the unknowns; the spline is affine in them, so
    the two zero-curvature conditions are a 2x2 linear system.
    """

    def build(y1: float, y3: float) -> CubicSpline:
        return CubicSpline(_KNOTS, [y0, y1, y2, y3, y4], bc_type=((1, g0), (1, g1)))

    def ends(sp: CubicSpline) -> NDArray[np.float64]:
        return np.asarray(sp(np.array([0.0, 1.0]), 2), dtype=float)

    base = ends(build(0.0, 0.0))
    A = np.column_stack([ends(build(1.0, 0.0)) - base, ends(build(0.0, 1.0)) - base])
    y1, y3 = np.linalg.solve(A, -base)
    return build(float(y1), float(y3))


# The C2-clamped spline is linear in its data (y0, y2, y4, g0, g1): keep the polynomial
# coefficients of the five basis splines, shape (5, 4 powers, 4 intervals), and combine them,
# so that a new duty factor (every tick of a transition) costs no spline solve.
_BASIS_COEFFS = np.stack([_c2_spline(*row).c for row in np.eye(5)])


class SwingSpline:
    """Piecewise cubic on the swing fraction ``s`` in [0, 1] (callable like ``CubicSpline``).

    Parameters
    ----------
    y0, y2, y4 : float
        Values at ``s = 0, 1/2, 1``.
    g0, g1 : float
        Slopes at ``s = 0`` and ``s = 1``; the curvature is zero at both ends.
    """

    def __init__(self, y0: float, y2: float, y4: float, g0: float, g1: float) -> None:
        data = np.array([y0, y2, y4, g0, g1], dtype=float)
        self.c = np.tensordot(data, _BASIS_COEFFS, axes=1)  # (4 powers, 4 intervals)

    def __call__(self, s: ArrayLike, nu: int = 0) -> NDArray[np.float64]:
        """Value (``nu=0``), first or second derivative of the spline at ``s``, shape of ``s``."""
        x = np.asarray(s, dtype=float)
        i = np.clip(np.searchsorted(_KNOTS, x, side='right') - 1, 0, 3)
        h = x - _KNOTS[i]
        c3, c2, c1, c0 = self.c[0, i], self.c[1, i], self.c[2, i], self.c[3, i]
        if nu == 0:
            return ((c3 * h + c2) * h + c1) * h + c0
        if nu == 1:
            return (3.0 * c3 * h + 2.0 * c2) * h + c1
        if nu == 2:
            return 6.0 * c3 * h + 2.0 * c2
        raise InvalidGaitError(f'derivative order must be 0, 1 or 2, got {nu!r}')


_UP_SPLINE = SwingSpline(0.0, 1.0, 0.0, 0.0, 0.0)


@lru_cache(maxsize=1024)
def swing_splines(duty_factor: float) -> tuple[SwingSpline, SwingSpline]:
    """Unit swing splines for one duty factor.

    Returns
    -------
    forward : SwingSpline
        Forward coordinate per unit step length, from -1/2 to +1/2, in the swing fraction ``s``.
    up : SwingSpline
        Height per unit step height, 0 -> 1 -> 0.
    """
    beta = float(duty_factor)
    if not (0.0 < beta < 1.0):
        raise InvalidGaitError(f'duty_factor must be in (0, 1), got {duty_factor!r}')
    # Stance speed in d(forward)/d(phi) is -1/beta per unit step; in swing-fraction units the
    # slope is multiplied by d(phi)/ds = 1 - beta.
    g = -(1.0 - beta) / beta
    return SwingSpline(-0.5, 0.0, 0.5, g, g), _UP_SPLINE


@dataclass(frozen=True)
class TipPath:
    """Forward coordinate ``u`` and height ``z`` of a tip path and their phase derivatives.

    Every array has shape (n,); ``u`` and ``z`` in [m], ``du``/``dz`` in [m per unit phase],
    ``ddu``/``ddz`` in [m per unit phase^2].
    """

    u: NDArray[np.float64]
    du: NDArray[np.float64]
    ddu: NDArray[np.float64]
    z: NDArray[np.float64]
    dz: NDArray[np.float64]
    ddz: NDArray[np.float64]
    in_stance: NDArray[np.bool_]


def _basis(s: NDArray[np.float64], nu: int) -> NDArray[np.float64]:
    """Values (or derivatives) of the five basis swing splines at ``s``, shape (5,) + s.shape."""
    i = np.clip(np.searchsorted(_KNOTS, s, side='right') - 1, 0, 3)
    h = s - _KNOTS[i]
    c = _BASIS_COEFFS[:, :, i]  # (5, 4, ...)
    if nu == 0:
        return ((c[:, 0] * h + c[:, 1]) * h + c[:, 2]) * h + c[:, 3]
    if nu == 1:
        return (3.0 * c[:, 0] * h + 2.0 * c[:, 1]) * h + c[:, 2]
    return 6.0 * c[:, 0] * h + 2.0 * c[:, 1]


def tip_path(
    leg_phase: ArrayLike,
    *,
    duty_factor: ArrayLike,
    step_length_m: ArrayLike,
    step_height_m: ArrayLike,
    with_acceleration: bool = True,
) -> TipPath:
    """Tip path relative to the stance midpoint, as a function of the leg phase.

    Parameters
    ----------
    leg_phase : float or array, shape (n,) (or any shape)
        Leg phase in ``[0, 1)``, 0 = touchdown.
    duty_factor, step_length_m, step_height_m : float or array broadcastable to leg_phase
        ``beta``, ``L`` [m], ``h`` [m].
    with_acceleration : bool
        False skips the second derivatives (``ddu``, ``ddz`` are then zeros).

    Returns
    -------
    TipPath
        ``u`` along the forward axis (``+L/2`` at touchdown), ``z`` up (0 in stance); arrays of
        the broadcast shape (at least 1-D).
    """
    phi = np.atleast_1d(np.asarray(leg_phase, dtype=float))
    beta = np.asarray(duty_factor, dtype=float)
    if np.any(~((beta > 0.0) & (beta < 1.0))):
        raise InvalidGaitError(f'duty_factor must be in (0, 1), got {duty_factor!r}')
    L = np.asarray(step_length_m, dtype=float)
    h = np.asarray(step_height_m, dtype=float)
    phi, beta, L, h = np.broadcast_arrays(phi, beta, L, h)
    stance = phi < beta
    s = np.clip((phi - beta) / (1.0 - beta), 0.0, 1.0)
    k1 = 1.0 / (1.0 - beta)
    # unit forward spline = -1/2 B(y0) + 1/2 B(y4) + g (B(g0) + B(g1)), unit up spline = B(y2)
    g = -(1.0 - beta) / beta
    b0, b1 = _basis(s, 0), _basis(s, 1)

    def fwd(b: NDArray[np.float64]) -> NDArray[np.float64]:
        return -0.5 * b[0] + 0.5 * b[2] + g * (b[3] + b[4])

    u = np.where(stance, L * (0.5 - phi / beta), L * fwd(b0))
    du = np.where(stance, -L / beta, L * fwd(b1) * k1)
    z = np.where(stance, 0.0, h * b0[1])
    dz = np.where(stance, 0.0, h * b1[1] * k1)
    if with_acceleration:
        b2 = _basis(s, 2)
        ddu = np.where(stance, 0.0, L * fwd(b2) * k1 * k1)
        ddz = np.where(stance, 0.0, h * b2[1] * k1 * k1)
    else:
        ddu = ddz = np.zeros_like(u)
    return TipPath(u=u, du=du, ddu=ddu, z=z, dz=dz, ddz=ddz, in_stance=stance)


def default_forward_axis(leg: str) -> tuple[float, float, float]:
    """Body-forward direction in a leg base frame with x outward and z up (right-handed).

    Right legs: ``+y``; left legs: ``-y``.
    """
    return (0.0, 1.0, 0.0) if leg_side(leg) == 'right' else (0.0, -1.0, 0.0)


class LegTrajectory:
    """One leg following its gait's tip path in its leg base frame.

    Parameters
    ----------
    gait : GaitPattern
    leg_index : int
        Index into ``gait.leg_names``.
    kinematics : LegKinematics
    neutral_tip_m : (3,) float
        Stance midpoint in the leg base frame [m] (ground height is its z).
    forward_axis : (3,) float, optional
        Unit vector of the body's forward direction in the leg base frame; default from
        :func:`default_forward_axis`. The tip moves against it during stance.
    branch : {'knee_up', 'knee_down'}
        Inverse-kinematics branch.
    """

    def __init__(
        self,
        gait: GaitPattern,
        leg_index: int,
        *,
        kinematics: LegKinematics | None = None,
        neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M,
        forward_axis: ArrayLike | None = None,
        branch: Branch = 'knee_up',
    ) -> None:
        if not (0 <= int(leg_index) < gait.leg_count):
            raise InvalidGaitError(
                f'leg_index must be in [0, {gait.leg_count}), got {leg_index!r}'
            )
        self.gait = gait
        self.leg_index = int(leg_index)
        self.leg = gait.leg_names[self.leg_index]
        self.kinematics = kinematics if kinematics is not None else LegKinematics()
        self.neutral_tip_m = np.asarray(neutral_tip_m, dtype=float).reshape(3)
        axis = np.asarray(
            default_forward_axis(self.leg) if forward_axis is None else forward_axis, dtype=float
        ).reshape(3)
        norm = float(np.linalg.norm(axis))
        if norm == 0.0:
            raise InvalidGaitError('forward_axis must not be zero')
        self.forward_axis = axis / norm
        self.branch: Branch = branch

    def _path(self, t_s: ArrayLike) -> TipPath:
        phi = self.gait.leg_phase(t_s)[:, self.leg_index]
        return tip_path(
            phi,
            duty_factor=self.gait.duty_factor,
            step_length_m=self.gait.step_length_m,
            step_height_m=self.gait.step_height_m,
        )

    def _compose(self, u: NDArray[np.float64], z: NDArray[np.float64]) -> NDArray[np.float64]:
        return u[:, None] * self.forward_axis[None, :] + z[:, None] * np.array([0.0, 0.0, 1.0])

    def tip(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Tip position in the leg base frame, shape (n, 3) [m]."""
        path = self._path(t_s)
        return self.neutral_tip_m[None, :] + self._compose(path.u, path.z)

    def tip_velocity(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Tip velocity, shape (n, 3) [m/s]."""
        path = self._path(t_s)
        return self._compose(path.du, path.dz) / self.gait.period_s

    def tip_acceleration(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Tip acceleration, shape (n, 3) [m/s^2]."""
        path = self._path(t_s)
        return self._compose(path.ddu, path.ddz) / self.gait.period_s**2

    def in_stance(self, t_s: ArrayLike) -> NDArray[np.bool_]:
        """Stance flag of this leg, shape (n,)."""
        return self.gait.stance_mask(t_s)[:, self.leg_index]

    def joints(
        self, t_s: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Joint position [rad], velocity [rad/s], acceleration [rad/s^2], each shape (n, 3)."""
        t = _times(t_s)
        path = self._path(t)
        T = self.gait.period_s
        p = self.neutral_tip_m[None, :] + self._compose(path.u, path.z)
        v = self._compose(path.du, path.dz) / T
        a = self._compose(path.ddu, path.ddz) / T**2
        kin = self.kinematics
        q = kin.inverse(p, branch=self.branch)
        qd = kin.joint_velocity(q, v)
        qdd = kin.joint_acceleration(q, qd, a)
        return q, qd, qdd
