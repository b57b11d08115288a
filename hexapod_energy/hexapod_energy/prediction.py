"""Whole-robot input and output power from one leg (Brodoline et al. 2024, Eq. 1-3, 6).

Input power, Eq. 1, with the exact support profile ``L(t)`` of the gait (a step function of the
cycle phase, :meth:`hexapod_gait.gait.GaitPattern.support_profile`)::

    P_in = sum_j w_j [ L_j P_stance(T_stance, m_c(L_j)) + (N - L_j) P_swing(T_swing, m_sw) ]

``w_j`` the width of support interval ``j`` (fractions of the cycle summing to 1), ``N`` the leg
count, ``T_stance = beta T``, ``T_swing = (1 - beta) T``, ``m_c(L) = (M - m_leg L) / L`` the mass
carried by each stance leg (Eq. 2) and ``m_sw`` the load of a swinging leg: 0 by default (a leg
in the air carries nothing; ``swing_load='carried'`` uses ``m_c`` as some readings of the paper
do).

Step geometry. The bench walks one tip path (the paper: 100 mm steps, 40 mm lift), so its
surfaces hold for that path; a robot walking another step length or height moves its joints
farther or less far in the same phase time. A phase of duration ``T`` along a joint path of
length ``J = sum_i integral |dq_i|`` (the leg's inverse kinematics over the phase) is read on
the surface at ``T J_bench / J``, the duration in which the bench's path is covered at the same
joint speeds (:func:`phase_duration_scales`; the model's ``bench_step_`` gives the bench's
geometry, the paths are taken at the run's duty factor). On the simulated AntBot at 0.15-0.45
m/s this brought 70 and 140 mm steps and 20 and 60 mm lifts from -18 .. +20 % to -8 .. +2 %
(the 100 mm runs -2 .. -4 %). A model that does not know its bench's geometry is used as is.

Output power, Eq. 6 summed over the legs: every leg follows the same joint path in its own leg
phase (the single-leg method's premise), shifted by its phase offset; while in stance it carries
``m_c(L(t))`` at the cycle phase it is at.  See :mod:`hexapod_energy.dynamics` for the
definition of average mechanical power.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Literal, Protocol

import numpy as np
from numpy.typing import ArrayLike

from hexapod_energy.dynamics import (
    ANTBOT_LEG_SPEC,
    LegDynamics,
    LegSpec,
    PhaseTorques,
    PowerDefinition,
    mean_mechanical_power_w,
)
from hexapod_energy.errors import InvalidInputError

__all__ = [
    'ANTBOT_ROBOT',
    'NO_BASAL_NOTE',
    'OutputPowerModel',
    'PhasePowerModel',
    'joint_paths',
    'RobotSpec',
    'bench_domain_check',
    'geometry_limits',
    'carried_mass_profile_kg',
    'phase_duration_scales',
    'phase_path',
    'power_breakdown_w',
    'predict_power_in_w',
]


@dataclass(frozen=True)
class RobotSpec:
    """Robot constants (DESIGN §7 defaults: AntBot).

    Attributes
    ----------
    mass_kg : float
        Robot mass without payload [kg].
    leg : LegSpec
        DH table and link masses of every leg.
    """

    mass_kg: float = 2.183
    leg: LegSpec = field(default_factory=lambda: ANTBOT_LEG_SPEC)

    @property
    def leg_mass_kg(self) -> float:
        return self.leg.leg_mass_kg

    def total_mass_kg(self, payload_kg: float) -> float:
        return self.mass_kg + float(payload_kg)


ANTBOT_ROBOT = RobotSpec()


class PhasePowerModel(Protocol):
    """Anything giving average phase powers, e.g. a fitted
    :class:`hexapod_energy.single_leg.SingleLegModel`."""

    def p_stance_w(self, t_stance_s: ArrayLike, load_kg: ArrayLike) -> np.ndarray: ...

    def p_swing_w(self, t_swing_s: ArrayLike, load_kg: ArrayLike) -> np.ndarray: ...


def _carried(total_mass_kg: float, leg_mass_kg: float, supporting: np.ndarray) -> np.ndarray:
    from hexapod_gait.gait import carried_mass_per_leg_kg

    return carried_mass_per_leg_kg(total_mass_kg, leg_mass_kg, supporting)


def predict_power_in_w(
    model: PhasePowerModel,
    gait: Any,
    *,
    total_mass_kg: float,
    leg_mass_kg: float = ANTBOT_LEG_SPEC.leg_mass_kg,
    periods_s: ArrayLike | None = None,
    swing_load: Literal['zero', 'carried'] = 'zero',
    load_offset_kg: float = 0.0,
) -> np.ndarray | float:
    """Whole-robot average input power, Eq. 1 [W].

    Parameters
    ----------
    model : PhasePowerModel
        Single-leg phase-power surfaces.
    gait : hexapod_gait.gait.GaitPattern
        Gait (leg count, offsets, duty factor, period).
    total_mass_kg : float
        Robot mass with payload ``M`` [kg].
    leg_mass_kg : float
        Mass of one leg [kg].
    periods_s : array (k,), optional
        Evaluate at these periods instead of ``gait.period_s`` (same support profile).
    swing_load : {'zero', 'carried'}
        Load of a swinging leg (module docstring).
    load_offset_kg : float
        Subtracted from ``m_c`` to give the bench load the surfaces are evaluated at [kg]
        (clipped at 0).  0 by the paper: the bench tip carries ``(m_leg + load) g``, a robot's
        stance tip ``M g / L = (m_c + m_leg) g`` (the simulated robot's too,
        ``robot_sim.tip_forces_n``), so ``load = m_c``.  A bench whose tip also carries a
        stage of mass ``m_s`` is matched by ``load_offset_kg = m_s``.

    Returns
    -------
    float, or array (k,) when ``periods_s`` is given.
    """
    scalar = periods_s is None
    stance, swing, _, _ = _phase_terms(model, gait, total_mass_kg=total_mass_kg,
                                       leg_mass_kg=leg_mass_kg, periods_s=periods_s,
                                       swing_load=swing_load, load_offset_kg=load_offset_kg)
    total = stance + swing
    return float(total[0]) if scalar else total


def _phase_terms(model: PhasePowerModel, gait: Any, *, total_mass_kg: float,
                 leg_mass_kg: float, periods_s: ArrayLike | None, swing_load: str,
                 load_offset_kg: float, basal: Any = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Eq. 1's stance and swing sums over the support profile, (k,) each [W]; with
    ``basal`` (one leg's basal power at a load [W], a callable) also the basal power of the
    stance legs at their loads and of the swing legs unloaded (else zeros)."""
    bp, supporting = gait.support_profile()
    widths = np.diff(np.append(bp, 1.0))
    n_legs = gait.leg_count
    beta = gait.duty_factor
    periods = np.atleast_1d(np.asarray(gait.period_s if periods_s is None else periods_s,
                                       dtype=float))
    if np.any(periods <= 0):
        raise InvalidInputError(f'periods_s must be > 0, got min {periods.min()}')
    if swing_load not in ('zero', 'carried'):
        raise InvalidInputError(f"swing_load must be 'zero' or 'carried', got {swing_load!r}")
    stance, swing = np.zeros_like(periods), np.zeros_like(periods)
    hold_st, hold_sw = np.zeros_like(periods), np.zeros_like(periods)
    k_st, k_sw = phase_duration_scales(model, gait)
    t_st, t_sw = k_st * beta * periods, k_sw * (1.0 - beta) * periods
    for w, big_l in zip(widths, supporting):
        if w <= 0:
            continue
        m_c = max(float(_carried(total_mass_kg, leg_mass_kg, np.array([big_l]))[0]) -
                  float(load_offset_kg), 0.0)
        if big_l > 0:
            stance += w * big_l * model.p_stance_w(t_st, m_c)
            if basal is not None:
                hold_st += w * big_l * float(basal(m_c))
        if big_l < n_legs:
            m_sw = m_c if (swing_load == 'carried' and big_l > 0) else 0.0
            swing += w * (n_legs - big_l) * model.p_swing_w(t_sw, m_sw)
            if basal is not None:
                hold_sw += w * (n_legs - big_l) * float(basal(m_sw))
    return stance, swing, hold_st, hold_sw


