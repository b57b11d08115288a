"""Buehler clock for RHex-class legs (Komsuoglu et al., Fig. 2b and Table 1).

Each hip turns continuously in one direction. Over one period ``T`` the target angle sweeps the
stance arc ``phi_s`` slowly during the fraction ``dc`` of the period (slow phase, putative
stance), centred on the leg offset ``phi_0``, and the remaining ``2 pi - phi_s`` quickly during
``(1 - dc) T`` (fast phase, recirculation/swing). With the clock phase ``c`` of a tripod
(``c = t / T`` for the left tripod, ``t / T - 1/2`` for the right one, the two tripods in
anti-phase) and ``k = floor(c)``, ``f = c - k``:

    slow, ``f < dc``:  ``angle = 2 pi k + phi_0 - phi_s / 2 + phi_s * f / dc``
    fast, ``f >= dc``: ``angle = 2 pi k + phi_0 + phi_s / 2 + (2 pi - phi_s)(f - dc) / (1 - dc)``

The angle is unwrapped (monotonically increasing; one full turn per period), 0 = leg pointing
straight down. Target speeds are ``phi_s / (dc T)`` and ``(2 pi - phi_s) / ((1 - dc) T)``.
Tripods as in Fig. 2a: left = ``L1, R2, L3``, right = ``R1, L2, R3``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidGaitError
from .gait import GaitPattern, _times, gait_phase_offsets
from .legs import leg_names as _leg_names
from .legs import leg_rank, leg_side

__all__ = [
    'BuehlerClock',
    'BUEHLER_PRESETS',
    'TRIPOD_LEGS',
    'buehler_angle',
    'tripod_of_leg',
]

Tripod = Literal['left', 'right']

TRIPOD_LEGS: dict[str, tuple[str, ...]] = {
    'left': ('L1', 'R2', 'L3'),
    'right': ('R1', 'L2', 'R3'),
}

_TWO_PI = 2.0 * math.pi


def tripod_of_leg(leg: str) -> Tripod:
    """``'left'`` for legs whose slow phase starts at clock phase 0 (``L1, R2, L3, ...``)."""
    parity = (leg_rank(leg) - 1 + (0 if leg_side(leg) == 'left' else 1)) % 2
    return 'left' if parity == 0 else 'right'


def buehler_angle(
    leg_phase: ArrayLike,
    *,
    duty_factor: float,
    sweep_angle_rad: float,
    leg_offset_rad: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Within-cycle target angle and its phase derivative.

    Parameters
    ----------
    leg_phase : array, shape (n,) (or any shape)
        Clock phase of the leg in ``[0, 1)``, 0 = start of the slow phase.
    duty_factor, sweep_angle_rad, leg_offset_rad : float or array broadcastable to leg_phase
        ``dc``, ``phi_s`` [rad], ``phi_0`` [rad].

    Returns
    -------
    angle : ndarray, shape (n,)
        In ``[phi_0 - phi_s/2, phi_0 - phi_s/2 + 2 pi)`` [rad].
    dangle : ndarray, shape (n,)
        ``d angle / d phase`` [rad per cycle].
    """
    f = np.atleast_1d(np.asarray(leg_phase, dtype=float))
    dc = np.asarray(duty_factor, dtype=float)
    phs = np.asarray(sweep_angle_rad, dtype=float)
    ph0 = np.asarray(leg_offset_rad, dtype=float)
    slow = f < dc
    angle = np.where(
        slow,
        ph0 - 0.5 * phs + phs * f / dc,
        ph0 + 0.5 * phs + (_TWO_PI - phs) * (f - dc) / (1.0 - dc),
    )
    dangle = np.where(slow, phs / dc, (_TWO_PI - phs) / (1.0 - dc))
    return angle, np.broadcast_to(dangle, angle.shape).copy()


