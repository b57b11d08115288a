"""``energy_monitor``: EnergeticDescriptors over whole gait cycles from the robot's topics.

Subscribes ``/battery_state``, ``/gait/phase``, ``/joint_states`` and ``/mocap/body``; publishes
``/energy/descriptors`` each time a window of ``cycles`` gait cycles is complete. P_out is the mean
positive joint power (:mod:`hexapod_energy.dynamics`): from joint efforts when present, else from
the Eq. 6 inverse-dynamics model of the gait on ``/gait/phase`` (``power_out_source``). The science
is in :mod:`hexapod_energy.descriptors`.

Cycle boundaries (``cycle_source``): ``auto`` (default) takes them from ``/gait/phase`` as soon
as its messages arrive and, until then (a robot running its own gait code publishes none), from
the joint positions (:mod:`hexapod_energy.cycles`: the step period by autocorrelation,
re-estimated every 0.5 s over the last 10 periods, fed one JointState at a time); ``gait_phase``
and ``joints`` force one source. Speed: ``/mocap/body``, else the gait schedule, else ``odom``
(nav_msgs/Odometry, position differenced over the window in the odometry frame), else the
parameter ``speed`` (0 = unknown: speed, CoT and specific resistance NaN). On the joint path
without joint efforts P_out is NaN (the Eq. 6 model needs the gait schedule).

Times are header stamps. A message whose header stamp is zero (drivers that never fill it) is
stamped with the node's clock on arrival instead (the bag time under replay), with one warning
per topic, as the offline reader falls back to the bag's receive time.

Time going backwards by more than a second (a looped bag, a simulation clock reset under
``use_sim_time``) is logged once as a warning naming the jump, and the accumulation restarts
from the new time; a window is at most 60 s long and older samples are dropped, so the buffers
stay bounded when ``/gait/phase`` stops, which is logged as a warning while the battery keeps
coming (:mod:`hexapod_energy.descriptors`).

A schedule on ``gait/phase`` that the robot cannot walk (beyond the actuator ``limits``, by
default AntBot's servos', on the schedule's step; or with no leg on the ground at some phase)
is warned about once per schedule, as ``hexapod-analyze energy`` warns about a bag's; its
windows are still published.

Masses: ``mass`` is the whole robot with its payload; not given, AntBot's 2.183 kg is assumed
with a warning at start (as the offline ``hexapod-analyze energy`` warns without
``--robot-mass``). The Eq. 6 P_out model is for a robot of ``robot_mass`` carrying
``mass - robot_mass``; ``robot_mass`` not given (0) is ``mass``, payload 0, so ``-p mass:=M``
gives the P_out of ``hexapod-analyze energy --robot-mass M`` (a robot_mass defaulted to
AntBot's made a 1.6 kg robot's P_out that of a 2.183 kg one, +7.5 %). A ``robot_mass`` above
``mass`` is warned about (the payload cannot be negative: the model uses payload 0).

Several batteries on ``battery_state`` (distinct ``header.frame_id``: a servo pack and a logic
pack) are summed as they appear (:class:`hexapod_common.battery.BatteryCombiner`, logged), or
one is kept (parameter ``battery_source``); several live publishers whose messages name one
battery (an empty frame_id) are reported as an error (their samples would read as the mean),
as are several live publishers on ``gait/phase`` (two schedules interleave: the windows follow
neither). Live publishers are told from the messages' publication sequence numbers
(:mod:`hexapod_common.publishers`), not from the graph, which keeps a crashed publisher's
endpoint until its DDS lease runs out (a respawned driver read as two batteries); once per
episode, again if it recurs. A middleware that does not number its messages falls back on the
graph's publisher count for the battery.

Joint states arriving after the battery sample that ends a window (a servo bus behind a USB
adapter, one message per leg) are waited for: a window is computed once every joint that gave
power has a sample past its end, or :data:`hexapod_energy.descriptors.JOINT_WAIT_S` of battery
time later (then the stream stopped inside it: flagged as a joint gap). A JointState whose
velocity or effort array has another length than its names keeps its positions (warned). A
topic carrying two clocks (a second publisher stamped more than an hour from the others) has
its far samples dropped, said once (:class:`hexapod_common.clocks.StreamClock`). On a Buehler
clock schedule the efforts are not put to the PWM-load test and the Eq. 6 model is not used.

A topic stamped on another clock than the others (a board without time synchronisation) is
told from its first message (:class:`hexapod_energy.descriptors.ArrivalClockGate`: its header
stamps more than an hour from the other topics', each against the node clock on arrival) and
reported once, as an error: its messages cannot be matched live and are left out until its
stamps are on the others' clock again (said once; the offline readers re-stamp it from the
bag's receive times). Checked at the 200th message only, a battery board joining late was never
reported and 'no /battery_state for 1795857615.9 s' came 3 times a second.

Where P_out comes from is said when it changes: the first window from the Eq. 6 model (naming
AntBot's leg when no ``leg_file`` is given, and how to give the robot's own), and every switch
between the joint efforts and the model mid-series (single windows' efforts refused).

Messages missing from an input (a lossy link, or the node behind its input: the DDS history
overwrites the oldest without a word, from about 2,000 msg/s in all on this 2-core machine)
are counted from the gaps in each stream's stamps (:class:`hexapod_common.clocks.StreamLoss`,
``loss.missing``; a publisher late on its timer counts too) and logged on the topic's 1st,
10th, 100th, 1000th ... missing message; the window's powers interpolate over them.
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('energy_monitor')

import dataclasses
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import PoseStamped
from hexapod_interfaces.msg import EnergeticDescriptors, GaitPhase
from nav_msgs.msg import Odometry
from rclpy.node import Node
from sensor_msgs.msg import BatteryState, JointState

from hexapod_common.battery import (
    MILLI_THRESHOLD,
    AbsentBatteryFilter,
    BatteryCombiner,
    milli_factors,
)
from hexapod_common.clocks import LiveClockWatch, StreamLoss, count_milestone
from hexapod_common.conversions import (
    MOCAP_TYPES,
    battery_from_msg,
    battery_source,
    gait_phase_from_msg,
    joint_state_from_msg,
    odometry_from_msg,
    pose_from_msg,
    s_to_stamp,
)
from hexapod_common.node_utils import (
    RELIABLE_QOS,
    SENSOR_QOS,
    InputWatch,
    PublishersWatch,
    declare_params,
    mocap_msg_class,
    overridden,
    param,
    publisher_names,
    run_node,
)
from hexapod_common.publishers import PublisherSequences, publication_sequence
from hexapod_common.renaming_logger import RenamingLogger, topic_renames
from hexapod_gait.feasibility import ActuatorLimits
from hexapod_gait.kinematics import ANTBOT_MASS_KG, default_robot_mass_kg

from hexapod_energy.descriptors import (
    BATTERY_GAP_NOTE,
    ArrivalClockGate,
    JOINT_GAP_NOTE,
    STILL_JOINTS_NOTE,
    DescriptorAccumulator,
    Descriptors,
    model_power_out,
    velocityless_note,
)
from hexapod_energy.leg_description import antbot_leg, load_leg_description

__all__ = ['EnergyMonitorNode', 'EnergyParams', 'descriptors_to_msg', 'main']


#: battery names whose publishers are told apart (:mod:`hexapod_common.publishers`); more
#: (names that keep changing) forget the oldest
MAX_BATTERY_NAMES = 16
#: kinds of dropped message counted apart (further kinds are counted together)
MAX_DROP_KINDS = 64
#: the numbers in a drop's reason (voltage=nan, current=-1.85): one kind whatever they are
_NUMBER = re.compile(r'[-+]?(?:\b(?:nan|inf)\b|\d+(?:\.\d*)?(?:e[-+]?\d+)?)', re.IGNORECASE)

#: leading battery samples with V * I == 0 after which the node reports an unmeasured current
ZERO_POWER_SAMPLES = 100


@dataclass(frozen=True)
class EnergyParams:
    mass: float = param(ANTBOT_MASS_KG, "total robot mass [kg], payload included (not given: "
                        "AntBot's 2.183 kg, with leg_file AntBot's body with six of its legs, "
                        'with a warning)',
                        validate=lambda v: None if v > 0 else 'must be > 0', read_only=True)
    cycles: int = param(1, 'whole gait cycles per published window',
                        validate=lambda v: None if v >= 1 else 'must be >= 1', read_only=True)
    current_sign: str = param(
        'auto', 'battery current sign: ros (negative discharging), positive_discharge, auto',
        validate=lambda v: None if v in ('ros', 'positive_discharge', 'auto')
        else 'expected ros, positive_discharge or auto', read_only=True)
    power_out_source: str = param(
        'auto', 'P_out from: auto (joint efforts when present, else the Eq. 6 model), effort, '
        'or model (for drivers whose effort is not a torque, e.g. AX-series PWM load)',
        validate=lambda v: None if v in ('auto', 'effort', 'model')
        else 'expected auto, effort or model', read_only=True)
    robot_mass: float = param(0.0, 'robot mass without payload [kg], for the P_out model '
                              '(payload = mass - robot_mass); 0: mass (payload 0)',
                              validate=lambda v: None if v >= 0 else 'must be >= 0 (0: mass)',
                              read_only=True)
    cycle_source: str = param(
        'auto', 'gait cycle boundaries from: auto (/gait/phase when its messages arrive, else '
        'the joint positions), gait_phase, or joints (robots without /gait/phase)',
        validate=lambda v: None if v in ('auto', 'gait_phase', 'joints')
        else 'expected auto, gait_phase or joints', read_only=True)
    speed: float = param(0.0, 'robot speed [m/s] used when no /mocap/body, gait schedule or '
                         'odom gives one; 0 = unknown (speed-based descriptors NaN)',
                         validate=lambda v: None if v >= 0 else 'must be >= 0',
                         read_only=True)
    mocap_type: str = param(
        'PoseStamped', 'message type of mocap/body: PoseStamped (the contract), '
        'TransformStamped (vicon_bridge), PoseWithCovarianceStamped or Odometry',
        validate=lambda v: None if v in MOCAP_TYPES else f'expected one of {list(MOCAP_TYPES)}',
        read_only=True)
    leg_file: str = param(
        '', "the robot's leg for the Eq. 6 P_out model: a YAML/JSON leg file "
        '(hexapod_energy.leg_description: DH table, link masses, stance pose); empty: AntBot',
        read_only=True)
    limits: list[float] = param(
        [0.16, 0.15, 3.0], "actuator limits MIN_SWING_S MIN_STANCE_S MAX_FREQ_HZ on the bench's "
        "100 mm tip path (default AntBot's servos on AntBot's leg; given with leg_file: measured "
        "on that leg, as hexapod-analyze energy --limits --leg): a schedule on gait/phase "
        'beyond them (or with no leg on the ground) is warned about',
        read_only=True,
        validate=lambda v: None if len(v) == 3 and all(x > 0 for x in v)
        else 'expected 3 values > 0 (min swing [s], min stance [s], max step frequency [Hz])')
    battery_source: str = param(
        '', 'keep only this battery of battery_state (header.frame_id, else location or '
        'serial_number); empty: several batteries on the topic are summed',
        read_only=True)
    input_timeout_s: float = param(
        5.0, 'wall time [s] without any message on battery_state, gait/phase and '
        'joint_states after which that is warned (0: off)', read_only=True,
        validate=lambda v: None if math.isfinite(v) and v >= 0 else 'expected >= 0 s')


def warning_kind(warning: str) -> str:
    """The throttling key of a window warning: its text before any parenthesis, numbers left
    out ('negative mean input power -35.1 W' and '-35.2 W' are one kind: with the number in
    the key it was logged on every window; an outside review)."""
    return re.sub(r'[-+]?\d[\d.,eE+-]*', '#', warning.split('(')[0])[:60]


def descriptors_to_msg(d: Descriptors, msg: Any = None) -> EnergeticDescriptors:
    """Fill an EnergeticDescriptors message from core descriptors."""
    msg = msg or EnergeticDescriptors()
    msg.header.stamp.sec, msg.header.stamp.nanosec = s_to_stamp(d.t_end_s)
    msg.window = d.window_s
    msg.mass = d.mass_kg
    msg.speed = d.speed_mps
    msg.power_in = d.power_in_w
    msg.power_out = d.power_out_w
    msg.power_loss = d.power_loss_w
    msg.efficiency = d.efficiency
    msg.cost_of_transport = d.cost_of_transport_j_per_m
    msg.specific_cost_of_transport = d.specific_cost_of_transport
    msg.specific_resistance = d.specific_resistance
    return msg


class EnergyMonitorNode(Node):
    """Thin node around :class:`DescriptorAccumulator`."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, node_name: str = 'energy_monitor') -> None:
        super().__init__(node_name, context=context, namespace=namespace or '',
                         parameter_overrides=parameter_overrides or [])
        #: the node's logger naming the topics as remapped (a namespace, ``-r``): the core's
        #: messages name the contract's ("no /battery_state" for a remapped /lab/power)
        self._renaming_logger = RenamingLogger(super().get_logger())
        p = declare_params(self, EnergyParams)
        #: start-up warnings (an assumed mass, a robot_mass above mass), logged once each
        self.start_warnings: list[str] = []
        leg = load_leg_description(p.leg_file) if p.leg_file else antbot_leg()
        if not overridden(self, 'mass'):
            whose = f"AntBot's {ANTBOT_MASS_KG} kg"
            if p.leg_file:
                # AntBot's body with six of the file's legs, as sim_robot -p leg_file and
                # hexapod-analyze energy --leg assume (2.183 kg was assumed here for a robot
                # sim_robot walked as 2.237 kg: P_out and CoT/M 0.9 % and 2.4 % off)
                p = dataclasses.replace(p, mass=default_robot_mass_kg(6, leg.spec.leg_mass_kg))
                whose = (f"AntBot's body with six {leg.spec.leg_mass_kg:.3f} kg legs of "
                         f'{getattr(leg, "name", "") or "the leg file"}, {p.mass:.3f} kg')
            self.start_warnings.append(
                f'mass not given (-p mass:=KG): {whose} is assumed; give '
                '-p mass:=KG (CoT, CoT/M and specific resistance scale with the mass)')
        #: the P_out model's robot mass without payload [kg]: robot_mass, else mass
        self.robot_mass_kg = p.robot_mass if p.robot_mass > 0 else p.mass
        if self.robot_mass_kg > p.mass:
            self.start_warnings.append(
                f'robot_mass {self.robot_mass_kg:g} kg > mass {p.mass:g} kg: a negative payload;'
                ' the P_out model uses the robot_mass robot without payload (check -p mass and '
                '-p robot_mass)')
        for warning in self.start_warnings:
            self.get_logger().warning(warning)
        model = None
        if p.power_out_source != 'effort':
            model = model_power_out(leg.output_power_model(self.robot_mass_kg),
                                    robot_mass_kg=self.robot_mass_kg)
        #: the P_out model's leg given (-p leg_file), else AntBot's (said at the first
        #: window whose P_out is the model's)
        self._leg_given = bool(p.leg_file)
        self._leg_name = getattr(leg, 'name', '') or 'the leg file'
        #: the P_out source of the last published window, and its switches logged
        self._pout_source = ''
        self.pout_switches = 0
        self.core = DescriptorAccumulator(mass_kg=p.mass, cycles=p.cycles,
                                          current_sign=p.current_sign, power_out_model=model,
                                          power_out_source=p.power_out_source,
                                          cycle_source=p.cycle_source, speed_mps=p.speed,
                                          limits=self._limits(p, leg), leg=leg)
        # several batteries on one topic are summed, or one kept (hexapod_common.battery)
        self.batteries = BatteryCombiner(select=p.battery_source or None)
        self._absent = AbsentBatteryFilter()   # present = false samples (no battery)
        self._battery_notes = 0
        self._clocks = LiveClockWatch()   # stamps against the node clock
        #: topics stamped on another clock, told from their first messages (left out)
        self.clock_gate = ArrivalClockGate()
        self._zero_power: int | None = 0   # leading battery samples with V * I == 0
        self._milli: tuple[float, float] | None = None
        self.pub = self.create_publisher(EnergeticDescriptors, 'energy/descriptors',
                                         RELIABLE_QOS)
        self.dropped = 0
        #: dropped messages per kind (type, reason without its numbers): see _log_drop
        self._drops: dict[tuple[str, str], int] = {}
        #: JointStates whose velocity or effort array was left out (another length)
        self.malformed_joint_states = 0
        self._duplicates_logged = 0
        #: windows not published: across a gap in /battery_state (P_in would be interpolated)
        #: or in /joint_states (P_out from the efforts would miss part of the window)
        self.gap_windows = 0
        #: windows not published: the leg joints did not move while the schedule walked
        self.still_windows = 0
        self._sign_logged = False
        self._notes_logged = 0
        self._warned: dict[str, int] = {}  # warning kind -> windows seen with it
        self._zero_stamp_topics: set[str] = set()
        #: messages missing from the input streams, from their stamp gaps (logged on the 1st,
        #: 10th, 100th ... missing message of a topic)
        self.loss = StreamLoss()
        # two-argument callbacks: rclpy passes the message info (the publisher's sequence
        # numbers tell several live publishers apart)
        self._battery_sub = self.create_subscription(
            BatteryState, 'battery_state', lambda m, info: self._on_battery(m, info),
            SENSOR_QOS)
        self._battery_msgs = 0
        #: episodes of several live publishers on battery_state naming one battery, reported
        self.battery_publishers_warned = 0
        # one per battery name (header.frame_id): monitors of distinct names are summed, two
        # publishers of one name interleave into their mean
        self._battery_seqs: dict[str, PublisherSequences] = {}
        self._battery_interleaved: str | None = None   # the name of a new episode
        #: several live publishers on gait/phase (two schedules), said once per episode
        self.gait_publishers = PublishersWatch(
            self, 'two gait schedules reach this node and the windows follow neither (cycles '
            'are cut where the schedules switch); stop all but one gait node')
        gait_sub = self.create_subscription(GaitPhase, 'gait/phase',
                                            lambda m, info: self._on_gait(m, info), SENSOR_QOS)
        self.gait_publishers.subscription = gait_sub
        joint_sub = self.create_subscription(JointState, 'joint_states', self._on_joints,
                                             SENSOR_QOS)
        mocap_sub = self.create_subscription(mocap_msg_class(p.mocap_type), 'mocap/body',
                                             self._on_pose, SENSOR_QOS)
        odom_sub = self.create_subscription(Odometry, 'odom', self._on_odom, SENSOR_QOS)
        self._renaming_logger.set_renames(topic_renames({
            'battery_state': self._battery_sub, 'gait/phase': gait_sub,
            'joint_states': joint_sub, 'mocap/body': mocap_sub, 'odom': odom_sub}))
        #: inputs that never come (another namespace) or all stop: said on the wall clock
        self.inputs = InputWatch(
            self, {'battery_state': self._battery_sub, 'gait/phase': gait_sub,
                   'joint_states': joint_sub}, p.input_timeout_s,
            consequence='no descriptors can be computed')

    def _limits(self, p: Any, leg: Any) -> ActuatorLimits:
        """``-p limits``: AntBot's servo limits on AntBot's leg by default; given with
        ``-p leg_file``, measured on that leg (its 100 mm, 40 mm bench step): each schedule's
        step is scaled by its joint path on the robot's leg against that leg's bench path."""
        limits = ActuatorLimits(*p.limits)
        if not (p.leg_file and overridden(self, 'limits')):
            return limits
        from hexapod_gait.step_limits import measured_on_leg

        return measured_on_leg(limits, leg)

    def get_logger(self) -> Any:
        """The node's logger; its messages name the topics as this node resolved them
        (:class:`hexapod_common.renaming_logger.RenamingLogger`)."""
        log = getattr(self, '_renaming_logger', None)
        return log if log is not None else super().get_logger()

    def _guard(self, what: str, fn: Any, msg: Any) -> Any:
        try:
            return fn(msg)
        except (ValueError, IndexError) as err:
            self.dropped += 1
            self._log_drop(what, str(err))
            return None

    def _log_drop(self, what: str, why: str) -> None:
        """Log a dropped message: each kind (type and reason, its numbers aside) on its 1st,
        10th, 100th, 1000th, then every 10,000th occurrence, with the count. One 5 s throttle
        over every kind (an outside review) said one line per 5 s of a steady stream and hid
        the other kinds behind it: NaN battery samples every 0.1 s kept a /gait/phase of
        another duty factor than (0, 1), every message of it dropped, from ever being said."""
        kind = (what, _NUMBER.sub('#', why)[:160])
        if kind not in self._drops and len(self._drops) >= MAX_DROP_KINDS:
            kind = (what, 'other reasons')
        n = self._drops[kind] = self._drops.get(kind, 0) + 1
        if count_milestone(n):
            self.get_logger().warning(f'dropped a {what} message: {why}'
                                      + (f' [{n} such messages so far]' if n > 1 else ''))

    def _restamp(self, topic: str, sample: Any) -> Any:
        """``sample`` stamped with the node's clock when its header stamp is zero; a stamped
        one is checked for its clock and for messages missing before it. None: stamped on
        another clock than the other topics (:class:`ArrivalClockGate`), left out."""
        if sample.t_s != 0.0:
            keep, level, text = self.clock_gate.observe(
                topic, sample.t_s, self.get_clock().now().nanoseconds * 1e-9)
            # one call site per severity (rclpy refuses another severity from the same line:
            # the message that came back on the clock was dropped with that error)
            if level == 'error':
                self.get_logger().error(text)
            elif level:
                self.get_logger().info(text)
            if not keep:
                return None
            self._check_clock(topic, sample.t_s)
            self._count_loss(topic, sample)
            return sample
        if topic not in self._zero_stamp_topics:
            self._zero_stamp_topics.add(topic)
            self.get_logger().warning(f'{topic} messages have zero header stamps: using the '
                                      'arrival time on the node clock instead')
        return dataclasses.replace(sample, t_s=self.get_clock().now().nanoseconds * 1e-9)

    def _count_loss(self, topic: str, sample: Any) -> None:
        """Messages missing before ``sample`` (:class:`hexapod_common.clocks.StreamLoss`; a
        joint-state name group or a battery is a stream of its own), logged on the topic's
        1st, 10th, 100th, 1000th ... missing message."""
        note = self.loss.observe_topic(
            topic, (tuple(getattr(sample, 'names', ())), getattr(sample, 'source', '')),
            sample.t_s)
        if note:
            self.get_logger().warning(note)

    def _check_clock(self, topic: str, t_s: float) -> None:
        """Report (once) a topic stamped on another clock than the others."""
        for err in self._clocks.observe(topic, t_s, self.get_clock().now().nanoseconds * 1e-9):
            if not any(err.startswith(f'{t} stamped') for t in self.clock_gate.reported):
                self.get_logger().error(err)   # (not twice: the gate said it from the start)

    def _publish(self, results: Sequence[Descriptors] | None) -> None:
        notes = self.core.notes_
        while self._notes_logged < len(notes):   # time jumps, a quiet /gait/phase: once each
            self.get_logger().warning(notes[self._notes_logged])
            self._notes_logged += 1
        if self.core.sign_note_ and not self._sign_logged:
            self._sign_logged = True
            self.get_logger().info(self.core.sign_note_)
        for d in results or ():
            for warning in d.warnings:
                # a condition that holds for every window (e.g. AX efforts refused) is logged
                # on its 1st, 10th, 100th ... window, not once per gait cycle
                kind = warning_kind(warning)
                n = self._warned[kind] = self._warned.get(kind, 0) + 1
                if count_milestone(n):
                    self.get_logger().warning(warning if n == 1 else
                                              f'{warning} [{n} windows so far]')
            if BATTERY_GAP_NOTE in d.warnings or JOINT_GAP_NOTE in d.warnings:
                # its P_in would be interpolated over missing battery data, or its P_out miss
                # joint data: not published, as the offline analysis leaves it out
                self.gap_windows += 1
                continue
            if any(w.startswith(STILL_JOINTS_NOTE) for w in d.warnings):
                # a robot that did not follow the walking schedule: its speed and model P_out
                # would be a walking robot's; not published, as offline
                self.still_windows += 1
                continue
            self._say_pout_source(d)
            self.pub.publish(descriptors_to_msg(d))

    def _say_pout_source(self, d: Descriptors) -> None:
        """Say where P_out comes from when that changes: the first model window (AntBot's leg
        unless -p leg_file gives one: 0.398 W where the lab robot's joints gave 5.17 W, without
        a word), and every switch between the efforts and the model mid-series (logged on the
        1st, 10th ... window of its warning only, so the series mixed the two silently; an
        outside live review). Switches beyond the 20th are logged on the 100th, 1000th ..."""
        src = d.power_out_source
        if src not in ('effort', 'model') or src == self._pout_source:
            return
        prev, self._pout_source = self._pout_source, src
        log = self.get_logger()
        if not prev:
            if src == 'model':
                whose = (self._leg_name if self._leg_given else "AntBot's leg (no -p leg_file)")
                log.warning(f'P_out from the Eq. 6 model of {whose}, not measured: no usable '
                            'joint efforts on /joint_states' + (
                                '' if self._leg_given else
                                "; for this robot's own leg give -p leg_file:=LEG.yaml "
                                '(hexapod_energy.leg_description), or publish joint efforts'))
            return
        self.pout_switches += 1
        n = self.pout_switches
        if n > 20 and n not in (100, 1000) and n % 10000:
            return
        what = ('the Eq. 6 model' + ('' if self._leg_given else " (AntBot's leg)")
                if src == 'model' else 'the joint efforts')
        why = ''
        if src == 'model':
            why = next((w.split(';')[0] for w in d.warnings
                        if 'P_out from the Eq. 6 model' in w), 'no joint efforts in it')
        log.warning(f'P_out switches to {what} from the window ending {d.t_end_s:.3f} s '
                    f'(was {"the joint efforts" if prev == "effort" else "the model"})'
                    + (f': {why}' if why else '') + f' [{n} switch(es) so far]')

    @property
    def gait_publishers_warned(self) -> int:
        """Episodes of several live publishers on gait/phase, reported."""
        return self.gait_publishers.reported

    @property
    def _gait_seq(self) -> Any:
        return self.gait_publishers.sequences

    def _on_battery(self, msg: BatteryState, info: Any = None) -> None:
        self.inputs.seen('battery_state')
        name = battery_source(msg)   # as the combiner names it: frame_id, location, serial
        seqs = self._battery_seqs.pop(name, None)   # re-inserted: the dict is in recency order
        if seqs is None:
            if len(self._battery_seqs) >= MAX_BATTERY_NAMES:
                # names that keep changing (a counter in frame_id): the least recently heard
                # forgotten, not a steady pack heard first
                del self._battery_seqs[next(iter(self._battery_seqs))]
            seqs = PublisherSequences()
        self._battery_seqs[name] = seqs
        if seqs.add(publication_sequence(info)):
            self._battery_interleaved = name
        self._publish(self._guard('BatteryState', self._add_battery, msg))

    def _add_battery(self, msg: BatteryState) -> list[Descriptors]:
        raw = self._restamp('battery_state', battery_from_msg(msg))
        if raw is None:
            return []
        if not self._absent.keep(raw):
            if self._absent.dropped == 1:   # once: a gap in the battery stream follows
                self.get_logger().warning(
                    'battery_state: present = false (no battery) after the battery was '
                    'present, or 0 V and 0 A: such samples are left out (not a measurement)')
            return []
        if self._milli is None and (abs(raw.voltage_v) > MILLI_THRESHOLD or
                                    abs(raw.current_a) > MILLI_THRESHOLD):
            # milli-units (no pack reaches 1000 V or draws 1000 A), decided on the first such
            # sample as the offline reader decides on the run (hexapod_common.battery)
            self._milli = milli_factors(raw.voltage_v, raw.current_a)
            what = ' and '.join(x for x, f in zip(('voltage', 'current'), self._milli)
                                if f != 1.0)
            self.get_logger().warning(f'battery_state {what} in milli-units: divided by 1000')
        if self._milli is not None and self._milli != (1.0, 1.0):
            raw = dataclasses.replace(raw, voltage_v=self._milli[0] * raw.voltage_v,
                                      current_a=self._milli[1] * raw.current_a)
        self._battery_msgs += 1
        numbered = any(q.numbered for q in self._battery_seqs.values())
        if not numbered and (self._battery_msgs in (20, 200)
                             or self._battery_msgs % 2000 == 0):
            self._check_battery_publishers()   # a middleware without sequence numbers
        sample = self.batteries.add(raw)
        if self._battery_interleaved is not None:
            name, self._battery_interleaved = self._battery_interleaved, None
            if self.batteries.select is None or self.batteries.select == name:
                self._report_battery_publishers(None, name)
        for note in self.batteries.notes[self._battery_notes:]:
            self.get_logger().warning(note)
        self._battery_notes = len(self.batteries.notes)
        if sample is None:
            return []
        if self._zero_power is not None:   # a monitor that fills 0 for "not measured"
            if sample.voltage_v * sample.current_a != 0:
                self._zero_power = None
            else:
                self._zero_power += 1
                if self._zero_power == ZERO_POWER_SAMPLES:
                    self.get_logger().error(
                        f'battery_state: {ZERO_POWER_SAMPLES} samples with voltage or current '
                        '0: the monitor does not measure it; power_in 0 W is not a measurement')
        return self.core.add_battery(sample)

    def _check_battery_publishers(self) -> None:
        """Without sequence numbers: the graph's publisher count, once (a crashed
        publisher's endpoint counts until its DDS lease runs out)."""
        if self.battery_publishers_warned:
            return
        n = self.count_publishers(self._battery_sub.topic_name)
        if n > 1 and len(self.batteries.sources_) <= 1 and self.batteries.select is None:
            self._report_battery_publishers(
                n, self.batteries.sources_[0] if self.batteries.sources_ else '')

    def _report_battery_publishers(self, n: int | None, name: str) -> None:
        """Several publishers on battery_state whose messages name one battery: their
        samples interleave and read as one battery, the mean of the packs, not their sum (two
        monitors with an empty frame_id at 36 W and 6 W read 21 W: an outside review). Told
        per battery name from the sequence numbers: monitors of distinct names are summed,
        and one of them doubled is still reported; with ``battery_source`` only the kept
        name is."""
        self.battery_publishers_warned += 1
        topic = self._battery_sub.topic_name
        how = ('the graph\'s count' if n is not None
               else 'their messages\' sequence numbers interleave')
        self.get_logger().error(
            f'{n or "several live"} publishers on {topic} name one battery ({name!r}, from '
            f'header.frame_id, location or serial_number; {how}; publishers in the graph: '
            f'{publisher_names(self, topic)}): '
            'their samples interleave and are read as one '
            'battery (the mean of the packs, not their sum); give each monitor its own '
            'header.frame_id (they are then summed) or keep one with -p battery_source')

    def _on_gait(self, msg: GaitPhase, info: Any = None) -> None:
        self.inputs.seen('gait/phase')
        self.gait_publishers.add(info)
        self._publish(self._guard('GaitPhase', self._add_gait, msg))

    def _add_gait(self, msg: GaitPhase) -> list[Descriptors]:
        sample = self._restamp('gait/phase', gait_phase_from_msg(msg))
        return [] if sample is None else self.core.add_gait_phase(sample)

    def _on_joints(self, msg: JointState) -> None:
        self.inputs.seen('joint_states')
        self._publish(self._guard('JointState', self._add_joints, msg))

    def _add_joints(self, msg: JointState) -> list[Descriptors]:
        sample = joint_state_from_msg(msg)
        if sample.malformed:
            self.malformed_joint_states += 1
            self.get_logger().warning(
                f'joint_states: {sample.malformed} (positions kept; P_out from efforts '
                f'misses these messages) [{self.malformed_joint_states} so far]',
                throttle_duration_sec=5.0)
        skipped = self.core.velocityless_skipped_
        non_legs = len(self.core.leg_joints_.dropped)
        sample = self._restamp('joint_states', sample)
        if sample is None:
            return []
        out = self.core.add_joint_state(sample)
        if self.core.velocityless_skipped_ and not skipped:   # once
            self.get_logger().warning('joint_states: ' + velocityless_note(1))
        if len(self.core.leg_joints_.dropped) > non_legs:   # once per new name
            self.get_logger().warning('joint_states: ' + self.core.leg_joints_.note())
        n = self.core.duplicate_joint_states_
        if n and n == 10 ** int(math.log10(n)) and n != self._duplicates_logged:
            self._duplicates_logged = n   # on the 1st, 10th, 100th ...
            self.get_logger().info(
                f'joint_states: {n} message(s) so far repeat a recent one exactly (delivered '
                'twice: a replayed bag\'s duplicates, a bridge): left out, as offline')
        return out

    @staticmethod
    def _feed(add: Any, sample: Any) -> None:
        """``add(sample)`` unless the sample was left out (None)."""
        if sample is not None:
            add(sample)

    def _on_odom(self, msg: Odometry) -> None:
        self._guard('Odometry', lambda m: self._feed(
            self.core.add_odometry, self._restamp('odom', odometry_from_msg(m))), msg)
        self._publish(None)

    def _on_pose(self, msg: PoseStamped) -> None:
        self._guard('PoseStamped', lambda m: self._feed(
            self.core.add_pose, self._restamp('mocap/body', pose_from_msg(m))), msg)
        self._publish(None)


def main(args: Sequence[str] | None = None) -> int:
    return run_node(EnergyMonitorNode, args)