#: why :func:`power_breakdown_w` has no holding split (said in ``energy.json`` ``warnings``,
#: its ``power_breakdown_w.holding_missing`` and the where-the-watts-go plot)
NO_BASAL_NOTE = ('the bench has no 0 Hz (standing) session: no basal power per load, so the '
                 'holding split of the power breakdown (holding_w, stance_motion_w, '
                 'swing_motion_w, holding_share) is unknown (null); record a 0 Hz session '
                 'per load')


def power_breakdown_w(
    model: PhasePowerModel,
    gait: Any,
    *,
    total_mass_kg: float,
    leg_mass_kg: float = ANTBOT_LEG_SPEC.leg_mass_kg,
    swing_load: Literal['zero', 'carried'] = 'zero',
    load_offset_kg: float = 0.0,
) -> dict[str, float]:
    """Where Eq. 1's input power goes, for one gait [W].

    ``stance_w`` and ``swing_w``: the legs in stance and in swing (their sum is
    :func:`predict_power_in_w`). With the bench's basal power (``model.basal_power_at_w``,
    the 0 Hz sessions interpolated over load; a model without it leaves these nan):
    ``holding_w``, what the legs draw standing still at the loads they carry in this support
    pattern (a swinging leg unloaded); ``stance_motion_w`` and ``swing_motion_w``, what moving
    adds in each phase (``stance_w - `` its holding part, likewise for swing; either may be
    negative where a phase surface lies below the basal power). Arguments as
    :func:`predict_power_in_w`.
    """
    basal = getattr(model, 'basal_power_at_w', None)
    has_basal = basal is not None and math.isfinite(float(basal(0.0)))
    stance, swing, hold_st, hold_sw = _phase_terms(
        model, gait, total_mass_kg=total_mass_kg, leg_mass_kg=leg_mass_kg, periods_s=None,
        swing_load=swing_load, load_offset_kg=load_offset_kg,
        basal=basal if has_basal else None)
    nan = float('nan')
    out = {'predicted_w': float(stance[0] + swing[0]), 'stance_w': float(stance[0]),
           'swing_w': float(swing[0]), 'holding_w': nan, 'stance_motion_w': nan,
           'swing_motion_w': nan}
    if has_basal:
        out.update(holding_w=float(hold_st[0] + hold_sw[0]),
                   stance_motion_w=float(stance[0] - hold_st[0]),
                   swing_motion_w=float(swing[0] - hold_sw[0]))
    return out


