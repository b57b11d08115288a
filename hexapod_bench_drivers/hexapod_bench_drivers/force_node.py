"""``force_sensor`` node: treadmill load cell on a serial port -> ``bench/ground_force``.

Reads ``<t_ms>,<raw>`` lines (see :mod:`hexapod_bench_drivers.force_backend`), applies the
calibration ``force = c0 + c1 raw + c2 tip_x + c3 tip_y`` with the latest ``bench/leg_tip``
(geometry_msgs/PointStamped; 0, 0 until one arrives) and publishes
geometry_msgs/WrenchStamped with ``force.z`` = normal force [N], stamped at reception.
Malformed lines are counted (``malformed_lines``) and skipped.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from geometry_msgs.msg import PointStamped, WrenchStamped
from hexapod_common.node_utils import RELIABLE_QOS, SENSOR_QOS, declare_params, param, run_node
from rclpy.node import Node

from hexapod_bench_drivers.force_backend import ForceCalibration, SerialForceSource

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
        self.pub = self.create_publisher(WrenchStamped, 'bench/ground_force', RELIABLE_QOS)
        self.create_subscription(PointStamped, 'bench/leg_tip', self._on_tip, SENSOR_QOS)
        self.create_timer(1.0 / p.poll_hz, self._on_timer)

    @property
    def malformed_lines(self) -> int:
        return self.source.parser.malformed

    def _on_tip(self, msg: PointStamped) -> None:
        self.tip_xy = (float(msg.point.x), float(msg.point.y))

    def _on_timer(self) -> None:
        try:
            readings = self.source.poll()
        except OSError as err:
            self.get_logger().warning(f'force serial read failed: {err}')
            return
        for r in readings:
            msg = WrenchStamped()
            msg.header.stamp = self.get_clock().now().to_msg()
            msg.header.frame_id = self.params.frame_id
            msg.wrench.force.z = float(self.calibration.predict(r.raw, *self.tip_xy))
            self.pub.publish(msg)

    def destroy_node(self) -> None:
        self.source.close()
        super().destroy_node()


def main(args: Sequence[str] | None = None) -> int:
    """Console script ``force_sensor``."""
    return run_node(ForceSensorNode, args)


if __name__ == '__main__':
    raise SystemExit(main())
