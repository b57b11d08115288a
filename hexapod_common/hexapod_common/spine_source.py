"""A minimal simulated robot for the foundation path: ``/joint_states``, ``/battery_state``,
``/gait/phase`` at a fixed rate from closed-form signals (the physics simulators live in
``hexapod_bench_drivers``). Deterministic in the node's clock, so it runs under ``/clock`` too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from hexapod_interfaces.msg import GaitPhase
from rclpy.node import Node
from sensor_msgs.msg import BatteryState, JointState

from hexapod_common.conversions import s_to_stamp
from hexapod_common.node_utils import RELIABLE_QOS, declare_params, param

__all__ = ['SpineSourceNode', 'SpineSourceParams', 'spine_power_w']

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
TRIPOD_OFFSETS = (0.0, 0.5, 0.0, 0.5, 0.0, 0.5)


def spine_power_w(t_s: float, period_s: float) -> float:
    """Input power [W]: 12 W basal plus a load ripple at twice the step frequency."""
    return 12.0 + 10.0 / period_s + 4.0 * math.sin(4.0 * math.pi * t_s / period_s) ** 2


@dataclass(frozen=True)
class SpineSourceParams:
    rate: float = param(100.0, 'publish rate [Hz]',
                        validate=lambda v: None if v > 0 else 'must be > 0')
    period: float = param(1.0, 'gait period [s]',
                          validate=lambda v: None if v > 0 else 'must be > 0')
    voltage: float = param(11.9, 'supply voltage [V]')


class SpineSourceNode(Node):
    """Publishes a tripod gait's phase, 18 joint states and the battery at ``rate``."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, node_name: str = 'spine_source') -> None:
        super().__init__(node_name, context=context, namespace=namespace or '',
                         parameter_overrides=parameter_overrides or [])
        self.params = declare_params(self, SpineSourceParams)
        self.gait_pub = self.create_publisher(GaitPhase, 'gait/phase', RELIABLE_QOS)
        self.joint_pub = self.create_publisher(JointState, 'joint_states', RELIABLE_QOS)
        self.battery_pub = self.create_publisher(BatteryState, 'battery_state', RELIABLE_QOS)
        self.names = [f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia')]
        self.ticks = 0
        self.t0_ns: int | None = None
        self.create_timer(1.0 / self.params.rate, self.tick)

    def tick(self) -> None:
        now_ns = self.get_clock().now().nanoseconds
        if self.t0_ns is None:
            self.t0_ns = now_ns
        t = (now_ns - self.t0_ns) * 1e-9
        stamp = s_to_stamp(now_ns * 1e-9)
        period = self.params.period
        phase = (t / period) % 1.0
        gait = GaitPhase()
        gait.header.stamp.sec, gait.header.stamp.nanosec = stamp
        gait.gait, gait.period, gait.duty_factor = 'tripod', period, 0.5
        gait.step_length, gait.step_height = 0.1, 0.04
        gait.cycle_phase = phase
        gait.leg_names = list(LEGS)
        gait.phase_offsets = list(TRIPOD_OFFSETS)
        gait.in_stance = [((phase - off) % 1.0) < 0.5 for off in TRIPOD_OFFSETS]
        gait.supporting_legs = sum(gait.in_stance)
        joints = JointState()
        joints.header.stamp.sec, joints.header.stamp.nanosec = stamp
        joints.name = self.names
        w = 2 * math.pi / period
        joints.position = [0.3 * math.sin(w * t + i) for i in range(18)]
        joints.velocity = [0.3 * w * math.cos(w * t + i) for i in range(18)]
        joints.effort = [0.2 * math.sin(w * t + i) for i in range(18)]
        battery = BatteryState()
        battery.header.stamp.sec, battery.header.stamp.nanosec = stamp
        battery.voltage = self.params.voltage
        battery.current = -spine_power_w(t, period) / self.params.voltage  # ROS: discharging < 0
        battery.present = True
        battery.power_supply_status = BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
        self.gait_pub.publish(gait)
        self.joint_pub.publish(joints)
        self.battery_pub.publish(battery)
        self.ticks += 1