def bench_domain_check(
    model: Any,
    gait: Any,
    *,
    total_mass_kg: float,
    leg_mass_kg: float = ANTBOT_LEG_SPEC.leg_mass_kg,
    periods_s: ArrayLike | None = None,
    swing_load: Literal['zero', 'carried'] = 'zero',
    load_offset_kg: float = 0.0,
) -> list[list[str]]:
    """Where :func:`predict_power_in_w` reads the surfaces outside the bench's sessions.

    One list of reasons per period (``gait.period_s``, or each of ``periods_s``): the stance
    and swing durations and every stance load ``m_c(L) - offset`` of the support profile, each
    checked with ``model.outside_domain``; empty lists when all is inside. A model without
    ``outside_domain`` (not a fitted :class:`~hexapod_energy.single_leg.SingleLegModel`) is
    never flagged.
    """
    periods = np.atleast_1d(np.asarray(gait.period_s if periods_s is None else periods_s,
                                       dtype=float))
    check = getattr(model, 'outside_domain', None)
    if check is None:
        return [[] for _ in periods]
    _, supporting = gait.support_profile()
    loads = sorted({max(float(_carried(total_mass_kg, leg_mass_kg, np.array([big_l]))[0]) -
                        float(load_offset_kg), 0.0) for big_l in supporting if big_l > 0}) \
        or [0.0]
    swing_loads = loads if swing_load == 'carried' else [0.0]
    beta = gait.duty_factor
    k_st, k_sw = phase_duration_scales(model, gait)
    out = []
    for period in periods:
        t_st, t_sw = k_st * beta * period, k_sw * (1.0 - beta) * period
        reasons = check('stance', t_st, loads[0]) + check('swing', t_sw, swing_loads[0])
        for m in loads[1:]:
            reasons += [r for r in check('stance', t_st, m) if 'load' in r]
        out.append(list(dict.fromkeys(reasons)))
    return out


#: step lengths and heights within this fraction of the bench's are taken as the bench's
#: (:data:`hexapod_gait.step_limits.STEP_GEOMETRY_TOLERANCE`, the one source)
STEP_GEOMETRY_TOLERANCE = 0.005


