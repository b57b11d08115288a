"""Gait patterns and the number of supporting legs L(t) (Brodoline et al. 2024, Fig. 2 and Eq. 3).

A gait pattern is a periodic schedule. With cycle phase ``c = (t / T) mod 1``, leg ``i`` has the
leg phase ``phi_i = (c - theta_i) mod 1``; it touches down at ``phi_i = 0`` and is in stance while
``phi_i < beta``, in swing for ``beta <= phi_i < 1``. ``theta_i`` is the cycle phase at which
stance of leg ``i`` starts; ``beta = T_stance / T`` is the duty factor.

Named patterns for ``k = leg_count / 2`` legs per side (legs ``L1..Lk``, ``R1..Rk``, front to
rear). Offsets are touchdown phases; the swing of a leg ends at its touchdown, so the order of the
offsets is the order in which legs swing:

``alternating`` (``tripod`` for six legs)
    Two groups in anti-phase: ``L1, L3, ...`` with ``R2, R4, ...`` at ``theta = 0``, the others at
    ``0.5``. Six legs: ``L1, R2, L3`` at 0 and ``R1, L2, R3`` at 0.5. At ``beta = 0.5`` exactly
    half of the legs are on the ground at every instant. Four legs: the trot.
``wave``
    Metachronal wave, one leg swinging at a time when ``beta >= 1 - 1/n``: swing order
    ``Lk, ..., L1, Rk, ..., R1`` (rear to front on the left side, then on the right side),
    ``theta = j / n`` for the ``j``-th leg of that order. Typical ``beta = 1 - 1/n`` (5/6 for six).
``ripple``
    A metachronal wave rear to front on each side, spacing ``1/k``, the right side half a cycle
    behind the left: ``theta(Lj) = (k - j) / k``, ``theta(Rj) = ((k - j) / k + 0.5) mod 1``.
    One leg per side swings at a time for ``beta >= 1 - 1/k`` (2/3 for six legs), the two sides'
    swings are staggered by half a cycle.
``tetrapod``
    The same wave on each side, the right side one wave step (``1/k``) behind the left, so that
    legs swing in ``k`` diagonal pairs. Six legs: ``(L3, R1)`` at 0, ``(L2, R3)`` at 1/3,
    ``(L1, R2)`` at 2/3; with ``beta = 2/3`` exactly four legs are on the ground at every instant.
``custom``
    Any ``theta_i`` given by the caller.
``buehler``
    The alternating pattern of a Buehler clock (see :mod:`hexapod_gait.buehler`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from fractions import Fraction
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import InvalidGaitError
from .legs import leg_names as _leg_names
from .legs import leg_rank, leg_side

__all__ = [
    'GAIT_NAMES',
    'GaitPattern',
    'make_gait',
    'gait_phase_offsets',
    'typical_duty_factor',
    'carried_mass_per_leg_kg',
]

GAIT_NAMES: tuple[str, ...] = (
    'tripod',
    'alternating',
    'wave',
    'ripple',
    'tetrapod',
    'custom',
    'buehler',
)

# The largest double below one: a leg phase that rounds up to 1.0 is put here so that it stays
# in [0, 1) and on the swing side of the touchdown.
_BELOW_ONE = float(np.nextafter(1.0, 0.0))
# Cycle-phase distance under which two touchdown/lift-off instants are the same instant.
_SNAP = 1e-12


def _wrap01(x: NDArray[np.float64]) -> NDArray[np.float64]:
    """``x mod 1`` in ``[0, 1)``, values that round to 1.0 kept just below 1."""
    y = np.mod(x, 1.0)
    return np.where(y >= 1.0, _BELOW_ONE, y)


def _times(t_s: ArrayLike) -> NDArray[np.float64]:
    t = np.atleast_1d(np.asarray(t_s, dtype=float))
    if t.ndim != 1:
        raise InvalidGaitError(f't_s must be a scalar or a 1-D array, got shape {t.shape}')
    return t


@dataclass(frozen=True)
class GaitPattern:
    """A periodic leg schedule.

    Parameters
    ----------
    name : str
        ``tripod``, ``alternating``, ``wave``, ``ripple``, ``tetrapod``, ``custom`` or
        ``buehler`` (see the module docstring for the definitions).
    leg_names : tuple of str, length n
        Leg order used by every per-leg array.
    phase_offsets : tuple of float, length n
        ``theta_i`` in ``[0, 1)``: cycle phase at which stance of each leg starts.
    duty_factor : float
        ``beta = T_stance / T`` in ``(0, 1)``.
    period_s : float
        Cycle period ``T`` [s], > 0.
    step_length_m : float
        Distance the body travels during one stance [m], >= 0.
    step_height_m : float
        Height the tip is lifted by during swing [m], >= 0.
    """

    name: str
    leg_names: tuple[str, ...]
    phase_offsets: tuple[float, ...]
    duty_factor: float
    period_s: float
    step_length_m: float = 0.10
    step_height_m: float = 0.04

    def __post_init__(self) -> None:
        # Accept lists and numpy arrays, store tuples of plain Python values.
        object.__setattr__(self, 'leg_names', tuple(str(n) for n in self.leg_names))
        object.__setattr__(self, 'phase_offsets', tuple(float(x) for x in self.phase_offsets))
        for field in ('duty_factor', 'period_s', 'step_length_m', 'step_height_m'):
            object.__setattr__(self, field, float(getattr(self, field)))
        if self.name not in GAIT_NAMES:
            raise InvalidGaitError(f'gait name must be one of {GAIT_NAMES}, got {self.name!r}')
        n = len(self.leg_names)
        if n == 0:
            raise InvalidGaitError('leg_names must not be empty')
        if len(set(self.leg_names)) != n:
            raise InvalidGaitError(f'leg_names must be unique, got {self.leg_names}')
        if len(self.phase_offsets) != n:
            raise InvalidGaitError(
                f'phase_offsets must have one value per leg ({n}), '
                f'got {len(self.phase_offsets)}'
            )
        for leg, theta in zip(self.leg_names, self.phase_offsets):
            if not (0.0 <= theta < 1.0):
                raise InvalidGaitError(
                    f'phase offset of {leg} must be in [0, 1), got {theta!r}'
                )
        if not (0.0 < self.duty_factor < 1.0):
            raise InvalidGaitError(f'duty_factor must be in (0, 1), got {self.duty_factor!r}')
        if not (math.isfinite(self.period_s) and self.period_s > 0.0):
            raise InvalidGaitError(f'period_s must be finite and > 0, got {self.period_s!r}')
        if not (math.isfinite(self.step_length_m) and self.step_length_m >= 0.0):
            raise InvalidGaitError(f'step_length_m must be >= 0, got {self.step_length_m!r}')
        if not (math.isfinite(self.step_height_m) and self.step_height_m >= 0.0):
            raise InvalidGaitError(f'step_height_m must be >= 0, got {self.step_height_m!r}')

    # ----------------------------------------------------------------- derived quantities
    @property
    def leg_count(self) -> int:
        """Number of legs ``n``."""
        return len(self.leg_names)

    @property
    def stance_time_s(self) -> float:
        """``T_stance = beta * T`` [s]."""
        return self.duty_factor * self.period_s

    @property
    def swing_time_s(self) -> float:
        """``T_swing = (1 - beta) * T`` [s]."""
        return (1.0 - self.duty_factor) * self.period_s

    @property
    def step_frequency_hz(self) -> float:
        """``1 / T`` [Hz]."""
        return 1.0 / self.period_s

    @property
    def speed_mps(self) -> float:
        """Body speed ``v = step_length / (beta * T)`` [m/s]."""
        return self.step_length_m / (self.duty_factor * self.period_s)

    # ----------------------------------------------------------------- time functions
    def cycle_phase(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Cycle phase ``(t / T) mod 1``.

        Parameters
        ----------
        t_s : float or array, shape (n,)
            Times [s]; the cycle starts at ``t = 0``.

        Returns
        -------
        ndarray, shape (n,)
            Cycle phase in ``[0, 1)``.
        """
        return _wrap01(_times(t_s) / self.period_s)

    def leg_phase_at(self, cycle_phase: ArrayLike) -> NDArray[np.float64]:
        """Leg phases ``(c - theta_i) mod 1`` for given cycle phases.

        Parameters
        ----------
        cycle_phase : float or array, shape (n,)

        Returns
        -------
        ndarray, shape (n, legs)
            In ``[0, 1)``, 0 = touchdown of that leg; stance while ``< duty_factor``.
        """
        c = _times(cycle_phase)
        theta = np.asarray(self.phase_offsets, dtype=float)
        return _wrap01(c[:, None] - theta[None, :])

    def leg_phase(self, t_s: ArrayLike) -> NDArray[np.float64]:
        """Leg phases at times ``t_s``, shape (n, legs), in ``[0, 1)``; 0 = touchdown."""
        return self.leg_phase_at(self.cycle_phase(t_s))

    def stance_mask(self, t_s: ArrayLike) -> NDArray[np.bool_]:
        """Stance flags, shape (n, legs): True while the leg is on the ground."""
        return self.leg_phase(t_s) < self.duty_factor

    def supporting_legs(self, t_s: ArrayLike) -> NDArray[np.int64]:
        """Number of supporting legs ``L(t)`` (Eq. 3), shape (n,)."""
        return self.stance_mask(t_s).sum(axis=1).astype(np.int64)

    # ----------------------------------------------------------------- exact L(t)
    def _stance_intervals(self) -> list[list[tuple[float, float]]]:
        """Stance of each leg as half-open cycle-phase intervals inside ``[0, 1]``.

        Touchdown and lift-off phases closer than ``_SNAP`` (in cycle phase) are merged into one
        value first: ``theta + beta - 1`` and an offset such as ``1/6`` that are equal on paper
        differ in the last bit, which would otherwise leave slivers of width 1e-17 with a
        spurious ``L``.
        """
        beta = self.duty_factor
        raw = [(theta, (theta + beta) % 1.0) for theta in self.phase_offsets]
        values = sorted({v for pair in raw for v in pair} | {0.0, 1.0})
        canon: dict[float, float] = {}
        rep = values[0]
        for v in values:
            if v - rep > _SNAP:
                rep = v
            canon[v] = rep
        one = canon[1.0]
        for v, r in canon.items():
            if r == one:
                canon[v] = 0.0  # a boundary at 1 is the boundary at 0 of the next cycle
        out: list[list[tuple[float, float]]] = []
        for theta, end in raw:
            s, e = canon[theta], canon[end]
            if e > s:
                out.append([(s, e)])
            elif e == s:
                # beta within _SNAP of 0 or 1 cannot happen (validated), so this is a full wrap
                out.append([(0.0, 1.0)] if beta > 0.5 else [])
            else:
                out.append([(s, 1.0), (0.0, e)] if e > 0.0 else [(s, 1.0)])
        return out

    def support_profile(self) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """``L`` as an exact step function of the cycle phase.

        Built from the touchdown and lift-off phases of every leg (no sampling); boundaries
        that differ by less than 1e-12 of a cycle are treated as one instant.

        Returns
        -------
        breakpoints : ndarray, shape (m,)
            Sorted, distinct cycle phases in ``[0, 1)``, ``breakpoints[0] == 0``. Interval ``j``
            is ``[breakpoints[j], breakpoints[j+1])``, the last one ends at 1.
        supporting : ndarray of int, shape (m,)
            ``L`` on each interval.
        """
        intervals = self._stance_intervals()
        points = {0.0}
        for legs in intervals:
            for a, b in legs:
                points.add(a)
                if b < 1.0:
                    points.add(b)
        bp = np.array(sorted(points), dtype=float)
        ends = np.append(bp[1:], 1.0)
        counts = np.zeros(bp.size, dtype=np.int64)
        # A leg supports interval [a, b) iff one of its stance pieces [s, e) contains it; all
        # compared numbers are the same doubles, so the test is exact.
        for legs in intervals:
            for s, e in legs:
                counts += ((bp >= s) & (ends <= e)).astype(np.int64)
        return bp, counts

    def mean_supporting_legs(self) -> float:
        """Time average of ``L(t)`` over a cycle, from the exact profile (= ``n * beta``)."""
        bp, counts = self.support_profile()
        widths = np.diff(np.append(bp, 1.0))
        return float(np.sum(widths * counts))

    def min_supporting_legs(self) -> int:
        """Smallest ``L(t)`` over a cycle."""
        return int(self.support_profile()[1].min())

    def max_supporting_legs(self) -> int:
        """Largest ``L(t)`` over a cycle."""
        return int(self.support_profile()[1].max())

    def with_changes(self, **kw: Any) -> GaitPattern:
        """A copy with some fields replaced (validated again)."""
        return dataclasses.replace(self, **kw)


