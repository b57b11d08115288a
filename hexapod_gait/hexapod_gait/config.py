"""Gait from a flat parameter set (what the gait node's parameters describe), validated.

Kept out of the node so that the rules (speed chooses the period, feasibility, reach of every
tip on the path, static support of a live robot) are tested without ROS.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .buehler import BUEHLER_PRESETS, BuehlerClock
from .errors import InfeasibleGaitError, InvalidGaitError, UnreachableError
from .feasibility import ActuatorLimits, period_for_speed
from .gait import GaitPattern, make_gait
from .kinematics import Branch, LegKinematics
from .step_limits import check_feasible_for_step, limits_for_step, reference_note
from .trajectory import ANTBOT_NEUTRAL_TIP_M, default_forward_axis, tip_path

__all__ = ['SIDE_RULE_MIN_LEGS', 'build_gait', 'check_reachable', 'check_static_support',
           'min_supporting_per_side', 'unsupported_sides']

#: fewest legs the whole-side rule applies to: with one leg a side every swing lifts a side
#: (such a robot balances by other means)
SIDE_RULE_MIN_LEGS = 4


def check_reachable(
    gait: GaitPattern,
    *,
    kinematics: LegKinematics | None = None,
    neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M,
    branch: Branch = 'knee_up',
    samples: int = 200,
) -> None:
    """Raise :class:`UnreachableError` if any tip of the gait's path leaves the leg's workspace.

    The path is sampled at ``samples`` leg phases (it is the same for every leg up to the sign
    of the forward axis, so both signs are checked).
    """
    kin = kinematics if kinematics is not None else LegKinematics()
    phi = (np.arange(samples) + 0.5) / samples
    path = tip_path(phi, duty_factor=gait.duty_factor, step_length_m=gait.step_length_m,
                    step_height_m=gait.step_height_m)
    neutral = np.asarray(neutral_tip_m, dtype=float).reshape(3)
    for leg in {gait.leg_names[0][0] + '1', 'R1' if gait.leg_names[0][0] == 'L' else 'L1'}:
        axis = np.asarray(default_forward_axis(leg))
        p = neutral + path.u[:, None] * axis + path.z[:, None] * np.array([0.0, 0.0, 1.0])
        try:
            kin.inverse(p, branch=branch)
        except UnreachableError as err:
            raise UnreachableError(
                f'step length {gait.step_length_m:g} m / step height {gait.step_height_m:g} m '
                f'leave the leg workspace: {err}'
            ) from err


def min_supporting_per_side(gait: GaitPattern) -> dict[str, int]:
    """Fewest legs in stance on each side (first letter of the leg name) over a cycle.

    Exact: evaluated between the touchdown and lift-off phases of the side's legs.
    """
    intervals = gait._stance_intervals()
    out: dict[str, int] = {}
    for side in sorted({name[0] for name in gait.leg_names}):
        legs = [iv for name, iv in zip(gait.leg_names, intervals) if name[0] == side]
        points = sorted({0.0, 1.0} | {x for iv in legs for piece in iv for x in piece})
        mids = [(a + b) / 2 for a, b in zip(points[:-1], points[1:]) if b > a]
        out[side] = min(sum(any(s <= m < e for s, e in iv) for iv in legs) for m in mids)
    return out


def _largest_gap(offsets: list[float]) -> float:
    """Largest circular gap between consecutive phase offsets: the duty factor at which the
    stance intervals of these legs just cover the cycle (one of them is always down)."""
    x = sorted(o % 1.0 for o in offsets)
    return max(b - a for a, b in zip(x, x[1:] + [x[0] + 1.0]))


def unsupported_sides(gait: GaitPattern) -> list[str]:
    """The sides (the legs' first letter) whose legs are all in swing at some instant: the
    whole-side rule of :func:`check_static_support`, ``gait_scheduler``, ``hexapod-sim`` and
    the energy recommendation (one rule: the simulator and the recommendation each had their
    own, which differed on stepping in place and on two legs). Empty when the gait stands (step
    length and height 0) or has fewer than :data:`SIDE_RULE_MIN_LEGS` legs."""
    if gait.step_length_m == 0.0 and gait.step_height_m == 0.0:
        return []
    if len(gait.leg_names) < SIDE_RULE_MIN_LEGS:
        return []
    return [side for side, n in min_supporting_per_side(gait).items() if n == 0]


def check_static_support(gait: GaitPattern) -> None:
    """Raise :class:`InfeasibleGaitError` if no leg is on the ground for part of the cycle (a
    flight phase, e.g. the alternating gait below 0.5, on any number of legs) or, on
    :data:`SIDE_RULE_MIN_LEGS` or more legs, if at some instant every leg of one side is in
    swing (the robot falls over that side), e.g. the wave gait at duty factor 0.5 (see
    :func:`unsupported_sides`). Standing (step length and height 0) always passes.

    The message names the duty factor the gait's offsets need: the largest gap between the
    offsets of one side's legs (of all legs, under :data:`SIDE_RULE_MIN_LEGS` legs).
    """
    if gait.step_length_m == 0.0 and gait.step_height_m == 0.0:
        return
    lost = unsupported_sides(gait)
    if not lost and gait.min_supporting_legs() > 0:
        return
    n, beta = gait.leg_count, gait.duty_factor
    offsets = list(gait.phase_offsets)
    if len(gait.leg_names) < SIDE_RULE_MIN_LEGS:
        need = _largest_gap(offsets)
    else:
        need = max(_largest_gap([o for o, name in zip(offsets, gait.leg_names)
                                 if name[0] == side])
                   for side in {name[0] for name in gait.leg_names})
    if gait.min_supporting_legs() == 0:
        x = sorted(o % 1.0 for o in offsets)
        airborne = sum(max(0.0, b - a - beta) for a, b in zip(x, x[1:] + [x[0] + 1.0]))
        raise InfeasibleGaitError(
            f'gait {gait.name!r} at duty factor {beta:g} has a flight phase: no leg on the '
            f'ground for {100 * airborne:.3g} % of the cycle (the robot falls); it needs a duty '
            f'factor >= {need:.4g} on {n} legs' + (' (a leg on the ground on each side)'
                                                     if lost else ''))
    wave = (f' (the wave walks at 1 - 1/n = {1 - 1 / n:.4g} on {n} legs)'
            if gait.name == 'wave' else '')
    raise InfeasibleGaitError(
        f'gait {gait.name!r} at duty factor {beta:g} lifts every leg of side '
        f'{"/".join(lost)} at once: the robot falls over; raise the duty factor to >= '
        f'{need:.4g} for this gait on {n} legs{wave} or choose another gait')


def build_gait(
    gait: str,
    *,
    leg_count: int = 6,
    duty_factor: float = 0.5,
    period_s: float = 1.0,
    step_length_m: float = 0.10,
    step_height_m: float = 0.04,
    speed_mps: float = 0.0,
    sweep_angle_rad: float = 1.0,
    leg_offset_rad: float = 0.0,
    preset: str = '',
    limits: ActuatorLimits | None = ActuatorLimits(),
    kinematics: LegKinematics | None = None,
    neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M,
) -> GaitPattern | BuehlerClock:
    """The gait a parameter set asks for, or a typed error giving the reason.

    Parameters
    ----------
    gait : str
        A pattern name of :func:`hexapod_gait.gait.make_gait` (not ``custom``) or ``buehler``.
    speed_mps : float
        If > 0, the period is chosen for this speed (``period_s`` is ignored) and an infeasible
        speed is refused.
    sweep_angle_rad, leg_offset_rad : float
        Buehler clock only.
    preset : str
        Buehler clock only: a key of :data:`BUEHLER_PRESETS` (``running``, ``jogging``,
        ``pace``, ``walk``); when set, it gives period, duty cycle, sweep and offset.
    limits : ActuatorLimits or None
        Limits for 3-DOF patterns at the bench step of the leg they were measured on
        (``limits.measured_on``; None: no check); scaled to this step's joint path on this
        leg (:func:`hexapod_gait.step_limits.limits_for_step`) for the speed's period and the
        check.

    Raises
    ------
    InvalidGaitError, InfeasibleGaitError, UnreachableError
    """
    if gait == 'buehler':
        if preset:
            if preset not in BUEHLER_PRESETS:
                raise InvalidGaitError(
                    f'preset must be one of {sorted(BUEHLER_PRESETS)}, got {preset!r}'
                )
            return BUEHLER_PRESETS[preset]
        return BuehlerClock(period_s=period_s, duty_factor=duty_factor,
                            sweep_angle_rad=sweep_angle_rad, leg_offset_rad=leg_offset_rad)
    if gait == 'custom':
        raise InvalidGaitError("gait 'custom' needs phase offsets; build it with make_gait")
    if preset:
        raise InvalidGaitError(f'preset is for the buehler gait only, got gait {gait!r}')
    # the limits are for the bench's step; this step's joint path scales them (step_limits)
    step = limits_for_step(limits, duty_factor, step_length_m, step_height_m,
                           kinematics=kinematics, neutral_tip_m=neutral_tip_m) \
        if limits is not None else None
    if speed_mps > 0.0:
        try:
            period_s = period_for_speed(speed_mps, duty_factor, step_length_m,
                                        step if step is not None else ActuatorLimits(
                                            1e-12, 1e-12, 1e12))
        except InfeasibleGaitError as err:
            if step is None or step is limits:
                raise
            raise InfeasibleGaitError(
                f'{err} (the limits of a {1e3 * step_length_m:.3g} mm step: swing >= '
                f'{step.min_swing_s:.3g} s, stance >= {step.min_stance_s:.3g} s; the '
                f'{limits.min_swing_s:g} s and {limits.min_stance_s:g} s are for '
                f'{reference_note(limits, kinematics=kinematics, neutral_tip_m=neutral_tip_m)}'
                ')') from err
    elif speed_mps < 0.0:
        raise InfeasibleGaitError(f'speed must be >= 0 (0 = use the period), got {speed_mps!r}')
    pattern = make_gait(gait, leg_count=leg_count, duty_factor=duty_factor, period_s=period_s,
                        step_length_m=step_length_m, step_height_m=step_height_m)
    if limits is not None:
        check_feasible_for_step(pattern, limits, kinematics=kinematics,
                                neutral_tip_m=neutral_tip_m)
    check_reachable(pattern, kinematics=kinematics, neutral_tip_m=neutral_tip_m)
    return pattern
