"""Single servo leg on the MiMiC-Ant bench (Brodoline et al. 2024, Methods), simulated.

Core module: numpy, pinocchio and ``hexapod_gait``; no ROS. The 3-DOF leg (AntBot's, DESIGN
section 7, or a leg file's: ``BenchSimulator(leg=...)``, ``hexapod-sim bench --leg FILE``) hangs
from a vertical stage that carries the load (0 to 515 g) and walks the gait's tip trajectory on
a freewheel treadmill:

* **Contact.** The stage rests on a stop ``stop_drop_m`` below the leg's standing height under
  the session's load (set after heating, as the operator does); the leg
  lifts it whenever its tip reaches the ground: ``base_z = max(stop_z, -FK_z(q))``. The tip is on
  the ground (stance) exactly when it carries the stage. The force sensor under the treadmill
  then reads the weight of leg, stage and load, ``(m_leg + m_stage + m_load) g``; zero in swing.
* **Loads on the joints.** ``G(q) - J^T f`` with that ground force during the planned stance, the
  links' inertia riding on the servos; ``speed_friction`` adds the treadmill's drag ``c v``.
* **Sessions** of a plan (loads x frequencies) run in order, each its own time segment with
  ``/bench/session`` states ``heating`` (powered, standing; at least ``heat_s``, until the servos
  are at the gate temperature), ``walking`` (``walk_s``; a 0 Hz session stands still and gives the
  basal power), ``cooling`` (supply off until every winding is back under
  ``gate_temperature_c + 1``), and ``done`` at the end.
* **Measurements:** servo states, supply voltage/current (ROS sign), normal force, leg tip from
  the motion capture in the bench frame (x forward along the treadmill, z up from the belt).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields

import numpy as np
from numpy.typing import NDArray

from hexapod_gait.gait import make_gait
from hexapod_gait.kinematics import DHParameters
from hexapod_gait.leg_file import LegFile
from hexapod_gait.legs import joint_names
from hexapod_gait.trajectory import LegTrajectory

from .effects import EffectSet
from .servo_model import ServoModel, ServoParams
from .sim_core import (
    G_MPS2,
    LegLoads,
    SessionRecord,
    SimTrace,
    Supply,
    TraceBuilder,
    leg_summary,
    powered_step,
    quantise_position,
    resolve_leg,
)

__all__ = [
    'BENCH_LOADS_KG',
    'BenchConfig',
    'BenchPlan',
    'BenchSession',
    'BenchSimulator',
    'simulate_bench',
]

#: The paper's bench loads [kg].
BENCH_LOADS_KG = (0.0, 0.095, 0.141, 0.187, 0.515)

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class BenchSession:
    """One bench session: a load on the stage and a step frequency (0 = standing)."""

    load_kg: float
    frequency_hz: float
    duty_factor: float = 0.5
    step_length_m: float = 0.10
    step_height_m: float = 0.04

    def session_id(self, index: int) -> str:
        return f's{index:03d}_load{self.load_kg * 1000:.0f}g_f{self.frequency_hz:g}Hz'


@dataclass(frozen=True)
class BenchPlan:
    """Loads x frequencies, each session heating -> walking -> cooling.

    Attributes
    ----------
    loads_kg, frequencies_hz : tuple of float
        Sessions are every load (outer loop) at every frequency (inner loop).
    walk_s : float
        Walking (or standing, at 0 Hz) time of each session [s] (the paper: 600 s).
    heat_s : float
        Minimum powered standing time before walking [s].
    gate_temperature_c : float
        Walking starts at this winding temperature (the paper's 26 +/- 1 degC gate).
    max_cool_s : float
        Longest cooling [s] (the paper: about 30 min).
    pause_s : (float, float), optional
        (start, length) [s from the walk's start]: every walk pauses that long inside its
        ``walk_s`` (the gait clock stops and the leg holds where it is, then walks on from
        there), as an operator pausing the gait; None (default): no pause.
    hold : (float, float), optional
        (leg phase, share): the leg's trajectory holds still at that phase of its cycle (0 =
        touchdown) for that share of every cycle, the cycle's length kept (a gait that dwells
        by design: the rest of the cycle is walked faster); None (default): no hold.
    """

    loads_kg: tuple[float, ...] = BENCH_LOADS_KG
    frequencies_hz: tuple[float, ...] = (0.0, 0.5, 1.0, 1.5, 2.0, 2.5, 3.0)
    walk_s: float = 10.0
    heat_s: float = 1.0
    gate_temperature_c: float = 26.0
    max_cool_s: float = 1800.0
    duty_factor: float = 0.5
    step_length_m: float = 0.10
    step_height_m: float = 0.04
    pause_s: tuple[float, float] | None = None
    hold: tuple[float, float] | None = None

    def __post_init__(self) -> None:
        if not self.loads_kg or not self.frequencies_hz:
            raise ValueError('BenchPlan needs at least one load and one frequency')
        if any(m < 0 for m in self.loads_kg) or any(f < 0 for f in self.frequencies_hz):
            raise ValueError(f'BenchPlan loads {self.loads_kg} kg and frequencies '
                             f'{self.frequencies_hz} Hz must be >= 0')
        if not self.walk_s > 0:
            raise ValueError(f'BenchPlan.walk_s = {self.walk_s!r}: expected > 0 s')
        if self.pause_s is not None and not (self.pause_s[0] >= 0 and self.pause_s[1] > 0):
            raise ValueError(f'BenchPlan.pause_s = {self.pause_s!r}: expected (start >= 0 s, '
                             'length > 0 s)')
        if self.hold is not None and not (0 <= self.hold[0] < 1 and 0 < self.hold[1] < 1):
            raise ValueError(f'BenchPlan.hold = {self.hold!r}: expected (leg phase in [0, 1), '
                             'share in (0, 1))')

    def sessions(self) -> list[BenchSession]:
        return [BenchSession(m, f, self.duty_factor, self.step_length_m, self.step_height_m)
                for m in self.loads_kg for f in self.frequencies_hz]


@dataclass(frozen=True)
class BenchConfig:
    """Bench hardware (MiMiC-Ant defaults)."""

    leg: str = 'R2'
    servo: str = 'ax18a'
    supply_voltage_v: float = 11.9
    stage_mass_kg: float = 0.0
    stop_drop_m: float = 0.003
    rate_hz: float = 100.0
    cooling_rate_hz: float = 2.0
    ambient_temperature_c: float = 26.0
    initial_temperature_c: float = 26.0
    max_substep_s: float = 1.0 / 300.0


@dataclass
class _Segment:
    builder: TraceBuilder
    sessions: list[SessionRecord] = field(default_factory=list)


def _hold_clock(tg: FloatArray, period_s: float, offset: float, at: float, share: float
                ) -> tuple[FloatArray, FloatArray]:
    """The gait clock of a leg that holds at leg phase ``at`` for ``share`` of every cycle
    (the leg's phase offset ``offset``), and its rate against time (0 where it holds)."""
    cycles = tg / period_s - offset
    lp = cycles % 1.0
    a = at * (1.0 - share)
    m = np.where(lp < a, lp / (1.0 - share),
                 np.where(lp < a + share, at, (lp - share) / (1.0 - share)))
    still = (lp >= a) & (lp < a + share)
    return tg + (m - lp) * period_s, np.where(still, 0.0, 1.0 / (1.0 - share))


class BenchSimulator:
    """The MiMiC-Ant bench with one servo leg; :meth:`run_plan` runs a whole plan.

    ``leg`` (a :class:`~hexapod_gait.leg_file.LegFile`, ``hexapod-sim bench --leg FILE``) is
    the leg on the bench: its links and masses (rods, :class:`~.sim_core.LegLoads`), its
    neutral tip (the standing pose and the stance midpoint of the gait's tip path) and its
    inverse kinematics for the joint commands; the servos stay ``config.servo``'s (AX-18A).
    None: AntBot's leg (``dh`` alone: that DH table with AntBot's neutral tip).
    """

    kind = 'bench'

    def __init__(self, config: BenchConfig | None = None, *, effects: EffectSet | None = None,
                 seed: int = 0, dh: DHParameters | None = None,
                 leg: LegFile | None = None) -> None:
        self.config = config or BenchConfig()
        self.effects = effects if effects is not None else EffectSet.defaults()
        cfg, eff = self.config, self.effects
        self.rng = np.random.default_rng(seed)
        self.leg = cfg.leg
        self.joint_names = joint_names(cfg.leg)
        self._gait_template = make_gait('tripod')
        if cfg.leg not in self._gait_template.leg_names:
            raise ValueError(f'BenchConfig.leg = {cfg.leg!r}: expected one of '
                             f'{self._gait_template.leg_names}')
        self.leg_index = self._gait_template.leg_names.index(cfg.leg)
        self.leg_file = resolve_leg(leg, dh)
        self.loads = LegLoads(self.leg_file.dh)
        self.kinematics = self.loads.kinematics
        self.neutral_tip = np.array(self.leg_file.neutral_tip_m, dtype=float)
        self.neutral_q = self.kinematics.inverse(self.neutral_tip)[0]
        self.forward_axis = LegTrajectory(self._gait_template, self.leg_index).forward_axis
        self.stop_z = -self.neutral_tip[2] - cfg.stop_drop_m
        self.servo_params = ServoParams.by_name(cfg.servo)
        self.servos = ServoModel(
            self.servo_params, count=3, initial_position_rad=self.neutral_q,
            initial_temperature_c=cfg.initial_temperature_c,
            ambient_temperature_c=cfg.ambient_temperature_c,
            load_inertia_kgm2=self.loads.joint_inertia_kgm2(self.neutral_q),
            thermal_drift_w_k=float(eff.value('thermal_drift')),
            max_substep_s=cfg.max_substep_s)
        self.supply = Supply(voltage_v=cfg.supply_voltage_v,
                             series_resistance_ohm=float(eff.value('supply_resistance')))
        anomaly = eff.value('leg_anomaly')
        if anomaly is not None and anomaly[0] != cfg.leg:
            # the bench carries one leg: an anomaly on another would do nothing, yet be
            # recorded in the bag's metadata as on
            raise ValueError(f'effect leg_anomaly={anomaly[0]}:{anomaly[1]}: the bench carries '
                             f'leg {cfg.leg!r} only (give --leg {anomaly[0]}, or the anomaly '
                             f'on {cfg.leg})')
        self.anomaly_w = float(anomaly[1]) if anomaly is not None else 0.0
        self.noise = float(eff.value('sensor_noise'))
        self.t_s = 0.0

    # ----------------------------------------------------------------------------------------
    def _segment(self, n: int, dt: float, session: BenchSession, *, walking: bool,
                 powered: bool, origin_s: float | None = None,
                 pause_s: tuple[float, float] | None = None,
                 hold: tuple[float, float] | None = None) -> TraceBuilder:
        """Simulate ``n`` samples of ``dt`` seconds in one state.

        ``origin_s`` is the time the walk started (gait phase 0), so that a long walk split
        into chunks stays phase-continuous. ``pause_s`` (start, length) [s from
        ``origin_s``]: the gait clock stands still that long (the leg holds its pose).
        ``hold`` (leg phase, share): the leg holds at that phase for that share of every cycle
        (:attr:`BenchPlan.hold`).
        """
        cfg, eff = self.config, self.effects
        t = self.t_s + dt * np.arange(1, n + 1)
        tg = t - (self.t_s if origin_s is None else origin_s)
        held = np.zeros(n, dtype=bool)
        if pause_s is not None:
            p0, length = pause_s
            held = (tg >= p0) & (tg < p0 + length)
            tg = np.where(tg < p0, tg, np.where(held, p0, tg - length))
        gait = None
        if walking and session.frequency_hz > 0.0:
            gait = make_gait('tripod', duty_factor=session.duty_factor,
                             period_s=1.0 / session.frequency_hz,
                             step_length_m=session.step_length_m,
                             step_height_m=session.step_height_m)
        if gait is not None:
            traj = LegTrajectory(gait, self.leg_index, kinematics=self.kinematics,
                                 neutral_tip_m=self.neutral_tip)
            rate = np.ones(n)
            if hold is not None:
                tg, rate = _hold_clock(tg, gait.period_s,
                                       float(gait.phase_offsets[self.leg_index]), *hold)
            q, qd, _ = traj.joints(tg)
            tipv = traj.tip_velocity(tg)
            qd *= rate[:, None]
            tipv *= rate[:, None]
            qd[held] = 0.0
            tipv[held] = 0.0
            stance = gait.stance_mask(tg)[:, self.leg_index]
            phase = gait.cycle_phase(tg)
            speed = gait.speed_mps
        else:
            q = np.broadcast_to(self.neutral_q, (n, 3)).copy()
            qd = np.zeros((n, 3))
            tipv = np.zeros((n, 3))
            stance = np.ones(n, dtype=bool)
            phase = np.zeros(n)
            speed = 0.0
        weight_n = (self.loads.leg_mass_kg + cfg.stage_mass_kg + session.load_kg) * G_MPS2
        forces = np.zeros((n, 3))
        forces[:, 2] = np.where(stance, weight_n, 0.0)
        c = float(eff.value('speed_friction'))
        if c > 0.0:
            forces -= np.where(stance, c, 0.0)[:, None] * tipv
        tau = self.loads.static_torques(q, forces) if powered else np.zeros((n, 3))
        freq = session.frequency_hz if gait is not None else 0.0
        k_err = float(eff.value('kinematic_error'))
        goal = q
        if k_err and freq > 0.0:
            goal = q + 0.0025 * k_err * freq * (q - self.neutral_q)
        extra_w = np.zeros(n)
        if powered:
            extra_w += float(eff.value('basal_power')) + k_err * freq
            extra_w += self.anomaly_w * stance
        tb = TraceBuilder(n, 3, 1, bench=True)
        servos, supply, rng, noise = self.servos, self.supply, self.rng, self.noise
        kin, fwd = self.kinematics, self.forward_axis
        outward = np.array([1.0, 0.0, 0.0])
        positions = np.empty((n, 3))
        for k in range(n):
            if powered:
                out, volts, current = powered_step(servos, supply, dt, goal[k], -tau[k],
                                                   float(extra_w[k]))
            else:
                volts = 0.0
                out = servos.step(dt, goal[k], -tau[k], volts)
                current = float(out.current_a.sum())
                supply.draw(current, dt)
            positions[k] = out.position_rad
            tb.position_rad[k] = out.position_rad
            tb.velocity_rad_s[k] = out.velocity_rad_s
            tb.effort_nm[k] = out.load_fraction * self.servo_params.stall_torque_nm
            tb.temperature_c[k] = out.reported_temperature_c
            tb.servo_voltage_v[k] = out.reported_voltage_v
            tb.load_fraction[k] = out.load_fraction
            tb.servo_error[k] = out.error
            tb.battery_voltage_v[k] = volts
            tb.battery_current_a[k] = -current
            tb.true_power_in_w[k] = current * volts
            tb.true_mechanical_power_w[k] = out.mechanical_power_w
            tb.true_temperature_c[k] = out.temperature_c
        self.t_s = float(t[-1])
        # Measurements, vectorised over the segment.
        tip_leg = kin.forward(positions)
        base_z = np.maximum(self.stop_z, -tip_leg[:, 2])
        contact = -tip_leg[:, 2] >= self.stop_z
        tb.t_s[:] = t
        tb.position_rad[:] = quantise_position(tb.position_rad)
        tb.load_fraction[:] = np.round(tb.load_fraction * 1023.0) / 1023.0
        tb.command_position_rad[:] = q
        tb.command_velocity_rad_s[:] = qd
        tb.cycle_phase[:] = phase
        tb.in_stance[:, 0] = stance
        tb.supporting_legs[:] = stance.astype(np.int64)
        tb.gait_name[:] = 'tripod' if gait is not None else 'stand'
        tb.period_s[:] = gait.period_s if gait is not None else 0.0
        tb.duty_factor[:] = session.duty_factor
        tb.step_length_m[:] = session.step_length_m if gait is not None else 0.0
        tb.step_height_m[:] = session.step_height_m if gait is not None else 0.0
        tb.speed_mps[:] = speed
        tb.powered[:] = powered
        assert tb.ground_force_n is not None and tb.tip_m is not None
        tb.ground_force_n[:] = np.where(contact & powered, weight_n, 0.0)
        tb.tip_m[:, 0] = tip_leg @ fwd
        tb.tip_m[:, 1] = tip_leg @ outward
        tb.tip_m[:, 2] = base_z + tip_leg[:, 2]
        if noise:
            tb.velocity_rad_s += rng.normal(0.0, 0.02 * noise, (n, 3))
            tb.battery_voltage_v += np.where(powered, rng.normal(0.0, 0.004 * noise, n), 0.0)
            tb.battery_current_a += rng.normal(0.0, 0.008 * noise, n)
            tb.ground_force_n += rng.normal(0.0, 0.05 * noise, n)
            tb.tip_m += rng.normal(0.0, 0.0003 * noise, (n, 3))
        return tb

    def run_plan(self, plan: BenchPlan, *, progress: Callable[[int], None] | None = None
                 ) -> SimTrace:
        """Run every session of ``plan`` in one continuous timeline."""
        cfg = self.config
        dt = 1.0 / cfg.rate_hz
        dt_cool = 1.0 / cfg.cooling_rate_hz
        parts: list[TraceBuilder] = []
        records: list[SessionRecord] = []

        def mark(sid: str, state: str, s: BenchSession) -> None:
            records.append(SessionRecord(self.t_s, sid, state, s.load_kg, s.frequency_hz,
                                         s.duty_factor, s.step_length_m, s.step_height_m))

        gate_hi = plan.gate_temperature_c + 1.0
        for index, session in enumerate(plan.sessions()):
            sid = session.session_id(index)
            mark(sid, 'heating', session)
            heat_n = max(1, int(round(plan.heat_s * cfg.rate_hz)))
            parts.append(self._segment(heat_n, dt, session, walking=False, powered=True))
            # Heat up to the gate (a cold start below the gate) in 1 s chunks, at most 10 min.
            for _ in range(600):
                if self.servos.temperature_c.min() >= plan.gate_temperature_c - 1.0:
                    break
                parts.append(self._segment(int(cfg.rate_hz), dt, session, walking=False,
                                           powered=True))
            # The operator sets the stop just under the loaded leg's standing height.
            standing = self.kinematics.forward(self.servos.output_position_rad())[0]
            self.stop_z = float(-standing[2]) - cfg.stop_drop_m
            mark(sid, 'walking', session)
            walk_n = max(1, int(round(plan.walk_s * cfg.rate_hz)))
            chunk = int(10 * cfg.rate_hz)
            done = 0
            origin = self.t_s
            while done < walk_n:
                m = min(chunk, walk_n - done)
                parts.append(self._segment(m, dt, session, walking=True, powered=True,
                                           origin_s=origin, pause_s=plan.pause_s,
                                           hold=plan.hold))
                done += m
                if progress is not None:
                    progress(m)
            mark(sid, 'cooling', session)
            substep = self.servos.max_substep_s
            self.servos.max_substep_s = dt_cool
            cooled = 0.0
            while True:
                parts.append(self._segment(int(10 * cfg.cooling_rate_hz), dt_cool, session,
                                           walking=False, powered=False))
                cooled += 10.0
                if self.servos.temperature_c.max() < gate_hi or cooled >= plan.max_cool_s:
                    break
            self.servos.max_substep_s = substep
        last = plan.sessions()[-1]
        mark(last.session_id(len(plan.sessions()) - 1), 'done', last)
        return self._concat(parts, records, plan)

    def _concat(self, parts: list[TraceBuilder], records: list[SessionRecord],
                plan: BenchPlan) -> SimTrace:
        total = sum(p.n for p in parts)
        tb = TraceBuilder(total, 3, 1, bench=True)
        for f in fields(SimTrace):
            name = f.name
            if not hasattr(tb, name) or getattr(tb, name) is None:
                continue
            setattr(tb, name, np.concatenate([getattr(p, name) for p in parts]))
        return tb.build(
            kind=self.kind, joint_names=self.joint_names, leg_names=(self.leg,),
            phase_offsets=(0.0,), sessions=records,
            battery_stamp_offset_s=float(self.effects.value('time_offset')),
            servo_stamp_offset_s=float(self.effects.value('sensor_latency')),
            effects_json=self.effects.to_json(),
            config={'simulator': self.kind, **asdict(self.config), 'plan': asdict(plan),
                    'leg_description': leg_summary(self.leg_file)})


def simulate_bench(plan: BenchPlan | None = None, config: BenchConfig | None = None, *,
                   effects: EffectSet | None = None, seed: int = 0,
                   progress: Callable[[int], None] | None = None,
                   leg: LegFile | None = None) -> SimTrace:
    """Batch run of a bench plan into a :class:`SimTrace` (``leg``: the bench leg's file,
    None: AntBot's)."""
    return BenchSimulator(config, effects=effects, seed=seed, leg=leg).run_plan(
        plan or BenchPlan(), progress=progress)

