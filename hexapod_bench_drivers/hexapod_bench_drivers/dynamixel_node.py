"""``dynamixel_driver`` node: a Dynamixel bus as /joint_states, /servo_status and /diagnostics.

Topics (relative names, so a namespace applies):

- publishes ``joint_states`` (sensor_msgs/JointState: rad, rad/s, effort N m estimated from
  Present Current through the gear model, back-driven divided by ``eta^2``, or as Present Load
  fraction * stall torque; see :mod:`hexapod_bench_drivers.dynamixel_bus`) for the servos read
  this cycle; ``servo_status``
  (hexapod_interfaces/ServoStatus) for every configured servo, NaN where a servo did not answer;
  ``/diagnostics`` (diagnostic_msgs/DiagnosticArray) every ``diagnostics_period_s`` and at once
  when the temperature abort fires.
- subscribes ``joint_commands`` (sensor_msgs/JointState): positions -> Goal Position by Sync
  Write; with ``use_command_velocity`` the |velocity| becomes the moving speed. Names not on
  this bus are ignored. While several publishers interleave there, only the commands of the
  one that was there first are applied, the others' dropped, with an error once per episode
  (:class:`hexapod_common.node_utils.FirstPublisherWatch`).
- service ``set_torque`` (std_srvs/SetBool): torque on/off for every servo; turning torque on
  also clears a temperature abort once all servos are below the limit and none reports its
  overheating flag (else refused, "still aborted" with the reason). Servos the bus refused
  (unknown model, Status Return Level 0, an Operating Mode that ignores goals) do not make it
  fail; the message names them, and the servo's own reason when torque on fails. On Protocol
  1.0 a Torque Limit left at 0 by an Alarm Shutdown is written back from Max Torque (refused,
  with the reason, when Max Torque is 0 or the error lasts).

/diagnostics: ERROR for a servo left out (with the refusal; ``model changed: ...`` naming both
models when another model answers at its ID, also left out of ``joint_states``), silent, when
aborted, when the port is lost, for a servo that lost the torque the driver turned on (``came
back with torque off``, or ``torque off between two reads`` found by the bus's periodic
Torque Enable reads, or a Protocol 1.0 Alarm Shutdown: Torque Limit, register 34, reads 0;
``torque_enabled`` then False) or for two replies to one request (``duplicate id?``); WARN for
a servo whose commands are refused (its mode), which refused torque on (hardware error) or
reports hardware error flags, or whose goals are being clipped to its angle limits (CW/CCW
Angle Limit; Min/Max Position Limit in position mode: the count, the last commanded angle and
the limit, in the joint frame; until a goal inside the limits); OK otherwise.

Log: start-up findings and bus notes as warnings; run-time transitions (a servo silent or back,
a hardware error flag, torque lost, goals clipped to a servo's limits, the loop rate well
below ``rate_hz``) once per transition,
throttled (warning; info on recovery).

The port failing at run time (a USB adapter unplugged) is logged once as an error, published as
ERROR on /diagnostics naming the port, and the node stops with exit code 1 (no torque write on
the dead port at shutdown).

On shutdown, torque is turned off (``shutdown_action: torque_off``) or left on (``hold``).
Torque off that a servo the driver had written did not confirm (silent, garbled replies) is
logged as an error naming it and the node exits with code 3 (``EXIT_TORQUE_OFF_UNCONFIRMED``)
instead of 0; a servo left out (unknown model, Status Return Level 0) is named "left out, never
written; torque state unknown", except one at Status Return Level 0 whose model is known
(Protocol 2.0), which is sent Torque Enable 0 without waiting for a reply, said.
A stop (Ctrl-C, SIGTERM) while the node starts ends the torque-on pass at the next servo, and
any stop or error once the bus is open releases it the same way (``start-up stopped: ...``
logged) before the node stops (exit 0 for a stop, 3 for a stop whose torque off was not
confirmed, 2 for an error).
All bus logic lives in :class:`hexapod_bench_drivers.dynamixel_bus.DynamixelBus`.
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('dynamixel_driver')

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from hexapod_common.node_utils import (
    RELIABLE_QOS,
    SENSOR_QOS,
    FirstPublisherWatch,
    declare_params,
    param,
    run_node,
)
from hexapod_interfaces.msg import ServoStatus
from rclpy import logging as rclpy_logging
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_srvs.srv import SetBool

from hexapod_bench_drivers.control_tables import (
    BACK_DRIVE_DEAD_BAND_RAD_S,
    GEAR_EFFICIENCY_MIN,
    decode_error_flags,
)
from hexapod_bench_drivers.dynamixel_bus import (
    DUPLICATE_HOLD_CYCLES,
    DynamixelBus,
    PollResult,
    PortLostError,
    ServoHealth,
    load_joint_map,
)

__all__ = ['DynamixelDriverNode', 'DynamixelDriverParams', 'EXIT_PORT_LOST',
           'EXIT_TORQUE_OFF_UNCONFIRMED', 'main']

#: exit code of the node when its port fails at run time (a USB adapter unplugged)
EXIT_PORT_LOST = 1
#: exit code of a stop whose torque off at shutdown some servo the driver had written did not
#: confirm (silent, garbled), or that the port failing then kept from being sent
EXIT_TORQUE_OFF_UNCONFIRMED = 3


def _positive(v: float) -> str | None:
    return None if v > 0 else 'expected > 0'


def _temperature_limit(v: float) -> str | None:
    return None if 0 < v <= 100 else 'expected a limit in (0, 100] degC'


#: the start-up reading of a parameter that is not applied at run time: read only, so a
#: run-time change is refused with the reason instead of accepted and ignored
_START = {'read_only': True}


@dataclass(frozen=True)
class DynamixelDriverParams:
    """Parameters of the dynamixel_driver node.

    Applied at run time: ``temperature_limit_c`` (the bus's safety limit, at once),
    ``shutdown_action``, ``use_command_velocity``, ``frame_id``. The others configure the bus
    and timers when the node starts and are read only.
    """

    port: str = param('/dev/ttyUSB0', 'Serial device of the bus (or the emulator pty).',
                      **_START)
    baud_rate: int = param(1_000_000, 'Baud rate, one of the dynamixel_sdk rates.', **_START)
    protocol: int = param(1, 'Dynamixel protocol: 1 (AX series, MX on Protocol 1.0 firmware) '
                          'or 2 (X series, MX(2.0)); models are detected by ping '
                          '(control_tables.ALL_MODELS).',
                          validate=lambda v: None if v in (1, 2) else 'expected 1 or 2',
                          **_START)
    joints_file: str = param('', 'YAML joint map: joints: {name: {id, direction, offset_rad}}.',
                             validate=lambda v: None if v else 'expected a YAML file path',
                             **_START)
    rate_hz: float = param(100.0, 'Read/publish rate [Hz].', validate=_positive, **_START)
    timeout_margin_ms: float = param(
        5.0, 'Reply deadline beyond the bytes on the wire [ms]; raised at start to cover the '
        'round trips and a USB latency timer, and by late replies (at most 60 ms).',
        validate=_positive, **_START)
    retries: int = param(1, 'Extra attempts for a failed read or torque write.',
                         validate=lambda v: None if v >= 0 else 'expected >= 0', **_START)
    silent_after: int = param(3, 'Failed cycles in a row before a servo is declared silent.',
                              validate=lambda v: None if v >= 1 else 'expected >= 1', **_START)
    probe_interval_s: float = param(1.0, 'A silent servo is tried again this often [s].',
                                    validate=_positive, **_START)
    temperature_limit_c: float = param(
        70.0, 'Above it: torque off on all servos, abort [degC]; a run-time change applies '
        'from the next read cycle.', validate=_temperature_limit)
    shutdown_action: str = param(
        'torque_off', 'On shutdown: torque_off, or hold (leave torque on).',
        validate=lambda v: None if v in ('torque_off', 'hold') else 'expected torque_off or hold')
    torque_on_start: bool = param(True, 'Turn torque on when the node starts.', **_START)
    use_command_velocity: bool = param(
        False, 'Use |joint_commands.velocity| as moving speed (0 = as fast as possible).')
    frame_id: str = param('', 'header.frame_id of the published messages.')
    diagnostics_period_s: float = param(1.0, 'Period of /diagnostics [s].', validate=_positive,
                                        **_START)
    gear_efficiency: float = param(
        0.0, f'Gear efficiency eta in [{GEAR_EFFICIENCY_MIN}, 1] for the efforts from Present '
        'Current of every servo (back-driven: torque / eta^2); 0: each model\'s own '
        '(XM430-W350 0.739; 1 = no correction for the other Present Current models, which the '
        'start-up log names).',
        validate=lambda v: None if v == 0 or GEAR_EFFICIENCY_MIN <= v <= 1 else
        f'expected 0 (the model\'s) or [{GEAR_EFFICIENCY_MIN}, 1] (servo gears are about '
        '0.5-0.9; a lower figure looks like a typo)',
        **_START)
    back_drive_dead_band_rad_s: float = param(
        BACK_DRIVE_DEAD_BAND_RAD_S, 'Below this speed a servo whose Present Current opposes '
        'its velocity is taken as driving; the back-drive correction is full from twice it '
        '[rad/s].', validate=lambda v: None if math.isfinite(v) and v >= 0 else 'expected a '
        'finite value >= 0', **_START)


class DynamixelDriverNode(Node):
    """Thin node around DynamixelBus (see module doc)."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('dynamixel_driver', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = self.params = declare_params(self, DynamixelDriverParams, on_change=self._on_change)
        self.bus = DynamixelBus(
            p.port, load_joint_map(p.joints_file), protocol=p.protocol, baud_rate=p.baud_rate,
            timeout_margin_ms=p.timeout_margin_ms, retries=p.retries,
            silent_after=p.silent_after,
            probe_interval_cycles=max(1, int(round(p.probe_interval_s * p.rate_hz))),
            temperature_limit_c=p.temperature_limit_c, rate_hz=p.rate_hz,
            gear_efficiency=p.gear_efficiency or None,
            back_drive_dead_band_rad_s=p.back_drive_dead_band_rad_s).open()
        try:
            self._start()
        except BaseException as err:
            # a stop (Ctrl-C, SIGTERM: the context shut down, the next create_* raises) or an
            # error after the bus opened: the servos are released as at shutdown, said; run_node
            # never gets the node to destroy (an outside review: all 18 servos left torqued)
            self.exit_code_on_stop = 0
            self._release_bus('start-up stopped: ')
            # run_node has no node to ask: the exit code travels with the stop (it was 0 even
            # when the torque off after the stop was not confirmed)
            try:
                err.exit_code_on_stop = self.exit_code_on_stop
            except (AttributeError, TypeError):     # an exception type without attributes
                pass
            raise

    def _start(self) -> None:
        """The rest of the constructor, once the bus is open."""
        p = self.params
        #: done with the exit code when the node stops by itself (the port lost), see run_node
        self.finished = Future()
        #: the exit code after a stop (run_node): EXIT_TORQUE_OFF_UNCONFIRMED when torque off
        #: at shutdown was not confirmed, else 0
        self.exit_code_on_stop = 0
        for h in self.bus.health():
            self.get_logger().info(f'servo id {h.servo_id}: {h.model}'
                                   + (' (silent)' if h.silent else ''))
        for s in self.bus.servos:
            if s.refusal:
                self.get_logger().error(f'{s.joint.name} (id {s.joint.servo_id}) left out: '
                                        f'{s.refusal}')
        for note in self.bus.take_notes():
            self.get_logger().warning(note)
        if p.torque_on_start:
            refused = self.bus.refused
            # a stop requested meanwhile (rclpy's signal handler shuts the context down but
            # does not interrupt this constructor) ends the pass: no torque on after it
            results = self.bus.set_torque(True, stop=lambda: not self.context.ok())
            skipped = self.bus.not_written
            failed = [n for n, ok in results.items()
                      if not ok and n not in refused and n not in skipped]
            if failed:
                self._stop_logger().error(f'torque on failed for {failed}')
            for note in self.bus.take_notes():
                self._stop_logger().warning(note)
            if skipped:
                self._stop_logger().warning('stop requested while torque was turned on: not '
                                            f'sent to {", ".join(skipped)}')
                raise ExternalShutdownException()
        if not self.context.ok():
            raise ExternalShutdownException()   # stopped during bus.open(): nothing torqued
        self.pub_joints = self.create_publisher(JointState, 'joint_states', RELIABLE_QOS)
        self.pub_status = self.create_publisher(ServoStatus, 'servo_status', RELIABLE_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
        #: two command sources (two gait nodes, a teleop beside the gait node): said, and
        #: only the commands of the one that was there first are applied
        self.command_publishers = FirstPublisherWatch(self)
        self.command_publishers.subscription = self.create_subscription(
            JointState, 'joint_commands', lambda m, info: self._on_command(m, info), SENSOR_QOS)
        self.create_service(SetBool, 'set_torque', self._on_set_torque)
        self.commands_applied = 0
        self.commands_dropped = 0
        self._timers = [self.create_timer(1.0 / p.rate_hz, self._on_timer),
                        self.create_timer(p.diagnostics_period_s, self._publish_diagnostics)]

    # --- callbacks -------------------------------------------------------------------------
    def _on_change(self, new: DynamixelDriverParams) -> str | None:
        """Apply an accepted run-time change (the others are read only)."""
        bus = getattr(self, 'bus', None)   # None while the node is being built
        if bus is not None and new.temperature_limit_c != bus.temperature_limit_c:
            bus.temperature_limit_c = new.temperature_limit_c
            self.get_logger().warning(f'temperature limit now {new.temperature_limit_c:g} degC')
        return None

    def _on_timer(self) -> None:
        try:
            self._publish(self.bus.poll())
        except PortLostError as err:
            self._port_lost(err)
        self._log_bus()

    def _log_bus(self) -> None:
        log = self.get_logger()
        for note in self.bus.take_notes():
            log.warning(note)
        for level, line in self.bus.take_events():
            if level == 'info':   # one call site per severity (rclpy requires it)
                log.info(line)
            else:
                log.warning(line)

    def _port_lost(self, err: PortLostError) -> None:
        """Once: the error logged and on /diagnostics, timers stopped, the node finishes."""
        if self.finished.done():
            return
        for timer in self._timers:
            timer.cancel()
        self.get_logger().error(str(err))
        self._publish_diagnostics()
        self.finished.set_result(EXIT_PORT_LOST)

    def _on_command(self, msg: JointState, info: Any = None) -> None:
        if not self.command_publishers.admit(info, msg.header.frame_id):
            return                      # another publisher's (the error says so)
        try:
            self._apply_command(msg)
        except (ValueError, TypeError) as err:
            self.commands_dropped += 1
            self.get_logger().warning(f'joint_commands dropped: {err}')
        except PortLostError as err:
            self._port_lost(err)

    def _on_set_torque(self, request: Any, response: Any) -> Any:
        refused = self.bus.refused
        try:
            results = self.bus.set_torque(bool(request.data))
        except PortLostError as err:
            self._port_lost(err)
            response.success, response.message = False, str(err)
            return response
        if self.bus.port_lost:
            response.success, response.message = False, self.bus.port_lost
            return response
        failed = [n for n, ok in results.items() if not ok and n not in refused]
        response.success = not failed
        why = {h.servo_id: h.torque_error for h in self.bus.health() if h.torque_error}
        reasons = [f'{s.joint.name}: {why[s.joint.servo_id]}' for s in self.bus.servos
                   if s.joint.name in failed and s.joint.servo_id in why]
        response.message = ('torque ' + ('on' if request.data else 'off')
                            + (f'; failed for {failed}' if failed else '')
                            + ''.join(f'; {r}' for r in reasons)
                            + (f'; left out (refused): {sorted(refused)}' if refused else ''))
        if request.data and self.bus.aborted:
            response.message += f'; still aborted: {self.bus.abort_reason}'
        return response

    # --- helpers ---------------------------------------------------------------------------
    def _apply_command(self, msg: JointState) -> None:
        names = list(msg.name)
        if len(msg.position) != len(names):
            raise ValueError(f'{len(msg.position)} positions for {len(names)} names')
        positions = dict(zip(names, (float(x) for x in msg.position)))
        speeds = None
        if self.params.use_command_velocity and len(msg.velocity) == len(names):
            speeds = dict(zip(names, (abs(float(v)) for v in msg.velocity)))
        if self.bus.write_goals(positions, speeds):
            self.commands_applied += 1

    def _publish(self, result: PollResult) -> None:
        stamp = self.get_clock().now().to_msg()
        js = JointState()
        js.header.stamp = stamp
        js.header.frame_id = self.params.frame_id
        ok = [r for r in result.readings if r.ok]
        js.name = [r.name for r in ok]
        js.position = [r.position_rad for r in ok]
        js.velocity = [r.velocity_rad_s for r in ok]
        js.effort = [r.effort_nm for r in ok]
        self.pub_joints.publish(js)
        st = ServoStatus()
        st.header = js.header
        st.name = [r.name for r in result.readings]
        st.temperature = [float(r.temperature_c) for r in result.readings]
        st.voltage = [float(r.voltage_v) for r in result.readings]
        st.load = [float(r.load_fraction) for r in result.readings]
        st.error = [int(r.error_flags) & 0xFF for r in result.readings]
        self.pub_status.publish(st)
        if result.aborted_now:
            self.get_logger().error(result.abort_reason)
            self._publish_diagnostics()

    def _publish_diagnostics(self) -> None:
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        for h in self.bus.health():
            arr.status.append(self._servo_diagnostic(h))
        self.pub_diag.publish(arr)

    def _servo_diagnostic(self, h: ServoHealth) -> DiagnosticStatus:
        servo = next(s for s in self.bus.servos if s.joint.servo_id == h.servo_id)
        name = servo.joint.name
        d = DiagnosticStatus()
        d.name = f'{self.get_name()}: {name}'
        d.hardware_id = f'dynamixel id {h.servo_id}'
        flags = decode_error_flags(self.bus.protocol, h.last_error_flags)
        duplicate = self.bus.cycle - servo.last_duplicate_cycle <= DUPLICATE_HOLD_CYCLES
        if self.bus.port_lost:
            d.level, d.message = DiagnosticStatus.ERROR, self.bus.port_lost
        elif self.bus.aborted:
            d.level, d.message = DiagnosticStatus.ERROR, f'aborted: {self.bus.abort_reason}'
        elif servo.refusal:
            d.level, d.message = DiagnosticStatus.ERROR, f'left out: {servo.refusal}'
        elif duplicate:
            d.level = DiagnosticStatus.ERROR
            d.message = (f'duplicate id? {h.duplicate_replies} second replies to one request: '
                         'two servos share this ID; readings withheld')
        elif h.silent and h.silence() == 'refused reads':
            d.level = DiagnosticStatus.ERROR
            d.message = ('silent: its READs are refused (access error: another model at this '
                         'ID?)')
        elif h.silent and h.silence() == 'garbled replies':
            d.level = DiagnosticStatus.ERROR
            d.message = ('silent: garbled replies (a second servo at this ID? cabling, '
                         'termination)')
        elif h.silent:
            d.level, d.message = DiagnosticStatus.ERROR, 'silent: no reply'
        elif h.torque_lost:
            d.level, d.message = DiagnosticStatus.ERROR, h.torque_lost
        elif servo.command_refusal:
            d.level = DiagnosticStatus.WARN
            d.message = f'read only, commands refused: {servo.command_refusal}'
        elif h.goal_clip:
            d.level = DiagnosticStatus.WARN
            d.message = f'{h.goals_clipped} goals clipped so far: {h.goal_clip}'
        elif h.torque_error:
            d.level, d.message = DiagnosticStatus.WARN, h.torque_error
        elif flags:
            d.level, d.message = DiagnosticStatus.WARN, 'hardware error: ' + ', '.join(flags)
        else:
            d.level, d.message = DiagnosticStatus.OK, 'ok'
        values = {'model': h.model, 'reads_ok': h.reads_ok, 'timeouts': h.timeouts,
                  'corrupt': h.corrupt, 'retries': h.retries, 'failed_cycles': h.failed_cycles,
                  'error_replies': h.error_replies, 'error_flags': h.last_error_flags,
                  'torque_enabled': h.torque_enabled,
                  'status_return_level': h.status_return_level,
                  'late_replies': h.late_replies, 'operating_mode': h.operating_mode,
                  'duplicate_replies': h.duplicate_replies,
                  'rejected_instructions': h.rejected_instructions,
                  'refused_instructions': h.refused_instructions,
                  'goals_clipped': h.goals_clipped,
                  'reply_margin_ms': f'{self.bus.reply_margin_ms:.0f}'}
        d.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        return d

    def _release_bus(self, prefix: str = '') -> None:
        """``shutdown_action`` applied (torque off, or left on), said, and the bus closed."""
        if not self.bus.is_open:
            return
        if self.params.shutdown_action == 'torque_off':
            # said (it was silent): a servo that did not confirm may still hold; one the driver
            # never wrote is named as such (an outside review: "not confirmed" for servos left
            # out at start)
            report = self.bus.torque_off_at_shutdown()
            log = self._stop_logger()
            for level, line in report.lines():
                if level == 'error':   # one call site per severity (rclpy requires it)
                    log.error(prefix + line)
                elif level == 'warning':
                    log.warning(prefix + line)
                else:
                    log.info(prefix + line)
            if not report.ok:
                self.exit_code_on_stop = EXIT_TORQUE_OFF_UNCONFIRMED
        else:
            self._stop_logger().warning(f'{prefix}shutdown_action hold: torque left on, the '
                                   'servos hold their last position')
        self.bus.close()

    def _stop_logger(self) -> Any:
        """The node's logger while its context is valid. After a stop (Ctrl-C, SIGTERM: the
        context shut down) the lines go to the logger ``<node>.shutdown``, which has no
        /rosout publisher: through the node's own, every line at shutdown was followed by
        "Failed to publish log message to rosout: publisher's context is invalid"."""
        log = self.get_logger()
        if self.context.ok():
            return log
        return rclpy_logging.get_logger(f'{log.name}.shutdown')

    def destroy_node(self) -> None:
        self._release_bus()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``dynamixel_driver``."""
    return run_node(DynamixelDriverNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
