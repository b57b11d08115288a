"""``force_sensor`` node: treadmill load cell on a serial port -> ``bench/ground_force``.

Reads ``<t_ms>,<raw>`` lines (see :mod:`hexapod_bench_drivers.force_backend`), applies the
calibration ``force = c0 + c1 raw + c2 tip_x + c3 tip_y`` with the latest ``bench/leg_tip``
(geometry_msgs/PointStamped; 0, 0 until one arrives) and publishes
geometry_msgs/WrenchStamped with ``force.z`` = normal force [N], stamped with the
microcontroller time ``t_ms`` mapped onto ROS time (``use_mcu_clock``, see
:class:`~hexapod_bench_drivers.force_backend.McuClockMap`; else at reception).
Malformed lines are counted (``malformed_lines``) and skipped; 10 in a row with no valid line
give a warning naming the last line, the expected format, the port and baud rate (repeated
every 10 s while it lasts). Saturated HX711 values (8388607 / -8388608) are not published
(warning at once, then every 5 s). A failing port (unplugged) is one error line; it is reopened
with a backoff and a line says so. ``/diagnostics`` every ``diagnostics_period_s``: OK, WARN
(malformed or saturated samples in the period) or ERROR (port lost, no sample for 2 s), with the
rate, counts and the last force.
"""

from __future__ import annotations

# first: a SIGINT or SIGTERM during the imports below is noted, not lost (a background
# job starts with SIGINT ignored); run_node acts on it (hexapod_common.stop_signals)
from hexapod_common import stop_signals  # noqa: E402,I001

stop_signals.catch_if_program('force_sensor')

import time
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import PointStamped, WrenchStamped
from hexapod_common.node_utils import RELIABLE_QOS, SENSOR_QOS, declare_params, param, run_node
from rclpy.node import Node
from rclpy.time import Time

from hexapod_bench_drivers.force_backend import (
    ForceCalibration,
    MalformedWatch,
    McuClockMap,
    SerialForceSource,
)
from hexapod_bench_drivers.power_backends import FailureLog

__all__ = ['ForceSensorNode', 'ForceSensorParams', 'main']


@dataclass(frozen=True)
class ForceSensorParams:
    """Parameters of the force_sensor node."""

    serial_port: str = param('/dev/ttyACM0', 'Serial port of the load-cell microcontroller.')
    baud_rate: int = param(115200, 'Baud rate.')
    poll_hz: float = param(500.0, 'Serial polling rate [Hz] (>= the sample rate).',
                           validate=lambda v: None if v > 0 else 'expected > 0')
    calibration: tuple = param(
        (0.0, 1.0, 0.0, 0.0), 'c0 [N], c1 [N/count], c2 [N/m], c3 [N/m]: force = c0 + c1 raw '
        '+ c2 tip_x + c3 tip_y.',
        validate=lambda v: None if len(v) == 4 else 'expected 4 numbers')
    frame_id: str = param('treadmill', 'header.frame_id of ground_force.')
    use_mcu_clock: bool = param(True, 'Stamp with the microcontroller time t_ms mapped onto ROS '
                                      'time (False: stamp at reception).')
    diagnostics_period_s: float = param(1.0, 'Period of /diagnostics [s].',
                                        validate=lambda v: None if v > 0 else 'expected > 0')


