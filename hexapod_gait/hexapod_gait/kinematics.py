"""Kinematics of a 3-DOF coxa-femur-tibia leg from its DH table (DESIGN section 7).

Standard Denavit-Hartenberg convention, ``T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i)``, with
``theta_i = q_i + theta_offset_i``. The structure supported by the analytic inverse is the usual
insect leg: ``alpha = (pi/2, 0, 0)``, ``d_2 = d_3 = 0`` (``d_1`` is a vertical femur offset).
In the leg base frame (z up, x along the coxa at ``q_1 = 0``), with ``R`` the radial reach and
``Z`` the height of the tip:

    ``R = a1 + a2 cos(t2) + a3 cos(t2 + t3)``, ``Z = d1 + a2 sin(t2) + a3 sin(t2 + t3)``,
    ``p = (R cos(t1), R sin(t1), Z)``.

Inverse-kinematics branches: ``'knee_up'`` puts the femur-tibia joint above the line from the
femur joint to the tip (``t3 < 0``, the usual standing posture), ``'knee_down'`` below it
(``t3 > 0``). The coxa angle is ``atan2(y, x)`` (tip in front of the coxa axis, R > 0), or that
plus pi when only the coxa turned half a turn reaches the tip.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidGaitError, UnreachableError

__all__ = [
    'DHParameters',
    'ANTBOT_LEG',
    'ANTBOT_MASS_KG',
    'ANTBOT_BODY_KG',
    'UnreachableError',
    'LegKinematics',
    'default_robot_mass_kg',
    'dh_transform',
]

Branch = Literal['knee_up', 'knee_down']

# AX-18A: 300 degrees of travel, +-150 degrees around the centre.
_AX18_HALF_RANGE_RAD = math.radians(150.0)


@dataclass(frozen=True)
class DHParameters:
    """DH table of a 3-joint leg (all joints revolute).

    Parameters
    ----------
    a_m : tuple of 3 float
        Link lengths [m].
    alpha_rad : tuple of 3 float
        Link twists [rad].
    d_m : tuple of 3 float
        Link offsets [m].
    theta_offset_rad : tuple of 3 float
        DH angle at joint angle zero, ``theta_i = q_i + theta_offset_i`` [rad].
    link_masses_kg : tuple of 3 float
        Masses of coxa, femur, tibia [kg] (for dynamics; not used by kinematics).
    joint_limits_rad : tuple of 3 (lower, upper) pairs
        Joint-angle limits on ``q`` [rad].
    """

    a_m: tuple[float, float, float] = (0.053, 0.083, 0.146)
    alpha_rad: tuple[float, float, float] = (math.pi / 2, 0.0, 0.0)
    d_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    theta_offset_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)
    link_masses_kg: tuple[float, float, float] = (0.01498, 0.1118, 0.03923)
    joint_limits_rad: tuple[tuple[float, float], ...] = (
        (-_AX18_HALF_RANGE_RAD, _AX18_HALF_RANGE_RAD),
        (-_AX18_HALF_RANGE_RAD, _AX18_HALF_RANGE_RAD),
        (-_AX18_HALF_RANGE_RAD, _AX18_HALF_RANGE_RAD),
    )

    def __post_init__(self) -> None:
        for name in ('a_m', 'alpha_rad', 'd_m', 'theta_offset_rad', 'link_masses_kg'):
            value = tuple(float(x) for x in getattr(self, name))
            if len(value) != 3:
                raise InvalidGaitError(f'DHParameters.{name} needs 3 values, got {value}')
            object.__setattr__(self, name, value)
        limits = tuple((float(lo), float(hi)) for lo, hi in self.joint_limits_rad)
        if len(limits) != 3 or any(lo >= hi for lo, hi in limits):
            raise InvalidGaitError(
                f'DHParameters.joint_limits_rad needs 3 (lower < upper) pairs, got {limits}'
            )
        object.__setattr__(self, 'joint_limits_rad', limits)


ANTBOT_LEG = DHParameters()

#: AntBot's mass without payload [kg] (Brodoline et al.; DESIGN §7): the default robot of
#: the simulators and the analysis when a robot's mass is neither given nor declared
ANTBOT_MASS_KG = 2.183
#: AntBot's body without its six legs [kg]: 2.183 kg less 6 x 0.166 kg (DESIGN section 7)
ANTBOT_BODY_KG = ANTBOT_MASS_KG - 6 * sum(ANTBOT_LEG.link_masses_kg)


def default_robot_mass_kg(leg_count: int = 6, leg_mass_kg: float | None = None) -> float:
    """The robot assumed when no mass is given: AntBot's body with ``leg_count`` legs of
    ``leg_mass_kg`` each (payload excluded; None: AntBot's 0.166 kg leg). AntBot's leg gives
    2.183 kg on 6 legs, 1.851 kg on 4 and 2.515 kg on 8 (``M + (k - 6) m_leg``, the leg-count
    sweep's rule); a leg file's leg, ``M + (k - 6) m_AntBot + k (m_leg - m_AntBot)``:
    AntBot's 1.187 kg body plus the file's legs (a PhantomX-like 0.175 kg leg: 2.237 kg on 6
    legs). One rule for the simulators, ``energy_monitor`` and ``hexapod-analyze``."""
    leg_kg = sum(ANTBOT_LEG.link_masses_kg) if leg_mass_kg is None else float(leg_mass_kg)
    return ANTBOT_BODY_KG + leg_count * leg_kg


def dh_transform(theta: float, d: float, a: float, alpha: float) -> NDArray[np.float64]:
    """One standard DH transform ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``, shape (4, 4)."""
    ct, st = math.cos(theta), math.sin(theta)
    ca, sa = math.cos(alpha), math.sin(alpha)
    return np.array(
        [
            [ct, -st * ca, st * sa, a * ct],
            [st, ct * ca, -ct * sa, a * st],
            [0.0, sa, ca, d],
            [0.0, 0.0, 0.0, 1.0],
        ]
    )


def _as_q(q: ArrayLike) -> NDArray[np.float64]:
    arr = np.asarray(q, dtype=float)
    if arr.shape == (3,):
        return arr[None, :]
    if arr.ndim == 2 and arr.shape[1] == 3:
        return arr
    raise InvalidGaitError(f'joint angles must have shape (3,) or (n, 3), got {arr.shape}')


def _as_p(p: ArrayLike) -> NDArray[np.float64]:
    arr = np.asarray(p, dtype=float)
    if arr.shape == (3,):
        return arr[None, :]
    if arr.ndim == 2 and arr.shape[1] == 3:
        return arr
    raise InvalidGaitError(f'tip positions must have shape (3,) or (n, 3), got {arr.shape}')


class LegKinematics:
    """Forward/inverse kinematics and Jacobian of one 3-DOF leg.

    Parameters
    ----------
    dh : DHParameters
        DH table; must have ``alpha = (pi/2, 0, 0)`` and ``d_2 = d_3 = 0``.
    """

    def __init__(self, dh: DHParameters = ANTBOT_LEG) -> None:
        a1, a2, a3 = dh.a_m
        if not np.allclose(dh.alpha_rad, (math.pi / 2, 0.0, 0.0), atol=1e-12):
            raise InvalidGaitError(
                f'analytic leg kinematics need alpha = (pi/2, 0, 0), got {dh.alpha_rad}'
            )
        if dh.d_m[1] != 0.0 or dh.d_m[2] != 0.0:
            raise InvalidGaitError(f'analytic leg kinematics need d2 = d3 = 0, got {dh.d_m}')
        if a2 <= 0.0 or a3 <= 0.0:
            raise InvalidGaitError(f'femur and tibia lengths must be > 0, got {dh.a_m}')
        self.dh = dh
        self._a = (a1, a2, a3)
        self._d1 = dh.d_m[0]
        self._off = np.asarray(dh.theta_offset_rad, dtype=float)
        self.lower_rad = np.array([lo for lo, _ in dh.joint_limits_rad])
        self.upper_rad = np.array([hi for _, hi in dh.joint_limits_rad])

    # ----------------------------------------------------------------- reach
    @property
    def reach_m(self) -> tuple[float, float]:
        """Smallest and largest distance from the femur joint to the tip [m]."""
        _, a2, a3 = self._a
        return abs(a2 - a3), a2 + a3

    def within_limits(self, q: ArrayLike, *, tol_rad: float = 1e-12) -> NDArray[np.bool_]:
        """True for each joint vector inside the joint limits, shape (n,)."""
        qq = _as_q(q)
        return np.all(
            (qq >= self.lower_rad - tol_rad) & (qq <= self.upper_rad + tol_rad), axis=1
        )

    # ----------------------------------------------------------------- forward
    def _planar(self, q: NDArray[np.float64]) -> tuple[NDArray[np.float64], ...]:
        th = q + self._off
        a1, a2, a3 = self._a
        t1, t2, t23 = th[:, 0], th[:, 1], th[:, 1] + th[:, 2]
        c1, s1 = np.cos(t1), np.sin(t1)
        c2, s2 = np.cos(t2), np.sin(t2)
        c23, s23 = np.cos(t23), np.sin(t23)
        R = a1 + a2 * c2 + a3 * c23
        Z = self._d1 + a2 * s2 + a3 * s23
        return c1, s1, c2, s2, c23, s23, R, Z

    def forward(self, q: ArrayLike) -> NDArray[np.float64]:
        """Tip position in the leg base frame.

        Parameters
        ----------
        q : array, shape (3,) or (n, 3)
            Joint angles (coxa, femur, tibia) [rad].

        Returns
        -------
        ndarray, shape (n, 3)
            Tip position [m].
        """
        c1, s1, _, _, _, _, R, Z = self._planar(_as_q(q))
        return np.stack([c1 * R, s1 * R, Z], axis=1)

    def jacobian(self, q: ArrayLike) -> NDArray[np.float64]:
        """Tip Jacobian ``dp/dq``, shape (3, 3) for q of shape (3,), else (n, 3, 3) [m/rad]."""
        qq = _as_q(q)
        c1, s1, c2, s2, c23, s23, R, _ = self._planar(qq)
        _, a2, a3 = self._a
        dR2 = -a2 * s2 - a3 * s23
        dR3 = -a3 * s23
        dZ2 = a2 * c2 + a3 * c23
        dZ3 = a3 * c23
        J = np.zeros((qq.shape[0], 3, 3))
        J[:, 0, 0] = -s1 * R
        J[:, 0, 1] = c1 * dR2
        J[:, 0, 2] = c1 * dR3
        J[:, 1, 0] = c1 * R
        J[:, 1, 1] = s1 * dR2
        J[:, 1, 2] = s1 * dR3
        J[:, 2, 1] = dZ2
        J[:, 2, 2] = dZ3
        return J[0] if np.ndim(q) == 1 else J

    def tip_velocity(self, q: ArrayLike, qd: ArrayLike) -> NDArray[np.float64]:
        """``J(q) qd``, shape (n, 3) [m/s]."""
        J = self.jacobian(_as_q(q)).reshape(-1, 3, 3)
        return np.einsum('nij,nj->ni', J, _as_q(qd))

    def bias_acceleration(self, q: ArrayLike, qd: ArrayLike) -> NDArray[np.float64]:
        """``dJ/dt qd``: tip acceleration at zero joint acceleration, shape (n, 3) [m/s^2]."""
        qq, v = _as_q(q), _as_q(qd)
        c1, s1, c2, s2, c23, s23, R, _ = self._planar(qq)
        _, a2, a3 = self._a
        w1, w2, w23 = v[:, 0], v[:, 1], v[:, 1] + v[:, 2]
        Rd = -a2 * s2 * w2 - a3 * s23 * w23
        Rdd = -a2 * c2 * w2**2 - a3 * c23 * w23**2
        Zdd = -a2 * s2 * w2**2 - a3 * s23 * w23**2
        xdd = -c1 * w1**2 * R - 2.0 * s1 * w1 * Rd + c1 * Rdd
        ydd = -s1 * w1**2 * R + 2.0 * c1 * w1 * Rd + s1 * Rdd
        return np.stack([xdd, ydd, Zdd], axis=1)

    def frames(self, q: ArrayLike) -> list[NDArray[np.float64]]:
        """Homogeneous transforms of the DH frames 0..3 in the leg base frame.

        Parameters
        ----------
        q : array, shape (3,)

        Returns
        -------
        list of 4 ndarrays, shape (4, 4)
            ``[I, T_01, T_02, T_03]``; frame ``i`` is attached to the end of link ``i``, so the
            origin of ``T_03`` is the tip and joint ``i+1`` turns about the z axis of frame ``i``.
        """
        qq = np.asarray(q, dtype=float)
        if qq.shape != (3,):
            raise InvalidGaitError(f'frames() needs q of shape (3,), got {qq.shape}')
        th = qq + self._off
        out = [np.eye(4)]
        for i in range(3):
            out.append(
                out[-1]
                @ dh_transform(th[i], self.dh.d_m[i], self.dh.a_m[i], self.dh.alpha_rad[i])
            )
        return out

    # ----------------------------------------------------------------- inverse
    def inverse(
        self,
        p: ArrayLike,
        *,
        branch: Branch = 'knee_up',
        check_limits: bool = True,
    ) -> NDArray[np.float64]:
        """Joint angles that put the tip at ``p`` (analytic).

        Parameters
        ----------
        p : array, shape (3,) or (n, 3)
            Tip positions in the leg base frame [m].
        branch : {'knee_up', 'knee_down'}
            Elbow branch (see the module docstring).
        check_limits : bool
            Raise if a solution lies outside the joint limits.

        Returns
        -------
        ndarray, shape (n, 3)
            Joint angles [rad], coxa in ``(-pi, pi]``.

        Raises
        ------
        UnreachableError
            Naming the first bad target, its distance from the femur joint and the reach.
        """
        if branch not in ('knee_up', 'knee_down'):
            raise InvalidGaitError(f"branch must be 'knee_up' or 'knee_down', got {branch!r}")
        pp = _as_p(p)
        a1, a2, a3 = self._a
        x, y, z = pp[:, 0], pp[:, 1], pp[:, 2] - self._d1
        t1 = np.arctan2(y, x)
        r = np.hypot(x, y) - a1
        dist2 = r * r + z * z
        D = (dist2 - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
        # A tip behind the coxa axis may be reachable only with the coxa turned half a turn
        # (femur pointing backwards over the coxa): use that solution when the usual one fails.
        r_back = -np.hypot(x, y) - a1
        D_back = (r_back * r_back + z * z - a2 * a2 - a3 * a3) / (2.0 * a2 * a3)
        back = ~(np.abs(D) <= 1.0 + 1e-12) & (np.abs(D_back) <= 1.0 + 1e-12)
        if np.any(back):
            t1 = np.where(back, t1 + np.pi, t1)
            r = np.where(back, r_back, r)
            D = np.where(back, D_back, D)
            dist2 = np.where(back, r_back * r_back + z * z, dist2)
        lo, hi = self.reach_m
        bad = ~(np.abs(D) <= 1.0 + 1e-12) | ~np.isfinite(D)
        if np.any(bad):
            i = int(np.flatnonzero(bad)[0])
            raise UnreachableError(
                f'tip target {tuple(round(float(v), 6) for v in pp[i])} m is out of reach: '
                f'{math.sqrt(float(dist2[i])):.6g} m from the femur joint, reach is '
                f'[{lo:.6g}, {hi:.6g}] m'
            )
        D = np.clip(D, -1.0, 1.0)
        # sin(t3) from sqrt(1 - D^2) computed as sqrt((1-D)(1+D)) keeps precision near |D| = 1
        s3 = np.sqrt((1.0 - D) * (1.0 + D))
        if branch == 'knee_up':
            s3 = -s3
        t3 = np.arctan2(s3, D)
        t2 = np.arctan2(z, r) - np.arctan2(a3 * s3, a2 + a3 * D)
        th = np.stack([t1, t2, t3], axis=1)
        q = th - self._off
        q = (q + np.pi) % (2.0 * np.pi) - np.pi
        q = np.where(q <= -np.pi, q + 2.0 * np.pi, q)
        if check_limits:
            ok = self.within_limits(q, tol_rad=1e-9)
            if not np.all(ok):
                i = int(np.flatnonzero(~ok)[0])
                raise UnreachableError(
                    f'tip target {tuple(round(float(v), 6) for v in pp[i])} m needs joint '
                    f'angles {tuple(round(float(v), 6) for v in q[i])} rad ({branch}) outside '
                    f'the joint limits {self.dh.joint_limits_rad}'
                )
        return q

    def joint_velocity(self, q: ArrayLike, tip_velocity: ArrayLike) -> NDArray[np.float64]:
        """``qd = J(q)^-1 pd``, shape (n, 3) [rad/s]."""
        J = self.jacobian(_as_q(q)).reshape(-1, 3, 3)
        return np.linalg.solve(J, _as_p(tip_velocity)[..., None])[..., 0]

    def joint_acceleration(
        self, q: ArrayLike, qd: ArrayLike, tip_acceleration: ArrayLike
    ) -> NDArray[np.float64]:
        """``qdd = J^-1 (pdd - dJ/dt qd)``, shape (n, 3) [rad/s^2]."""
        J = self.jacobian(_as_q(q)).reshape(-1, 3, 3)
        rhs = _as_p(tip_acceleration) - self.bias_acceleration(q, qd)
        return np.linalg.solve(J, rhs[..., None])[..., 0]
