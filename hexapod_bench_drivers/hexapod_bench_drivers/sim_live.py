"""Live (sample-by-sample) drivers of the simulators, for the ``sim_robot``/``sim_bench`` nodes.

Core module: no ROS. The nodes feed the latest ``/joint_commands`` and ``/gait/phase`` (as the
plain samples of ``hexapod_common.conversions``) and call :meth:`tick` on a timer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from hexapod_gait.leg_file import LegFile

from .bench_sim import BenchConfig, BenchSimulator
from .effects import EffectSet
from .robot_sim import RobotConfig, RobotSimulator, SampleInput
from .sim_core import G_MPS2, powered_step, quantise_position

__all__ = ['LiveBench', 'LiveRobot', 'LiveSample', 'NameMismatch']

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class LiveSample:
    """One published sample: arrays over ``joint_names``; bench fields None on the robot."""

    joint_names: tuple[str, ...]
    position_rad: FloatArray
    velocity_rad_s: FloatArray
    effort_nm: FloatArray
    temperature_c: FloatArray
    voltage_v: FloatArray
    load_fraction: FloatArray
    error: NDArray[np.uint8]
    battery_voltage_v: float
    battery_current_a: float           # ROS sign: negative while discharging
    ground_force_n: float | None = None
    tip_m: FloatArray | None = None


def _listed(names: tuple[str, ...], most: int = 12) -> str:
    """``a, b, c`` (at most ``most`` names, then how many in all)."""
    shown = ', '.join(names[:most])
    return shown if len(names) <= most else f'{shown}, ... ({len(names)} in all)'


class NameMismatch:
    """Reports names in a message that the simulator does not have, once per distinct set.

    The simulators silently ignored joints (``/joint_commands``) and legs (``/gait/phase``)
    that are not theirs, so a gait node walking 8 legs drove a 6-legged ``sim_robot`` whose
    L4/R4 simply did not exist. :meth:`check` returns ``(level, message)`` the first time a set
    of unknown names is seen (``'warning'``), or a message that matches no name of ours at all
    (``'error'``), else None; at most ``max_sets`` distinct sets are reported.

    Parameters
    ----------
    topic : str
        The topic named in the messages.
    known : tuple of str
        The simulator's names (its joints or legs).
    owner : str
        Who ``known`` belongs to, e.g. ``'this robot (6 legs: L1, ..., R3)'``.
    kind : str
        ``'joints'`` or ``'legs'``.
    extra_ok : bool
        Unknown names are expected (the bench leg takes its three joints out of the whole
        robot's commands): only a message matching none of ours is reported.
    """

    def __init__(self, topic: str, known: tuple[str, ...], owner: str, kind: str, *,
                 extra_ok: bool = False, max_sets: int = 32) -> None:
        self.topic = topic
        self.known = tuple(known)
        self.owner = owner
        self.kind = kind
        self.extra_ok = extra_ok
        self.max_sets = max_sets
        self._seen: set[tuple[bool, frozenset[str]]] = set()
        self._known = frozenset(known)

    def check(self, names: tuple[str, ...]) -> tuple[str, str] | None:
        """``(level, message)`` for the names of one message, once per distinct case."""
        unknown = tuple(n for n in names if n not in self._known)
        none_ours = bool(names) and len(unknown) == len(names)
        if not unknown or (self.extra_ok and not none_ours):
            return None
        key = (none_ours, frozenset(unknown))
        if key in self._seen or len(self._seen) >= self.max_sets:
            return None
        self._seen.add(key)
        if none_ours:
            return 'error', (
                f'{self.topic}: none of its {len(names)} {self.kind} ({_listed(unknown)}) '
                f'belongs to {self.owner}, whose {self.kind} are {_listed(self.known)}; the '
                'message is ignored (check the leg count and the joint names of the nodes)')
        return 'warning', (
            f'{self.topic}: {self.kind} not on {self.owner} ignored: {_listed(unknown)} '
            f'(ours: {_listed(self.known)}); check the leg count of the nodes')


#: longest a late tick carries the latest command forward [s]; beyond, it is held
MAX_CARRY_S = 0.1
#: a command more than :data:`MAX_CARRY_S` after the previous one (and at most this [s]: a
#: gait node started again), whose joints jump more than :data:`LATE_COMMAND_JUMP_RAD`, came
#: late: the simulated servos held the old target and now step to the new one, drawing far
#: more than a walking robot (a busy host: the demo's live robot read 94-98 W for 35 W under
#: a load average of 8 on two cores, with no word from the simulator)
LATE_COMMAND_MAX_GAP_S = 5.0
LATE_COMMAND_JUMP_RAD = 0.05


class _Commands:
    """Latest joint commands by name, with a finite-difference acceleration."""

    def __init__(self, names: tuple[str, ...], q0: FloatArray) -> None:
        self.names = names
        self.index = {n: i for i, n in enumerate(names)}
        self.q = q0.astype(float).copy()
        self.qd = np.zeros_like(self.q)
        self.qdd = np.zeros_like(self.q)
        self._t_prev: float | None = None
        #: commands that came late (:data:`LATE_COMMAND_JUMP_RAD`): count, the last gap [s]
        #: and its largest joint jump [rad]
        self.late = 0
        self.late_gap_s = 0.0
        self.late_jump_rad = 0.0

    def update(self, t_s: float, names: tuple[str, ...], position: FloatArray,
               velocity: FloatArray) -> int:
        """Take the joints of ours in a JointState sample; returns how many were used."""
        used = 0
        q_old = self.q.copy()
        qd_new = self.qd.copy()
        for k, name in enumerate(names):
            i = self.index.get(name)
            if i is None:
                continue
            if position.size:
                self.q[i] = position[k]
            if velocity.size:
                qd_new[i] = velocity[k]
            used += 1
        if self._t_prev is not None and t_s > self._t_prev:
            self.qdd = (qd_new - self.qd) / (t_s - self._t_prev)
            gap = t_s - self._t_prev
            jump = float(np.max(np.abs(self.q - q_old))) if used else 0.0
            if MAX_CARRY_S < gap <= LATE_COMMAND_MAX_GAP_S and jump > LATE_COMMAND_JUMP_RAD:
                self.late += 1
                self.late_gap_s, self.late_jump_rad = gap, jump
        self._t_prev = t_s
        self.qd = qd_new
        return used

    @property
    def last_stamp_s(self) -> float | None:
        """Stamp of the latest command [s] (None before the first)."""
        return self._t_prev




class LiveRobot:
    """The servo hexapod stepped live from ``/joint_commands`` and ``/gait/phase``."""

    def __init__(self, config: RobotConfig | None = None, *,
                 effects: EffectSet | None = None, seed: int = 0,
                 leg: LegFile | None = None) -> None:
        # The live robot is driven by the gait node, so its own gait is "standing".
        cfg = config or RobotConfig()
        self.sim = RobotSimulator(RobotConfig(**{**cfg.__dict__, 'period_s': 0.0,
                                                 'speed_mps': 0.0}),
                                  effects=effects, seed=seed, leg=leg)
        self.commands = _Commands(self.sim.joint_names, self.sim.neutral_q.ravel())
        n_legs = len(self.sim.leg_names)
        self.in_stance = np.ones(n_legs, dtype=bool)
        self.speed_mps = 0.0
        self.step_frequency_hz = 0.0

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.sim.joint_names

    def describe(self) -> str:
        """``this robot (6 legs: L1, L2, L3, R1, R2, R3)``, for the mismatch messages."""
        legs = self.sim.leg_names
        return f'this robot ({len(legs)} legs: {", ".join(legs)})'

    def set_gait(self, leg_names: tuple[str, ...], in_stance: NDArray[np.bool_],
                 speed_mps: float, period_s: float) -> None:
        """Stance flags (by leg name) and speed from a ``/gait/phase`` sample; legs that are
        not this robot's are skipped (the node reports them, :class:`NameMismatch`)."""
        for name, flag in zip(leg_names, in_stance):
            if name in self.sim.leg_names:
                self.in_stance[self.sim.leg_names.index(name)] = bool(flag)
        self.speed_mps = float(speed_mps)
        self.step_frequency_hz = 1.0 / period_s if period_s > 0 else 0.0

    def tick(self, dt_s: float, now_s: float | None = None,
             nominal_s: float = 0.01) -> LiveSample:
        """Step the robot by ``dt_s`` under the latest command.

        With ``now_s`` (the node clock, on the commands' clock), as the batch simulator sees
        its gait: the tick is split into steps of at most ``nominal_s``, each under the latest
        command carried forward along its own velocity and acceleration to the step's start
        (at most :data:`MAX_CARRY_S`), as if the commands the gait node sent meanwhile had
        arrived on time. The simulated robot's power then does not depend on when the host
        runs the timer: held stale, a jittered 100 Hz tick (mean 10 ms) raised P_in at 0.3 m/s
        from 34.1 W (batch and on-time ticks) to 36.6 W (carried forward: 33.8 W), and to
        38.7 +- 3 W in the demo on a loaded machine. The battery sample is the mean over the
        steps."""
        sim, c = self.sim, self.commands
        n_legs = len(sim.leg_names)
        t_cmd = c.last_stamp_s
        carry = now_s is not None and t_cmd is not None
        steps = max(1, math.ceil(dt_s / nominal_s - 1e-9)) if carry else 1
        h = dt_s / steps
        volts_sum = current_sum = 0.0
        for j in range(steps):
            if carry:
                assert now_s is not None and t_cmd is not None
                tau = min(max(now_s - dt_s + j * h - t_cmd, 0.0), MAX_CARRY_S)
                q = c.q + c.qd * tau + 0.5 * c.qdd * tau * tau
                qd = c.qd + c.qdd * tau
            else:
                q, qd = c.q, c.qd
            inp = SampleInput(q.reshape(n_legs, 3), qd.reshape(n_legs, 3),
                              c.qdd.reshape(n_legs, 3), self.in_stance.copy(), self.speed_mps,
                              self.step_frequency_hz, None)
            res = sim.step(h, inp)
            volts_sum += res['voltage_v']
            current_sum += res['current_a']
        out = res['servo']
        noise, rng = sim.noise, sim.rng
        volts, current = volts_sum / steps, current_sum / steps
        vel = out.velocity_rad_s
        if noise:
            volts += rng.normal(0.0, 0.004 * noise)
            current += rng.normal(0.0, 0.008 * noise)
            vel = vel + rng.normal(0.0, 0.02 * noise, vel.shape)
        return LiveSample(
            sim.joint_names, quantise_position(out.position_rad), vel,
            out.load_fraction * sim.servo_params.stall_torque_nm,
            out.reported_temperature_c.astype(float), out.reported_voltage_v,
            out.load_fraction, out.error, float(volts), -float(current))


class LiveBench:
    """The bench leg stepped live; the load on the stage is a setting."""

    def __init__(self, config: BenchConfig | None = None, *, load_kg: float = 0.0,
                 effects: EffectSet | None = None, seed: int = 0,
                 leg: LegFile | None = None) -> None:
        self.sim = BenchSimulator(config, effects=effects, seed=seed, leg=leg)
        self.load_kg = float(load_kg)
        self.commands = _Commands(self.sim.joint_names, self.sim.neutral_q)
        self.in_stance = True
        self.step_frequency_hz = 0.0

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.sim.joint_names

    def set_gait(self, leg_names: tuple[str, ...], in_stance: NDArray[np.bool_],
                 period_s: float) -> None:
        if self.sim.leg in leg_names:
            self.in_stance = bool(in_stance[list(leg_names).index(self.sim.leg)])
        self.step_frequency_hz = 1.0 / period_s if period_s > 0 else 0.0

    def tick(self, dt_s: float) -> LiveSample:
        sim = self.sim
        eff = sim.effects
        weight_n = (sim.loads.leg_mass_kg + sim.config.stage_mass_kg + self.load_kg) * G_MPS2
        force = np.array([0.0, 0.0, weight_n if self.in_stance else 0.0])
        q = self.commands.q
        tau = sim.loads.static_torques(q, force)[0]
        k_err = float(eff.value('kinematic_error'))
        goal = q + 0.0025 * k_err * self.step_frequency_hz * (q - sim.neutral_q)
        extra = float(eff.value('basal_power')) + k_err * self.step_frequency_hz \
            + (sim.anomaly_w if self.in_stance else 0.0)
        out, volts, current = powered_step(sim.servos, sim.supply, dt_s, goal, -tau, extra)
        tip_leg = sim.kinematics.forward(out.position_rad)[0]
        contact = -tip_leg[2] >= sim.stop_z
        base_z = max(sim.stop_z, -tip_leg[2])
        tip = np.array([tip_leg @ sim.forward_axis, tip_leg[0], base_z + tip_leg[2]])
        f = weight_n if contact else 0.0
        noise, rng = sim.noise, sim.rng
        vel = out.velocity_rad_s
        if noise:
            volts += rng.normal(0.0, 0.004 * noise)
            current += rng.normal(0.0, 0.008 * noise)
            f += rng.normal(0.0, 0.05 * noise)
            tip = tip + rng.normal(0.0, 0.0003 * noise, 3)
            vel = vel + rng.normal(0.0, 0.02 * noise, 3)
        return LiveSample(
            sim.joint_names, quantise_position(out.position_rad), vel,
            out.load_fraction * sim.servo_params.stall_torque_nm,
            out.reported_temperature_c.astype(float), out.reported_voltage_v,
            out.load_fraction, out.error, float(volts), -float(current), float(f), tip)