class ForceSensorNode(Node):
    """Thin node around SerialForceSource + ForceCalibration (see module doc)."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, **kw: Any) -> None:
        super().__init__('force_sensor', context=context,
                         parameter_overrides=parameter_overrides, namespace=namespace, **kw)
        p = self.params = declare_params(self, ForceSensorParams)
        self.calibration = ForceCalibration.from_coefficients([float(c) for c in p.calibration])
        self.source = SerialForceSource(p.serial_port, baud_rate=p.baud_rate)
        self.tip_xy = (0.0, 0.0)
        self.clock_map = McuClockMap()
        self.malformed_watch = MalformedWatch()
        self.saturation = FailureLog(5.0)
        self.published = 0
        self.last_force_n = float('nan')
        self.achieved_hz = float('nan')
        self._lost_logged = False
        self._last_ok = self._diag_t = time.monotonic()
        self._diag_counts = (0, 0, 0)     # published, malformed, saturated at the last report
        self.pub = self.create_publisher(WrenchStamped, 'bench/ground_force', RELIABLE_QOS)
        self.pub_diag = self.create_publisher(DiagnosticArray, '/diagnostics', RELIABLE_QOS)
        self.create_subscription(PointStamped, 'bench/leg_tip', self._on_tip, SENSOR_QOS)
        self.create_timer(1.0 / p.poll_hz, self._on_timer)
        self.create_timer(p.diagnostics_period_s, self._publish_diagnostics)

    @property
    def malformed_lines(self) -> int:
        return self.source.parser.malformed

    def _on_tip(self, msg: PointStamped) -> None:
        self.tip_xy = (float(msg.point.x), float(msg.point.y))

    @property
    def saturated_samples(self) -> int:
        return self.saturation.total

    def _where(self) -> str:
        return f'{self.source.port} at {self.source.baud_rate} Bd'

    def _on_timer(self) -> None:
        was_lost = self.source.lost
        readings = self.source.poll()
        now = time.monotonic()
        if self.source.lost and not self._lost_logged:
            self._lost_logged = True
            self.get_logger().error(f'force serial port {self.source.port} failed '
                                    f'({self.source.lost}); reopening it with a backoff')
        elif was_lost and not self.source.lost:
            self._lost_logged = False
            self.get_logger().info(f'force serial port {self.source.port} reopened')
        warning = self.malformed_watch.check(now, self.source.parser)
        if warning is not None:
            self.get_logger().warning(f'force lines on {self._where()}: {warning} (check the '
                                      'sketch output and baud_rate)')
        if not readings:
            return
        t_recv_ns = self.get_clock().now().nanoseconds
        if self.params.use_mcu_clock:
            stamps = self.clock_map.stamp_batch([r.t_mcu_s for r in readings if not r.saturated],
                                                t_recv_ns * 1e-9)
        for r in readings:
            if r.saturated:
                line = self.saturation.failed(now, f'raw {r.raw} at the HX711 limit: load cell '
                                                   'overloaded, sample dropped')
                if line is not None:
                    self.get_logger().warning(f'force: {line}')
                continue
            line = self.saturation.succeeded(now)
            if line is not None:
                self.get_logger().info(f'force: saturation {line}')
            self._last_ok = now
            msg = WrenchStamped()
            if self.params.use_mcu_clock:
                msg.header.stamp = Time(nanoseconds=round(stamps.pop(0) * 1e9)).to_msg()
            else:
                msg.header.stamp = Time(nanoseconds=t_recv_ns).to_msg()
            msg.header.frame_id = self.params.frame_id
            msg.wrench.force.z = self.last_force_n = float(
                self.calibration.predict(r.raw, *self.tip_xy))
            self.pub.publish(msg)
            self.published += 1

    def _publish_diagnostics(self) -> None:
        now = time.monotonic()
        parser = self.source.parser
        published, malformed, saturated = self._diag_counts
        dt = now - self._diag_t
        if dt > 0:
            self.achieved_hz = (self.published - published) / dt
        new_bad = parser.malformed - malformed
        new_sat = self.saturation.total - saturated
        self._diag_t = now
        self._diag_counts = (self.published, parser.malformed, self.saturation.total)
        d = DiagnosticStatus()
        d.name = f'{self.get_name()}: load cell'
        d.hardware_id = self.source.port
        if self.source.lost:
            d.level, d.message = DiagnosticStatus.ERROR, f'port lost: {self.source.lost}'
        elif now - self._last_ok > 2.0:
            d.level = DiagnosticStatus.ERROR
            d.message = f'no sample for {now - self._last_ok:.1f} s'
            if new_bad:
                d.message += f' ({new_bad} malformed lines, last {parser.last_malformed!r})'
        elif new_bad or new_sat:
            d.level = DiagnosticStatus.WARN
            d.message = f'{new_bad} malformed lines, {new_sat} saturated samples'
        else:
            d.level, d.message = DiagnosticStatus.OK, 'ok'
        values = {'rate_hz': f'{self.achieved_hz:.2f}', 'published': self.published,
                  'malformed_lines': parser.malformed, 'saturated': self.saturation.total,
                  'reconnects': self.source.reconnects, 'baud_rate': self.source.baud_rate,
                  'clock_restarts': self.clock_map.restarts,
                  'force_n': f'{self.last_force_n:.4f}'}
        d.values = [KeyValue(key=k, value=str(v)) for k, v in values.items()]
        arr = DiagnosticArray()
        arr.header.stamp = self.get_clock().now().to_msg()
        arr.status.append(d)
        self.pub_diag.publish(arr)

    def destroy_node(self) -> None:
        self.source.close()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``force_sensor``."""
    return run_node(ForceSensorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
