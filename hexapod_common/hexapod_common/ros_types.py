"""Resolve ROS message classes from type names such as ``sensor_msgs/msg/JointState``."""

from __future__ import annotations

import importlib
from functools import lru_cache
from typing import Any

from hexapod_common.errors import UnknownTypeError

__all__ = ['CONTRACT_TOPICS', 'ros_message_class']

#: Every topic of the DESIGN §4 contract and its type.
CONTRACT_TOPICS: dict[str, str] = {
    '/joint_states': 'sensor_msgs/msg/JointState',
    '/joint_commands': 'sensor_msgs/msg/JointState',
    '/servo_status': 'hexapod_interfaces/msg/ServoStatus',
    '/battery_state': 'sensor_msgs/msg/BatteryState',
    '/bench/ground_force': 'geometry_msgs/msg/WrenchStamped',
    '/bench/leg_tip': 'geometry_msgs/msg/PointStamped',
    '/bench/session': 'hexapod_interfaces/msg/BenchSession',
    '/mocap/body': 'geometry_msgs/msg/PoseStamped',
    '/gait/phase': 'hexapod_interfaces/msg/GaitPhase',
    '/energy/descriptors': 'hexapod_interfaces/msg/EnergeticDescriptors',
    '/slip/fit': 'hexapod_interfaces/msg/SlipFit',
}


@lru_cache(maxsize=None)
def ros_message_class(msgtype: str) -> Any:
    """The rclpy message class of ``pkg/msg/Name`` (``pkg/Name`` accepted too)."""
    parts = msgtype.split('/')
    if len(parts) == 2:
        parts = [parts[0], 'msg', parts[1]]
    if len(parts) != 3 or not all(parts):
        raise UnknownTypeError(f'not a message type name: {msgtype!r}')
    pkg, kind, name = parts
    try:
        module = importlib.import_module(f'{pkg}.{kind}')
        return getattr(module, name)
    except (ImportError, AttributeError) as err:
        raise UnknownTypeError(
            f'message type {msgtype!r} is not installed in this ROS environment') from err
