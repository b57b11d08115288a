"""Actuator limits for a step geometry (one source of truth for the gait node, the bench
sequencer, the simulators and the energy model).

The timing limits of :class:`~hexapod_gait.feasibility.ActuatorLimits` (AntBot: swing >= 0.16 s,
stance >= 0.15 s, Brodoline et al. 2024) are phase durations measured on the bench's tip path,
100 mm steps with a 40 mm lift (:data:`BENCH_STEP_M`): the durations in which the joints cover
that path at the servos' top speed. A step that moves the joints ``1/k`` times as far needs
``1/k`` times as long (:func:`phase_duration_scales`, the joint path ``sum_i integral |dq_i|``
over the phase by the leg's inverse kinematics); the step-frequency cap is kept
(:func:`limits_for_step`). AntBot, duty factor 0.5: a 140 mm step needs swing >= 0.192 s and
stance >= 0.221 s (top speed 0.63 m/s), a 120 mm step 0.176 s and 0.185 s (0.65 m/s); the bench
step keeps the limits exactly. No step (length 0: a stand, or a lift in place) keeps them too,
and so does a shorter path than the bench's (:func:`floor_scales`).

The limits are joint-speed limits of the servos on the leg they were measured on
(``ActuatorLimits.measured_on``, a :class:`~hexapod_gait.feasibility.LimitsReference`: AntBot's
leg at the 100 mm, 40 mm step for the AX-18A limits and the servo presets scaled from them;
:func:`measured_on_leg` for limits measured on another leg's bench). Another leg's step is
scaled by its own joint path against the reference leg's bench path: a PhantomX-like leg
(52/66/133 mm) moves its joints 12 % further in stance and 15 % further in swing than AntBot's
at the 100 mm step, so it needs stance >= 0.168 s and swing >= 0.185 s there (before, the
reference path was the walking leg's own 100 mm path, so every leg kept AntBot's limits there).

Core module: no ROS.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .errors import HexapodGaitError, InfeasibleGaitError
from .feasibility import (
    ANTBOT_BENCH,
    ActuatorLimits,
    LimitsReference,
    feasibility_violations,
    min_period_s,
)
from .gait import GaitPattern
from .kinematics import ANTBOT_LEG, LegKinematics
from .trajectory import ANTBOT_NEUTRAL_TIP_M

__all__ = [
    'BENCH_STEP_M',
    'STEP_GEOMETRY_TOLERANCE',
    'check_feasible_for_step',
    'floor_scales',
    'joint_paths',
    'limits_for_gait',
    'limits_for_step',
    'measured_on_leg',
    'phase_duration_scales',
    'reference_note',
    'step_violations',
]

#: (step length, step height) [m] of the tip path the actuator limits were measured on
#: (AntBot's bench: 100 mm steps, 40 mm lift)
BENCH_STEP_M: tuple[float, float] = (0.10, 0.04)
#: relative difference of step length and height within which a step is the bench's
STEP_GEOMETRY_TOLERANCE = 0.005
#: leg phase samples of the joint path
_SAMPLES = 400

_JOINT_PATHS: dict[tuple[Any, ...], tuple[float, float]] = {}


def joint_paths(beta: float, length: float, height: float, *,
                kinematics: LegKinematics | None = None,
                neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M) -> tuple[float, float]:
    """Joint-space path lengths ``sum_i integral |dq_i/dphi| dphi`` [rad] of one leg over its
    stance and over its swing (tripod leg 0; the path does not depend on the gait's legs).

    Raises :class:`~hexapod_gait.errors.UnreachableError` for a path the leg cannot reach.
    """
    from .gait import make_gait
    from .trajectory import LegTrajectory

    dh = kinematics.dh if kinematics is not None else ANTBOT_LEG
    tip = tuple(float(x) for x in np.asarray(neutral_tip_m, dtype=float).reshape(3))
    key = (round(float(beta), 9), round(float(length), 9), round(float(height), 9), dh, tip)
    if key not in _JOINT_PATHS:
        gait = make_gait('tripod', duty_factor=beta, period_s=1.0, step_length_m=length,
                         step_height_m=height)
        traj = LegTrajectory(gait, 0, kinematics=kinematics, neutral_tip_m=tip)
        phase = np.arange(_SAMPLES) / _SAMPLES
        _, d1, _ = traj.joints(float(gait.phase_offsets[0]) + phase)
        speed = np.sum(np.abs(np.asarray(d1)), axis=1) / phase.size
        stance = phase < gait.duty_factor
        if len(_JOINT_PATHS) > 4096:
            _JOINT_PATHS.clear()
        _JOINT_PATHS[key] = (float(np.sum(speed[stance])), float(np.sum(speed[~stance])))
    return _JOINT_PATHS[key]


def _leg(dh: Any, neutral_tip_m: ArrayLike | None) -> tuple[Any, tuple[float, ...]]:
    """(DH table, neutral tip) of a leg, AntBot's for None."""
    tip = ANTBOT_NEUTRAL_TIP_M if neutral_tip_m is None else neutral_tip_m
    return (ANTBOT_LEG if dh is None else dh,
            tuple(float(x) for x in np.asarray(tip, dtype=float).reshape(3)))


def phase_duration_scales(
    duty_factor: float, step_length_m: float, step_height_m: float, *,
    bench_step_m: tuple[float, float] | None = BENCH_STEP_M,
    kinematics: LegKinematics | None = None,
    neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M,
    bench_leg: Any = None,
) -> tuple[float, float]:
    """Factors ``(k_stance, k_swing)``: the bench step's joint path over the phase divided by
    this step's, both at ``duty_factor``; this step on this leg (``kinematics``,
    ``neutral_tip_m``), the bench step on ``bench_leg`` (anything with ``dh`` and
    ``neutral_tip_m``, None for either: AntBot's; a
    :class:`~hexapod_gait.feasibility.LimitsReference`, a leg file) or, when ``bench_leg`` is
    None, on this leg too. ``(1, 1)`` when the bench step is unknown (None), there is no step
    (length 0), the step is the bench's (within :data:`STEP_GEOMETRY_TOLERANCE`) on the bench's
    leg, or a path a leg cannot reach (its reach check says so where it matters)."""
    length = float(step_length_m or 0.0)
    height = float(step_height_m or 0.0)
    if bench_step_m is None or not length > 0 or not height >= 0:
        return 1.0, 1.0
    lb, hb = float(bench_step_m[0]), float(bench_step_m[1])
    own_leg = _leg(kinematics.dh if kinematics is not None else None, neutral_tip_m)
    ref_leg = own_leg if bench_leg is None else _leg(getattr(bench_leg, 'dh', None),
                                                     getattr(bench_leg, 'neutral_tip_m', None))
    if ref_leg == own_leg and abs(length - lb) <= STEP_GEOMETRY_TOLERANCE * lb and \
            abs(height - hb) <= STEP_GEOMETRY_TOLERANCE * max(hb, 1e-9):
        return 1.0, 1.0
    beta = float(duty_factor)
    try:
        bench = joint_paths(beta, lb, hb, kinematics=LegKinematics(ref_leg[0]),
                            neutral_tip_m=ref_leg[1])
        own = joint_paths(beta, length, height, kinematics=LegKinematics(own_leg[0]),
                          neutral_tip_m=own_leg[1])
    except HexapodGaitError:
        return 1.0, 1.0
    if not (own[0] > 0 and own[1] > 0 and bench[0] > 0 and bench[1] > 0):
        return 1.0, 1.0
    return bench[0] / own[0], bench[1] / own[1]


def limits_for_step(
    limits: ActuatorLimits, duty_factor: float, step_length_m: float,
    step_height_m: float, **kw: Any,
) -> ActuatorLimits:
    """``limits`` (for the bench step of the leg they were measured on, ``limits.measured_on``)
    for a step of this length and height on the leg ``kw`` gives (``kinematics``,
    ``neutral_tip_m``; none: AntBot's): the minimal phase durations divided by
    :func:`phase_duration_scales` (this step's joint path on this leg against the bench step's
    on the reference leg), the step-frequency cap kept; ``limits`` itself when the scales are
    1. A shorter path never lowers them (:func:`floor_scales`): the servos' acceleration and
    the command rate bound a phase too (unfloored, a 20 mm step at beta 0.9 walked 33 ms
    swings, three commands: a review)."""
    ref = limits.measured_on
    k_st, k_sw = floor_scales(*phase_duration_scales(
        duty_factor, step_length_m, step_height_m, bench_step_m=ref.step_m, bench_leg=ref,
        **kw))
    if k_st == 1.0 and k_sw == 1.0:
        return limits
    return dataclasses.replace(limits, min_stance_s=limits.min_stance_s / k_st,
                               min_swing_s=limits.min_swing_s / k_sw)


def measured_on_leg(limits: ActuatorLimits, leg: Any,
                    step_m: tuple[float, float] = BENCH_STEP_M) -> ActuatorLimits:
    """``limits`` as measured on ``leg`` (a leg file or leg description: ``dh``,
    ``neutral_tip_m``, ``name``; None: AntBot's leg) walking ``step_m`` (default the 100 mm,
    40 mm bench step): limits a user measured on their own leg's bench."""
    if leg is None:
        ref = dataclasses.replace(ANTBOT_BENCH, step_length_m=float(step_m[0]),
                                  step_height_m=float(step_m[1]))
    else:
        ref = LimitsReference(step_length_m=float(step_m[0]), step_height_m=float(step_m[1]),
                              dh=leg.dh, neutral_tip_m=tuple(leg.neutral_tip_m),
                              name=str(getattr(leg, 'name', '') or 'the given leg'))
    return dataclasses.replace(limits, measured_on=ref)


def reference_note(limits: ActuatorLimits, *, kinematics: LegKinematics | None = None,
                   neutral_tip_m: ArrayLike = ANTBOT_NEUTRAL_TIP_M) -> str:
    """Where ``limits`` were measured, for messages: ``the 100 mm bench step``, with ``of
    <leg>`` when the walking leg (``kinematics``, ``neutral_tip_m``) is another."""
    ref = limits.measured_on
    own = _leg(kinematics.dh if kinematics is not None else None, neutral_tip_m)
    lift = '' if abs(ref.step_height_m - BENCH_STEP_M[1]) <= 1e-9 else \
        f' ({1e3 * ref.step_height_m:.3g} mm lift)'
    leg = '' if _leg(ref.dh, ref.neutral_tip_m) == own else f' of {ref.name}'
    return f'the {1e3 * ref.step_length_m:.3g} mm bench step{lift}{leg}'


def floor_scales(k_stance: float, k_swing: float) -> tuple[float, float]:
    """Phase-duration scales for the actuator limits: a longer joint path than the bench's
    (scale below 1) lengthens the minimal phase, a shorter one keeps the bench's."""
    return min(float(k_stance), 1.0), min(float(k_swing), 1.0)


def limits_for_gait(gait: Any, limits: ActuatorLimits, **kw: Any) -> ActuatorLimits:
    """:func:`limits_for_step` for ``gait``'s duty factor, step length and height."""
    return limits_for_step(limits, gait.duty_factor,
                           float(getattr(gait, 'step_length_m', 0.0) or 0.0),
                           float(getattr(gait, 'step_height_m', 0.0) or 0.0), **kw)


def _step_name(length: float, height: float) -> str:
    lift = '' if abs(height - BENCH_STEP_M[1]) <= 1e-9 else f' ({1e3 * height:.3g} mm lift)'
    return f'{1e3 * length:.3g} mm step{lift}'


def step_violations(gait: GaitPattern, limits: ActuatorLimits, **kw: Any) -> list[str]:
    """The limits ``gait`` violates on its step geometry (:func:`limits_for_gait`), each
    naming the duration that step needs; empty when feasible. At the bench step (or no step)
    this is :func:`~hexapod_gait.feasibility.feasibility_violations` unchanged."""
    lim = limits_for_gait(gait, limits, **kw)
    if lim is limits:
        return feasibility_violations(gait, limits)
    step = _step_name(gait.step_length_m, gait.step_height_m)
    out = []
    for what, have, need in (('swing', gait.swing_time_s, lim.min_swing_s),
                             ('stance', gait.stance_time_s, lim.min_stance_s)):
        if have < need * (1.0 - 1e-9):
            out.append(f'{what} {have:.3g} s below the {need:.3g} s a {step} needs')
    if gait.step_frequency_hz > lim.max_step_frequency_hz * (1.0 + 1e-9):
        out.append(f'step frequency {gait.step_frequency_hz:.4g} Hz > maximum '
                   f'{lim.max_step_frequency_hz:.4g} Hz')
    if out:
        beta = gait.duty_factor
        t_min = min_period_s(beta, lim)
        out[-1] += (f' (period {gait.period_s:.4g} s, duty factor {beta:.4g}; this step needs '
                    f'a period >= {t_min:.4g} s: top speed '
                    f'{gait.step_length_m / (beta * t_min):.3g} m/s; the {limits.min_swing_s:g} '
                    f's swing and {limits.min_stance_s:g} s stance limits are for '
                    f'{reference_note(limits, **kw)})')
    return out


def check_feasible_for_step(gait: GaitPattern, limits: ActuatorLimits, **kw: Any) -> None:
    """Raise :class:`InfeasibleGaitError` naming every limit ``gait`` violates on its step
    geometry (:func:`step_violations`); return None if feasible."""
    problems = step_violations(gait, limits, **kw)
    if problems:
        raise InfeasibleGaitError(f'gait {gait.name!r} is infeasible: ' + '; '.join(problems))
