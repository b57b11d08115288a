"""``power_monitor`` node: supply voltage and current as ``battery_state`` (ROS sign).

Backends (parameter ``backend``): ``sim`` (constant voltage/current, optional noise), ``ina226`` /
``ina219`` on Linux I2C bus ``i2c_bus`` (smbus2), ``scpi`` (lab supply on ``serial_port``).
``BatteryState.current`` is **negative while the robot draws current** (REP/ROS convention).

Zero-current offset: with ``zero_offset_samples`` > 0, the first that many readings (taken with
the robot unpowered) are averaged into an offset, subtracted afterwards; the service
``calibrate_zero`` (std_srvs/Trigger) starts a new calibration at any time. Nothing is published
while calibrating.

Failed reads drop the sample (a clipped, wrapped, overrange or possibly stale value is never
published): the first is logged at once, then one summary per 5 s, and a line on recovery; a
chip reset (configuration rewritten) is always logged. A lost SCPI port is one error line; the
backend reopens it with a backoff. ``/diagnostics``
(diagnostic_msgs/DiagnosticArray, every ``diagnostics_period_s``): OK, WARN (failing reads, read
rate below 80 % of ``rate_hz``, calibrating) or ERROR (port lost, no sample for 2 s), with the
achieved read rate, error counts and the last values; a read rate below 80 % is also logged
(at most every 30 s).
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('power_monitor')

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from hexapod_common.node_utils import RELIABLE_QOS, declare_params, param, run_node
from rclpy.node import Node
from sensor_msgs.msg import BatteryState
from std_srvs.srv import Trigger

from hexapod_bench_drivers.power_backends import (
    FailureLog,
    Ina2xxBackend,
    PowerBackend,
    PowerBackendError,
    PowerPortLost,
    PowerSample,
    PowerSensorReset,
    ScpiSupplyBackend,
    SimPowerBackend,
    ZeroOffset,
    ros_battery_current,
)

__all__ = ['PowerMonitorNode', 'PowerMonitorParams', 'main', 'make_backend', 'supply_status']

BACKENDS = ('sim', 'ina226', 'ina219', 'scpi')


@dataclass(frozen=True)
class PowerMonitorParams:
    """Parameters of the power_monitor node.

    ``frame_id`` and ``zero_offset_samples`` apply at run time; the others (backend, rate,
    bus settings) are read when the node starts and are read only.
    """

    backend: str = param(
        'sim', 'sim, ina226, ina219 or scpi.',
        validate=lambda v: None if v in BACKENDS else f'expected one of {BACKENDS}')
    rate_hz: float = param(100.0, 'Sampling/publish rate [Hz].',
                           validate=lambda v: None if v > 0 else 'expected > 0')
    i2c_bus: int = param(1, 'Linux I2C bus number (/dev/i2c-N) for ina226/ina219.')
    i2c_address: int = param(0x40, '7-bit I2C address of the INA chip.')
    shunt_ohm: float = param(0.01, 'Shunt resistance [ohm].')
    max_current_a: float = param(8.0, 'Largest expected current [A] (sets the current LSB).')
    serial_port: str = param('/dev/ttyUSB1', 'Serial port of the SCPI lab supply.')
    baud_rate: int = param(9600, 'Baud rate of the SCPI supply.')
    sim_voltage_v: float = param(11.9, 'sim backend: supply voltage [V].')
    sim_current_a: float = param(1.0, 'sim backend: drawn current [A].')
    sim_noise_a: float = param(0.0, 'sim backend: current noise, standard deviation [A].')
    zero_offset_samples: int = param(0, 'Readings averaged into the zero-current offset at '
                                        'start (0 = no calibration); a run-time change applies '
                                        'to the next calibrate_zero.', live=True)
    frame_id: str = param('', 'header.frame_id of battery_state.', live=True)
    diagnostics_period_s: float = param(1.0, 'Period of /diagnostics [s].',
                                        validate=lambda v: None if v > 0 else 'expected > 0')


def make_backend(p: PowerMonitorParams) -> PowerBackend:
    """The backend the parameters select (opens the I2C bus or serial port)."""
    if p.backend == 'sim':
        return SimPowerBackend(p.sim_voltage_v, p.sim_current_a, noise_a=p.sim_noise_a)
    if p.backend == 'scpi':
        return ScpiSupplyBackend(p.serial_port, baud_rate=p.baud_rate)
    from smbus2 import SMBus

    try:
        bus = SMBus(p.i2c_bus)
    except OSError as err:
        raise PowerBackendError(f'/dev/i2c-{p.i2c_bus}: cannot open: {err}') from err
    return Ina2xxBackend(bus, chip=p.backend, address=p.i2c_address, shunt_ohm=p.shunt_ohm,
                         max_current_a=p.max_current_a)


#: a current into the battery [A] above this (and 3 x the zero-offset noise) is CHARGING
CHARGING_MIN_A = 0.01


def supply_status(current_a: float, noise_a: float = 0.0) -> int:
    """BatteryState.power_supply_status for a current [A] positive on discharge: DISCHARGING
    above 0, CHARGING when current flows back into the battery (a regenerating load: a leg
    lowered, a motor braked) beyond ``max(CHARGING_MIN_A, 3 noise_a)``, else NOT_CHARGING.
    (Regeneration read NOT_CHARGING: an outside review.)"""
    if current_a > 0:
        return BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    if current_a < -max(CHARGING_MIN_A, 3.0 * noise_a):
        return BatteryState.POWER_SUPPLY_STATUS_CHARGING
    return BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING


class PowerMonitorNode(Node):
    """Thin node: backend.read() -> zero offset -> BatteryState (see module doc)."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, backend: PowerBackend | None = None,
                 **kw: Any) -> None:
        super().__init__('power_monitor', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = self.params = declare_params(self, PowerMonitorParams)
        self.backend = backend if backend is not None else make_backend(p)
        self.offset: ZeroOffset | None = None
        self._calibration: list[float] = []
        self._calibrating = p.zero_offset_samples > 0
        self.read_errors = 0
        self.published = 0
        self.reads = 0
        self.failures = FailureLog(5.0)
        self.last_sample: PowerSample | None = None
        self.achieved_hz = float('nan')
        self._port_lost_logged = False
        self._last_ok = self._diag_t = time.monotonic()
        self._diag_reads = 0
        self._diag_windows = 0
        self._rate_warned = -float('inf')
        self.pub = self.create_publisher(BatteryState, 'battery_state', RELIABLE_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
        self.create_service(Trigger, 'calibrate_zero', self._on_calibrate)
        # /diagnostics from the sampling timer (one timer: its period is the rate_hz contract).
        self.create_timer(1.0 / p.rate_hz, self._on_timer)

    def _on_calibrate(self, request: Any, response: Any) -> Any:
        self._calibration = []
        self._calibrating = True
        response.success = True
        response.message = (f'averaging the next {max(10, self.params.zero_offset_samples)} '
                            'readings; keep the robot unpowered')
        return response

    def _on_timer(self) -> None:
        now = time.monotonic()
        if now - self._diag_t >= self.params.diagnostics_period_s:
            self._publish_diagnostics()
        self.reads += 1
        try:
            sample = self.backend.read()
        except PowerBackendError as err:
            self.read_errors += 1
            line = self.failures.failed(now, str(err))
            if isinstance(err, PowerPortLost) and not self._port_lost_logged:
                self._port_lost_logged = True
                self.get_logger().error(f'{err}')
            elif isinstance(err, PowerSensorReset) or line is not None:
                self.get_logger().warning(f'power read failed: {line or err}')
            return
        self._last_ok = now
        self._port_lost_logged = False
        recovered = self.failures.succeeded(now)
        if recovered is not None:
            self.get_logger().info(f'power reads {recovered}')
        self.last_sample = sample
        if self._calibrating:
            self._calibration.append(sample.current_a)
            if len(self._calibration) >= max(10, self.params.zero_offset_samples):
                self.offset = ZeroOffset().fit(self._calibration)
                self._calibrating = False
                self.get_logger().info(f'zero-current offset {self.offset.offset_a_:+.4f} A '
                                       f'(noise {self.offset.noise_a_:.4f} A)')
            return
        if self.offset is not None:
            sample = self.offset.apply(sample)
        msg = BatteryState()
        msg.header.stamp = self.get_clock().now().to_msg()
        msg.header.frame_id = self.params.frame_id
        msg.voltage = float(sample.voltage_v)
        msg.current = ros_battery_current(sample.current_a)
        msg.power_supply_status = supply_status(
            sample.current_a, self.offset.noise_a_ if self.offset is not None else 0.0)
        msg.present = True
        for name in ('charge', 'capacity', 'design_capacity', 'percentage', 'temperature'):
            setattr(msg, name, float('nan'))
        self.pub.publish(msg)
        self.published += 1

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        dt = now - self._diag_t
        if dt > 0:
            self.achieved_hz = (self.reads - self._diag_reads) / dt    # reads, ok or failed
        self._diag_t, self._diag_reads = now, self.reads
        self._diag_windows += 1
        requested = self.params.rate_hz
        slow = self._diag_windows > 1 and self.achieved_hz < 0.8 * requested
        if slow and now - self._rate_warned >= 30.0:
            self._rate_warned = now
            self.get_logger().warning(
                f'reading at {self.achieved_hz:.1f} Hz, below the requested rate_hz '
                f'{requested:g} (reads take too long: lower rate_hz, or a faster link)')
        d = DiagnosticStatus()
        d.name = f'{self.get_name()}: {self.params.backend}'
        d.hardware_id = str(getattr(self.backend, 'port', '') or self.params.backend)
        lost = getattr(self.backend, 'lost', None)
        if lost or now - self._last_ok > 2.0:
            d.level = DiagnosticStatus.ERROR
            d.message = (f'port lost: {lost}' if lost else
                         f'no sample for {now - self._last_ok:.1f} s: '
                         f'{self.failures.last_reason}')
        elif self.failures.run:
            d.level, d.message = DiagnosticStatus.WARN, self.failures.last_reason
        elif slow:
            d.level, d.message = DiagnosticStatus.WARN, 'rate below 80 % of rate_hz'
        elif self._calibrating:
            d.level, d.message = DiagnosticStatus.WARN, 'zero-current calibration running'
        else:
            d.level, d.message = DiagnosticStatus.OK, 'ok'
        values = {'read_rate_hz': f'{self.achieved_hz:.2f}', 'rate_hz_requested': f'{requested:g}',
                  'published': self.published, 'read_errors': self.read_errors}
        for name in ('query_failures', 'resyncs', 'reconnects', 'resets'):
            if hasattr(self.backend, name):
                values[name] = getattr(self.backend, name)
        if self.last_sample is not None:
            values['voltage_v'] = f'{self.last_sample.voltage_v:.4f}'
            values['current_a'] = f'{self.last_sample.current_a:+.4f}'
        d.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status.append(d)
        self.pub_diag.publish(arr)

    def destroy_node(self) -> None:
        self.backend.close()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``power_monitor``."""
    return run_node(PowerMonitorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
