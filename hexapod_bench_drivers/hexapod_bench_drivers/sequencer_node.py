"""``bench_sequencer`` node: runs a bench plan, one bag per session (core: sequencer.py).

- subscribes ``servo_status`` (temperatures for the gate; NaN or no status = not in the gate);
- publishes ``bench/session`` (hexapod_interfaces/BenchSession, transient local) whenever the
  state or the session changes: the gait/bench side walks while the state is ``heating`` or
  ``walking`` at the session's frequency, duty factor and step length;
- service ``confirm_load`` (std_srvs/Trigger): the operator has put the requested load on the
  stage (``auto_load_change: true`` confirms at once, for simulation);
- optional torque control: with ``torque_service`` set (e.g. ``set_torque`` of dynamixel_driver)
  it calls that std_srvs/SetBool on every torque change (off while cooling);
- records the ``record_topics`` of each walking phase into ``<output_dir>/<session_id>`` (an
  unfinished earlier attempt is moved aside to ``<session_id>.interrupted-N``);
- progress in ``state_file`` (JSON), so a restart resumes at the first unfinished session.

- ``gait_node`` (e.g. ``gait_scheduler``): the sequencer drives the walk by setting that node's
  ``period``, ``duty_factor``, ``step_length`` and ``step_height`` parameters to the session's
  gait while heating/walking, and ``step_length = step_height = 0`` (standing) otherwise. A
  0 Hz session (the paper's basal session) is recorded standing at its load, its heating
  walked at ``HEAT_FREQUENCY_HZ``.

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
    param,
    run_node,
)
from hexapod_common.ros_types import CONTRACT_TOPICS, ros_message_class
from hexapod_common.conversions import s_to_stamp
from hexapod_interfaces.msg import BenchSession, ServoStatus
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.task import Future
from rcl_interfaces.srv import SetParameters
from rosgraph_msgs.msg import Clock
from std_srvs.srv import SetBool, Trigger

from hexapod_bench_drivers.dynamixel_bus import config_file
from hexapod_bench_drivers.sequencer import (
    BenchSequencer,
    SequencerCommand,
    load_plan,
    move_aside,
)

__all__ = ['SIM_EPOCH_S', 'BenchSequencerNode', 'BenchSequencerParams', 'main']

#: Clock time of the embedded simulator's t = 0 [s] (the bag time of its per-session bags).
SIM_EPOCH_S = 1_700_000_000.0

#: step frequency [Hz] that heats the servos into the gate before a basal (0 Hz) session
HEAT_FREQUENCY_HZ = 1.0

# Relative names, so that the node's namespace applies (as to every topic of the drivers).
DEFAULT_RECORD = ('joint_states', 'joint_commands', 'servo_status', 'battery_state',
                  'bench/ground_force', 'bench/leg_tip', 'bench/session', 'gait/phase')


@dataclass(frozen=True)
class BenchSequencerParams:
    """Parameters of the bench_sequencer node."""

    plan_file: str = param('', 'YAML bench plan (see hexapod_bench_drivers.sequencer).',
                           validate=lambda v: None if v else 'expected a YAML file path')
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
    exit_when_done: bool = param(True, 'Exit (code 0; 1 if aborted) once the plan is done '
                                 'or aborted; false keeps publishing the final state.')


class BenchSequencerNode(Node):
    """Thin node around BenchSequencer (see module doc)."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('bench_sequencer', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = self.params = declare_params(self, BenchSequencerParams)
        plan = load_plan(config_file(p.plan_file))   # bench_plan.yaml: the package config
        self.sim_run: Any = None
        if p.backend == 'sim':
            from hexapod_bench_drivers.bench_sim import BenchConfig
            from hexapod_bench_drivers.sequencer_sim import SimulatedBench, SimulatedBenchRun

            bench = SimulatedBench(BenchConfig(
                initial_temperature_c=p.sim_initial_temperature_c,
                ambient_temperature_c=p.sim_ambient_temperature_c), seed=p.sim_seed)
            self.sim_run = SimulatedBenchRun(plan, bench, state_file=p.state_file,
                                             output_dir=p.output_dir, step_s=p.sim_step_s,
                                             cool_step_s=p.sim_cool_step_s)
            self.seq = self.sim_run.seq
        else:
            self.seq = BenchSequencer(plan, state_file=p.state_file)
        if self.seq.skipped:
            self.get_logger().info(f'resuming: {len(self.seq.skipped)} sessions already done')
        self.temperatures: list[float] = []
        self.pub = self.create_publisher(BenchSession, 'bench/session', LATCHED_QOS)
        self.create_service(Trigger, 'confirm_load', self._on_confirm)
        self.torque_client = (self.create_client(SetBool, p.torque_service)
                              if p.torque_service else None)
        self.gait_client = (self.create_client(
            SetParameters, f'{p.gait_node.rstrip("/")}/set_parameters')
            if p.gait_node else None)
        self._gait_sent: tuple[float, ...] | None = None
        self._last: tuple[str, str] | None = None
        self._torque: bool | None = None
        self.writer: BagWriter | None = None
        self._recording_id = ''
        self._rec_subs: list[Any] = []
        self.last_command: SequencerCommand | None = None
        #: Resolved with the exit code (0 done, 1 aborted) when the plan ends, if
        #: ``exit_when_done``; ``run_node`` spins until then.
        self.finished = Future()
        self._calls: list[Any] = []        # service calls in flight (torque, gait)
        if self.sim_run is not None:
            from rclpy.qos import QoSProfile

            self.pub_clock = self.create_publisher(Clock, '/clock', QoSProfile(depth=10))
            self.pub_status = self.create_publisher(ServoStatus, 'servo_status', RELIABLE_QOS)
            self.create_timer(1.0 / p.rate_hz, self._on_sim_timer)
        else:
            self.create_subscription(ServoStatus, 'servo_status', self._on_status, SENSOR_QOS)
            self._subscribe_recorded()
            self.create_timer(1.0 / p.rate_hz, self._on_timer)

    def _on_status(self, msg: ServoStatus) -> None:
        self.temperatures = [float(t) for t in msg.temperature]

    def _on_confirm(self, request: Any, response: Any) -> Any:
        self.seq.confirm_load()
        response.success = True
        response.message = f'load {self.seq.progress.current_load_kg} kg confirmed'
        return response

    def _on_timer(self) -> None:
        t_s = self.get_clock().now().nanoseconds * 1e-9
        cmd = self.last_command = self.seq.update(t_s, self.temperatures)
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
        cmd = self.last_command = run.step()
        if cmd.finished_session:
            self.get_logger().info(f'session {cmd.finished_session} done')
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
        self._calls = [c for c in self._calls if not c.done()]
        if cmd.state in ('done', 'aborted') and not self.finished.done():
            if self._calls:             # the final torque-off / stand request is still in flight
                return
            self.get_logger().info(f'plan {cmd.state}: {len(self.seq.completed)} sessions '
                                   'completed')
            if self.params.exit_when_done:
                self._stop_recording()
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
        if on == self._torque or self.torque_client is None:
            return
        if self.torque_client.service_is_ready():
            self._calls.append(self.torque_client.call_async(SetBool.Request(data=on)))
            self._torque = on

    def _set_gait(self, cmd: SequencerCommand) -> None:
        """Set the gait node's parameters to the session's gait (walk) or standing."""
        s, sent = cmd.session, self._gait_sent
        if self.gait_client is None or (s is None and sent is None):
            return
        if s is None:                   # done or aborted: stand with the last gait's timing
            assert sent is not None
            values = (sent[0], sent[1], 0.0, 0.0)
        elif cmd.walk and s.frequency_hz > 0:
            values = (1.0 / s.frequency_hz, s.duty_factor, s.step_length_m, s.step_height_m)
        elif cmd.walk and not cmd.record:
            # heating before a basal (0 Hz) session: walk at HEAT_FREQUENCY_HZ, then stand
            values = (1.0 / HEAT_FREQUENCY_HZ, s.duty_factor, s.step_length_m, s.step_height_m)
        else:
            # holding (and the basal session itself): the gait's step is 0, the leg stands
            values = (1.0 / s.frequency_hz if s.frequency_hz > 0 else 1.0, s.duty_factor,
                      0.0, 0.0)
        if values == self._gait_sent or not self.gait_client.service_is_ready():
            return
        names = ('period', 'duty_factor', 'step_length', 'step_height')
        request = SetParameters.Request(parameters=[
            Parameter(n, value=float(v)).to_parameter_msg() for n, v in zip(names, values)])
        call = self.gait_client.call_async(request)
        call.add_done_callback(self._on_gait_set)
        self._calls.append(call)
        self._gait_sent = values

    def _on_gait_set(self, future: Any) -> None:
        try:
            results = future.result().results
        except Exception as err:  # noqa: BLE001 -- a failed call is logged, never raised
            self.get_logger().error(f'setting the gait failed: {err}')
            return
        for r in results:
            if not r.successful:
                self.get_logger().error(f'gait node refused the session gait: {r.reason}')

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
        elif not cmd.record and self.writer is not None:
            self._stop_recording()

    def _subscribe_recorded(self) -> None:
        # Subscribed from the start (not per session): a new subscription needs discovery
        # time, which would cut the beginning of each session.
        for topic in self.params.record_topics:
            name = self.resolve_topic_name(topic)
            msgtype = CONTRACT_TOPICS.get('/' + topic.lstrip('/'))
            if msgtype is None:
                self.get_logger().warning(f'not recording {topic}: not a contract topic')
                continue
            qos = LATCHED_QOS if topic.endswith('bench/session') else RELIABLE_QOS
            # Recorded under the contract name (namespace stripped): the analysis reads
            # /battery_state, /bench/session, ... whatever namespace the bench ran in.
            contract = '/' + topic.lstrip('/')
            self._rec_subs.append(self.create_subscription(
                ros_message_class(msgtype), name,
                lambda data, _t=contract, _m=msgtype: self._record(_t, _m, data), qos,
                raw=True))

    def _record(self, topic: str, msgtype: str, data: bytes) -> None:
        if self.writer is not None:
            self.writer.write(topic, msgtype, data, self.get_clock().now().nanoseconds)

    def _stop_recording(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None

    def destroy_node(self) -> None:
        self._stop_recording()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``bench_sequencer``."""
    return run_node(BenchSequencerNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
