"""Servo hexapod simulator (AntBot defaults; 4, 6 or 8 legs), the embedded default hardware.

Core module: numpy, pinocchio and ``hexapod_gait``; no ROS. Each leg is the 3-DOF DH leg of
DESIGN section 7 (or a leg file's: ``RobotSimulator(leg=...)``, ``hexapod-sim robot --leg
FILE``) driven by three servos (:mod:`servo_model`, AX-18A by default). Every output
sample (100 Hz by default):

1. the commanded joint angles (from the gait's tip trajectories in batch mode, or from
   ``/joint_commands`` in the live node) and the stance flags give the load each joint carries:
   ``tau = M qdd + C qd + G - J^T f`` with the ground force ``f = (0, 0, (m_c + m_leg) g)`` on
   each stance tip, ``m_c = (M - m_leg L) / L`` the mass each of the ``L`` supporting legs
   carries (body weight shared by the stance legs, payload included) plus the leg's own weight
   (Brodoline et al. Eq. 4: the stance tips carry ``M g`` together, as the bench tip carries
   ``(m_leg + load) g``), plus the ``speed_friction`` drag;
2. the servos track the commands against that load (finite stiffness, back-EMF, gear friction),
   draw current and heat up;
3. the supply (lab supply at 11.9 V, or a 3S LiPo) delivers the sum of the servo currents plus
   the effects' extra power; the power monitor measures voltage and current (ROS sign).

Standing still (``period_s = 0``) holds every leg on the ground at its neutral pose.

``stance_preload`` (:func:`stance_preload_forces_n`) adds the internal forces of an
over-constrained stance to step 1's ground forces: more than three legs on the ground.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from hexapod_gait.gait import GaitPattern, carried_mass_per_leg_kg, make_gait
from hexapod_gait.kinematics import (ANTBOT_BODY_KG, ANTBOT_MASS_KG, DHParameters,
                                     default_robot_mass_kg)
from hexapod_gait.leg_file import LegFile
from hexapod_gait.legs import joint_names, leg_rank, leg_side
from hexapod_gait.trajectory import LegTrajectory

from .effects import EffectSet
from .servo_model import ServoModel, ServoParams
from .sim_core import (
    G_MPS2,
    LegLoads,
    SimTrace,
    Supply,
    TraceBuilder,
    leg_summary,
    powered_step,
    quantise_position,
    resolve_leg,
)

__all__ = ['ANTBOT_BODY_KG', 'RobotConfig', 'RobotSimulator', 'SampleInput',
           'default_robot_mass_kg', 'robot_mass_problem', 'simulate_robot',
           'stance_preload_forces_n']



FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class RobotConfig:
    """Robot, gait and hardware of one simulated run (AntBot defaults).

    Attributes
    ----------
    leg_count : int
        4, 6 or 8 (any even count works).
    gait : str
        ``hexapod_gait`` gait name (``tripod`` is ``alternating`` for other leg counts).
    duty_factor, period_s, step_length_m, step_height_m : float
        Gait parameters; ``period_s = 0`` means standing still.
    speed_mps : float
        If > 0, the period is ``step_length / (duty_factor * speed)`` instead of ``period_s``.
    robot_mass_kg : float
        Robot mass without payload [kg] (legs included): finite, > 0, and more than the legs
        (checked by :class:`RobotSimulator`, which knows the leg). The default is AntBot's;
        another leg count or leg: :func:`default_robot_mass_kg` (what ``hexapod-sim robot``
        and ``sim_robot`` take when no mass is given).
    payload_kg : float
        Payload on the body [kg], finite and >= 0.
    supply : {'supply', 'battery'}
        Lab supply at ``supply_voltage_v`` or a 3S LiPo.
    supply_voltage_v : float
        Lab supply voltage [V].
    servo : str
        Servo preset (``ax18a``, ``ax12a``, ``xl430``, ``xm430``).
    rate_hz : float
        Output sample rate [Hz].
    ambient_temperature_c, initial_temperature_c : float
        Air and starting winding temperature [degC].
    max_substep_s : float
        Servo integration sub-step [s].
    """

    leg_count: int = 6
    gait: str = 'tripod'
    duty_factor: float = 0.5
    period_s: float = 1.0
    speed_mps: float = 0.0
    step_length_m: float = 0.10
    step_height_m: float = 0.04
    robot_mass_kg: float = ANTBOT_MASS_KG
    payload_kg: float = 0.0
    supply: str = 'supply'
    supply_voltage_v: float = 11.9
    servo: str = 'ax18a'
    rate_hz: float = 100.0
    ambient_temperature_c: float = 26.0
    initial_temperature_c: float = 26.0
    max_substep_s: float = 1.0 / 300.0

    def __post_init__(self) -> None:
        if self.leg_count < 2 or self.leg_count % 2 != 0:
            raise ValueError(f'leg_count = {self.leg_count!r}: expected an even number >= 2')
        if not (math.isfinite(self.robot_mass_kg) and self.robot_mass_kg > 0.0):
            raise ValueError(f'robot_mass_kg = {self.robot_mass_kg!r}: expected a finite mass '
                             '> 0 kg')
        if not (math.isfinite(self.payload_kg) and self.payload_kg >= 0.0):
            raise ValueError(f'payload_kg = {self.payload_kg!r}: expected a finite mass >= 0 kg')

    def gait_pattern(self) -> GaitPattern | None:
        """The gait, or None when standing still."""
        period = self.effective_period_s
        if period <= 0.0:
            return None
        name = self.gait
        if name == 'tripod' and self.leg_count != 6:
            name = 'alternating'
        return make_gait(name, leg_count=self.leg_count, duty_factor=self.duty_factor,
                         period_s=period, step_length_m=self.step_length_m,
                         step_height_m=self.step_height_m)

    @property
    def effective_period_s(self) -> float:
        if self.speed_mps > 0.0:
            return self.step_length_m / (self.duty_factor * self.speed_mps)
        return max(self.period_s, 0.0)

    @property
    def total_mass_kg(self) -> float:
        return self.robot_mass_kg + self.payload_kg


@dataclass
class SampleInput:
    """What one sample of the simulator is driven with (batch: the gait; live: the topics).

    Arrays: ``q``, ``qd``, ``qdd`` (legs, 3) commanded joint angle, velocity, acceleration;
    ``in_stance`` (legs,); ``speed_mps`` body speed; ``step_frequency_hz`` (0 standing).
    """

    q: FloatArray
    qd: FloatArray
    qdd: FloatArray
    in_stance: NDArray[np.bool_]
    speed_mps: float
    step_frequency_hz: float
    tip_velocity_mps: FloatArray | None = None   # (legs, 3) for speed_friction


def robot_mass_problem(robot_mass_kg: float, leg_count: int, leg_mass_kg: float) -> str | None:
    """Why a robot of ``robot_mass_kg`` (payload excluded, legs included) cannot have
    ``leg_count`` legs of ``leg_mass_kg`` each, else None.

    The body's mass ``M - N m_leg`` must be positive: a lighter robot gives the stance legs a
    negative carried mass (Eq. 2), i.e. tips pulled up by the ground.
    """
    legs_kg = leg_count * leg_mass_kg
    if robot_mass_kg > legs_kg:
        return None
    return (f'robot mass {robot_mass_kg:.4g} kg (payload excluded) <= {leg_count} legs x '
            f'{leg_mass_kg:.4g} kg = {legs_kg:.4g} kg: the legs alone outweigh the robot')


#: The tips' height mismatches that set the direction of ``stance_preload``'s internal forces
#: (uneven ground, leg zero offsets): ``cos(golden angle x k)``, ``k`` numbering every footfall
#: of every leg, an irregular sequence whose projection on the internal forces is not zero
#: for any stance of four or more legs; each touchdown lands at a new height, so no one leg
#: carries the preload run after run
_GOLDEN_ANGLE = math.pi * (3.0 - math.sqrt(5.0))


def footfall_counts(stance: NDArray[np.bool_], previous: NDArray[np.bool_],
                    counts: NDArray[np.int64]) -> NDArray[np.int64]:
    """Each leg's touchdowns so far at every sample, (n, legs), from ``stance`` (n, legs), the
    stance before the first sample ``previous`` (legs,) and the counts then ``counts``."""
    st = np.asarray(stance, dtype=bool)
    before = np.vstack([np.asarray(previous, dtype=bool)[None, :], st[:-1]])
    return np.asarray(counts)[None, :] + np.cumsum(st & ~before, axis=0)


def _footprint(leg_names: tuple[str, ...]) -> FloatArray:
    """Nominal (x, y) of each leg's stance tip on the body, (legs, 2): the legs equally spaced
    along each side (1 apart, front positive), the two sides 2 apart (a hexapod's front and
    rear tips as far apart as its left and right ones)."""
    ranks = np.array([leg_rank(n) for n in leg_names], dtype=float)
    side = np.array([1.0 if leg_side(n) == 'left' else -1.0 for n in leg_names])
    per_side = float(np.max(ranks)) if ranks.size else 0.0
    return np.column_stack([(per_side + 1.0) / 2.0 - ranks, side])


def stance_preload_forces_n(stance: NDArray[np.bool_], leg_names: tuple[str, ...],
                            preload_n: float, footfalls: NDArray[np.int64] | None = None
                            ) -> FloatArray:
    """Vertical tip forces of an over-constrained stance (effect ``stance_preload``), (n, legs)
    [N] for ``stance`` (n, legs) or (legs,) (then (legs,)); ``footfalls`` (same shape) each
    leg's touchdown count (:func:`footfall_counts`; None: 0, the first footfall).

    Three tips fix a body's height, roll and pitch; every further stance leg is a redundant
    support, and a position-controlled robot's small mismatches (leg zero offsets, uneven
    ground, body flex) load it against the others. With ``L`` legs on the ground the forces
    lie in the ``L - 3``-dimensional space of vertical tip forces with no net force and no
    roll or pitch moment on the nominal footprint (:func:`_footprint`): the tips' height
    mismatches (new at every footfall) less the plane the body settles in, scaled to the norm
    ``preload_n sqrt(L - 3)`` (each redundant support carries ``preload_n``; the forces'
    squares, the servos' copper loss to first order, grow as ``L - 3``). Zero with three or
    fewer legs on the ground. The body's weight is not changed: the forces add to it.
    """
    st = np.asarray(stance, dtype=bool)
    single = st.ndim == 1
    st2 = np.atleast_2d(st)
    out = np.zeros(st2.shape)
    if preload_n == 0.0 or st2.size == 0:
        return out[0] if single else out
    xy = _footprint(leg_names)
    n_legs = st2.shape[1]
    falls = np.zeros(st2.shape, dtype=np.int64) if footfalls is None else \
        np.atleast_2d(np.asarray(footfalls, dtype=np.int64))
    # every footfall of every leg its own index of the mismatch sequence
    index = 1 + np.arange(n_legs)[None, :] + n_legs * falls
    key = np.where(st2, index, 0)
    patterns, inv = np.unique(key, axis=0, return_inverse=True)
    inv = np.asarray(inv).reshape(-1)
    for k, pat in enumerate(patterns):
        legs = np.flatnonzero(pat)
        if legs.size <= 3:
            continue
        a = np.column_stack([np.ones(legs.size), xy[legs]])
        e = np.cos(_GOLDEN_ANGLE * pat[legs].astype(float))
        r = e - a @ np.linalg.lstsq(a, e, rcond=None)[0]
        norm = float(np.linalg.norm(r))
        if norm < 1e-9:          # not for any stance of 4-8 legs; kept for other layouts
            r = np.linalg.svd(a.T)[2][-1]
            norm = float(np.linalg.norm(r))
        f = np.zeros(st2.shape[1])
        f[legs] = preload_n * math.sqrt(legs.size - 3) * r / norm
        out[inv == k] = f
    return out[0] if single else out


class RobotSimulator:
    """Stateful servo hexapod; :meth:`step` advances one sample, :meth:`run` a whole batch.

    Parameters
    ----------
    config : RobotConfig
    effects : EffectSet, optional
        Named effects (defaults: sensor noise on).
    seed : int
        Seed of the sensor noise (same seed, same data).
    dh : DHParameters, optional
        Leg geometry and masses, with AntBot's neutral tip (None: AntBot's leg).
    leg : LegFile, optional
        The robot's leg from a leg file (:func:`hexapod_gait.leg_file.read_leg_file`,
        ``hexapod-sim robot --leg FILE``): links, masses (rods, :class:`~.sim_core.LegLoads`),
        neutral tip (the standing pose, the stance midpoint of the tip paths) and inverse
        kinematics of every leg; the servos stay ``config.servo``'s (AX-18A by default).
        Not with ``dh``.

    Raises
    ------
    ValueError
        A robot not heavier than its legs (:func:`robot_mass_problem`).
    """

    kind = 'robot'

    def __init__(self, config: RobotConfig | None = None, *, effects: EffectSet | None = None,
                 seed: int = 0, dh: DHParameters | None = None,
                 leg: LegFile | None = None) -> None:
        self.config = config or RobotConfig()
        self.effects = effects if effects is not None else EffectSet.defaults()
        self.rng = np.random.default_rng(seed)
        cfg = self.config
        self.gait = cfg.gait_pattern()
        legs_gait = self.gait or make_gait('alternating' if cfg.leg_count != 6 else 'tripod',
                                           leg_count=cfg.leg_count)
        self.leg_names: tuple[str, ...] = legs_gait.leg_names
        self.joint_names: tuple[str, ...] = tuple(
            j for leg in self.leg_names for j in joint_names(leg))
        self.leg_file = resolve_leg(leg, dh)
        self.loads = LegLoads(self.leg_file.dh)
        if reason := robot_mass_problem(cfg.robot_mass_kg, cfg.leg_count,
                                        self.loads.leg_mass_kg):
            raise ValueError(reason)
        self.kinematics = self.loads.kinematics
        n_legs = len(self.leg_names)
        tip = np.array(self.leg_file.neutral_tip_m, dtype=float)
        self.trajectories = [LegTrajectory(legs_gait, i, kinematics=self.kinematics,
                                           neutral_tip_m=tip)
                             for i in range(n_legs)]
        self.neutral_q = np.tile(self.kinematics.inverse(tip)[0], (n_legs, 1))
        self.servo_params = ServoParams.by_name(cfg.servo)
        eff = self.effects
        self.servos = ServoModel(
            self.servo_params, count=3 * n_legs, initial_position_rad=self.neutral_q.ravel(),
            initial_temperature_c=cfg.initial_temperature_c,
            ambient_temperature_c=cfg.ambient_temperature_c,
            thermal_drift_w_k=float(eff.value('thermal_drift')),
            load_inertia_kgm2=np.tile(self.loads.joint_inertia_kgm2(self.neutral_q[0]), n_legs),
            max_substep_s=cfg.max_substep_s)
        self.supply = Supply(kind=cfg.supply, voltage_v=cfg.supply_voltage_v,
                             series_resistance_ohm=float(eff.value('supply_resistance')))
        anomaly = eff.value('leg_anomaly')
        self.anomaly_leg = -1
        self.anomaly_w = 0.0
        if anomaly is not None:
            if anomaly[0] not in self.leg_names:
                raise ValueError(f'effect leg_anomaly={anomaly[0]}:{anomaly[1]}: leg '
                                 f'{anomaly[0]!r} is not one of {self.leg_names}')
            self.anomaly_leg = self.leg_names.index(anomaly[0])
            self.anomaly_w = float(anomaly[1])
        self.preload_n = float(eff.value('stance_preload'))
        # each leg's touchdowns so far and the stance of the last sample (stance_preload)
        self._footfalls = np.zeros(n_legs, dtype=np.int64)
        self._last_stance = np.ones(n_legs, dtype=bool)
        self.noise = float(eff.value('sensor_noise'))
        self.powered = True
        self.t_s = 0.0

    # ----------------------------------------------------------------------------------------
    def carried_mass_kg(self, supporting: int) -> float:
        """Mass each stance leg carries with ``supporting`` legs on the ground [kg]."""
        if supporting <= 0:
            return 0.0
        return float(carried_mass_per_leg_kg(self.config.total_mass_kg, self.loads.leg_mass_kg,
                                             supporting)[0])

    def tip_forces_n(self, inp: SampleInput) -> FloatArray:
        """Ground force on every tip, (legs, 3) [N]."""
        stance = inp.in_stance
        supporting = int(stance.sum())
        forces = np.zeros((len(self.leg_names), 3))
        forces[stance, 2] = (self.carried_mass_kg(supporting) + self.loads.leg_mass_kg) * G_MPS2
        if self.preload_n:
            falls = footfall_counts(stance[None, :], self._last_stance, self._footfalls)[0]
            forces[:, 2] += stance_preload_forces_n(stance, self.leg_names, self.preload_n,
                                                    falls)
        c = float(self.effects.value('speed_friction'))
        if c > 0.0 and supporting > 0 and inp.tip_velocity_mps is not None:
            # Ground drag c v on the body, shared by the stance legs: it pushes on each stance
            # tip against the tip's motion relative to the body.
            forces[stance] -= c * inp.tip_velocity_mps[stance] / supporting
        return forces

    def step(self, dt_s: float, inp: SampleInput,
             tau_required_nm: FloatArray | None = None) -> dict[str, Any]:
        """Advance one sample of ``dt_s`` seconds; returns the measured and true quantities.

        ``tau_required_nm`` (legs, 3), if given, is the precomputed load of every joint.
        """
        eff = self.effects
        if tau_required_nm is None:
            tau_req = self.loads.static_torques(inp.q, self.tip_forces_n(inp))
        else:
            tau_req = tau_required_nm
        if self.preload_n:
            stance = np.asarray(inp.in_stance, dtype=bool)
            self._footfalls = self._footfalls + (stance & ~self._last_stance)
            self._last_stance = stance.copy()
        goal = inp.q
        k_err = float(eff.value('kinematic_error'))
        if k_err and inp.step_frequency_hz > 0.0:
            goal = inp.q + 0.0025 * k_err * inp.step_frequency_hz * (inp.q - self.neutral_q)
        extra_w = 0.0
        if self.powered:
            extra_w += float(eff.value('basal_power'))
            extra_w += k_err * inp.step_frequency_hz
            if self.anomaly_leg >= 0 and inp.in_stance[self.anomaly_leg]:
                extra_w += self.anomaly_w
            out, volts, current = powered_step(self.servos, self.supply, dt_s, goal.ravel(),
                                               -tau_req.ravel(), extra_w)
        else:
            volts = 0.0
            out = self.servos.step(dt_s, goal.ravel(), -tau_req.ravel(), volts)
            current = float(out.current_a.sum())
            self.supply.draw(current, dt_s)
        self.t_s += dt_s
        return {'servo': out, 'current_a': current, 'voltage_v': volts,
                'power_w': current * volts}

    # ----------------------------------------------------------------------------------------
    def gait_inputs(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray,
                                                     NDArray[np.bool_], FloatArray]:
        """Commanded q, qd, qdd (n, legs, 3), stance (n, legs), tip velocity (n, legs, 3)."""
        n, n_legs = t_s.shape[0], len(self.leg_names)
        if self.gait is None:
            zeros = np.zeros((n, n_legs, 3))
            return (np.broadcast_to(self.neutral_q, (n, n_legs, 3)).copy(), zeros, zeros.copy(),
                    np.ones((n, n_legs), dtype=bool), zeros.copy())
        q = np.empty((n, n_legs, 3))
        qd = np.empty_like(q)
        qdd = np.empty_like(q)
        tipv = np.empty_like(q)
        for i, traj in enumerate(self.trajectories):
            q[:, i], qd[:, i], qdd[:, i] = traj.joints(t_s)
            tipv[:, i] = traj.tip_velocity(t_s)
        return q, qd, qdd, self.gait.stance_mask(t_s), tipv

    def required_torques(self, q: FloatArray, qd: FloatArray, qdd: FloatArray,
                         stance: NDArray[np.bool_], tip_velocity: FloatArray) -> FloatArray:
        """Quasi-static joint loads of a batch, (n, legs, 3) [N m]; inputs as :meth:`gait_inputs`.

        Gravity and ground forces only: the links' inertia rides on the servos (their diagonal
        joint-space inertia at the neutral pose), so it acts on the servos' actual motion.
        """
        n, n_legs = stance.shape
        supporting = stance.sum(axis=1)
        carried = np.zeros(n)
        some = supporting > 0
        carried[some] = carried_mass_per_leg_kg(self.config.total_mass_kg,
                                                self.loads.leg_mass_kg, supporting[some])
        forces = np.zeros((n, n_legs, 3))
        # each stance tip carries its share of the body and its own leg: M g over the L tips
        forces[..., 2] = np.where(stance, (carried[:, None] + self.loads.leg_mass_kg) * G_MPS2,
                                  0.0)
        if self.preload_n:
            falls = footfall_counts(stance, self._last_stance, self._footfalls)
            forces[..., 2] += stance_preload_forces_n(stance, self.leg_names, self.preload_n,
                                                      falls)
        c = float(self.effects.value('speed_friction'))
        if c > 0.0:
            share = np.where(stance, c / np.maximum(supporting, 1)[:, None], 0.0)
            forces -= share[..., None] * tip_velocity
        tau = self.loads.static_torques(q.reshape(-1, 3), forces.reshape(-1, 3))
        return tau.reshape(n, n_legs, 3)

    def run(self, duration_s: float, *, progress: Callable[[int], None] | None = None
            ) -> SimTrace:
        """Simulate ``duration_s`` seconds from the current state (batch mode)."""
        cfg = self.config
        dt = 1.0 / cfg.rate_hz
        n = int(round(duration_s * cfg.rate_hz))
        t = self.t_s + dt * np.arange(1, n + 1)
        q, qd, qdd, stance, tipv = self.gait_inputs(t)
        gait = self.gait
        speed = gait.speed_mps if gait is not None else 0.0
        freq = gait.step_frequency_hz if gait is not None else 0.0
        tau = self.required_torques(q, qd, qdd, stance, tipv)
        tb = TraceBuilder(n, len(self.joint_names), len(self.leg_names))
        for k in range(n):
            inp = SampleInput(q[k], qd[k], qdd[k], stance[k], speed, freq, tipv[k])
            res = self.step(dt, inp, tau[k])
            self._record(tb, k, t[k], inp, res)
            if progress is not None and k % 100 == 99:
                progress(100)
        tb.cycle_phase[:] = gait.cycle_phase(t) if gait is not None else 0.0
        tb.gait_name[:] = gait.name if gait is not None else 'stand'
        tb.period_s[:] = gait.period_s if gait is not None else 0.0
        tb.duty_factor[:] = cfg.duty_factor
        tb.step_length_m[:] = cfg.step_length_m if gait is not None else 0.0
        tb.step_height_m[:] = cfg.step_height_m if gait is not None else 0.0
        offsets = gait.phase_offsets if gait is not None else (0.0,) * len(self.leg_names)
        return self._finish(tb, offsets)

    def _finish(self, tb: TraceBuilder, offsets: tuple[float, ...]) -> SimTrace:
        return tb.build(
            kind=self.kind, joint_names=self.joint_names, leg_names=self.leg_names,
            phase_offsets=tuple(offsets),
            battery_stamp_offset_s=float(self.effects.value('time_offset')),
            servo_stamp_offset_s=float(self.effects.value('sensor_latency')),
            effects_json=self.effects.to_json(),
            config={'simulator': self.kind, **asdict(self.config),
                    'leg_description': leg_summary(self.leg_file)})

    def _record(self, tb: TraceBuilder, k: int, t: float, inp: SampleInput,
                res: dict[str, Any]) -> None:
        out = res['servo']
        rng, noise = self.rng, self.noise
        n_j = out.position_rad.shape[0]
        tb.t_s[k] = t
        tb.position_rad[k] = quantise_position(out.position_rad)
        vel = out.velocity_rad_s
        if noise:
            vel = vel + rng.normal(0.0, 0.02 * noise, n_j)
        tb.velocity_rad_s[k] = vel
        tb.effort_nm[k] = out.load_fraction * self.servo_params.stall_torque_nm
        tb.command_position_rad[k] = inp.q.ravel()
        tb.command_velocity_rad_s[k] = inp.qd.ravel()
        tb.temperature_c[k] = out.reported_temperature_c
        tb.servo_voltage_v[k] = out.reported_voltage_v
        tb.load_fraction[k] = np.round(out.load_fraction * 1023.0) / 1023.0
        tb.servo_error[k] = out.error
        volts, current = res['voltage_v'], res['current_a']
        if noise:
            volts = volts + rng.normal(0.0, 0.004 * noise)
            current = current + rng.normal(0.0, 0.008 * noise)
        tb.battery_voltage_v[k] = volts
        tb.battery_current_a[k] = -current
        tb.in_stance[k] = inp.in_stance
        tb.supporting_legs[k] = int(inp.in_stance.sum())
        tb.true_power_in_w[k] = res['power_w']
        tb.true_mechanical_power_w[k] = out.mechanical_power_w
        tb.true_temperature_c[k] = out.temperature_c
        tb.speed_mps[k] = inp.speed_mps
        tb.powered[k] = self.powered


def simulate_robot(duration_s: float, config: RobotConfig | None = None, *,
                   effects: EffectSet | None = None, seed: int = 0,
                   progress: Callable[[int], None] | None = None,
                   leg: LegFile | None = None) -> SimTrace:
    """Batch run of the servo hexapod: ``duration_s`` seconds into a :class:`SimTrace`
    (``leg``: the robot's leg file, None: AntBot's leg)."""
    if not (math.isfinite(duration_s) and duration_s > 0.0):
        raise ValueError(f'duration_s = {duration_s!r}: expected a finite duration > 0 s')
    return RobotSimulator(config, effects=effects, seed=seed, leg=leg).run(
        duration_s, progress=progress)
