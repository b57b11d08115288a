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

Time is the node clock (simulated time with ``use_sim_time``), so a simulator running faster
than real time runs the plan in accelerated time.
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
from hexapod_interfaces.msg import BenchSession, ServoStatus
from rclpy.node import Node
from std_srvs.srv import SetBool, Trigger

from hexapod_bench_drivers.sequencer import BenchSequencer, SequencerCommand, load_plan

__all__ = ['BenchSequencerNode', 'BenchSequencerParams', 'main']

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


class BenchSequencerNode(Node):
    """Thin node around BenchSequencer (see module doc)."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('bench_sequencer', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = self.params = declare_params(self, BenchSequencerParams)
        self.seq = BenchSequencer(load_plan(p.plan_file), state_file=p.state_file)
        if self.seq.skipped:
            self.get_logger().info(f'resuming: {len(self.seq.skipped)} sessions already done')
        self.temperatures: list[float] = []
        self.pub = self.create_publisher(BenchSession, 'bench/session', LATCHED_QOS)
        self.create_subscription(ServoStatus, 'servo_status', self._on_status, SENSOR_QOS)
        self.create_service(Trigger, 'confirm_load', self._on_confirm)
        self.torque_client = (self.create_client(SetBool, p.torque_service)
                              if p.torque_service else None)
        self._last: tuple[str, str] | None = None
        self._torque: bool | None = None
        self.writer: BagWriter | None = None
        self._recording_id = ''
        self._rec_subs: list[Any] = []
        self.last_command: SequencerCommand | None = None
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
        key = (cmd.state, cmd.session.session_id if cmd.session else '')
        if key != self._last:
            self._last = key
            if cmd.load_request_kg is not None and not self.params.auto_load_change:
                self.get_logger().warning(f'put {cmd.load_request_kg:.3f} kg on the stage, '
                                          'then call confirm_load')
            self._publish(cmd)

    def _publish(self, cmd: SequencerCommand) -> None:
        msg = BenchSession()
        msg.header.stamp = self.get_clock().now().to_msg()
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
            self.torque_client.call_async(SetBool.Request(data=on))
            self._torque = on

    def _set_recording(self, cmd: SequencerCommand) -> None:
        if (self.writer is not None and cmd.session is not None
                and cmd.session.session_id != self._recording_id):
            self._stop_recording()          # the next session walks at once: new bag
        if cmd.record and self.writer is None and cmd.session is not None:
            self._recording_id = cmd.session.session_id
            path = Path(self.params.output_dir) / cmd.session.session_id
            if path.exists():
                k = 1
                while path.with_name(f'{path.name}.interrupted-{k}').exists():
                    k += 1
                path.rename(path.with_name(f'{path.name}.interrupted-{k}'))
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
            self._rec_subs.append(self.create_subscription(
                ros_message_class(msgtype), name,
                lambda data, _t=name, _m=msgtype: self._record(_t, _m, data), qos, raw=True))

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