@dataclass(frozen=True)
class BuehlerClock:
    """Two-speed hip clock.

    Parameters
    ----------
    period_s : float
        ``T = 2 pi / w_c`` [s].
    duty_factor : float
        ``dc``, fraction of the period in the slow phase, in (0, 1).
    sweep_angle_rad : float
        ``phi_s``, angle swept in the slow phase [rad], in (0, 2 pi).
    leg_offset_rad : float
        ``phi_0``, centre of the slow phase [rad].
    kp_norm, kd_norm : float
        Normalised PD gains of Table 1 (for simulators; not used by the clock).
    """

    period_s: float
    duty_factor: float
    sweep_angle_rad: float
    leg_offset_rad: float = 0.0
    kp_norm: float = 0.0
    kd_norm: float = 0.0

    def __post_init__(self) -> None:
        for name in ('period_s', 'duty_factor', 'sweep_angle_rad', 'leg_offset_rad',
                     'kp_norm', 'kd_norm'):
            object.__setattr__(self, name, float(getattr(self, name)))
        if not (math.isfinite(self.period_s) and self.period_s > 0.0):
            raise InvalidGaitError(f'period_s must be > 0, got {self.period_s!r}')
        if not (0.0 < self.duty_factor < 1.0):
            raise InvalidGaitError(f'duty_factor must be in (0, 1), got {self.duty_factor!r}')
        if not (0.0 < self.sweep_angle_rad < _TWO_PI):
            raise InvalidGaitError(
                f'sweep_angle_rad must be in (0, 2 pi), got {self.sweep_angle_rad!r}'
            )
        if not math.isfinite(self.leg_offset_rad):
            raise InvalidGaitError(f'leg_offset_rad must be finite, got {self.leg_offset_rad!r}')

    @property
    def cycle_frequency_rad_s(self) -> float:
        """``w_c = 2 pi / T`` [rad/s]."""
        return _TWO_PI / self.period_s

    @property
    def slow_speed_rad_s(self) -> float:
        """Target hip speed in the slow phase [rad/s]."""
        return self.sweep_angle_rad / (self.duty_factor * self.period_s)

    @property
    def fast_speed_rad_s(self) -> float:
        """Target hip speed in the fast phase [rad/s]."""
        return (_TWO_PI - self.sweep_angle_rad) / ((1.0 - self.duty_factor) * self.period_s)

    def _clock(self, t_s: ArrayLike, tripod: Tripod) -> NDArray[np.float64]:
        if tripod not in ('left', 'right'):
            raise InvalidGaitError(f"tripod must be 'left' or 'right', got {tripod!r}")
        c = _times(t_s) / self.period_s
        return c if tripod == 'left' else c - 0.5

    def target_angle(self, t_s: ArrayLike, tripod: Tripod) -> NDArray[np.float64]:
        """Unwrapped target hip angle of a tripod, shape (n,) [rad]."""
        c = self._clock(t_s, tripod)
        k = np.floor(c)
        angle, _ = buehler_angle(
            c - k,
            duty_factor=self.duty_factor,
            sweep_angle_rad=self.sweep_angle_rad,
            leg_offset_rad=self.leg_offset_rad,
        )
        return _TWO_PI * k + angle

    def target_speed(self, t_s: ArrayLike, tripod: Tripod) -> NDArray[np.float64]:
        """Target hip speed of a tripod, shape (n,) [rad/s]."""
        c = self._clock(t_s, tripod)
        _, dangle = buehler_angle(
            c - np.floor(c),
            duty_factor=self.duty_factor,
            sweep_angle_rad=self.sweep_angle_rad,
            leg_offset_rad=self.leg_offset_rad,
        )
        return dangle / self.period_s

    def in_slow_phase(self, t_s: ArrayLike, tripod: Tripod) -> NDArray[np.bool_]:
        """True while the tripod is in its slow (putative stance) phase, shape (n,)."""
        c = self._clock(t_s, tripod)
        return (c - np.floor(c)) < self.duty_factor

    def stance_windows(
        self, t0_s: float, t1_s: float, tripod: Tripod, *, clip: bool = False
    ) -> NDArray[np.float64]:
        """Slow-phase intervals of a tripod.

        Parameters
        ----------
        t0_s, t1_s : float
            Time range [s].
        tripod : {'left', 'right'}
        clip : bool
            False: only the windows entirely inside ``[t0_s, t1_s]``. True: every window that
            overlaps the range, clipped to it.

        Returns
        -------
        ndarray, shape (m, 2)
            ``[start, end]`` times [s], sorted.
        """
        if not t1_s >= t0_s:
            raise InvalidGaitError(f't1_s must be >= t0_s, got {t0_s!r}, {t1_s!r}')
        T = self.period_s
        shift = 0.0 if tripod == 'left' else 0.5 * T
        if tripod not in ('left', 'right'):
            raise InvalidGaitError(f"tripod must be 'left' or 'right', got {tripod!r}")
        k0 = math.floor((t0_s - shift) / T) - 1
        k1 = math.ceil((t1_s - shift) / T) + 1
        starts = shift + T * np.arange(k0, k1 + 1, dtype=float)
        ends = starts + self.duty_factor * T
        if clip:
            keep = (ends > t0_s) & (starts < t1_s)
            w = np.column_stack([np.maximum(starts, t0_s), np.minimum(ends, t1_s)])
        else:
            keep = (starts >= t0_s) & (ends <= t1_s)
            w = np.column_stack([starts, ends])
        return w[keep].reshape(-1, 2)

    def as_pattern(self, leg_count: int = 6) -> GaitPattern:
        """The clock's stance schedule as a :class:`GaitPattern` named ``'buehler'``.

        Left-tripod legs (``L1, R2, L3, ...``) start their slow phase at cycle phase 0, the others
        at 0.5; the duty factor is ``dc``; step length and height are 0 (not defined for
        RHex-class legs).
        """
        legs = _leg_names(leg_count)
        return GaitPattern(
            name='buehler',
            leg_names=legs,
            phase_offsets=gait_phase_offsets('buehler', legs),
            duty_factor=self.duty_factor,
            period_s=self.period_s,
            step_length_m=0.0,
            step_height_m=0.0,
        )


def _preset(wc: float, phs: float, ph0: float, dc: float, kp: float, kd: float) -> BuehlerClock:
    return BuehlerClock(
        period_s=_TWO_PI / wc,
        duty_factor=dc,
        sweep_angle_rad=phs,
        leg_offset_rad=ph0,
        kp_norm=kp,
        kd_norm=kd,
    )


# Komsuoglu et al., Table 1: w_c [rad/s], phi_s [rad], phi_0 [rad], dc, kp, kd.
BUEHLER_PRESETS: dict[str, BuehlerClock] = {
    'running': _preset(19.0, 0.75, 0.35, 0.3, 0.56, 0.03),
    'jogging': _preset(17.4, 1.12, 0.2, 0.45, 0.56, 0.03),
    'pace': _preset(10.0, 1.0, 0.2, 0.6, 0.7, 0.0),
    'walk': _preset(6.0, 1.2, 0.0, 0.7, 0.7, 0.0),
}
