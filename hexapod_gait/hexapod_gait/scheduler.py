"""Gait scheduler: a running gait whose parameters can change while walking (core of the node).

Phase continuity. The scheduler integrates the cycle phase ``c(t) = c(t_s) + int f(tau) dtau``
(``f = 1/T``), so the cycle phase never jumps. A change of gait starts a transition of duration
``D = transition_cycles * max(T_old, T_new)``: every parameter (step frequency, duty factor, step
length, step height, each leg's phase offset along the shorter way round the circle, and the
Buehler sweep and offset) moves from its value at the switch to the new value with the C2
smoothstep ``w(s) = 10 s^3 - 15 s^4 + 6 s^5``, ``s = (t - t_s) / D``. The tip position (and the
Buehler hip angle) is a continuous function of the leg phase and of these parameters, so the
commanded joints never jump: this is the paper's continuous duty-factor adjustment and gait
switching. The frequency ramp has the closed-form integral
``int_0^s w = 5/2 s^4 - 3 s^5 + s^6``.

Static support during a transition. When both end points keep a leg on the ground on each side
(the rule of :func:`hexapod_gait.config.check_static_support`), every schedule in between must
too: ramping the phase offsets and the duty factor together can lift a whole side (4 legs,
alternating 0.5 to wave 0.75: a side in the air 0.44 s at ``transition_cycles`` 1, 1.7 s at 4).
:meth:`GaitScheduler.set_gait` checks the schedule of the whole ramp (:func:`side_support_ok`,
exact per side, densely sampled); if it loses a side, the transition is staged: the duty
factor rises first with the old offsets (more stance never loses support), the offsets move at
that duty factor (the smallest from ``max(beta_old, beta_new)`` up that keeps both sides
supported, capped so that the swing is not shorter than ``limits.min_swing_s``), then the duty
factor falls to the new value with the new offsets. Each stage lasts ``transition_cycles``
periods of the slower gait; frequency, step length and step height ramp over the whole staged
transition. If no staged path keeps both sides supported, the change is refused
(:class:`~hexapod_gait.errors.InfeasibleGaitError`, nothing changes). A Buehler clock, or a
change whose end points already lift a side, ramps as before.

A change requested during a transition starts a new transition from the parameters of that
instant. The leg count and the kind of legs (3-DOF pattern or Buehler clock) cannot change.
``transition_cycles`` is at least :data:`MIN_TRANSITION_CYCLES`, so that a change cannot jump
the joints faster than the servos follow.

Standing: a 3-DOF pattern with step length and step height 0 does not move the tips; its state
then has every leg in stance (``supporting_legs`` = every leg), whatever the cycle phase.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .buehler import BuehlerClock, buehler_angle
from .errors import InfeasibleGaitError, InvalidGaitError
from .feasibility import ActuatorLimits
from .gait import GaitPattern, _wrap01
from .kinematics import Branch, LegKinematics
from .legs import all_joint_names
from .step_limits import check_feasible_for_step
from .trajectory import ANTBOT_NEUTRAL_TIP_M, default_forward_axis, tip_path

__all__ = ['MIN_TRANSITION_CYCLES', 'GaitState', 'GaitScheduler', 'side_support_ok',
           'smoothstep']

_TWO_PI = 2.0 * np.pi
# Time step of the central differences used for velocities during a transition [s].
_FD_STEP_S = 1e-5
#: Shortest transition, in periods of the slower gait: below it a gait change (e.g. tripod to
#: wave) commands joint steps faster than an AX-18A follows.
MIN_TRANSITION_CYCLES = 0.5
# Samples of a transition's schedule per stage when checking its static support.
_SUPPORT_SAMPLES = 600
# Steps of the duty factor at which a staged transition moves the offsets.
_BETA_HI_STEP = 0.01
# A touchdown closer than this (in cycle phase) after a lift-off counts as simultaneous: equal
# on paper, they differ in the last bits (``theta + beta - 1`` against an offset like 1/6).
_EDGE = 1e-9


def smoothstep(s: ArrayLike) -> NDArray[np.float64]:
    """C2 ramp ``10 s^3 - 15 s^4 + 6 s^5`` of ``s`` clipped to [0, 1]."""
    x = np.clip(np.asarray(s, dtype=float), 0.0, 1.0)
    return x * x * x * (10.0 + x * (-15.0 + 6.0 * x))


def _ramp01(s: NDArray[np.float64], a: float, b: float) -> NDArray[np.float64]:
    """Smoothstep from 0 at ``s = a`` to 1 at ``s = b`` (a step at ``b`` if ``a == b``)."""
    if b <= a:
        return (s >= b).astype(float)
    return smoothstep((s - a) / (b - a))


def side_support_ok(theta: ArrayLike, beta: ArrayLike,
                    sides: Sequence[str]) -> NDArray[np.bool_]:
    """Whether each schedule keeps at least one leg in stance on each side over a whole cycle.

    Parameters
    ----------
    theta : (S, legs) float
        Phase offsets of S schedules (leg phase ``c - theta``, stance while it is < beta).
    beta : (S,) float
        Their duty factors.
    sides : sequence of str, length legs
        Side label of each leg (e.g. ``'L'``/``'R'``).

    Exact up to :data:`_EDGE`: the number of legs in stance on a side only drops at a lift-off,
    so its minimum over the cycle is found just after one of the lift-offs.
    """
    th = np.atleast_2d(np.asarray(theta, dtype=float))
    b = np.broadcast_to(np.asarray(beta, dtype=float), th.shape[:1])
    x = np.mod(th + b[:, None], 1.0) + _EDGE                      # just after each lift-off
    ph = np.mod(x[:, :, None] - th[:, None, :], 1.0)             # (S, lift-offs, legs)
    stance = ph < b[:, None, None]
    ok = np.ones(th.shape[0], dtype=bool)
    labels = np.asarray(list(sides))
    for side in sorted(set(labels.tolist())):
        idx = np.flatnonzero(labels == side)
        ok &= stance[:, :, idx].sum(axis=-1).min(axis=-1) >= 1
    return ok


def _smoothstep_integral(s: NDArray[np.float64]) -> NDArray[np.float64]:
    x = np.clip(s, 0.0, 1.0)
    return x**4 * (2.5 + x * (-3.0 + x))


@dataclass(frozen=True)
class GaitState:
    """Schedule at one instant.

    Attributes
    ----------
    t_s : float
        Time [s].
    cycle_phase : float
        In ``[0, 1)``.
    leg_phase : ndarray, shape (legs,)
        In ``[0, 1)``, 0 = touchdown.
    in_stance : ndarray of bool, shape (legs,)
    supporting_legs : int
        ``L(t)``.
    gait : GaitPattern
        The pattern in force at ``t_s`` (during a transition: the intermediate parameters, with
        the target's name).
    transition : float
        Progress of the current transition in [0, 1]; 1 when settled.
    clock : BuehlerClock or None
        The Buehler clock in force, for RHex-class legs.
    """

    t_s: float
    cycle_phase: float
    leg_phase: NDArray[np.float64]
    in_stance: NDArray[np.bool_]
    supporting_legs: int
    gait: GaitPattern
    transition: float
    clock: BuehlerClock | None = None


@dataclass(frozen=True)
class _Params:
    """Parameters that ramp during a transition."""

    freq_hz: float
    beta: float
    step_length_m: float
    step_height_m: float
    theta: NDArray[np.float64]
    sweep_rad: float
    offset_rad: float


@dataclass(frozen=True)
class _Plan:
    """How the duty factor and the offsets move over a transition's progress ``s`` in [0, 1].

    Not staged: both with the smoothstep of ``s``. Staged: the duty factor rises to ``beta_hi``
    over ``[0, s1]``, the offsets move over ``[s1, s2]``, the duty factor falls over ``[s2, 1]``.
    ``half_up``: an offset half a cycle from its target moves up (+0.5), not down (-0.5).
    """

    staged: bool = False
    s1: float = 0.0
    s2: float = 1.0
    beta_hi: float = 0.0
    stages: int = 1
    half_up: bool = False


class GaitScheduler:
    """A running gait with phase-continuous changes.

    Parameters
    ----------
    gait : GaitPattern or BuehlerClock
        Initial gait. A :class:`BuehlerClock` drives one hip joint per leg (``<leg>_hip``);
        a :class:`GaitPattern` drives 3-DOF legs through :mod:`hexapod_gait.trajectory`.
    t0_s : float
        Time at which the cycle phase is 0 [s].
    leg_count : int
        Number of legs for a Buehler clock (ignored for a pattern).
    kinematics : LegKinematics, optional
        Leg kinematics of 3-DOF legs (default: AntBot).
    neutral_tip_m : (3,) float
        Stance midpoint of every leg in its base frame [m].
    branch : {'knee_up', 'knee_down'}
    transition_cycles : float
        Transition duration in periods of the slower of the two gaits,
        >= :data:`MIN_TRANSITION_CYCLES`.
    limits : ActuatorLimits, optional
        If given, :meth:`set_gait` (and the constructor) refuse infeasible patterns (the
        limits of the bench step, scaled to the pattern's step:
        :func:`hexapod_gait.step_limits.check_feasible_for_step`).
    """

    def __init__(
        self,
        gait: GaitPattern | BuehlerClock,
        t0_s: float = 0.0,
        *,
        leg_count: int = 6,
        kinematics: LegKinematics | None = None,
        neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M,
        branch: Branch = 'knee_up',
        transition_cycles: float = 1.0,
        limits: ActuatorLimits | None = None,
    ) -> None:
        self.limits = limits
        self.transition_cycles = transition_cycles
        self.is_buehler = isinstance(gait, BuehlerClock)
        pattern = gait.as_pattern(leg_count) if isinstance(gait, BuehlerClock) else gait
        if limits is not None and not self.is_buehler:
            check_feasible_for_step(pattern, limits, kinematics=kinematics,
                                    neutral_tip_m=neutral_tip_m)
        self.leg_names = pattern.leg_names
        self.joint_names = all_joint_names(self.leg_names, 1 if self.is_buehler else 3)
        self.kinematics = kinematics if kinematics is not None else LegKinematics()
        self.neutral_tip_m = np.asarray(neutral_tip_m, dtype=float).reshape(3)
        self.branch: Branch = branch
        self._forward = np.array([default_forward_axis(leg) for leg in self.leg_names])
        self._target = gait
        self._target_pattern = pattern
        params = self._params_of(gait, pattern)
        self._p0 = params
        self._p1 = params
        self._t_switch = float(t0_s)
        self._c_switch = 0.0
        self._duration_s = self.transition_cycles / params.freq_hz
        self._plan = _Plan()
        self._changed = False  # no transition yet: settled at every time

    @property
    def transition_cycles(self) -> float:
        """Transition duration in periods of the slower gait (>= MIN_TRANSITION_CYCLES)."""
        return self._transition_cycles

    @transition_cycles.setter
    def transition_cycles(self, value: float) -> None:
        if not float(value) >= MIN_TRANSITION_CYCLES:
            raise InvalidGaitError(
                f'transition_cycles must be >= {MIN_TRANSITION_CYCLES:g} (shorter changes jump '
                f'the joints faster than the servos follow), got {value!r}')
        self._transition_cycles = float(value)

    # ----------------------------------------------------------------- parameters
    @staticmethod
    def _params_of(gait: GaitPattern | BuehlerClock, pattern: GaitPattern) -> _Params:
        sweep = gait.sweep_angle_rad if isinstance(gait, BuehlerClock) else 0.0
        offset = gait.leg_offset_rad if isinstance(gait, BuehlerClock) else 0.0
        return _Params(
            freq_hz=1.0 / pattern.period_s,
            beta=pattern.duty_factor,
            step_length_m=pattern.step_length_m,
            step_height_m=pattern.step_height_m,
            theta=np.asarray(pattern.phase_offsets, dtype=float),
            sweep_rad=sweep,
            offset_rad=offset,
        )

    @property
    def target(self) -> GaitPattern | BuehlerClock:
        """The gait requested last (reached at the end of the transition)."""
        return self._target

    @property
    def last_change_s(self) -> float:
        """Time of the last :meth:`set_gait` (or ``t0_s``) [s]."""
        return self._t_switch

    @property
    def transition_end_s(self) -> float:
        """Time at which the current transition ends [s]."""
        return self._t_switch + self._duration_s

    def _progress(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        if not self._changed:
            return np.ones_like(t)
        return np.clip((t - self._t_switch) / self._duration_s, 0.0, 1.0)

    def _ramp(self, t: NDArray[np.float64]) -> dict[str, NDArray[np.float64]]:
        """Parameters at times ``t`` (n,): scalars as (n,), ``theta`` as (n, legs)."""
        return self._ramp_at(self._progress(t), self._p0, self._p1, self._plan)

    @staticmethod
    def _ramp_at(s: NDArray[np.float64], p0: _Params, p1: _Params,
                 plan: _Plan) -> dict[str, NDArray[np.float64]]:
        """Parameters at transition progress ``s`` (n,) from ``p0`` to ``p1`` along ``plan``."""
        w = smoothstep(s)
        out = {
            name: getattr(p0, name) + (getattr(p1, name) - getattr(p0, name)) * w
            for name in ('freq_hz', 'beta', 'step_length_m', 'step_height_m', 'sweep_rad',
                         'offset_rad')
        }
        d = np.mod(p1.theta - p0.theta + 0.5, 1.0) - 0.5     # the shorter way round
        if plan.half_up:
            d = np.where(np.abs(d + 0.5) < _EDGE, d + 1.0, d)
        w_theta = w
        if plan.staged:
            w_theta = _ramp01(s, plan.s1, plan.s2)
            up = p0.beta + (plan.beta_hi - p0.beta) * _ramp01(s, 0.0, plan.s1)
            down = plan.beta_hi + (p1.beta - plan.beta_hi) * _ramp01(s, plan.s2, 1.0)
            out['beta'] = np.where(s < plan.s1, up, np.where(s < plan.s2, plan.beta_hi, down))
        out['theta'] = p0.theta[None, :] + d[None, :] * w_theta[:, None]
        return out

    # ----------------------------------------------------------------- static support
    def _supported(self, p: _Params) -> bool:
        """End point rule: standing, or a leg in stance on each side all cycle."""
        if p.step_length_m == 0.0 and p.step_height_m == 0.0:
            return True
        sides = [name[0] for name in self.leg_names]
        return bool(side_support_ok(p.theta[None, :], np.array([p.beta]), sides)[0])

    def _path_supported(self, p0: _Params, p1: _Params, plan: _Plan) -> bool:
        """Every schedule of the transition (sampled densely, exact per side) keeps a leg in
        stance on each side, or stands (step length and height 0)."""
        n = _SUPPORT_SAMPLES * plan.stages
        s = np.unique(np.concatenate([np.linspace(0.0, 1.0, n + 1), [plan.s1, plan.s2]]))
        r = self._ramp_at(s, p0, p1, plan)
        standing = (r['step_length_m'] == 0.0) & (r['step_height_m'] == 0.0)
        sides = [name[0] for name in self.leg_names]
        return bool(np.all(standing | side_support_ok(r['theta'], r['beta'], sides)))

    def _plan_transition(self, p0: _Params, p1: _Params, target: GaitPattern) -> _Plan:
        """The plain ramp if it keeps both sides supported (or the rule does not apply), else
        the first staged plan that does; raises InfeasibleGaitError if none does."""
        if self.is_buehler or not (self._supported(p0) and self._supported(p1)):
            return _Plan()
        for half_up in (False, True):
            if self._path_supported(p0, p1, _Plan(half_up=half_up)):
                return _Plan(half_up=half_up)
        limits = self.limits if self.limits is not None else ActuatorLimits()
        t_min = 1.0 / max(p0.freq_hz, p1.freq_hz)
        lo = max(p0.beta, p1.beta)
        cap = max(lo, 1.0 - limits.min_swing_s / t_min)
        for beta_hi in np.append(np.arange(lo, cap, _BETA_HI_STEP), cap):
            beta_hi = float(beta_hi)
            rise, fall = beta_hi > p0.beta, beta_hi > p1.beta
            stages = 1 + int(rise) + int(fall)
            s1 = 1.0 / stages if rise else 0.0
            s2 = 1.0 - (1.0 / stages if fall else 0.0)
            for half_up in (False, True):
                plan = _Plan(staged=True, s1=s1, s2=s2, beta_hi=beta_hi, stages=stages,
                             half_up=half_up)
                if self._path_supported(p0, p1, plan):
                    return plan
        raise InfeasibleGaitError(
            f'the transition to {target.name!r} at duty factor {p1.beta:.4g} would lift every '
            'leg of one side at once on the way (phase offsets and duty factor ramped '
            f'together), and no staged transition (duty factor raised to at most {cap:.3g} '
            f'while the offsets move, swing >= {limits.min_swing_s:g} s) keeps a leg on the '
            'ground on each side: the robot would fall over; change through an intermediate '
            'gait')

    def _cycles(self, t: NDArray[np.float64]) -> NDArray[np.float64]:
        """Unwrapped cycle count ``c(t)``, shape (n,)."""
        dt = t - self._t_switch
        f0, f1, D = self._p0.freq_hz, self._p1.freq_hz, self._duration_s
        s = np.clip(dt / D, 0.0, 1.0)
        extra = D * _smoothstep_integral(s) + np.maximum(dt - D, 0.0)
        return self._c_switch + f0 * dt + (f1 - f0) * extra

    def _pattern_at(self, t: float) -> tuple[GaitPattern, BuehlerClock | None]:
        if float(self._progress(np.array([t]))[0]) >= 1.0:
            clock = self._target if isinstance(self._target, BuehlerClock) else None
            return self._target_pattern, clock
        r = {k: v[0] for k, v in self._ramp(np.array([t])).items()}
        pattern = self._target_pattern.with_changes(
            phase_offsets=tuple(_wrap01(r['theta'])),
            duty_factor=float(r['beta']),
            period_s=1.0 / float(r['freq_hz']),
            step_length_m=float(r['step_length_m']),
            step_height_m=float(r['step_height_m']),
        )
        clock = None
        if isinstance(self._target, BuehlerClock):
            clock = BuehlerClock(
                period_s=pattern.period_s,
                duty_factor=pattern.duty_factor,
                sweep_angle_rad=float(r['sweep_rad']),
                leg_offset_rad=float(r['offset_rad']),
                kp_norm=self._target.kp_norm,
                kd_norm=self._target.kd_norm,
            )
        return pattern, clock

    # ----------------------------------------------------------------- public API
    def set_gait(self, new_gait: GaitPattern | BuehlerClock, t_s: float) -> None:
        """Start a phase-continuous transition to ``new_gait`` at time ``t_s``.

        Raises
        ------
        InvalidGaitError
            If the legs or the kind of gait differ, or ``t_s`` is before the last change.
        InfeasibleGaitError
            If ``limits`` were given and the new pattern violates them, or both end points keep
            a leg on the ground on each side but no transition between them does (see the
            module docstring); nothing changes.
        """
        t_s = float(t_s)
        if t_s < self._t_switch:
            raise InvalidGaitError(
                f'set_gait time {t_s!r} s is before the last change at {self._t_switch!r} s'
            )
        if isinstance(new_gait, BuehlerClock) != self.is_buehler:
            raise InvalidGaitError(
                'cannot switch between a Buehler clock (1 hip joint per leg) and a 3-DOF gait '
                'pattern while running'
            )
        pattern = (
            new_gait.as_pattern(len(self.leg_names))
            if isinstance(new_gait, BuehlerClock) else new_gait
        )
        if pattern.leg_names != self.leg_names:
            raise InvalidGaitError(
                f'new gait legs {pattern.leg_names} differ from the running legs '
                f'{self.leg_names}; the leg count cannot change while walking'
            )
        if self.limits is not None and not self.is_buehler:
            check_feasible_for_step(pattern, self.limits, kinematics=self.kinematics,
                                    neutral_tip_m=self.neutral_tip_m)
        t = np.array([t_s])
        r = {k: v[0] for k, v in self._ramp(t).items()}
        c_now = float(self._cycles(t)[0])
        p0 = _Params(
            freq_hz=float(r['freq_hz']),
            beta=float(r['beta']),
            step_length_m=float(r['step_length_m']),
            step_height_m=float(r['step_height_m']),
            theta=np.asarray(r['theta'], dtype=float),
            sweep_rad=float(r['sweep_rad']),
            offset_rad=float(r['offset_rad']),
        )
        p1 = self._params_of(new_gait, pattern)
        plan = self._plan_transition(p0, p1, pattern)   # raises before anything changes
        self._p0, self._p1, self._plan = p0, p1, plan
        self._c_switch = c_now
        self._t_switch = t_s
        self._duration_s = plan.stages * self.transition_cycles / min(p0.freq_hz, p1.freq_hz)
        self._target = new_gait
        self._target_pattern = pattern
        self._changed = True

    def leg_phases(self, t_s: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Cycle phase (n,) and leg phases (n, legs) at times ``t_s``, both in [0, 1)."""
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        c = self._cycles(t)
        theta = self._ramp(t)['theta']
        return _wrap01(c), _wrap01(c[:, None] - theta)

    def state(self, t_s: float) -> GaitState:
        """Schedule at time ``t_s`` [s]."""
        t = float(t_s)
        cycle, phi = self.leg_phases(t)
        pattern, clock = self._pattern_at(t)
        in_stance = phi[0] < pattern.duty_factor
        if not self.is_buehler and pattern.step_length_m == 0.0 and pattern.step_height_m == 0.0:
            in_stance = np.ones_like(in_stance)     # standing: every tip on the ground
        return GaitState(
            t_s=t,
            cycle_phase=float(cycle[0]),
            leg_phase=phi[0],
            in_stance=in_stance,
            supporting_legs=int(in_stance.sum()),
            gait=pattern,
            transition=float(self._progress(np.array([t]))[0]),
            clock=clock,
        )

    def _positions(
        self, t: NDArray[np.float64], *, with_velocity: bool = False
    ) -> tuple[NDArray[np.float64], NDArray[np.float64] | None]:
        """Tip positions (n, legs, 3) [m] or unwrapped hip angles (n, legs) [rad].

        With ``with_velocity`` also their time derivative at fixed parameters
        (``d/dphi * dphi/dt``, exact when no transition is under way), else None.
        """
        r = self._ramp(t)
        c = self._cycles(t)
        rel = c[:, None] - r['theta']
        phi = _wrap01(rel)
        freq = r['freq_hz'][:, None]
        if self.is_buehler:
            angle, dangle = buehler_angle(
                phi, duty_factor=r['beta'][:, None], sweep_angle_rad=r['sweep_rad'][:, None],
                leg_offset_rad=r['offset_rad'][:, None],
            )
            return _TWO_PI * np.floor(rel) + angle, (dangle * freq if with_velocity else None)
        path = tip_path(
            phi, duty_factor=r['beta'][:, None], step_length_m=r['step_length_m'][:, None],
            step_height_m=r['step_height_m'][:, None], with_acceleration=False,
        )
        up = np.array([0.0, 0.0, 1.0])
        pos = self.neutral_tip_m + path.u[..., None] * self._forward[None] + path.z[..., None] * up
        if not with_velocity:
            return pos, None
        vel = (path.du[..., None] * self._forward[None] + path.dz[..., None] * up)
        vel = vel * freq[..., None]
        return pos, vel

    def _pos_vel(self, t_s: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Position and velocity at one time: analytic when settled, else central difference."""
        t = np.array([t_s])
        if self._progress(t - _FD_STEP_S)[0] >= 1.0:
            pos, vel = self._positions(t, with_velocity=True)
            assert vel is not None
            return pos[0], vel[0]
        p, _ = self._positions(np.array([t_s, t_s - _FD_STEP_S, t_s + _FD_STEP_S]))
        return p[0], (p[2] - p[1]) / (2.0 * _FD_STEP_S)

    def tip_targets(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Commanded tip positions in each leg's base frame, shape (n, legs, 3) [m] (3-DOF)."""
        if self.is_buehler:
            raise InvalidGaitError('a Buehler clock commands hip angles, not tip positions')
        return self._positions(np.atleast_1d(np.asarray(t_s, dtype=float)))[0]

    def joint_targets(
        self, t_s: float
    ) -> tuple[tuple[str, ...], NDArray[np.float64], NDArray[np.float64]]:
        """Joint names, positions [rad] and velocities [rad/s] at time ``t_s``.

        Returns
        -------
        names : tuple of str, length J
            Leg-major (``L1_coxa, L1_femur, L1_tibia, L2_coxa, ...`` or ``L1_hip, ...``).
        q : ndarray, shape (J,)
            Positions; Buehler hip angles are unwrapped.
        qd : ndarray, shape (J,)
        """
        pos, vel = self._pos_vel(float(t_s))
        if self.is_buehler:
            return self.joint_names, pos.copy(), vel.copy()
        q = self.kinematics.inverse(pos, branch=self.branch)
        qd = self.kinematics.joint_velocity(q, vel)
        return self.joint_names, q.reshape(-1), qd.reshape(-1)
