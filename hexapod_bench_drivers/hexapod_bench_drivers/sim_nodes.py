"""Nodes ``sim_robot`` and ``sim_bench``: simulated hardware on live topics.

Both subscribe to ``/joint_commands`` and ``/gait/phase`` (from the gait node) and publish, on a
timer of the node clock (so ``use_sim_time`` and a ``/clock`` publisher drive them), the real
drivers' topics: ``/joint_states``, ``/servo_status`` (every ``status_every`` ticks),
``/battery_state`` (ROS sign), and for the bench ``/bench/ground_force``, ``/bench/leg_tip`` and
``/bench/session`` (latched). The physics is in ``sim_live`` (core); callbacks are one line.

Parameters configure the simulation when the node starts and are read only, except
``status_every`` (applies at once). A robot not heavier than its legs (``robot_mass`` <=
``leg_count`` legs' mass) is refused at start-up.

``leg_file`` (both nodes; the file ``gait_scheduler -p leg_file`` reads, so that the joint
commands come from the same inverse kinematics) makes the simulated legs that file's: links,
masses, rod inertias, neutral tip (standing pose); the servos stay the ``servo`` preset's
(AX-18A). ``sim_robot`` without ``robot_mass`` then simulates AntBot's 1.187 kg body with
``leg_count`` of the file's legs (``robot_sim.default_robot_mass_kg``).

Joints on ``/joint_commands`` and legs on ``/gait/phase`` that the simulator does not have (a
gait node walking 8 legs, ``<leg>_hip`` names) are ignored and reported once per distinct set
as a warning naming them and the simulator's own; a message that matches none of its joints
(legs) is reported as an error (``sim_live.NameMismatch``). The bench leg takes its three
joints out of the whole robot's commands, so only a message without them is reported there.

While several publishers interleave on ``/joint_commands``, only the commands of the one that
was there first are applied, as on the real driver
(:class:`hexapod_common.node_utils.FirstPublisherWatch`).
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('sim_robot')
stop_signals.catch_if_program('sim_bench')

import math
from dataclasses import dataclass
from typing import Any

from rclpy.node import Node

from geometry_msgs.msg import PointStamped, WrenchStamped
from hexapod_common.clocks import count_milestone
from hexapod_common.conversions import gait_phase_from_msg, joint_state_from_msg
from hexapod_common.errors import ParameterError
from hexapod_common.node_utils import (
    LATCHED_QOS,
    RELIABLE_QOS,
    SENSOR_QOS,
    FirstPublisherWatch,
    declare_params,
    overridden,
    param,
    run_node,
)
from hexapod_gait.kinematics import ANTBOT_LEG, ANTBOT_MASS_KG
from hexapod_gait.leg_file import LegFile, LegFileError, read_leg_file
from hexapod_interfaces.msg import BenchSession, GaitPhase, ServoStatus
from sensor_msgs.msg import BatteryState, JointState

from .bench_sim import BenchConfig
from .effects import EffectError, parse_effects
from .robot_sim import RobotConfig, default_robot_mass_kg, robot_mass_problem
from .sim_live import LiveBench, LiveRobot, LiveSample, NameMismatch

__all__ = ['BenchNodeParams', 'RobotNodeParams', 'SimBenchNode', 'SimRobotNode', 'main_bench',
           'main_robot']


def _positive(x: Any) -> str | None:
    return None if x > 0 else 'must be > 0'


_LEG_FILE_HELP = ("the simulated leg's file (YAML/JSON: DH table, link masses, neutral_tip_m; "
                  "gait_scheduler's -p leg_file): its links, masses and neutral tip, AX-18A "
                  "servos; empty = AntBot's leg")


def _leg(node: Node, path: str) -> LegFile | None:
    """The leg file of parameter ``leg_file`` (None when empty), said at start-up; a file
    that cannot be used is refused (ParameterError naming it and the problem)."""
    if not path:
        return None
    try:
        leg = read_leg_file(path)
    except LegFileError as err:
        raise ParameterError(f'leg_file refused: {err}') from err
    node.get_logger().info(f'leg {leg.name!r} from {path}: link lengths '
                           f'{[round(x, 4) for x in leg.dh.a_m]} m, masses '
                           f'{[round(x, 4) for x in leg.dh.link_masses_kg]} kg, neutral tip '
                           f'{[round(x, 4) for x in leg.neutral_tip_m]} m')
    return leg


def _effects_ok(items: Any) -> str | None:
    try:
        parse_effects(list(items))
    except EffectError as err:
        return str(err)
    return None


@dataclass(frozen=True)
class RobotNodeParams:
    leg_count: int = param(6, 'number of legs (even)', validate=lambda x: None
                           if x >= 2 and x % 2 == 0 else 'must be even and >= 2')
    payload: float = param(0.0, 'payload on the body [kg]')
    robot_mass: float = param(ANTBOT_MASS_KG, 'robot mass without payload [kg] (not given: '
                              "AntBot's body with leg_count legs of leg_file's leg)",
                              validate=_positive)
    battery: bool = param(False, 'true: 3S LiPo; false: 11.9 V lab supply')
    servo: str = param('ax18a', 'servo preset: ax18a, ax12a, xl430, xm430')
    rate: float = param(100.0, 'publish rate [Hz]', validate=_positive)
    status_every: int = param(10, 'publish /servo_status every N ticks', validate=_positive,
                              live=True)
    effects: tuple[str, ...] = param(('sensor_noise=1',), 'named effects NAME=VALUE',
                                     validate=_effects_ok)
    seed: int = param(0, 'noise seed')
    leg_file: str = param('', _LEG_FILE_HELP, read_only=True)


@dataclass(frozen=True)
class BenchNodeParams:
    leg: str = param('R2', 'leg on the bench (its joints are taken from /joint_commands)')
    load: float = param(0.0, 'load on the vertical stage [kg]',
                        validate=lambda x: None if x >= 0 else 'must be >= 0')
    servo: str = param('ax18a', 'servo preset')
    rate: float = param(100.0, 'publish rate [Hz]', validate=_positive)
    status_every: int = param(10, 'publish /servo_status every N ticks', validate=_positive,
                              live=True)
    effects: tuple[str, ...] = param(('sensor_noise=1',), 'named effects NAME=VALUE',
                                     validate=_effects_ok)
    seed: int = param(0, 'noise seed')
    session_id: str = param('live', 'session id on /bench/session')
    leg_file: str = param('', _LEG_FILE_HELP, read_only=True)


class _SimNode(Node):
    """Shared plumbing of the two simulator nodes."""

    live: Any
    params: Any
    #: reporters of the joints (legs) of /joint_commands (/gait/phase) that are not ours
    command_check: NameMismatch
    gait_check: NameMismatch

    def _setup(self) -> None:
        p = self.params
        #: (level, message) of every joint/leg mismatch reported, in order
        self.name_notes: list[tuple[str, str]] = []
        self._tick_count = 0
        self._last_ns: int | None = None
        self.pub_js = self.create_publisher(JointState, 'joint_states', RELIABLE_QOS)
        self.pub_status = self.create_publisher(ServoStatus, 'servo_status', RELIABLE_QOS)
        self.pub_battery = self.create_publisher(BatteryState, 'battery_state', RELIABLE_QOS)
        #: two command sources (two gait nodes, a teleop beside the gait node): said, and
        #: only the commands of the one that was there first are applied
        self.command_publishers = FirstPublisherWatch(self)
        self.command_publishers.subscription = self.create_subscription(
            JointState, 'joint_commands', lambda m, info: self._on_commands(m, info),
            SENSOR_QOS)
        self.create_subscription(GaitPhase, 'gait/phase', self._on_gait, SENSOR_QOS)
        self.timer = self.create_timer(1.0 / p.rate, self._on_timer)

    def _on_commands(self, msg: JointState, info: Any = None) -> None:
        if not self.command_publishers.admit(info, msg.header.frame_id):
            return                      # another publisher's (the error says so)
        commands = self.live.commands
        late = commands.late
        try:
            s = joint_state_from_msg(msg)
            commands.update(s.t_s, s.names, s.position, s.velocity)
        except (ValueError, IndexError) as err:
            self.get_logger().warning(f'dropped a bad /joint_commands message: {err}')
            return
        if commands.late > late and count_milestone(commands.late):
            self.get_logger().warning(
                f'/joint_commands came {1000 * commands.late_gap_s:.0f} ms after the one '
                f'before, its joints {commands.late_jump_rad:.2f} rad away ({commands.late} '
                f'such so far): the simulated servos held the old target, then step to the '
                'new one and draw far more than a walking robot (a busy host starves the gait '
                'node or this one of CPU?); the power is not a walking robot\'s')
        self._report(self.command_check.check(tuple(s.names)))

    def _on_gait(self, msg: GaitPhase) -> None:
        try:
            g = gait_phase_from_msg(msg)
            self._apply_gait(g)
        except (ValueError, IndexError) as err:
            self.get_logger().warning(f'dropped a bad /gait/phase message: {err}')
            return
        self._report(self.gait_check.check(tuple(g.leg_names)))

    def _report(self, note: tuple[str, str] | None) -> None:
        """Log a :class:`NameMismatch` note at its level (it is given once per case) and keep
        it in ``name_notes``."""
        if note is not None:
            self.name_notes.append(note)
            level, text = note
            if level == 'error':    # one call site per severity (rclpy's logger wants it)
                self.get_logger().error(text)
            else:
                self.get_logger().warning(text)

    def _apply_gait(self, g: Any) -> None:
        raise NotImplementedError

    def _on_timer(self) -> None:
        now = self.get_clock().now()
        now_ns = now.nanoseconds
        dt = 1.0 / self.params.rate if self._last_ns is None or now_ns <= self._last_ns \
            else min((now_ns - self._last_ns) * 1e-9, 0.1)
        self._last_ns = now_ns
        sample = self.live.tick(dt, now_ns * 1e-9, 1.0 / self.params.rate) \
            if isinstance(self.live, LiveRobot) else self.live.tick(dt)
        self._publish(sample, now.to_msg())
        self._tick_count += 1

    def _publish(self, s: LiveSample, stamp: Any) -> None:
        js = JointState()
        js.header.stamp = stamp
        js.name = list(s.joint_names)
        js.position = [float(x) for x in s.position_rad]
        js.velocity = [float(x) for x in s.velocity_rad_s]
        js.effort = [float(x) for x in s.effort_nm]
        self.pub_js.publish(js)
        if self._tick_count % self.params.status_every == 0:
            st = ServoStatus()
            st.header.stamp = stamp
            st.name = list(s.joint_names)
            st.temperature = [float(x) for x in s.temperature_c]
            st.voltage = [float(x) for x in s.voltage_v]
            st.load = [float(x) for x in s.load_fraction]
            st.error = bytes(int(x) for x in s.error)
            self.pub_status.publish(st)
        bat = BatteryState()
        bat.header.stamp = stamp
        bat.header.frame_id = 'supply'
        bat.voltage = s.battery_voltage_v
        bat.current = s.battery_current_a
        for name in ('temperature', 'charge', 'capacity', 'design_capacity', 'percentage'):
            setattr(bat, name, math.nan)
        bat.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        bat.present = True
        self.pub_battery.publish(bat)


class SimRobotNode(_SimNode):
    """``sim_robot``: the servo hexapod on live topics."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('sim_robot', context=context, parameter_overrides=parameter_overrides,
                         namespace=namespace, **kw)
        p = declare_params(self, RobotNodeParams)
        leg = _leg(self, p.leg_file)
        leg_kg = sum((ANTBOT_LEG if leg is None else leg.dh).link_masses_kg)
        mass = p.robot_mass
        if (p.leg_count != 6 or leg is not None) and not overridden(self, 'robot_mass'):
            # AntBot's body with this many legs (the leg-count sweep's rule, M + (k - 6) m_leg:
            # 1.851 kg on 4 legs), not the 6-leg robot's 2.183 kg (kept silently before: an
            # outside review); with a leg file, that many of its legs
            mass = default_robot_mass_kg(p.leg_count, leg_kg)
            whose = '' if leg is None else f' (leg {leg.name!r})'
            self.get_logger().info(
                f'robot_mass not given: AntBot\'s body with {p.leg_count} legs of '
                f'{leg_kg:.3f} kg{whose}, {mass:.3f} kg (set -p robot_mass:= for another '
                'robot)')
        if reason := robot_mass_problem(mass, p.leg_count, leg_kg):
            raise ParameterError(f'parameters robot_mass = {mass} and leg_count = '
                                 f'{p.leg_count} refused: {reason}')
        cfg = RobotConfig(leg_count=p.leg_count, payload_kg=p.payload, robot_mass_kg=mass,
                          supply='battery' if p.battery else 'supply', servo=p.servo,
                          rate_hz=p.rate)
        self.live = LiveRobot(cfg, effects=parse_effects(list(p.effects), defaults=False),
                              seed=p.seed, leg=leg)
        owner = self.live.describe()
        self.command_check = NameMismatch('/joint_commands', self.live.joint_names, owner,
                                          'joints')
        self.gait_check = NameMismatch('/gait/phase', self.live.sim.leg_names, owner, 'legs')
        self._setup()

    def _apply_gait(self, g: Any) -> None:
        self.live.set_gait(g.leg_names, g.in_stance, g.speed_mps, g.period_s)


