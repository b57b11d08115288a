"""Gait recommendation: minimum CoT/M for a target speed and payload within actuator limits.

Candidates: every gait name in ``gaits`` x duty factor in ``duty_factors`` x step length in
``step_lengths_m`` for the robot's leg count (``leg_count``; every named gait
:func:`hexapod_gait.gait.make_gait` builds for it, ``tetrapod`` included).  The default
duty-factor grid (0.5 to 0.85 by 0.05, and 5/6) also holds each gait's typical duty factor for
the leg count (:func:`hexapod_gait.gait.typical_duty_factor`: an 8-leg wave's 7/8).  A candidate
is kept when the period giving the target speed (``T = step_length / (beta v)``) satisfies the
actuator limits (:func:`hexapod_gait.feasibility.check_feasible`; default AntBot's servos',
:data:`hexapod_gait.feasibility.ANTBOT_LIMITS`), the body is always supported
(``min L(t) >= min_supporting_legs``, and a leg down on each side: :func:`lifted_sides`) and
its leg path is reachable.  The one with the lowest
``CoT/M = (P_in - P_out) / (M v)`` among those whose phase durations and loads lie within the
bench's sessions wins (configurations that would extrapolate the surfaces are counted in
``outside_bench`` and only used, with a note, when no other is feasible); the saving is reported
against the default gait (tripod for 6 legs, alternating for other leg counts; beta 0.5, 100 mm)
at the same speed and payload, when that one is feasible.  The recommendation records the leg
count, robot mass and limits it used.
"""

from __future__ import annotations

import math

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.prediction import (
    OutputPowerModel,
    PhasePowerModel,
    bench_domain_check,
    geometry_limits,
    predict_power_in_w,
)

__all__ = ['Candidate', 'Recommendation', 'default_gait_name', 'infeasible_schedule',
           'lifted_sides', 'recommend_gait']


@dataclass(frozen=True)
class Candidate:
    """One evaluated gait configuration at the target speed."""

    gait: str
    leg_count: int
    duty_factor: float
    step_length_m: float
    period_s: float
    power_in_w: float
    power_out_w: float
    efficiency: float
    specific_cost_of_transport: float
    outside_bench: tuple[str, ...] = ()
    #: the lift priced [m] (the robot's own when its bags give it; AntBot's 40 mm else)
    step_height_m: float = 0.04


@dataclass(frozen=True)
class Recommendation:
    """Best configuration, the default for comparison, and the saving."""

    speed_mps: float
    payload_kg: float
    best: Candidate
    default: Candidate | None
    saving_fraction: float | None  # 1 - CoT/M(best) / CoT/M(default)
    evaluated: int
    rejected: int
    outside_bench: int = 0
    note: str = ''
    leg_count: int = 6
    robot_mass_kg: float = float('nan')  # without payload
    limits: dict[str, float] = field(default_factory=dict)
    step_height_m: float = 0.04

    def to_dict(self) -> dict[str, Any]:
        return {
            'step_height_m': self.step_height_m,
            'outside_bench': self.outside_bench,
            'note': self.note,
            'speed_mps': self.speed_mps,
            'payload_kg': self.payload_kg,
            'leg_count': self.leg_count,
            'robot_mass_kg': self.robot_mass_kg,
            'mass_kg': self.robot_mass_kg + self.payload_kg,
            'limits': dict(self.limits),
            'best': asdict(self.best),
            'default': None if self.default is None else asdict(self.default),
            'saving_fraction': self.saving_fraction,
            'evaluated': self.evaluated,
            'rejected': self.rejected,
        }


