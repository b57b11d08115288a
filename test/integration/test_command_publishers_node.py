"""The drivers say when two sources command their joints (two gait nodes, a teleop beside the
gait node): their targets alternate. Said once per episode from the messages' sequence
numbers; a respawned gait node (one publisher again) is not two."""

from __future__ import annotations

from typing import Any

import pytest
import rclpy
from harness import KEEP_ALL_QOS, capture_errors, ros_env
from sensor_msgs.msg import JointState


def _commands(env: Any, n: int) -> list[Any]:
    node = env.add(rclpy.create_node(f'commander{n}', context=env.context,
                                     namespace=env.namespace))
    return [node.create_publisher(JointState, 'joint_commands', KEEP_ALL_QOS)
            for _ in range(n)]


@pytest.mark.timeout(120)
def test_sim_robot_reports_two_command_sources_once() -> None:
    from hexapod_bench_drivers.sim_nodes import SimRobotNode

    with ros_env('two_commanders') as env:
        sim = env.make(SimRobotNode, parameter_overrides=[])
        errors = capture_errors(sim)
        pubs = _commands(env, 2)
        assert env.spin_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs), 20)
        names = list(sim.live.joint_names)
        for k in range(30):
            for pub, q in zip(pubs, (0.1, -0.1)):
                pub.publish(JointState(name=names, position=[q] * len(names)))
            env.executor.spin_once(timeout_sec=0.0)
        assert env.spin_until(lambda: sim.command_publishers.reported >= 1, 20)
        env.spin_until(lambda: False, 0.2)
    reported = [e for e in errors if 'joint_commands' in e]
    assert len(reported) == 1 and 'alternate' in reported[0]


@pytest.mark.timeout(120)
def test_one_command_source_restarted_is_not_two() -> None:
    from hexapod_bench_drivers.sim_nodes import SimRobotNode

    with ros_env('one_commander') as env:
        sim = env.make(SimRobotNode, parameter_overrides=[])
        errors = capture_errors(sim)
        names = list(sim.live.joint_names)
        for _ in range(2):      # a gait node, then its respawn: a new writer, numbers anew
            [pub] = _commands(env, 1)
            assert env.spin_until(lambda: pub.get_subscription_count() >= 1, 20)
            for k in range(150):
                pub.publish(JointState(name=names, position=[0.0] * len(names)))
                env.executor.spin_once(timeout_sec=0.0)
            env.spin_until(lambda: False, 0.2)
            env.nodes[-1].destroy_publisher(pub)
        assert sim.command_publishers.sequences.numbered
        assert sim.command_publishers.reported == 0, errors


@pytest.mark.timeout(120)
def test_dynamixel_driver_reports_two_command_sources(tmp_path) -> None:
    from rclpy.parameter import Parameter

    from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode
    from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

    names = ['L1_coxa', 'L1_femur', 'L1_tibia', 'R1_coxa']
    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n' + ''.join(f'  {n}: {{id: {i + 1}}}\n'
                                            for i, n in enumerate(names)))
    with ServoBusEmulator.of_model('xl430', range(1, 5)) as emu, ros_env('dxl_two') as env:
        node = env.make(DynamixelDriverNode, parameter_overrides=[
            Parameter('port', value=emu.port_name), Parameter('protocol', value=2),
            Parameter('joints_file', value=str(joints)),
            Parameter('timeout_margin_ms', value=20.0)])
        errors = capture_errors(node)
        pubs = _commands(env, 2)
        assert env.spin_until(lambda: all(p.get_subscription_count() >= 1 for p in pubs), 20)
        for k in range(20):
            for pub, q in zip(pubs, (0.1, -0.1)):
                pub.publish(JointState(name=names, position=[q] * 4))
            env.executor.spin_once(timeout_sec=0.0)
        assert env.spin_until(lambda: node.command_publishers.reported >= 1, 20)
    assert len([e for e in errors if 'alternate' in e]) == 1