class SimBenchNode(_SimNode):
    """``sim_bench``: one leg on the MiMiC-Ant bench on live topics."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('sim_bench', context=context, parameter_overrides=parameter_overrides,
                         namespace=namespace, **kw)
        p = declare_params(self, BenchNodeParams)
        self.live = LiveBench(BenchConfig(leg=p.leg, servo=p.servo, rate_hz=p.rate),
                              load_kg=p.load,
                              effects=parse_effects(list(p.effects), defaults=False),
                              seed=p.seed, leg=_leg(self, p.leg_file))
        owner = f'bench leg {p.leg}'
        self.command_check = NameMismatch('/joint_commands', self.live.joint_names, owner,
                                          'joints', extra_ok=True)
        self.gait_check = NameMismatch('/gait/phase', (p.leg,), owner, 'legs', extra_ok=True)
        self.pub_force = self.create_publisher(WrenchStamped, 'bench/ground_force', RELIABLE_QOS)
        self.pub_tip = self.create_publisher(PointStamped, 'bench/leg_tip', RELIABLE_QOS)
        self.pub_session = self.create_publisher(BenchSession, 'bench/session', LATCHED_QOS)
        self._frequency_hz = 0.0
        self._gait = (0.5, 0.1, 0.04)
        self._setup()
        self._publish_session()

    def _publish_session(self) -> None:
        msg = BenchSession()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = 'bench'
        msg.session_id = self.params.session_id
        msg.state = 'walking'
        msg.load_mass = float(self.params.load)
        msg.frequency = float(self._frequency_hz)
        msg.duty_factor, msg.step_length, msg.step_height = (float(x) for x in self._gait)
        self.pub_session.publish(msg)

    def _apply_gait(self, g: Any) -> None:
        self.live.set_gait(g.leg_names, g.in_stance, g.period_s)
        freq = 1.0 / g.period_s if g.period_s > 0 else 0.0
        gait = (g.duty_factor, g.step_length_m, g.step_height_m)
        if freq != self._frequency_hz or gait != self._gait:
            self._frequency_hz, self._gait = freq, gait
            self._publish_session()

    def _publish(self, s: LiveSample, stamp: Any) -> None:
        super()._publish(s, stamp)
        w = WrenchStamped()
        w.header.stamp = stamp
        w.header.frame_id = 'bench'
        w.wrench.force.z = float(s.ground_force_n or 0.0)
        self.pub_force.publish(w)
        tip = PointStamped()
        tip.header.stamp = stamp
        tip.header.frame_id = 'bench'
        if s.tip_m is not None:
            tip.point.x, tip.point.y, tip.point.z = (float(v) for v in s.tip_m)
        self.pub_tip.publish(tip)


def main_robot(args: list[str] | None = None) -> int:
    return run_node(SimRobotNode, args)


def main_bench(args: list[str] | None = None) -> int:
    return run_node(SimBenchNode, args)
