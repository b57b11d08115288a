"""``bench_sequencer`` node: runs a bench plan, one bag per session (core: sequencer.py).

- subscribes ``servo_status`` (temperatures for the gate; NaN or no status = not in the gate);
- publishes ``bench/session`` (hexapod_interfaces/BenchSession, transient local) whenever the
  state or the session changes: the gait/bench side walks while the state is ``heating`` or
  ``walking`` at the session's frequency, duty factor and step length;
- service ``confirm_load`` (std_srvs/Trigger): the operator has put the requested load on the
  stage (``auto_load_change: true`` confirms at once, for simulation);
- optional torque control: with ``torque_service`` set (e.g. ``set_torque`` of dynamixel_driver)
  it calls that std_srvs/SetBool on every torque change (off while cooling); empty, a warning
  at start says the torque is not controlled. A torque off that could not be sent at the end
  (the service is gone: the driver died or its adapter was unplugged), failed or went
  unanswered is logged as an error: the servos may still hold torque;
- records the ``record_topics`` of each walking phase into ``<output_dir>/<session_id>`` (an
  unfinished earlier attempt is moved aside to ``<session_id>.interrupted-N``). Each topic is
  subscribed once a publisher is discovered (checked every 0.5 s) with the publishers'
  reliability (best effort as soon as one publisher is best effort, e.g. a motion-capture
  bridge with SensorDataQoS: a reliable subscription would hear nothing), one subscription
  per topic (no duplicates). A recorded topic not received by the end of ``starting``
  aborts the plan, naming the topic and its owner (leave it out of ``record_topics`` if the
  bench has none, e.g. ``bench/leg_tip`` without motion capture);
- progress in ``state_file`` (JSON), so a restart resumes at the first unfinished session.

- ``gait_node`` (e.g. ``gait_scheduler``): the sequencer drives the walk by setting that node's
  ``period``, ``duty_factor``, ``step_length`` and ``step_height`` parameters to the session's
  gait while heating/walking, and ``step_length = step_height = 0`` (standing) otherwise, in one
  ``set_parameters_atomically`` call (all or nothing). A 0 Hz session (the paper's basal
  session) is recorded standing at its load, its heating walked at ``HEAT_FREQUENCY_HZ``. A gait
  the gait node refuses aborts the plan (the session is not recorded under values it did not
  walk). Empty with ``backend: external``, a warning at start says the plan's gaits are not
  commanded (whatever the gait node walks is recorded under the plan's values).

Safety (core: :class:`~.sequencer.BenchSequencer`):

- the recording of a session starts once ``gait/phase`` shows the gait node settled at the
  session gait (state ``starting`` until then, at most ``stand_timeout_s``);
- stand before torque off: after a walk the leg is stood (torque on) until ``gait/phase``
  shows the gait node settled at step 0, then the torque goes off. A leg the gait node does
  not report standing within ``stand_timeout_s``, or whose gait node is gone (its parameter
  service unavailable: no wait), is NOT stood: the torque is kept on (a loaded leg dropping is
  worse than a held one), the plan is aborted and the log says to support the stage before
  turning the torque off;
- a silent stream names its owner (``servo_status``, ``joint_states``: the driver;
  ``battery_state``: the power monitor; ``bench/ground_force``: the force sensor;
  ``bench/leg_tip``: the motion capture; ``gait/phase``, ``joint_commands``: the gait node);
- while cooling, ``servo_status`` silent for ``stream_timeout_s`` after it was seen aborts the
  plan (the gate could never be met: a driver gone would leave it waiting without a word);
- while walking, an overheating servo (``servo_status`` error flags, or a temperature above the
  plan's ``temperature_limit_c``), ``servo_status`` silent for ``stream_timeout_s``, or
  ``battery_state`` or any of the ``record_topics`` (``bench/ground_force``,
  ``bench/leg_tip``, ``joint_states``...; not ``bench/session``) silent as long after it was
  seen once, aborts the plan (the session would be recorded without it);
- SIGINT / SIGTERM (console script) abort the plan: the leg stands, the torque goes off,
  ``bench/session`` says ``aborted``, the partial bag is moved aside to
  ``<session_id>.interrupted-N`` and the exit code is 1 (a second signal skips the wait for the
  stand). Any abort ends the node with exit code 1, whatever ``exit_when_done``.

Time is the node clock (simulated time with ``use_sim_time``), so a simulator running faster
than real time runs the plan in accelerated time.

``backend: sim`` runs the plan on the embedded bench simulator instead (core:
:mod:`.sequencer_sim`): each timer tick advances the simulated bench by ``sim_step_s``
(``sim_cool_step_s`` with the torque off) and feeds its servo temperatures to the gate, so the
plan runs in accelerated time; the node publishes ``clock`` (the simulated time), ``servo_status``
(the simulated temperatures) and ``bench/session`` stamped in simulated time, and writes each
session's walk to ``<output_dir>/<session_id>`` with the bench topics that
``hexapod-analyze energy --bench`` reads. Load changes are automatic.
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('bench_sequencer')

import signal
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from hexapod_common.bags import BagWriter
from hexapod_common.node_utils import (
    LATCHED_QOS,
    RELIABLE_QOS,
    SENSOR_QOS,
    declare_params,
    on_stop_signals,
    param,
    run_node,
)
from hexapod_common.ros_types import CONTRACT_TOPICS, ros_message_class
from hexapod_common.conversions import s_to_stamp
from hexapod_interfaces.msg import BenchSession, ServoStatus
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from hexapod_interfaces.msg import GaitPhase
from rcl_interfaces.srv import SetParametersAtomically
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import BatteryState
from std_srvs.srv import SetBool, Trigger

from hexapod_bench_drivers.dynamixel_bus import config_file
from hexapod_bench_drivers.sequencer import (
    HEAT_FREQUENCY_HZ,
    BenchSequencer,
    PlanError,
    SequencerCommand,
    load_plan,
    move_aside,
)

__all__ = ['HEAT_FREQUENCY_HZ', 'SIM_EPOCH_S', 'BenchSequencerNode', 'BenchSequencerParams',
           'abort_on_signals', 'main']

#: Clock time of the embedded simulator's t = 0 [s] (the bag time of its per-session bags).
SIM_EPOCH_S = 1_700_000_000.0

#: Seconds between looks for the publishers of the recorded topics (their QoS).
DISCOVERY_PERIOD_S = 0.5


def recording_qos(reliable: bool) -> QoSProfile:
    """QoS of a recording subscription: reliable only if every publisher is (a reliable
    subscription does not match a best-effort publisher), volatile, a deep queue."""
    return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE if reliable
                      else ReliabilityPolicy.BEST_EFFORT,
                      durability=DurabilityPolicy.VOLATILE)

# Relative names, so that the node's namespace applies (as to every topic of the drivers).
DEFAULT_RECORD = ('joint_states', 'joint_commands', 'servo_status', 'battery_state',
                  'bench/ground_force', 'bench/leg_tip', 'bench/session', 'gait/phase')


@dataclass(frozen=True)
class BenchSequencerParams:
    """Parameters of the bench_sequencer node."""

    plan_file: str = param('', 'YAML bench plan (see hexapod_bench_drivers.sequencer).',
                           validate=lambda v: None if v else 'expected a YAML file path')
    leg_file: str = param('', "the bench leg's file (gait_scheduler's -p leg_file: DH table, "
                          "link masses, neutral_tip_m), the plan's gaits are checked on its "
                          "reach and joint paths; empty: AntBot's leg")
    state_file: str = param('bench_state.json', 'Progress file (resume after a crash).')
    output_dir: str = param('bench_bags', 'Folder of the per-session bags.')
    record_topics: tuple = param(DEFAULT_RECORD, 'Topics recorded while walking.')
    auto_load_change: bool = param(False, 'Confirm load changes at once (simulation).')
    torque_service: str = param('', 'std_srvs/SetBool service for servo torque ("" = none).')
    rate_hz: float = param(10.0, 'State machine update rate [Hz].',
                           validate=lambda v: None if v > 0 else 'expected > 0')
    gait_node: str = param('', 'Gait node whose gait parameters the sequencer sets ("" = none).')
    backend: str = param('external', 'external (drivers and gait node on topics) or sim '
                         '(embedded bench simulator, accelerated time)',
                         validate=lambda v: None if v in ('external', 'sim')
                         else 'expected external or sim')
    sim_step_s: float = param(0.5, 'sim: simulated seconds per tick while powered [s].',
                              validate=lambda v: None if v > 0 else 'expected > 0')
    sim_cool_step_s: float = param(5.0, 'sim: simulated seconds per tick with torque off [s].',
                                   validate=lambda v: None if v > 0 else 'expected > 0')
    sim_initial_temperature_c: float = param(26.0, 'sim: servo temperature at start [degC].')
    sim_ambient_temperature_c: float = param(25.5, 'sim: air temperature [degC].')
    sim_seed: int = param(0, 'sim: noise seed.')
    stand_timeout_s: float = param(10.0, 'Longest wait for the leg to stand (gait/phase at step '
                                   '0) before the torque goes off [s].',
                                   validate=lambda v: None if v > 0 else 'expected > 0')
    stream_timeout_s: float = param(5.0, 'While walking: servo_status (or battery_state or a '
                                    'recorded topic, once seen) silent this long aborts the '
                                    'plan [s] (5 s: a 1 Hz '
                                    'fuel gauge with jitter, a SCPI supply resynchronising).',
                                    validate=lambda v: None if v > 0 else 'expected > 0')
    exit_when_done: bool = param(True, 'Exit (code 0) once the plan is done; false keeps '
                                 'publishing the final state. An aborted plan always exits '
                                 '(code 1).')


def gait_values(s: Any, state: str, walk: bool) -> tuple[float, float, float, float]:
    """Gait node ``(period, duty_factor, step_length, step_height)`` for session ``s`` in
    sequencer state ``state`` (``walk``: the command walks)."""
    if walk and s.frequency_hz > 0:
        return (1.0 / s.frequency_hz, s.duty_factor, s.step_length_m, s.step_height_m)
    if walk and state == 'heating':
        # heating before a basal (0 Hz) session: walk at HEAT_FREQUENCY_HZ, then stand
        return (1.0 / HEAT_FREQUENCY_HZ, s.duty_factor, s.step_length_m, s.step_height_m)
    # holding (and the basal session itself): the gait's step is 0, the leg stands
    return (1.0 / s.frequency_hz if s.frequency_hz > 0 else 1.0, s.duty_factor, 0.0, 0.0)


class BenchSequencerNode(Node):
    """Thin node around BenchSequencer (see module doc)."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('bench_sequencer', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = self.params = declare_params(self, BenchSequencerParams)
        leg = None
        if p.leg_file:
            from hexapod_gait.leg_file import LegFileError, read_leg_file

            try:
                leg = read_leg_file(p.leg_file)
            except LegFileError as err:
                raise PlanError(f'leg_file refused: {err}') from err
        # bench_plan.yaml: the package config
        plan = load_plan(config_file(p.plan_file), leg=leg)
        self.sim_run: Any = None
        if p.backend == 'sim':
            from hexapod_bench_drivers.bench_sim import BenchConfig
            from hexapod_bench_drivers.sequencer_sim import SimulatedBench, SimulatedBenchRun

            # the simulated bench walks the leg file's leg (links, masses, neutral tip, inverse
            # kinematics; AX-18A servos), the leg the plan is checked on
            bench = SimulatedBench(BenchConfig(
                initial_temperature_c=p.sim_initial_temperature_c,
                ambient_temperature_c=p.sim_ambient_temperature_c), seed=p.sim_seed, leg=leg)
            if leg is not None:
                self.get_logger().info(f'backend sim: the simulated bench walks {leg.name!r} '
                                       f'of {p.leg_file} (AX-18A servos)')
            self.sim_run = SimulatedBenchRun(plan, bench, state_file=p.state_file,
                                             output_dir=p.output_dir, step_s=p.sim_step_s,
                                             cool_step_s=p.sim_cool_step_s)
            self.seq = self.sim_run.seq
        else:
            self.seq = BenchSequencer(plan, state_file=p.state_file,
                                      stand_timeout_s=p.stand_timeout_s,
                                      stream_timeout_s=p.stream_timeout_s,
                                      torque_controlled=bool(p.torque_service))
            self._warn_unconnected()
        if self.seq.skipped:
            self.get_logger().info(f'resuming: {len(self.seq.skipped)} sessions already done')
        self.temperatures: list[float] = []
        self.error_flags: list[int] = []
        self._status_ns: int | None = None      # node clock at the last servo_status
        self._battery_ns: int | None = None     # ... battery_state (None: never seen)
        self._seen_ns: dict[str, int] = {}      # ... each recorded topic seen so far
        self._phase_standing = False            # last gait/phase at step 0
        self._phase_seen = False                # any gait/phase message yet
        self._phase: GaitPhase | None = None
        self._gait_accepted: tuple[float, ...] | None = None
        self._abort_requests = 0
        self._abort_logged = False
        self._counts: dict[str, int] = {}       # messages per topic in the current bag
        self.pub = self.create_publisher(BenchSession, 'bench/session', LATCHED_QOS)
        self.create_service(Trigger, 'confirm_load', self._on_confirm)
        self.torque_client = (self.create_client(SetBool, p.torque_service)
                              if p.torque_service else None)
        self.gait_client = (self.create_client(
            SetParametersAtomically, f'{p.gait_node.rstrip("/")}/set_parameters_atomically')
            if p.gait_node else None)
        self._gait_sent: tuple[float, ...] | None = None
        self._last: tuple[str, str] | None = None
        self._torque: bool | None = None
        self._torque_wanted: bool | None = None   # last torque commanded (no service: noted)
        self._torque_wanted_on = False            # torque on commanded once (no service)
        self._torque_failed = ''                  # why the last torque call failed, else ''
        self._torque_call: Any = None             # the last torque call sent
        self._torque_unsent: bool | None = None   # a torque value not sent (no service)
        self._hold_logged = False
        self.writer: BagWriter | None = None
        self._recording_id = ''
        # contract topic -> (resolved name, message type); its subscription, and whether the
        # subscription is reliable
        self._rec_wanted: dict[str, tuple[str, str]] = {}
        self._rec_subs: dict[str, Any] = {}
        self._rec_reliable: dict[str, bool] = {}
        self.last_command: SequencerCommand | None = None
        #: Resolved with the exit code (0 done, 1 aborted) when the plan ends, if
        #: ``exit_when_done``; ``run_node`` spins until then.
        self.finished = Future()
        #: service calls in flight (torque, gait), each with its client
        self._calls: list[tuple[Any, Any]] = []
        self._calls_since_ns: int | None = None
        if self.sim_run is not None:
            from rclpy.qos import QoSProfile

            self.pub_clock = self.create_publisher(Clock, '/clock', QoSProfile(depth=10))
            self.pub_status = self.create_publisher(ServoStatus, 'servo_status', RELIABLE_QOS)
            self.create_timer(1.0 / p.rate_hz, self._on_sim_timer)
        else:
            self.create_subscription(ServoStatus, 'servo_status', self._on_status, SENSOR_QOS)
            self.create_subscription(BatteryState, 'battery_state', self._on_battery,
                                     SENSOR_QOS)
            if self.gait_client is not None:
                self.create_subscription(GaitPhase, 'gait/phase', self._on_phase, SENSOR_QOS)
            self._subscribe_recorded()
            self.create_timer(DISCOVERY_PERIOD_S, self._discover_recorded)
            self.create_timer(1.0 / p.rate_hz, self._on_timer)

    def _warn_unconnected(self) -> None:
        """backend external: say at start what an empty gait_node / torque_service means."""
        p, log = self.params, self.get_logger()
        if not p.gait_node:
            log.warning('gait_node is empty: the plan\'s gaits will NOT be commanded (the leg '
                        'walks whatever the gait node is set to, recorded under the plan\'s '
                        'frequencies) and the leg is not stood before the torque goes off; '
                        'set -p gait_node:=/gait_scheduler')
        if not p.torque_service:
            log.warning('torque_service is empty: the servos\' torque is NOT controlled by '
                        'the sequencer (never turned off to cool, nor at the end or on an '
                        'abort); set -p torque_service:=/set_torque (dynamixel_driver)')

    def _on_status(self, msg: ServoStatus) -> None:
        self.temperatures = [float(t) for t in msg.temperature]
        self.error_flags = [int(e) for e in msg.error]
        self._status_ns = self.get_clock().now().nanoseconds

    def _on_battery(self, msg: BatteryState) -> None:
        self._battery_ns = self.get_clock().now().nanoseconds

    def _on_phase(self, msg: GaitPhase) -> None:
        self._phase = msg
        self._phase_standing = msg.step_length == 0.0 and msg.step_height == 0.0
        self._phase_seen = True

    def request_abort(self, reason: str) -> None:
        """Abort the plan (a signal, a refused gait): stand, torque off, exit code 1.

        A second request no longer waits for the stand (torque off at the next tick).
        """
        self._abort_requests += 1
        if self._abort_requests > 1 and self.seq.state == 'aborted':
            self.get_logger().error(f'{reason} again: torque off without waiting for the stand')
        self.seq.abort(reason)       # logged by the next tick with the reason

    def _gait_ready(self) -> bool:
        """The gait node has accepted the current session's gait and walks it settled
        (``gait/phase`` carries the target values only once the transition is over)."""
        s = self.seq.current
        if self.gait_client is None or s is None:
            return True
        values = gait_values(s, 'walking', walk=True)
        phase = self._phase
        return (self._gait_accepted == values and phase is not None
                and all(abs(a - b) <= 1e-9 * max(1.0, abs(b)) for a, b in zip(
                    (phase.period, phase.duty_factor, phase.step_length, phase.step_height),
                    values)))

    def _stand_unavailable(self) -> str:
        """Why the gait node cannot stand the leg now (its parameter service is gone), else
        '' (also after a second abort request: the operator skips the stand)."""
        if (self.gait_client is None or self._abort_requests > 1
                or self.gait_client.service_is_ready()):
            return ''
        return (f'gait node {self.params.gait_node} unavailable: its '
                'set_parameters_atomically service is gone, so it cannot stand the leg')

    def _unseen(self) -> list[str]:
        """Recorded topics (not bench/session) not received yet."""
        return [c.lstrip('/') for c in self._rec_wanted if c.lstrip('/') not in self._seen_ns]

    def _standing(self) -> bool | None:
        """The gait node has accepted the stand and reports step 0. No gait node: what
        /gait/phase says, if anything publishes it, else None (unknown: the stand then lasts
        stand_timeout_s; it was True, one tick, so torque could go off mid-step: a second
        review)."""
        if self._abort_requests > 1:
            return True
        if self.gait_client is None:
            return self._phase_standing if self._phase_seen else None
        sent = self._gait_accepted
        return (sent is not None and sent[2] == 0.0 and sent[3] == 0.0
                and self._phase_standing)

    def _ages(self, now_ns: int) -> dict[str, float]:
        """Seconds since the last message of each watched stream."""
        ages = {'servo_status': (now_ns - self._status_ns) * 1e-9
                if self._status_ns is not None else float('inf')}
        if self._battery_ns is not None:
            ages['battery_state'] = (now_ns - self._battery_ns) * 1e-9
        for topic, seen_ns in self._seen_ns.items():
            ages.setdefault(topic, (now_ns - seen_ns) * 1e-9)
        return ages

    def _on_confirm(self, request: Any, response: Any) -> Any:
        self.seq.confirm_load()
        response.success = True
        response.message = f'load {self.seq.progress.current_load_kg} kg confirmed'
        return response

    def _on_timer(self) -> None:
        now_ns = self.get_clock().now().nanoseconds
        t_s = now_ns * 1e-9
        ages = self._ages(now_ns)
        # A silent driver's last temperatures are not in the gate.
        fresh = ages['servo_status'] <= self.params.stream_timeout_s
        cmd = self.last_command = self.seq.update(
            t_s, self.temperatures if fresh else [],
            error_flags=self.error_flags if fresh else [], stream_ages_s=ages,
            standing=self._standing(), gait_ready=self._gait_ready(),
            unseen_topics=self._unseen(), stand_unavailable=self._stand_unavailable())
        if cmd.state == 'aborted' and not self._abort_logged:
            self._abort_logged = True
            self.get_logger().error(f'plan aborted: {self.seq.abort_reason}')
        if cmd.hold and not self._hold_logged:
            self._hold_logged = True
            off = (f" (ros2 service call {self._torque_srv()} std_srvs/srv/SetBool "
                   "'{data: false}')" if self.torque_client is not None else '')
            self.get_logger().error(self.seq.hold_reason + off)
        if self.seq.stand_warning:
            self.get_logger().warning(self.seq.stand_warning)
            self.seq.stand_warning = ''
        if cmd.finished_session:
            self.get_logger().info(f'session {cmd.finished_session} done')
        if cmd.load_request_kg is not None and self.params.auto_load_change:
            self.seq.confirm_load(cmd.load_request_kg)
        self._set_recording(cmd)
        self._set_torque(cmd.torque)
        self._set_gait(cmd)
        key = (cmd.state, cmd.session.session_id if cmd.session else '')
        if key != self._last:
            self._last = key
            if cmd.load_request_kg is not None and not self.params.auto_load_change:
                self.get_logger().warning(f'put {cmd.load_request_kg:.3f} kg on the stage, '
                                          'then call confirm_load')
            self._publish(cmd)
        self._check_finished(cmd)

    def _on_sim_timer(self) -> None:
        run = self.sim_run
        if run.done:
            return
        n_events = len(run.events)
        cmd = self.last_command = run.step()
        if cmd.finished_session:
            self.get_logger().info(f'session {cmd.finished_session} done')
        for e in run.events[n_events:]:
            if e.kind == 'interrupted':
                self.get_logger().error(f'session {e.session_id} aborted: its partial bag '
                                        f'is {e.detail}, not counted')
        t_s = SIM_EPOCH_S + run.bench.t_s
        sec, nanosec = s_to_stamp(t_s)
        clock = Clock()
        clock.clock.sec, clock.clock.nanosec = sec, nanosec
        self.pub_clock.publish(clock)
        status = ServoStatus()
        status.header.stamp = clock.clock
        status.name = list(run.bench.sim.joint_names)
        status.temperature = [float(t) for t in run.bench.temperatures_c]
        self.pub_status.publish(status)
        key = (cmd.state, cmd.session.session_id if cmd.session else '')
        if key != self._last:
            self._last = key
            self._publish(cmd, stamp=clock.clock)
        self._check_finished(cmd)

    def _check_finished(self, cmd: SequencerCommand) -> None:
        # a call whose server has gone (a gait node killed after it was asked to stand) will
        # never be answered: not waited for (it held the plan's end for stand_timeout_s when
        # the servo_status silence was noticed before the gait node's)
        self._calls = [(cl, c) for cl, c in self._calls
                       if not c.done() and cl.service_is_ready()]
        now_ns = self.get_clock().now().nanoseconds
        if not self._calls:
            self._calls_since_ns = None
        elif self._calls_since_ns is None:
            self._calls_since_ns = now_ns
        if cmd.state == 'aborted':
            self._stop_recording(aborted=True)
        if (cmd.state in ('done', 'aborted') and (not cmd.torque or cmd.hold)
                and not self.finished.done()):
            # the final torque-off / stand request still in flight (waited for at most
            # stand_timeout_s: a driver that never answers must not hang the node)
            if self._calls and (now_ns - self._calls_since_ns) * 1e-9 < \
                    self.params.stand_timeout_s:
                return
            if not cmd.hold and self.sim_run is None:
                self._report_torque_off()
            self.get_logger().info(f'plan {cmd.state}: {len(self.seq.completed)} sessions '
                                   'completed')
            if self.params.exit_when_done or cmd.state == 'aborted':
                self._stop_recording(aborted=cmd.state == 'aborted')
                self.finished.set_result(0 if cmd.state == 'done' else 1)

    def _publish(self, cmd: SequencerCommand, stamp: Any = None) -> None:
        msg = BenchSession()
        msg.header.stamp = stamp if stamp is not None else self.get_clock().now().to_msg()
        msg.state = cmd.state
        s = cmd.session
        if s is not None:
            msg.session_id = s.session_id
            msg.load_mass = s.load_kg
            msg.frequency = s.frequency_hz
            msg.duty_factor = s.duty_factor
            msg.step_length = s.step_length_m
            msg.step_height = s.step_height_m
        self.pub.publish(msg)

    def _set_torque(self, on: bool) -> None:
        if self.torque_client is None:
            if on != self._torque_wanted and (on or self._torque_wanted is not None):
                self.get_logger().info(f'torque {"on" if on else "off"} not applied: no '
                                       'torque_service (the sequencer does not control the '
                                       'torque)')
            self._torque_wanted = on
            self._torque_wanted_on = self._torque_wanted_on or on
            return
        if on == self._torque:
            return
        if self.torque_client.service_is_ready():
            call = self._torque_call = self.torque_client.call_async(SetBool.Request(data=on))
            call.add_done_callback(lambda f, _on=on: self._on_torque_set(_on, f))
            self._calls.append((self.torque_client, call))
            self._torque = on
            self._torque_failed = ''
            self._torque_unsent = None
        elif not on and self._torque and self._torque_unsent is not False:
            # a torque off after our torque on (at start-up the service may not be
            # discovered yet): said once
            self._torque_unsent = False
            self._say_torque_unavailable()

    def _on_torque_set(self, on: bool, future: Any) -> None:
        try:
            response = future.result()
        except Exception as err:  # noqa: BLE001 -- noted, reported at the end
            self._torque_failed = f'the torque {"on" if on else "off"} call failed: {err}'
            return
        if not response.success:
            self._torque_failed = (f'the driver refused the torque {"on" if on else "off"}: '
                                   f'{response.message}')

    def _torque_srv(self) -> str:
        """The torque service's full name ('' without one)."""
        name = self.params.torque_service
        return self.resolve_service_name(name) if name else ''

    def _say_torque_unavailable(self) -> None:
        self.get_logger().error(f'torque service {self._torque_srv()} unavailable: the servos '
                                'may still hold torque (the torque off was not sent: the '
                                'driver is gone or its adapter unplugged); support the leg, '
                                'then power the servos off')

    def _report_torque_off(self) -> None:
        """At the end: an error when the final torque off was not applied (D6)."""
        srv = self._torque_srv()
        if self.torque_client is None:
            if self._torque_wanted_on:
                self.get_logger().warning('no torque_service: the sequencer did not turn the '
                                          'torque off; the servos may still hold torque')
        elif self._torque is not False:
            if self._torque_unsent is not False:   # not said yet
                self._say_torque_unavailable()
        elif self._torque_call is not None and not self._torque_call.done():
            self.get_logger().error(f'torque service {srv} did not answer the torque off: the '
                                    'servos may still hold torque')
        elif self._torque_failed:
            self.get_logger().error(f'torque service {srv}: {self._torque_failed}; the servos '
                                    'may still hold torque')

    def _set_gait(self, cmd: SequencerCommand) -> None:
        """Set the gait node's parameters to the session's gait (walk) or standing."""
        s, sent = cmd.session, self._gait_sent
        if self.gait_client is None or (s is None and sent is None):
            return
        if s is None:                   # done or aborted: stand with the last gait's timing
            assert sent is not None
            values = (sent[0], sent[1], 0.0, 0.0)
        else:
            values = gait_values(s, cmd.state, cmd.walk)
        if values == self._gait_sent or not self.gait_client.service_is_ready():
            return
        names = ('period', 'duty_factor', 'step_length', 'step_height')
        request = SetParametersAtomically.Request(parameters=[
            Parameter(n, value=float(v)).to_parameter_msg() for n, v in zip(names, values)])
        call = self.gait_client.call_async(request)
        call.add_done_callback(lambda f, _v=values: self._on_gait_set(_v, f))
        self._calls.append((self.gait_client, call))
        self._gait_sent = values
        self._gait_accepted = None

    def _on_gait_set(self, values: tuple[float, ...], future: Any) -> None:
        """A refused (or failed) gait aborts the plan: nothing is recorded under values the
        leg did not walk, and a leg that cannot be stood must not go on."""
        what = 'stand' if values[2] == 0.0 and values[3] == 0.0 else 'session gait'
        gait = ', '.join(f'{n} {v:g}' for n, v in
                         zip(('period', 'duty_factor', 'step_length', 'step_height'), values))
        try:
            result = future.result().result
        except Exception as err:  # noqa: BLE001 -- a failed call aborts, never raises
            self.request_abort(f'setting the {what} ({gait}) on {self.params.gait_node} '
                               f'failed: {err}')
            return
        if not result.successful:
            self.request_abort(f'gait node {self.params.gait_node} refused the {what} '
                               f'({gait}): {result.reason}; fix the plan or the gait node')
        elif values == self._gait_sent:
            self._gait_accepted = values

    def _set_recording(self, cmd: SequencerCommand) -> None:
        if (self.writer is not None and cmd.session is not None
                and cmd.session.session_id != self._recording_id):
            self._stop_recording()          # the next session walks at once: new bag
        if cmd.record and self.writer is None and cmd.session is not None:
            self._recording_id = cmd.session.session_id
            path = Path(self.params.output_dir) / cmd.session.session_id
            move_aside(path)
            path.parent.mkdir(parents=True, exist_ok=True)
            self.writer = BagWriter(path)
            self.writer.set_custom_data('bench_session', cmd.session.session_id)
            self._counts = {}
        elif not cmd.record and self.writer is not None:
            self._stop_recording(aborted=cmd.state == 'aborted')

    def _subscribe_recorded(self) -> None:
        # Subscribed as soon as a publisher is discovered (not per session: a new subscription
        # needs discovery time, which would cut the beginning of each session), with the
        # publishers' reliability: a reliable subscription hears no best-effort publisher
        # (a mocap bridge with SensorDataQoS was never recorded: outside review D4).
        for topic in self.params.record_topics:
            name = self.resolve_topic_name(topic)
            msgtype = CONTRACT_TOPICS.get('/' + topic.lstrip('/'))
            if msgtype is None:
                self.get_logger().warning(f'not recording {topic}: not a contract topic')
                continue
            # Recorded under the contract name (namespace stripped): the analysis reads
            # /battery_state, /bench/session, ... whatever namespace the bench ran in.
            contract = '/' + topic.lstrip('/')
            if topic.endswith('bench/session'):     # our own publisher, latched
                self._rec_subs[contract] = self.create_subscription(
                    ros_message_class(msgtype), name,
                    lambda data, _t=contract, _m=msgtype: self._record(_t, _m, data),
                    LATCHED_QOS, raw=True)
                continue
            self._rec_wanted[contract] = (name, msgtype)
        self._discover_recorded()

    def _discover_recorded(self) -> None:
        """Subscribe each recorded topic once it has publishers, reliable only if all of them
        are; a reliable subscription is replaced by a best-effort one when a best-effort
        publisher appears (one subscription per topic at any time: no duplicates)."""
        for contract, (name, msgtype) in self._rec_wanted.items():
            have = self._rec_reliable.get(contract)
            if have is False:
                continue                    # best effort hears every publisher
            infos = self.get_publishers_info_by_topic(name)
            if not infos:
                continue
            reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                           for i in infos)
            if have is reliable:
                continue
            old = self._rec_subs.pop(contract, None)
            if old is not None:
                self.destroy_subscription(old)
            self._rec_subs[contract] = self.create_subscription(
                ros_message_class(msgtype), name,
                lambda data, _t=contract, _m=msgtype: self._record(_t, _m, data),
                recording_qos(reliable), raw=True)
            self._rec_reliable[contract] = reliable

    def _record(self, topic: str, msgtype: str, data: bytes) -> None:
        now_ns = self.get_clock().now().nanoseconds
        if topic != '/bench/session':       # our own, latched: published on change only
            self._seen_ns[topic.lstrip('/')] = now_ns
        if self.writer is not None:
            self.writer.write(topic, msgtype, data, now_ns)
            self._counts[topic] = self._counts.get(topic, 0) + 1

    def _stop_recording(self, *, aborted: bool = False) -> None:
        """Close the bag; an aborted session's bag is moved aside (``.interrupted-N``), and
        a bag lacking some of the ``record_topics`` is named in the log."""
        if self.writer is None:
            return
        self.writer.close()
        self.writer = None
        path = Path(self.params.output_dir) / self._recording_id
        if aborted:
            target = move_aside(path)
            self.get_logger().error(f'session {self._recording_id} aborted: its partial bag '
                                    f'is {target}, not counted')
            return
        missing = ['/' + t.lstrip('/') for t in self.params.record_topics
                   if self._counts.get('/' + t.lstrip('/'), 0) == 0]
        if missing:
            self.get_logger().warning(f'session {self._recording_id}: bag {path} has no '
                                      f'{missing}; the analysis may refuse it')

    def destroy_node(self) -> None:
        self._stop_recording()
        super().destroy_node()


def abort_on_signals(node: BenchSequencerNode,
                     signals: Sequence[int] = (signal.SIGINT, signal.SIGTERM)) -> None:
    """SIGINT / SIGTERM abort the plan safely (:meth:`BenchSequencerNode.request_abort`)
    instead of shutting rclpy down under a walking leg; the node then exits with code 1."""
    on_stop_signals(node.request_abort, signals, node=node)


def _node_aborting_on_signals(**kw: Any) -> BenchSequencerNode:
    """``bench_sequencer`` node built by the console script (signals abort the plan)."""
    node = BenchSequencerNode(**kw)
    abort_on_signals(node)
    return node


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``bench_sequencer``."""
    return run_node(_node_aborting_on_signals, args, params=BenchSequencerParams)


if __name__ == '__main__':
    raise SystemExit(main())
