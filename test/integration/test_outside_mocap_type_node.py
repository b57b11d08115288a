"""``energy_monitor`` and ``slip_fitter`` with ``mocap_type``: a vicon_bridge publishes the body
as ``geometry_msgs/TransformStamped``; with ``mocap_type:=TransformStamped`` the nodes subscribe
that type and take its poses (with the default PoseStamped subscription the types would not
match and no pose would arrive). An unknown type is refused at start-up."""

from __future__ import annotations

import pytest
import rclpy
from geometry_msgs.msg import TransformStamped
from harness import ros_env
from rclpy.parameter import Parameter

from hexapod_common.conversions import s_to_stamp
from hexapod_common.errors import ParameterError
from hexapod_energy.energy_node import EnergyMonitorNode
from slip_identification.slip_node import SlipFitterNode


def _tf(t_s: float, x: float) -> TransformStamped:
    m = TransformStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t_s)
    m.header.frame_id = 'world'
    m.child_frame_id = 'robot'
    m.transform.translation.x = x
    m.transform.rotation.w = 1.0
    return m


def _mocap_type(node) -> type:
    (sub,) = [s for s in node.subscriptions if s.topic_name.endswith('mocap/body')]
    return sub.msg_type


@pytest.mark.timeout(60)
def test_nodes_take_transform_stamped_mocap():
    with ros_env('mocaptype') as env:
        energy = env.make(EnergyMonitorNode, parameter_overrides=[
            Parameter('mass', value=2.3), Parameter('mocap_type', value='TransformStamped')])
        slip = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('mocap_type', value='TransformStamped')])
        assert _mocap_type(energy) is TransformStamped is _mocap_type(slip)
        src = env.add(rclpy.create_node('vicon', context=env.context, namespace=env.namespace))
        pub = src.create_publisher(TransformStamped, 'mocap/body', 10)
        assert env.spin_until(lambda: pub.get_subscription_count() >= 2, 20.0)
        for k in range(5):
            pub.publish(_tf(1.0 + 0.01 * k, 0.003 * k))
        # both nodes take every pose (waiting on both: the executor serves them in turn)
        assert env.spin_until(lambda: len(energy.core._poses) == 5 and slip.received == 5,
                              20.0)
        assert [p[1] for p in energy.core._poses] == pytest.approx([0.003 * k for k in range(5)])


@pytest.mark.timeout(60)
def test_default_mocap_type_and_unknown_refused():
    with ros_env('mocapbad') as env:
        # (one DDS participant cannot hold one topic with two types: a context of its own)
        default = env.make(EnergyMonitorNode, parameter_overrides=[Parameter('mass', value=2.3)])
        assert _mocap_type(default).__name__ == 'PoseStamped'
        with pytest.raises(ParameterError, match='mocap_type'):
            env.make(EnergyMonitorNode, parameter_overrides=[
                Parameter('mass', value=2.3), Parameter('mocap_type', value='Pose')])