def _leg_kwargs(leg: Any) -> dict[str, Any]:
    """``kinematics`` and ``neutral_tip_m`` of a ``LegDescription`` (None: AntBot's leg) for
    :mod:`hexapod_gait.step_limits`."""
    if leg is None:
        return {}
    from hexapod_gait.kinematics import LegKinematics

    return {'kinematics': LegKinematics(leg.dh), 'neutral_tip_m': leg.neutral_tip_m}


def phase_duration_scales(model: Any, gait: Any) -> tuple[float, float]:
    """Factors ``(k_stance, k_swing)`` on the phase durations at which Eq. 1 reads the bench
    surfaces for ``gait``'s step length and height (module docstring): the bench's joint path
    over the phase divided by the gait's, both at the gait's duty factor, with the leg of
    the robot's leg. ``(1, 1)`` when the model does not know
    its bench's geometry (``bench_step_`` None or absent), the gait has no step (a
    clock-driven schedule), or the geometry is the bench's. ``model.bench_leg_`` (a
    :class:`~hexapod_energy.leg_description.LegDescription`, default AntBot's leg) gives the
    kinematics and tip path. The computation is
    :func:`hexapod_gait.step_limits.phase_duration_scales` (shared with the gait node)."""
    from hexapod_gait.step_limits import phase_duration_scales as scales

    geo = getattr(model, 'bench_step_', None)
    length = float(getattr(gait, 'step_length_m', 0.0) or 0.0)
    height = float(getattr(gait, 'step_height_m', 0.0) or 0.0)
    if geo is None or not length > 0 or not height >= 0:
        return 1.0, 1.0
    try:
        kw = _leg_kwargs(getattr(model, 'bench_leg_', None))
    except ValueError:   # a leg the analytic kinematics cannot take: nothing to map
        return 1.0, 1.0
    return scales(float(gait.duty_factor), length, height,
                  bench_step_m=(float(geo[0]), float(geo[1])), **kw)