def infeasible_schedule(gait: Any, limits: Any | None = None) -> list[str]:
    """Why a walked schedule is not one the robot can walk (empty when it can): the actuator
    limits it violates (:func:`hexapod_gait.feasibility.feasibility_violations`; default
    AntBot's servo limits) and phases of the cycle with no leg on the ground (``L(t) = 0``:
    the body falls) or with every leg of a side in swing (:func:`lifted_sides`).  The
    checks :func:`recommend_gait` applies to its candidates, for a robot run's schedule: its
    measured descriptors are those of a gait the project calls
    infeasible (a wave at duty factor 0.1 gave CoT/M 29.0 J/(m kg), better than any feasible
    gait).  Standing (period 0) and clock-driven schedules (a RHex's Buehler clock: step
    length 0, rotating legs that may run with a flight phase) are not checked, nor the
    ground contact of a schedule of fewer than 4 legs (a single-leg bench, a biped)."""
    from hexapod_gait.feasibility import ANTBOT_LIMITS, feasibility_violations

    if not (gait.period_s > 0 and gait.step_length_m > 0) or gait.name == 'buehler':
        return []
    lim = ANTBOT_LIMITS if limits is None else limits
    out = list(feasibility_violations(gait, lim))
    if len(gait.leg_names) < 4:
        return out
    bp, supporting = gait.support_profile()
    widths = np.diff(np.append(np.asarray(bp, float), 1.0))
    airborne = float(widths[np.asarray(supporting) == 0].sum())
    if airborne > 1e-9:
        out.append(f'no leg on the ground {100 * airborne:.0f} % of the cycle (L(t) = 0; '
                   f'{gait.name}, duty factor {gait.duty_factor:.4g}, {gait.leg_count} legs)')
    else:
        out.extend(lifted_sides(gait))
    return out


def lifted_sides(gait: Any) -> list[str]:
    """Why ``gait`` tips the body over a side: for each side (the legs' first letter) whose
    legs are all in swing at some instant, one sentence (empty when every side keeps a leg
    down; schedules of fewer than 4 legs and standing are not checked).  The rule
    ``gait_scheduler`` applies (:func:`hexapod_gait.config.unsupported_sides`): a wave at
    duty factor 0.5-0.55 keeps three legs down yet lifts a whole side, and had been
    recommended (an outside review; the ripple at the same duty factor costs the same)."""
    from hexapod_gait.config import unsupported_sides

    lost = unsupported_sides(gait)
    if not lost:
        return []
    return [f'every leg of side {"/".join(lost)} is in swing at once ({gait.name}, duty factor '
            f'{gait.duty_factor:.4g}, {gait.leg_count} legs): the body tips over that side']


def default_gait_name(leg_count: int) -> str:
    """The default gait's name: ``tripod`` for 6 legs, ``alternating`` (the same pattern) for
    other leg counts."""
    return 'tripod' if leg_count == 6 else 'alternating'


def _evaluate(
    name: str, legs: int, beta: float, step_m: float, speed: float, payload: float,
    phase_power: PhasePowerModel, output_power: OutputPowerModel, limits: Any,
    min_supporting_legs: int, load_offset_kg: float = 0.0, step_height_m: float = 0.04,
) -> Candidate | tuple[str, str]:
    """The candidate, or ``(kind, why)`` when the configuration is not one: ``kind`` is
    ``invalid`` (no such gait for ``legs``), ``limits`` (actuator limits), ``support`` (too few
    supporting legs) or ``unreachable`` (leg path out of reach, or another model refusal)."""
    from hexapod_gait.errors import InfeasibleGaitError, InvalidGaitError
    from hexapod_gait.feasibility import check_feasible
    from hexapod_gait.gait import make_gait

    period = step_m / (beta * speed)
    try:
        gait = make_gait(name, leg_count=legs, duty_factor=beta, period_s=period,
                         step_length_m=step_m, step_height_m=step_height_m)
    except InvalidGaitError as err:
        return 'invalid', str(err)
    try:
        # the limits hold for the bench's tip path: scaled to this step's joint path
        check_feasible(gait, geometry_limits(phase_power, gait, limits))
    except InfeasibleGaitError as err:
        return 'limits', str(err)
    if gait.min_supporting_legs() < min_supporting_legs:
        return 'support', (f'{name} beta {beta:g} supports the body on '
                           f'{gait.min_supporting_legs()} legs < {min_supporting_legs}')
    tipped = lifted_sides(gait)
    if tipped:
        return 'support', tipped[0]
    total = output_power.robot.mass_kg + payload
    try:
        p_in = float(predict_power_in_w(phase_power, gait, total_mass_kg=total,
                                        leg_mass_kg=output_power.robot.leg_mass_kg,
                                        load_offset_kg=load_offset_kg))
        p_out = float(output_power.power_out_w(gait, payload_kg=payload))
        outside = bench_domain_check(phase_power, gait, total_mass_kg=total,
                                     leg_mass_kg=output_power.robot.leg_mass_kg,
                                     load_offset_kg=load_offset_kg)[0]
    except ValueError as err:  # unreachable leg path (or a load the model refuses)
        return 'unreachable', str(err)
    return Candidate(name, legs, beta, step_m, period, p_in, p_out, p_out / p_in,
                     (p_in - p_out) / (total * speed), tuple(outside), step_height_m)


