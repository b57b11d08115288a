"""Gait-parameter sweeps of the energetic descriptors (Brodoline et al. 2024, Fig. 3A-D).

A :class:`SweepCurve` is one gait configuration (gait, leg count, duty factor, step length)
evaluated over speeds from :data:`MIN_SPEED_MPS` up to the configuration's maximum speed under
the actuator limits, and over a payload band (default 0 to 0.5 kg).  Speed sets the period,
``T = step_length / (beta v)``; ``P_in`` comes from Eq. 1 (:func:`predict_power_in_w`), ``P_out``
from Eq. 6 (:class:`OutputPowerModel`).

Optimal operating points are taken on the nominal payload (the first of the band): maximum
``P_out``, minimum ``CoT/M`` and maximum efficiency; ``min(eta)`` is reported per curve, over
every point and over the points the bench covers (:meth:`SweepCurve.min_efficiency_point`: the
slowest speeds of a sweep often lie below the bench's slowest session, where Eq. 1 extrapolates
and ``eta`` is smallest).  The paper draws Fig. 3C at a 140 g load
(:data:`PAPER_GAIT_TYPE_PAYLOAD_KG`); :func:`with_payload` adds such a payload to a curve.

:func:`standard_sweeps` gives the paper's four sweeps for a robot's leg count (the duty-factor,
step-length and gait-type sweeps at that leg count; the leg-count sweep is always 4/6/8 legs as
Fig. 3D); :data:`STANDARD_SWEEPS` is AntBot's (6 legs).  The actuator limits default to AntBot's
servos' (:data:`hexapod_gait.feasibility.ANTBOT_LIMITS`).

Robot mass.  Every curve is for the robot of the output-power model (``RobotSpec.mass_kg``, the
robot described: ``hexapod-analyze energy --robot-mass``), except in the leg-count sweep: a
robot with more legs is heavier, so (as the authors' code, ``robot_mass = legs * m_leg +
body``) each of its curves keeps the described robot's body, ``M - N m_leg`` (``N`` the
described robot's legs, :attr:`SweepSpec.mass_reference_legs`), and carries its own ``k``
legs: ``M_k = M + (k - N) m_leg`` (AntBot, 2.183 kg on 6 legs of 0.166 kg: 1.851, 2.183 and
2.515 kg).  The curve of the robot's own leg count has the given mass.  Each curve records its
mass (``robot_mass_kg``; ``mass_rule`` says how in the leg-count sweep).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.metrics import G_MPS2
from hexapod_energy.prediction import (
    OutputPowerModel,
    PhasePowerModel,
    bench_domain_check,
    geometry_limits,
    predict_power_in_w,
)

__all__ = [
    'DEFAULT_PAYLOADS_KG',
    'GAIT_TYPE_MIN_SPEED_MPS',
    'MIN_SPEED_MPS',
    'PAPER_GAIT_TYPE_PAYLOAD_KG',
    'STANDARD_SWEEPS',
    'SweepCurve',
    'SweepSpec',
    'compare_curves',
    'run_standard_sweeps',
    'standard_sweeps',
    'sweep_curve',
    'with_payload',
]

MIN_SPEED_MPS = 0.05
#: the gait-type sweep (3C) starts lower: the wave gait's saving under load lies at the slowest
#: speeds (simulated AntBot with 0.5 kg, P_loss: -12 % at 0.02 m/s, -9 % at 0.04, -5 % at 0.06,
#: even at 0.08, +6 % at 0.1; the paper: up to -8 % below 0.13 m/s). Below the bench's slowest
#: walking session the curves read the surfaces between it and the standing session (flagged
#: outside the bench, dotted and clipped in the plots)
GAIT_TYPE_MIN_SPEED_MPS = 0.02
DEFAULT_PAYLOADS_KG = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5)
#: the load of the paper's Fig. 3C (tripod against wave gait: "when the robot transports a load
#: of 140 g"); the gait-type plot's nominal (solid) curve
PAPER_GAIT_TYPE_PAYLOAD_KG = 0.14


@dataclass(frozen=True)
class SweepSpec:
    """One curve of a sweep: gait configuration and its label."""

    label: str
    gait: str = 'tripod'
    leg_count: int = 6
    duty_factor: float = 0.5
    step_length_m: float = 0.10
    step_height_m: float = 0.04
    #: when set, the robot's given mass is that of a robot with this many legs: the curve keeps
    #: its body and carries ``leg_count`` legs, ``M + (leg_count - mass_reference_legs) m_leg``
    #: (the leg-count sweep); None: the given mass whatever ``leg_count``
    mass_reference_legs: int | None = None
    #: the curve's lowest speed [m/s]; None: the sweep's (:data:`MIN_SPEED_MPS` by default)
    min_speed_mps: float | None = None


def standard_sweeps(leg_count: int = 6) -> dict[str, tuple[SweepSpec, ...]]:
    """The paper's four sweeps for a robot of ``leg_count`` legs.

    Duty factor (3A: beta 0.5-0.8, 100 mm steps), step length (3B: 70-140 mm, beta 0.5) and gait
    type (3C: the alternating gait at beta 0.5, the wave gait at its typical duty factor, 1 - 1/n
    (the paper's 0.83 for 6 legs), and at 0.5, from :data:`GAIT_TYPE_MIN_SPEED_MPS`) at
    ``leg_count`` legs, the alternating gait being
    ``tripod`` for 6 legs; leg count (3D): the alternating gait on 4, 6 and 8 legs, beta 0.5,
    100 mm, whatever ``leg_count``, each curve with the body of the ``leg_count``-legged robot
    and its own legs (:attr:`SweepSpec.mass_reference_legs`, module docstring).
    """
    n = int(leg_count)
    alt = 'tripod' if n == 6 else 'alternating'
    wave_beta = 0.83 if n == 6 else round(1.0 - 1.0 / n, 3)
    return {
        'duty_factor': tuple(
            SweepSpec(f'beta {b:.1f}', alt, n, b) for b in (0.5, 0.6, 0.7, 0.8)
        ),
        'step_length': tuple(
            SweepSpec(f'step {int(round(s * 1000))} mm', alt, n, 0.5, s)
            for s in (0.07, 0.10, 0.12, 0.14)
        ),
        'gait_type': tuple(
            SweepSpec(label, g, n, b, min_speed_mps=GAIT_TYPE_MIN_SPEED_MPS)
            for label, g, b in ((f'{alt} beta 0.5', alt, 0.5),
                                (f'wave beta {wave_beta:g}', 'wave', wave_beta),
                                ('wave beta 0.5', 'wave', 0.5))
        ),
        'leg_count': tuple(
            SweepSpec(f'{k} legs', 'alternating', k, 0.5, mass_reference_legs=n)
            for k in (4, 6, 8)
        ),
    }


#: The paper's four sweeps for AntBot (6 legs): duty factor (3A), step length (3B), gait type
#: (3C), leg count (3D).
STANDARD_SWEEPS: dict[str, tuple[SweepSpec, ...]] = standard_sweeps(6)


@dataclass(frozen=True)
class SweepCurve:
    """Descriptors of one configuration over speed x payload.

    Attributes
    ----------
    spec : SweepSpec
    speeds_mps : (k,)
    payloads_kg : (m,)
    mass_kg : (m,)          total robot mass per payload [kg] (this curve's robot: see
                            :attr:`SweepSpec.mass_reference_legs`)
    power_in_w, power_out_w, efficiency, cot_per_mass, specific_resistance : (k, m)
        ``cot_per_mass`` = CoT/M [J/(m kg)].
    outside_bench : (k, m) bool, optional
        Points whose ``P_in`` reads the bench surfaces outside their sessions' range
        (:func:`~hexapod_energy.prediction.bench_domain_check`); ``outside_reasons`` says how.
    """

    spec: SweepSpec
    speeds_mps: np.ndarray
    payloads_kg: np.ndarray
    mass_kg: np.ndarray
    power_in_w: np.ndarray
    power_out_w: np.ndarray
    efficiency: np.ndarray
    cot_per_mass: np.ndarray
    specific_resistance: np.ndarray
    outside_bench: np.ndarray | None = None
    outside_reasons: tuple[str, ...] = ()
    mass_rule: str = ''   # how the mass was set (the leg-count sweep's body + legs), else ''
    #: why the schedule is not walkable though Eq. 1 can price it (a whole side in swing: the
    #: paper's wave at beta 0.5, Fig. 3C, drawn as the paper does), else ''
    support_note: str = ''

    @property
    def robot_mass_kg(self) -> float:
        """This curve's robot mass without payload [kg]."""
        return float(self.mass_kg[0] - self.payloads_kg[0])

    def optimal_points(self, payload_index: int = 0) -> dict[str, dict[str, float]]:
        """Operating points at one payload: ``max_power_out``, ``min_cot_per_mass``,
        ``max_efficiency``, each ``{'speed_mps', 'value', 'unit'}`` (W, J/(m kg), a fraction)."""
        j = payload_index
        out = {}
        for key, arr, pick, unit in (
            ('max_power_out', self.power_out_w[:, j], np.argmax, 'W'),
            ('min_cot_per_mass', self.cot_per_mass[:, j], np.argmin, 'J/(m kg)'),
            ('max_efficiency', self.efficiency[:, j], np.argmax, 'fraction'),
        ):
            i = int(pick(arr))
            out[key] = {'speed_mps': float(self.speeds_mps[i]), 'value': float(arr[i]),
                        'unit': unit}
            if self.outside_bench is not None:
                out[key]['outside_bench'] = bool(self.outside_bench[i, j])
        return out

    @property
    def min_efficiency(self) -> float:
        """min(eta) over speeds and payloads."""
        return float(np.min(self.efficiency))

    def min_efficiency_point(self, *, on_bench: bool = False) -> dict[str, Any]:
        """Where ``min(eta)`` lies: ``{'value', 'speed_mps', 'payload_kg', 'outside_bench'}``
        over every point, or (``on_bench``) over the points the bench covers only (value and
        place None when it covers none; without an ``outside_bench`` mask every point counts
        as covered)."""
        eff = np.asarray(self.efficiency, dtype=float)
        out = np.zeros(eff.shape, bool) if self.outside_bench is None else \
            np.asarray(self.outside_bench, dtype=bool)
        cand = np.where(out, np.nan, eff) if on_bench else eff
        ok = np.isfinite(cand)
        if not ok.any():
            return {'value': None, 'speed_mps': None, 'payload_kg': None,
                    'outside_bench': None}
        i, j = np.unravel_index(int(np.argmin(np.where(ok, cand, np.inf))), cand.shape)
        return {'value': float(cand[i, j]), 'speed_mps': float(self.speeds_mps[i]),
                'payload_kg': float(self.payloads_kg[j]), 'outside_bench': bool(out[i, j])}

    def to_dict(self) -> dict[str, Any]:
        return {
            'label': self.spec.label,
            'gait': self.spec.gait,
            'leg_count': self.spec.leg_count,
            'duty_factor': self.spec.duty_factor,
            'step_length_m': self.spec.step_length_m,
            'robot_mass_kg': self.robot_mass_kg,
            'mass_kg': self.mass_kg.tolist(),
            'mass_rule': self.mass_rule,
            'speeds_mps': self.speeds_mps.tolist(),
            'payloads_kg': self.payloads_kg.tolist(),
            'power_in_w': self.power_in_w.tolist(),
            'power_out_w': self.power_out_w.tolist(),
            'efficiency': self.efficiency.tolist(),
            'specific_cost_of_transport': self.cot_per_mass.tolist(),
            'specific_resistance': self.specific_resistance.tolist(),
            'optimal_points': self.optimal_points(),
            'min_efficiency': self.min_efficiency,
            **self._min_efficiency_keys(),
            'max_speed_mps': float(self.speeds_mps[-1]),
            'outside_bench': None if self.outside_bench is None else
            self.outside_bench.tolist(),
            'outside_bench_reasons': list(self.outside_reasons),
            'not_walkable': self.support_note,
        }

    def _min_efficiency_keys(self) -> dict[str, Any]:
        """energy.json's keys beside ``min_efficiency``: where it lies, whether that point is
        extrapolated, and the minimum over the points the bench covers."""
        every = self.min_efficiency_point()
        bench = self.min_efficiency_point(on_bench=True)
        return {'min_efficiency_speed_mps': every['speed_mps'],
                'min_efficiency_payload_kg': every['payload_kg'],
                'min_efficiency_outside_bench': every['outside_bench'],
                'min_efficiency_on_bench': bench['value'],
                'min_efficiency_on_bench_speed_mps': bench['speed_mps'],
                'min_efficiency_on_bench_payload_kg': bench['payload_kg']}


def sweep_curve(
    spec: SweepSpec,
    phase_power: PhasePowerModel,
    output_power: OutputPowerModel,
    *,
    payloads_kg: Sequence[float] = DEFAULT_PAYLOADS_KG,
    n_speeds: int = 40,
    limits: Any | None = None,
    min_speed_mps: float = MIN_SPEED_MPS,
    load_offset_kg: float = 0.0,
) -> SweepCurve:
    """Evaluate one configuration over speeds up to its maximum and over payloads.

    ``load_offset_kg`` is passed to :func:`predict_power_in_w` (bench load = m_c - offset);
    ``spec.min_speed_mps``, when set, replaces ``min_speed_mps``;
    ``limits`` (default AntBot's servos') set the maximum speed.  The robot's mass is
    ``output_power.robot.mass_kg``, or with ``spec.mass_reference_legs`` set that robot's
    body with ``spec.leg_count`` legs (module docstring).

    Raises
    ------
    InvalidInputError
        If the maximum speed is below the sweep start, or the robot's mass does not exceed its
        legs' (``M <= n m_leg``: the body would carry a negative mass).
    ValueError
        If the leg cannot follow the configuration's path (out of reach).
    """
    from hexapod_gait.feasibility import ANTBOT_LIMITS, max_speed_mps
    from hexapod_gait.gait import make_gait

    lim = ANTBOT_LIMITS if limits is None else limits
    m_leg = output_power.robot.leg_mass_kg
    legs_kg = spec.leg_count * m_leg
    given = robot_kg = float(output_power.robot.mass_kg)
    rule = ''
    if spec.mass_reference_legs is not None:
        n_ref = int(spec.mass_reference_legs)
        body = given - n_ref * m_leg
        robot_kg = body + legs_kg
        rule = (f'body {body:.4g} kg (the {given:.4g} kg {n_ref}-legged robot less its legs) '
                f'+ {spec.leg_count} legs x {m_leg:.4g} kg = {robot_kg:.4g} kg')
    if robot_kg <= legs_kg:
        raise InvalidInputError(
            f'{spec.label}: robot mass {robot_kg:.4g} kg <= {spec.leg_count} '
            f'legs x {m_leg:.4g} kg = {legs_kg:.4g} kg')
    # the limits were measured on the bench's tip path: another step geometry reaches the
    # joints' top speed at other phase durations
    shape = make_gait(spec.gait, leg_count=spec.leg_count, duty_factor=spec.duty_factor,
                      step_length_m=spec.step_length_m, step_height_m=spec.step_height_m)
    lim = geometry_limits(phase_power, shape, lim)
    v_max = max_speed_mps(spec.duty_factor, spec.step_length_m, lim)
    if spec.min_speed_mps is not None:
        min_speed_mps = float(spec.min_speed_mps)
    if v_max <= min_speed_mps:
        raise InvalidInputError(
            f'{spec.label}: maximum speed {v_max:.3f} m/s is below the sweep start '
            f'{min_speed_mps} m/s'
        )
    speeds = np.linspace(min_speed_mps, v_max, n_speeds)
    periods = spec.step_length_m / (spec.duty_factor * speeds)
    gait = make_gait(
        spec.gait, leg_count=spec.leg_count, duty_factor=spec.duty_factor,
        period_s=float(periods[-1]), step_length_m=spec.step_length_m,
        step_height_m=spec.step_height_m,
    )
    bp, supporting = gait.support_profile()
    airborne = float(np.diff(np.append(np.asarray(bp, float), 1.0))[
        np.asarray(supporting) == 0].sum())
    if airborne > 1e-9:
        # Eq. 1 carries nothing while no leg stands: less support read as less power (a tripod
        # at beta 0.3 gave the lowest CoT/M of any curve; an outside review)
        raise InvalidInputError(
            f'{spec.label}: no leg on the ground {100 * airborne:.0f} % of the cycle '
            f'({spec.gait}, duty factor {spec.duty_factor:g}, {spec.leg_count} legs): Eq. 1 '
            'has no weight to carry then; raise the duty factor')
    from hexapod_energy.recommend import lifted_sides
    support_note = '; '.join(lifted_sides(gait))
    payloads = np.asarray(payloads_kg, dtype=float)
    mass = robot_kg + payloads
    p_in = np.stack(
        [
            np.asarray(predict_power_in_w(phase_power, gait, total_mass_kg=float(m),
                                          leg_mass_kg=output_power.robot.leg_mass_kg,
                                          periods_s=periods,
                                          load_offset_kg=load_offset_kg))
            for m in mass
        ],
        axis=1,
    )
    checks = [bench_domain_check(phase_power, gait, total_mass_kg=float(m),
                                 leg_mass_kg=output_power.robot.leg_mass_kg, periods_s=periods,
                                 load_offset_kg=load_offset_kg) for m in mass]
    outside = np.array([[bool(c[i]) for c in checks] for i in range(periods.size)])
    reasons = tuple(dict.fromkeys(r for c in checks for rs in c for r in rs))
    # Eq. 6 depends on the total mass only: a heavier robot is the model's robot with more payload
    p_out = np.asarray(output_power.power_out_w(
        gait, payload_kg=mass - output_power.robot.mass_kg, periods_s=periods))
    v = speeds[:, None]
    with np.errstate(divide='ignore', invalid='ignore'):
        eff = p_out / p_in
        cot_m = (p_in - p_out) / (mass[None, :] * v)
        sr = p_in / (mass[None, :] * G_MPS2 * v)
    return SweepCurve(spec, speeds, payloads, mass, p_in, p_out, eff, cot_m, sr, outside,
                      _summarise_reasons(reasons), rule, support_note)


def _summarise_reasons(reasons: Sequence[str]) -> tuple[str, ...]:
    """One line per kind of reason (stance/swing duration, stance load): the extreme."""
    kinds: dict[str, list[str]] = {}
    for r in reasons:
        kinds.setdefault(' '.join(r.split()[:2]) if ' load ' in r else r.split()[0], []).append(r)
    out = []
    for rs in kinds.values():
        out.append(rs[0] if len(rs) == 1 else f'{rs[0]} (and {len(rs) - 1} more like it)')
    return tuple(out)


def run_standard_sweeps(
    phase_power: PhasePowerModel,
    output_power: OutputPowerModel,
    *,
    sweeps: dict[str, tuple[SweepSpec, ...]] | None = None,
    payloads_kg: Sequence[float] = DEFAULT_PAYLOADS_KG,
    n_speeds: int = 40,
    progress: Any | None = None,
    load_offset_kg: float = 0.0,
    leg_count: int = 6,
    limits: Any | None = None,
    skipped: list[str] | None = None,
) -> dict[str, list[SweepCurve]]:
    """All four standard sweeps for ``leg_count`` legs (:func:`standard_sweeps`) or ``sweeps``.

    Parameters
    ----------
    progress : tqdm-like, optional
        Advanced once per curve.
    limits : hexapod_gait.feasibility.ActuatorLimits, optional
        Default AntBot's servo limits.
    skipped : list of str, optional
        When given, a curve the model cannot evaluate (a leg that cannot reach its step, a
        robot lighter than its legs, a maximum speed below the start) is left out and a line
        naming the sweep and the curve is appended here; without it the error is raised.
    """
    todo = standard_sweeps(leg_count) if sweeps is None else sweeps
    out: dict[str, list[SweepCurve]] = {}
    for name, specs in todo.items():
        out[name] = []
        for spec in specs:
            try:
                out[name].append(
                    sweep_curve(spec, phase_power, output_power, payloads_kg=payloads_kg,
                                n_speeds=n_speeds, load_offset_kg=load_offset_kg,
                                limits=limits)
                )
            except ValueError as err:
                if skipped is None:
                    raise
                skipped.append(f'sweep {name!r}, curve {spec.label!r} skipped: {err}')
            if progress is not None:
                progress.update(1)
    return out


def compare_curves(base: SweepCurve, other: SweepCurve, *, n_speeds: int = 60
                   ) -> dict[str, Any]:
    """``other``'s CoT/M over ``base``'s at the speeds both reach, per payload (Fig. 3C's
    question: at which speeds does the wave gait lose less than the tripod?).

    Both curves must share their payloads. Returns ``speeds_mps`` (n,), ``payloads_kg`` (m,),
    ``ratio`` (n, m: ``other / base``, below 1 where ``other`` is cheaper), ``outside_bench``
    (n, m: either curve extrapolated there), and per payload ``below_one_until_mps`` (the
    highest speed of the first run of speeds where ``other`` is cheaper, None when it never
    is) and ``best_ratio`` with ``best_speed_mps``; the same on the points the bench covers
    for both curves only: ``below_one_until_mps_on_bench``, ``best_ratio_on_bench`` and
    ``best_speed_mps_on_bench`` (None where the bench covers no speed of that payload). A
    saving found only at extrapolated speeds is the surfaces' reading below the bench's
    slowest session, not a measured one.

    Raises
    ------
    InvalidInputError
        If the payloads differ or the curves share no speed range.
    """
    pay = np.asarray(base.payloads_kg, dtype=float)
    if pay.shape != np.shape(other.payloads_kg) or not np.allclose(pay, other.payloads_kg):
        raise InvalidInputError(f'{base.spec.label!r} and {other.spec.label!r}: the curves '
                                'have different payloads')
    lo = max(float(base.speeds_mps[0]), float(other.speeds_mps[0]))
    hi = min(float(base.speeds_mps[-1]), float(other.speeds_mps[-1]))
    if not hi > lo:
        raise InvalidInputError(f'{base.spec.label!r} and {other.spec.label!r} share no '
                                'speed range')
    v = np.linspace(lo, hi, n_speeds)

    def at(c: SweepCurve, values: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(v, c.speeds_mps, values[:, j])
                                for j in range(pay.size)])

    ratio = at(other, other.cot_per_mass) / at(base, base.cot_per_mass)
    outside = np.zeros(ratio.shape, dtype=bool)
    for c in (base, other):
        if c.outside_bench is not None:
            outside |= at(c, np.asarray(c.outside_bench, dtype=float)) > 0.0
    until = [_first_run_end(v, ratio[:, j] < 1.0) for j in range(pay.size)]
    until_bench = [_first_run_end(v, (ratio[:, j] < 1.0) & ~outside[:, j])
                   for j in range(pay.size)]
    best = np.argmin(ratio, axis=0)
    best_bench: list[int | None] = [
        int(np.argmin(np.where(outside[:, j], np.inf, ratio[:, j])))
        if not outside[:, j].all() else None for j in range(pay.size)]
    return {'base': base.spec.label, 'other': other.spec.label,
            'speeds_mps': v, 'payloads_kg': pay, 'ratio': ratio, 'outside_bench': outside,
            'below_one_until_mps': until,
            'best_ratio': [float(ratio[i, j]) for j, i in enumerate(best)],
            'best_speed_mps': [float(v[i]) for i in best],
            'below_one_until_mps_on_bench': until_bench,
            'best_ratio_on_bench': [None if i is None else float(ratio[i, j])
                                    for j, i in enumerate(best_bench)],
            'best_speed_mps_on_bench': [None if i is None else float(v[i])
                                        for i in best_bench]}


def _first_run_end(v: np.ndarray, below: np.ndarray) -> float | None:
    """The highest speed of the first run of ``below`` (None when it is nowhere true)."""
    if not below.any():
        return None
    first = int(np.argmax(below))
    run_end = first + int(np.argmin(below[first:])) - 1 if not below[first:].all() \
        else v.size - 1
    return float(v[run_end])


def with_payload(curve: SweepCurve, payload_kg: float, phase_power: PhasePowerModel,
                 output_power: OutputPowerModel, *, limits: Any | None = None,
                 load_offset_kg: float = 0.0) -> SweepCurve:
    """``curve`` with one more payload column, evaluated like the others (same speeds), the
    columns in payload order; ``curve`` itself when it has that payload already.  For a plot
    whose nominal load is not in the sweep's band (Fig. 3C at the paper's 140 g,
    :data:`PAPER_GAIT_TYPE_PAYLOAD_KG`); energy.json keeps the sweep's own payloads.

    Raises
    ------
    InvalidInputError
        If the new column's speeds differ from the curve's (other limits or speed count).
    """
    pay = np.asarray(curve.payloads_kg, dtype=float)
    if np.any(np.isclose(pay, payload_kg, rtol=0.0, atol=1e-9)):
        return curve
    extra = sweep_curve(curve.spec, phase_power, output_power, payloads_kg=(payload_kg,),
                        n_speeds=curve.speeds_mps.size, limits=limits,
                        min_speed_mps=float(curve.speeds_mps[0]),
                        load_offset_kg=load_offset_kg)
    if not np.allclose(extra.speeds_mps, curve.speeds_mps, rtol=1e-12, atol=0.0):
        raise InvalidInputError(f'{curve.spec.label}: the {payload_kg:g} kg column has other '
                                'speeds than the curve (other limits?)')
    order = np.argsort(np.append(pay, payload_kg), kind='stable')

    def col(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        return np.concatenate([np.asarray(a), np.asarray(b)], axis=-1)[..., order]

    out = None if curve.outside_bench is None or extra.outside_bench is None else \
        col(curve.outside_bench, extra.outside_bench)
    return SweepCurve(curve.spec, curve.speeds_mps, col(pay, extra.payloads_kg),
                      col(curve.mass_kg, extra.mass_kg), col(curve.power_in_w, extra.power_in_w),
                      col(curve.power_out_w, extra.power_out_w),
                      col(curve.efficiency, extra.efficiency),
                      col(curve.cot_per_mass, extra.cot_per_mass),
                      col(curve.specific_resistance, extra.specific_resistance), out,
                      tuple(dict.fromkeys(curve.outside_reasons + extra.outside_reasons)),
                      curve.mass_rule)