def load_offset_problem(load_offset_kg: float, mass_kg: float, leg_mass_kg: float,
                        legs: int) -> str:
    """Why ``load_offset_kg`` cannot work for a robot of ``mass_kg`` on ``legs`` legs (it is
    not below what a stance leg carries with half the legs down: every stance would read the
    bench at 0 kg or less, which the prediction clamps without a word), else ''."""
    from hexapod_gait.gait import carried_mass_per_leg_kg

    down = max(legs // 2, 1)
    m_c = float(carried_mass_per_leg_kg(mass_kg, leg_mass_kg, np.array([down]))[0])
    if load_offset_kg < m_c:
        return ''
    return (f'--load-offset {load_offset_kg:g} kg is not below the mass a stance leg carries '
            f'({m_c:.3g} kg with {down} of {legs} legs down): every stance would read the '
            'bench at a load of 0 kg or less')


def geometry_limits(model: Any, gait: Any, limits: Any) -> Any:
    """Actuator limits for ``gait``'s step geometry on the robot's leg (``model.bench_leg_``,
    a :class:`~hexapod_energy.leg_description.LegDescription`; absent or None: AntBot's): the
    minimal phase durations of ``limits`` (``hexapod_gait.feasibility.ActuatorLimits``,
    measured on the tip path and leg of ``limits.measured_on``: the paper's 0.15 s stance and
    0.16 s swing at 100 mm on AntBot's leg) are where the joints reach their top speed, so a
    path ``1/k`` times as long needs ``1/k`` times as long; the step-frequency limit is kept
    (:func:`hexapod_gait.step_limits.limits_for_gait`, the gait node's rule). ``limits``
    unchanged on the reference step and leg, with no step, or for a leg the analytic
    kinematics cannot take. (A 140 mm step on AntBot's leg: stance 0.22 s, swing 0.19 s; the
    top speed at beta 0.5 0.63 m/s, not the 0.84 m/s that the unscaled limits and the 3 Hz
    cap give, where the paper puts that step's best point. A PhantomX-like leg at 100 mm:
    stance 0.168 s, swing 0.185 s, its joints covering 12 % and 15 % more than AntBot's.)

    The bench model's own step (``bench_step_``) is not the limits' reference: the limits
    carry theirs (AntBot's 100 mm, 40 mm step unless measured elsewhere,
    :func:`hexapod_gait.step_limits.measured_on_leg`)."""
    from hexapod_gait.step_limits import limits_for_gait

    try:
        kw = _leg_kwargs(getattr(model, 'bench_leg_', None))
    except ValueError:   # a leg the analytic kinematics cannot take: nothing to map
        return limits
    return limits_for_gait(gait, limits, **kw)


def joint_paths(beta: float, length: float, height: float, leg: Any
                ) -> tuple[float, float]:
    """Joint-space path lengths ``sum_i integral |dq_i/dphi| dphi`` [rad] of one leg over its
    stance and over its swing (tripod leg 0; the path does not depend on the gait's legs):
    :func:`hexapod_gait.step_limits.joint_paths` on ``leg`` (None: AntBot's)."""
    from hexapod_gait.step_limits import joint_paths as paths

    return paths(beta, length, height, **_leg_kwargs(leg))


def carried_mass_profile_kg(
    gait: Any, leg_phase: ArrayLike, *, total_mass_kg: float, leg_mass_kg: float
) -> np.ndarray:
    """Mass each leg carries at leg phases ``leg_phase`` (n,) -> (legs, n) [kg], 0 in swing.

    Leg ``i`` at leg phase ``phi`` is at cycle phase ``(theta_i + phi) mod 1``; it carries
    ``m_c(L)`` there while ``phi < beta``.
    """
    phi = np.asarray(leg_phase, dtype=float)
    bp, supporting = gait.support_profile()
    offsets = np.asarray(gait.phase_offsets, dtype=float)[:, None]
    cycle = (offsets + phi[None, :]) % 1.0
    big_l = supporting[np.clip(np.searchsorted(bp, cycle, side='right') - 1, 0, len(bp) - 1)]
    m_c = _carried(total_mass_kg, leg_mass_kg, big_l.ravel()).reshape(big_l.shape)
    stance = phi[None, :] < gait.duty_factor
    return np.where(stance & np.isfinite(m_c), m_c, 0.0)


def phase_path(
    gait: Any,
    *,
    leg_index: int = 0,
    n_samples: int = 200,
    trajectory_factory: Callable[..., Any] | None = None,
    kinematics: Any | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """One leg's joint path over one leg cycle, parameterised by leg phase.

    Uses ``hexapod_gait.trajectory.LegTrajectory`` (or ``trajectory_factory(gait, leg_index,
    **kw)``) on a copy of the gait with ``T = 1 s``, so time derivatives are phase derivatives.

    Returns
    -------
    phase : (n,)            leg phase in [0, 1), 0 = touchdown
    q, dq_dphase, d2q_dphase2 : (n, 3)
    stance : (n,) bool      phase < beta
    """
    if trajectory_factory is None:
        try:
            from hexapod_gait.trajectory import LegTrajectory
        except ImportError as err:  # pragma: no cover - depends on the gait package's progress
            raise InvalidInputError(
                'output power needs hexapod_gait.trajectory.LegTrajectory, not importable'
            ) from err
        trajectory_factory = LegTrajectory
    unit = gait.with_changes(period_s=1.0)
    kw = {} if kinematics is None else {'kinematics': kinematics}
    traj = trajectory_factory(unit, leg_index, **kw)
    phase = np.arange(n_samples) / n_samples
    theta = float(unit.phase_offsets[leg_index])
    q, d1, d2 = traj.joints(theta + phase)
    return phase, np.asarray(q), np.asarray(d1), np.asarray(d2), phase < unit.duty_factor


@dataclass
class OutputPowerModel:
    """Whole-robot output power (Eq. 6) along the gait's joint paths.

    Parameters
    ----------
    robot : RobotSpec
    n_samples : int
        Phase samples per cycle. 600: the positive part of the joint power and the jumps of
        the carried mass at touchdown make the phase sum converge only as 1/n; at 200 samples
        the wave gait (beta 5/6) read +0.67 % (0.5694 W for 0.5656 W, an independent
        inverse-dynamics review), at 600 every gait tried is within 0.02 % of 4,800 samples.
    definition : {'absolute', 'positive', 'net'}
        Average mechanical power definition (:mod:`hexapod_energy.dynamics`).
    trajectory_factory : callable, optional
        Replaces ``hexapod_gait.trajectory.LegTrajectory`` (tests).
    kinematics : optional
        ``LegKinematics`` passed to the trajectory.
    """

    robot: RobotSpec = field(default_factory=RobotSpec)
    n_samples: int = 600
    definition: PowerDefinition = 'positive'
    trajectory_factory: Callable[..., Any] | None = None
    kinematics: Any | None = None
    _cache: dict[tuple[Any, ...], PhaseTorques] = field(default_factory=dict, repr=False)

    def __post_init__(self) -> None:
        self.dynamics = LegDynamics(self.robot.leg)

    def phase_torques(self, gait: Any) -> PhaseTorques:
        """Torque decomposition of the gait's leg path (cached by path shape)."""
        key = (gait.duty_factor, gait.step_length_m, gait.step_height_m, self.n_samples)
        if key not in self._cache:
            phase, q, d1, d2, stance = phase_path(
                gait, n_samples=self.n_samples, trajectory_factory=self.trajectory_factory,
                kinematics=self.kinematics,
            )
            self._cache[key] = self.dynamics.phase_torques(phase, q, d1, d2, stance)
        return self._cache[key]

    def power_out_w(
        self,
        gait: Any,
        *,
        payload_kg: ArrayLike = 0.0,
        periods_s: ArrayLike | None = None,
    ) -> np.ndarray | float:
        """Whole-robot average output power [W].

        Parameters
        ----------
        gait : GaitPattern
        payload_kg : float or array (m,)
            Payload on top of :attr:`RobotSpec.mass_kg` [kg].
        periods_s : array (k,), optional
            Periods to evaluate at (default ``gait.period_s``).

        Returns
        -------
        float if both are scalars, else array (k, m) (k = 1 or m = 1 squeezed away when scalar).
        """
        pt = self.phase_torques(gait)
        scalar_t = periods_s is None
        periods = np.atleast_1d(np.asarray(gait.period_s if scalar_t else periods_s, float))
        payload = np.asarray(payload_kg, dtype=float)
        scalar_m = payload.ndim == 0
        payloads = np.atleast_1d(payload)
        out = np.zeros((len(periods), len(payloads)))
        inv_t = 1.0 / periods
        for j, m_pay in enumerate(payloads):
            carried = carried_mass_profile_kg(
                gait, pt.phase, total_mass_kg=self.robot.total_mass_kg(float(m_pay)),
                leg_mass_kg=self.robot.leg_mass_kg,
            )  # (legs, n)
            # legs with the same carried-mass profile have the same power: evaluate once each
            carried, counts = np.unique(carried, axis=0, return_counts=True)
            # tau (legs, k, n, 3) = G + H / T^2 + (m_c + m_leg) u in stance (Eq. 4: the
            # stance tip carries the leg's own weight with its share of the body)
            supported = carried + self.robot.leg_mass_kg * pt.stance[None, :]
            tau = (
                pt.gravity_nm[None, None]
                + pt.inertial_nm_s2[None, None] * (inv_t**2)[None, :, None, None]
                + supported[:, None, :, None] * pt.per_carried_kg_nm[None, None]
            )
            power = tau * pt.dq_dphase[None, None] * inv_t[None, :, None, None]
            per_leg = mean_mechanical_power_w(power, self.definition, axis=-1)  # (legs, k)
            out[:, j] = counts @ per_leg
        if scalar_t and scalar_m:
            return float(out[0, 0])
        if scalar_t:
            return out[0]
        if scalar_m:
            return out[:, 0]
        return out

    def power_map_w(
        self,
        gait: Any,
        speeds_mps: ArrayLike,
        payloads_kg: ArrayLike,
    ) -> np.ndarray:
        """Output power over speed x payload (Fig. 7D), (n_speed, n_payload) [W].

        The period of each speed follows ``v = step_length / (beta T)``.
        """
        v = np.asarray(speeds_mps, dtype=float)
        if np.any(v <= 0):
            raise InvalidInputError(f'speeds must be > 0 m/s, got min {v.min()}')
        periods = gait.step_length_m / (gait.duty_factor * v)
        return np.asarray(
            self.power_out_w(gait, payload_kg=np.atleast_1d(payloads_kg), periods_s=periods)
        )