#: The default duty-factor grid (each gait's typical duty factor is added to it)
DEFAULT_DUTY_FACTORS: tuple[float, ...] = \
    tuple(float(b) for b in np.round(np.arange(0.5, 0.86, 0.05), 2)) + (5 / 6,)


def _limits_dict(limits: Any) -> dict[str, float]:
    return {'min_swing_s': float(limits.min_swing_s),
            'min_stance_s': float(limits.min_stance_s),
            'max_step_frequency_hz': float(limits.max_step_frequency_hz)}


def recommend_gait(
    phase_power: PhasePowerModel,
    output_power: OutputPowerModel,
    *,
    speed_mps: float,
    payload_kg: float = 0.0,
    leg_count: int = 6,
    gaits: Sequence[str] = ('alternating', 'wave', 'ripple', 'tetrapod'),
    duty_factors: Sequence[float] | None = None,
    step_lengths_m: Sequence[float] = tuple(np.round(np.arange(0.06, 0.141, 0.01), 3)),
    limits: Any | None = None,
    min_supporting_legs: int = 3,
    load_offset_kg: float = 0.0,
    step_height_m: float = 0.04,
) -> Recommendation:
    """The configuration minimising CoT/M at ``speed_mps`` with ``payload_kg``.

    Parameters
    ----------
    leg_count : int
        The robot's legs: every candidate and the default gait have this many.
    duty_factors : sequence of float, optional
        The duty factors searched (default :data:`DEFAULT_DUTY_FACTORS` plus each gait's
        typical duty factor for ``leg_count``).
    limits : hexapod_gait.feasibility.ActuatorLimits, optional
        Default AntBot's servo limits (:data:`~hexapod_gait.feasibility.ANTBOT_LIMITS`).
    min_supporting_legs : int
        Fewest legs on the ground at any time (capped at ``leg_count // 2``).
    step_height_m : float
        The lift every candidate is priced at [m] (default AntBot's 40 mm; ``energy`` gives
        the robot's own when its bags carry it: at 40 mm a robot lifting 30 mm read +4.3 %).

    Raises
    ------
    InvalidInputError
        If the speed is not positive, the payload negative (either not finite), a duty
        factor outside (0, 1), a step length not positive, or no candidate is feasible at
        that speed (the message says why the configurations were rejected).
    """
    from hexapod_gait.feasibility import ANTBOT_LIMITS
    from hexapod_gait.gait import typical_duty_factor

    if not (math.isfinite(speed_mps) and speed_mps > 0):
        raise InvalidInputError(f'speed_mps must be finite and > 0, got {speed_mps}')
    if not (math.isfinite(step_height_m) and step_height_m > 0):
        raise InvalidInputError(f'step_height_m must be finite and > 0, got {step_height_m}')
    if not (math.isfinite(payload_kg) and payload_kg >= 0):
        # a negative payload made a lighter robot and a recommendation for it (mass 1.18 kg
        # for AntBot with -1 kg), without a word
        raise InvalidInputError(f'payload_kg must be finite and >= 0, got {payload_kg}')
    # refused up front, named: a step of 0 had been called 'not gaits for this leg count',
    # and beside valid values dropped without a word (an outside review)
    bad_beta = [b for b in (duty_factors or ()) if not (math.isfinite(b) and 0 < b < 1)]
    if bad_beta:
        raise InvalidInputError(f'duty factors must lie in (0, 1), got {bad_beta}')
    bad_step = [x for x in step_lengths_m if not (math.isfinite(x) and x > 0)]
    if bad_step or not len(step_lengths_m):
        raise InvalidInputError(f'step lengths must be finite and > 0 [m], got '
                                f'{bad_step or list(step_lengths_m)}')
    if duty_factors is not None and not len(duty_factors):
        raise InvalidInputError('no duty factor to search (an empty list)')
    lim = ANTBOT_LIMITS if limits is None else limits
    min_sup = min(min_supporting_legs, leg_count // 2)
    best: Candidate | None = None
    best_outside: Candidate | None = None
    evaluated = rejected = outside = 0
    why: dict[str, list[str]] = {}
    for name in gaits:
        if name == 'alternating':
            # the default's name for it: 'tripod' on 6 legs (the recommendation read
            # "alternating beta 0.50 ... (default tripod beta 0.5)", one gait under two names)
            name = default_gait_name(leg_count)
        betas = list(duty_factors) if duty_factors is not None else list(DEFAULT_DUTY_FACTORS)
        if duty_factors is None:
            try:
                typical = typical_duty_factor(name, leg_count)
            except ValueError:
                typical = None
            if typical is not None and not any(abs(b - typical) < 1e-9 for b in betas):
                betas.append(typical)
        for beta in sorted(betas):
            for step in step_lengths_m:
                cand = _evaluate(name, leg_count, float(beta), float(step), speed_mps,
                                 payload_kg, phase_power, output_power, lim, min_sup,
                                 load_offset_kg, step_height_m)
                if not isinstance(cand, Candidate):
                    rejected += 1
                    why.setdefault(cand[0], []).append(cand[1])
                    continue
                evaluated += 1
                if cand.outside_bench:
                    outside += 1
                    if best_outside is None or cand.specific_cost_of_transport < \
                            best_outside.specific_cost_of_transport:
                        best_outside = cand
                elif best is None or cand.specific_cost_of_transport < \
                        best.specific_cost_of_transport:
                    best = cand
    note = ''
    if best is None and best_outside is not None:
        best = best_outside
        note = ('every feasible configuration reads the bench surfaces outside their sessions '
                f'({"; ".join(best.outside_bench)}): the recommendation is an extrapolation; '
                'measure the bench at these phase durations and loads')
    elif outside:
        note = (f'{outside} feasible configurations read the bench surfaces outside their '
                'sessions and were not considered (their predicted power is an extrapolation)')
    if best is None:
        raise InvalidInputError(
            f'no feasible gait reaches {speed_mps} m/s for {leg_count} legs: '
            + _rejections(why, gaits, lim))
    default_ = _evaluate(default_gait_name(leg_count), leg_count, 0.5, 0.10, speed_mps,
                         payload_kg, phase_power, output_power, lim, min_sup, load_offset_kg,
                         step_height_m)
    default = default_ if isinstance(default_, Candidate) else None
    saving = None if default is None else \
        1.0 - best.specific_cost_of_transport / default.specific_cost_of_transport
    if saving is not None and saving < 0 and default is not None:
        # the default costs less but was not eligible: say why the recommendation costs more
        why = ('it reads the bench surfaces outside their sessions (' +
               '; '.join(default.outside_bench) + ')') if default.outside_bench else \
            'it is not among the configurations searched'
        note = '; '.join(x for x in (note, (
            f'the default gait predicts {-100 * saving:.1f} % less CoT/M than this '
            f'recommendation, but {why}: its figure is an extrapolation, the recommendation '
            'the best the bench covers')) if x)
    return Recommendation(speed_mps, payload_kg, best, default, saving, evaluated, rejected,
                          outside, note, leg_count, float(output_power.robot.mass_kg),
                          _limits_dict(lim), float(step_height_m))


def _rejections(why: dict[str, list[str]], gaits: Sequence[str], limits: Any) -> str:
    """What happened to the configurations, by kind, with the first reason of each."""
    if not why:
        return f'no configuration was searched (gaits {tuple(gaits)})'
    kinds = {'invalid': 'are not gaits for this leg count',
             'limits': ('exceed the actuator limits (min swing {:g} s, min stance {:g} s on '
                        "the {:.3g} mm bench step of {}, scaled to each step's joint path on "
                        "the robot's leg; max {:g} Hz)"
                        ).format(limits.min_swing_s, limits.min_stance_s,
                                 1e3 * limits.measured_on.step_length_m,
                                 limits.measured_on.name, limits.max_step_frequency_hz),
             'support': 'support the body on too few legs or lift a whole side',
             'unreachable': 'have a leg path out of reach'}
    parts = [f'{len(v)} {kinds[k]} (e.g. {v[0]})' for k, v in why.items()]
    total = sum(len(v) for v in why.values())
    return (f'{total} configurations rejected, none evaluated: ' if total > 1 else
            '1 configuration rejected, none evaluated: ') + '; '.join(parts)
