"""Speed and feasibility of a gait under actuator limits (Brodoline et al. 2024, Fig. 3A).

A leg cannot swing faster than ``min_swing_s`` nor complete a stance faster than ``min_stance_s``
(both set by the servo's maximum rotary speed), and the step frequency is capped to avoid
inter-leg collisions. With ``v = step_length / (beta * T)`` the fastest feasible gait uses the
shortest feasible period

    ``T_min(beta) = max(min_stance_s / beta, min_swing_s / (1 - beta), 1 / max_step_frequency_hz)``

AntBot defaults (DESIGN section 7) reproduce the paper's maximum speeds: 0.60 m/s at beta 0.5,
0.42 at 0.6, 0.27 at 0.7 and 0.13 for the wave gait at 0.83 with 100 mm steps; 0.84 m/s with
140 mm steps at beta 0.5 with these limits as they are. They are for the 100 mm bench step: a
longer step needs longer phases (:mod:`hexapod_gait.step_limits`, what the gait node, the bench
sequencer and the simulators check): 0.63 m/s with 140 mm steps. The limits belong to the leg
they were measured on (:class:`LimitsReference`, ``ActuatorLimits.measured_on``; AntBot's leg
by default): another leg's step is scaled by its own joint path against that leg's bench path.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from .errors import InfeasibleGaitError, InvalidGaitError
from .gait import GaitPattern

__all__ = [
    'ActuatorLimits',
    'ANTBOT_BENCH',
    'ANTBOT_LIMITS',
    'LimitsReference',
    'InfeasibleGaitError',
    'check_feasible',
    'feasibility_violations',
    'min_period_s',
    'max_speed_mps',
    'max_speed_for_gait_mps',
    'period_for_speed',
]

# Relative slack so that a gait built exactly at a limit (e.g. T = 1/3 Hz) is accepted.
_REL_TOL = 1e-9


@dataclass(frozen=True)
class LimitsReference:
    """The leg and bench step on which phase-duration limits were measured: the durations in
    which that leg's joints cover that step's path at the servos' top speed
    (:mod:`hexapod_gait.step_limits` scales them to another step on another leg by the joint
    paths). The default is AntBot's leg on its bench (Brodoline et al. 2024: 100 mm steps,
    40 mm lift), where the AX-18A limits were measured.

    Parameters
    ----------
    step_length_m, step_height_m : float
        The bench step [m].
    dh : hexapod_gait.kinematics.DHParameters or None
        The leg's DH table; None: AntBot's (``hexapod_gait.kinematics.ANTBOT_LEG``).
    neutral_tip_m : tuple of 3 floats or None
        The leg's stance midpoint in its base frame [m]; None: AntBot's
        (``hexapod_gait.trajectory.ANTBOT_NEUTRAL_TIP_M``).
    name : str
        The leg's name, for messages.
    """

    step_length_m: float = 0.10
    step_height_m: float = 0.04
    dh: Any = None
    neutral_tip_m: tuple[float, float, float] | None = None
    name: str = "AntBot's leg"

    def __post_init__(self) -> None:
        for name in ('step_length_m', 'step_height_m'):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value >= 0.0):
                raise InvalidGaitError(f'LimitsReference.{name} must be >= 0, got {value!r}')
            object.__setattr__(self, name, value)
        if self.neutral_tip_m is not None:
            object.__setattr__(self, 'neutral_tip_m',
                               tuple(float(x) for x in self.neutral_tip_m))

    @property
    def step_m(self) -> tuple[float, float]:
        """(step length, step height) [m]."""
        return self.step_length_m, self.step_height_m


#: AntBot's leg on its bench step (100 mm, 40 mm lift): where the AX-18A limits were measured
ANTBOT_BENCH = LimitsReference()


@dataclass(frozen=True)
class ActuatorLimits:
    """Timing limits of a leg's actuators.

    Parameters
    ----------
    min_swing_s : float
        Shortest swing phase [s].
    min_stance_s : float
        Shortest stance phase [s].
    max_step_frequency_hz : float
        Highest step frequency ``1 / T`` [Hz].
    measured_on : LimitsReference
        The leg and step the phase durations were measured on (default AntBot's leg at the
        100 mm, 40 mm bench step); :mod:`hexapod_gait.step_limits` scales them to another
        step of another leg by the joint paths.
    """

    min_swing_s: float = 0.16
    min_stance_s: float = 0.15
    max_step_frequency_hz: float = 3.0
    measured_on: LimitsReference = ANTBOT_BENCH

    def __post_init__(self) -> None:
        for name in ('min_swing_s', 'min_stance_s', 'max_step_frequency_hz'):
            value = float(getattr(self, name))
            if not (math.isfinite(value) and value > 0.0):
                raise InvalidGaitError(f'ActuatorLimits.{name} must be > 0, got {value!r}')
            object.__setattr__(self, name, value)
        if not isinstance(self.measured_on, LimitsReference):
            raise InvalidGaitError('ActuatorLimits.measured_on must be a LimitsReference, got '
                                   f'{self.measured_on!r}')


ANTBOT_LIMITS = ActuatorLimits()


def _check_beta(duty_factor: float) -> float:
    beta = float(duty_factor)
    if not (0.0 < beta < 1.0):
        raise InvalidGaitError(f'duty_factor must be in (0, 1), got {duty_factor!r}')
    return beta


def feasibility_violations(gait: GaitPattern, limits: ActuatorLimits = ANTBOT_LIMITS) -> list[str]:
    """Human-readable list of the limits a gait violates (empty when feasible)."""
    out: list[str] = []
    if gait.swing_time_s < limits.min_swing_s * (1.0 - _REL_TOL):
        out.append(
            f'swing lasts {gait.swing_time_s:.4g} s < minimum {limits.min_swing_s:.4g} s '
            f'(period {gait.period_s:.4g} s, duty factor {gait.duty_factor:.4g})'
        )
    if gait.stance_time_s < limits.min_stance_s * (1.0 - _REL_TOL):
        out.append(
            f'stance lasts {gait.stance_time_s:.4g} s < minimum {limits.min_stance_s:.4g} s '
            f'(period {gait.period_s:.4g} s, duty factor {gait.duty_factor:.4g})'
        )
    if gait.step_frequency_hz > limits.max_step_frequency_hz * (1.0 + _REL_TOL):
        out.append(
            f'step frequency {gait.step_frequency_hz:.4g} Hz > maximum '
            f'{limits.max_step_frequency_hz:.4g} Hz'
        )
    return out


def check_feasible(gait: GaitPattern, limits: ActuatorLimits = ANTBOT_LIMITS) -> None:
    """Raise :class:`InfeasibleGaitError` naming every violated limit; return None if feasible."""
    problems = feasibility_violations(gait, limits)
    if problems:
        raise InfeasibleGaitError(f'gait {gait.name!r} is infeasible: ' + '; '.join(problems))


def min_period_s(duty_factor: float, limits: ActuatorLimits = ANTBOT_LIMITS) -> float:
    """Shortest feasible period ``T_min(beta)`` [s]."""
    beta = _check_beta(duty_factor)
    return max(
        limits.min_stance_s / beta,
        limits.min_swing_s / (1.0 - beta),
        1.0 / limits.max_step_frequency_hz,
    )


def max_speed_mps(
    duty_factor: float, step_length_m: float, limits: ActuatorLimits = ANTBOT_LIMITS
) -> float:
    """Highest feasible speed ``step_length / (beta * T_min(beta))`` [m/s]."""
    beta = _check_beta(duty_factor)
    if not (math.isfinite(step_length_m) and step_length_m >= 0.0):
        raise InvalidGaitError(f'step_length_m must be >= 0, got {step_length_m!r}')
    return float(step_length_m) / (beta * min_period_s(beta, limits))


def max_speed_for_gait_mps(gait: GaitPattern, limits: ActuatorLimits = ANTBOT_LIMITS) -> float:
    """Highest feasible speed of a gait's pattern, duty factor and step length [m/s].

    The limits are per leg, so the phase offsets do not enter: only ``beta`` and the step length.
    """
    return max_speed_mps(gait.duty_factor, gait.step_length_m, limits)


def period_for_speed(
    speed_mps: float,
    duty_factor: float,
    step_length_m: float,
    limits: ActuatorLimits = ANTBOT_LIMITS,
) -> float:
    """Period that gives a requested speed, ``T = step_length / (beta * v)`` [s].

    Raises
    ------
    InfeasibleGaitError
        If the speed is not positive or exceeds :func:`max_speed_mps` (the message gives the
        maximum and the limit that binds).
    """
    beta = _check_beta(duty_factor)
    v = float(speed_mps)
    if not (math.isfinite(v) and v > 0.0):
        raise InfeasibleGaitError(f'speed_mps must be finite and > 0, got {speed_mps!r}')
    if not (math.isfinite(step_length_m) and step_length_m > 0.0):
        raise InfeasibleGaitError(
            f'step_length_m must be > 0 to reach a speed, got {step_length_m!r}'
        )
    period = float(step_length_m) / (beta * v)
    t_min = min_period_s(beta, limits)
    if period < t_min * (1.0 - _REL_TOL):
        v_max = max_speed_mps(beta, step_length_m, limits)
        binding = {
            limits.min_stance_s / beta: f'minimum stance {limits.min_stance_s:g} s',
            limits.min_swing_s / (1.0 - beta): f'minimum swing {limits.min_swing_s:g} s',
            1.0 / limits.max_step_frequency_hz:
                f'maximum step frequency {limits.max_step_frequency_hz:g} Hz',
        }[t_min]
        raise InfeasibleGaitError(
            f'speed {v:.4g} m/s is infeasible with duty factor {beta:.4g} and step length '
            f'{step_length_m:.4g} m: it needs period {period:.4g} s < {t_min:.4g} s '
            f'({binding}); maximum speed is {v_max:.4g} m/s'
        )
    return period