def gait_phase_offsets(name: str, legs: Sequence[str]) -> tuple[float, ...]:
    """Touchdown phases ``theta_i`` of a named pattern for legs ``L1..Lk, R1..Rk``.

    Parameters
    ----------
    name : str
        ``tripod`` (six legs only), ``alternating``, ``wave``, ``ripple``, ``tetrapod`` or
        ``buehler`` (same as alternating).
    legs : sequence of str
        Leg names; both sides must have the same ranks ``1..k``.

    Returns
    -------
    tuple of float, one per leg, in ``[0, 1)``.
    """
    legs = tuple(legs)
    n = len(legs)
    k = n // 2
    ranks = {s: sorted(leg_rank(leg) for leg in legs if leg_side(leg) == s)
             for s in ('left', 'right')}
    if n % 2 or ranks['left'] != list(range(1, k + 1)) or ranks['right'] != ranks['left']:
        raise InvalidGaitError(
            f'named gaits need legs L1..Lk and R1..Rk, got {legs}'
        )
    if name == 'tripod' and n != 6:
        raise InvalidGaitError(
            f"gait 'tripod' needs 6 legs, got {n}; use 'alternating' for other leg counts"
        )
    out: list[float] = []
    theta: Fraction
    for leg in legs:
        left = leg_side(leg) == 'left'
        j = leg_rank(leg)
        if name in ('tripod', 'alternating', 'buehler'):
            group = (j - 1 + (0 if left else 1)) % 2  # L1, R2, L3, ... in group 0
            theta = Fraction(group, 2)
        elif name == 'wave':
            # swing order Lk..L1, Rk..R1
            theta = Fraction((k - j) + (0 if left else k), n)
        elif name == 'ripple':
            theta = Fraction(k - j, k) + (0 if left else Fraction(1, 2))
        elif name == 'tetrapod':
            theta = Fraction(k - j + (0 if left else 1), k)
        else:
            raise InvalidGaitError(
                f'no built-in phase offsets for gait {name!r}; '
                f"use 'custom' with phase_offsets"
            )
        out.append(float(theta % 1))
    return tuple(out)


def typical_duty_factor(name: str, leg_count: int = 6) -> float:
    """The duty factor a named pattern is usually walked with.

    ``alternating``/``tripod``/``buehler``: 0.5; ``wave``: ``1 - 1/n``; ``ripple`` and
    ``tetrapod``: ``1 - 2/n`` (one leg per side in swing at a time).
    """
    if name in ('tripod', 'alternating', 'buehler', 'custom'):
        return 0.5
    if name == 'wave':
        return 1.0 - 1.0 / leg_count
    if name in ('ripple', 'tetrapod'):
        return max(0.5, 1.0 - 2.0 / leg_count)
    raise InvalidGaitError(f'unknown gait name {name!r}, expected one of {GAIT_NAMES}')


def make_gait(
    name: str,
    *,
    leg_count: int = 6,
    duty_factor: float = 0.5,
    period_s: float = 1.0,
    step_length_m: float = 0.10,
    step_height_m: float = 0.04,
    phase_offsets: Sequence[float] | None = None,
) -> GaitPattern:
    """Build a named gait pattern for ``leg_count`` legs.

    Parameters
    ----------
    name : str
        ``tripod`` (6 legs), ``alternating``, ``wave``, ``ripple``, ``tetrapod``, ``buehler`` or
        ``custom`` (then ``phase_offsets`` is required).
    leg_count : int
        Even number of legs.
    duty_factor, period_s, step_length_m, step_height_m : float
        See :class:`GaitPattern`.
    phase_offsets : sequence of float, length leg_count, optional
        ``theta_i`` for ``custom`` gaits (taken mod 1). Not allowed with other names.

    Returns
    -------
    GaitPattern
    """
    legs = _leg_names(leg_count)
    if name == 'custom':
        if phase_offsets is None:
            raise InvalidGaitError("gait 'custom' needs phase_offsets (one per leg)")
        offsets = tuple(float(x) % 1.0 for x in phase_offsets)
        offsets = tuple(0.0 if x >= 1.0 else x for x in offsets)
    else:
        if phase_offsets is not None:
            raise InvalidGaitError(
                f"phase_offsets are only accepted with gait 'custom', got gait {name!r}"
            )
        if name not in GAIT_NAMES:
            raise InvalidGaitError(f'gait name must be one of {GAIT_NAMES}, got {name!r}')
        offsets = gait_phase_offsets(name, legs)
    return GaitPattern(
        name=name,
        leg_names=legs,
        phase_offsets=offsets,
        duty_factor=duty_factor,
        period_s=period_s,
        step_length_m=step_length_m,
        step_height_m=step_height_m,
    )


def carried_mass_per_leg_kg(
    total_mass_kg: float, leg_mass_kg: float, supporting_legs: ArrayLike
) -> NDArray[np.float64]:
    """Mass carried by each stance leg, ``(M - m_leg * L) / L`` (Eq. 2, authors' bench code).

    Parameters
    ----------
    total_mass_kg : float
        Robot mass ``M`` including payload [kg].
    leg_mass_kg : float
        Mass of one leg ``m_leg`` [kg].
    supporting_legs : int or array of int, shape (n,)
        ``L(t)``.

    Returns
    -------
    ndarray, shape (n,)
        [kg]; ``inf`` where ``L = 0`` (no leg on the ground: nothing is carried by a leg, the
        body is unsupported), so a caller cannot mistake that instant for a light load.
    """
    L = np.atleast_1d(np.asarray(supporting_legs, dtype=float))
    if np.any(L < 0):
        raise InvalidGaitError(f'supporting_legs must be >= 0, got min {L.min()}')
    with np.errstate(divide='ignore', invalid='ignore'):
        m = (float(total_mass_kg) - float(leg_mass_kg) * L) / L
    return np.where(L > 0, m, np.inf)
