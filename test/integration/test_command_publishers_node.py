"""The drivers say when two sources command their joints (two gait nodes, a teleop beside the
gait node), once per episode from the messages' sequence numbers, and apply only the one that
was there first (their targets alternated before); a respawned gait node (one publisher
again) is not two, and is followed."""

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
        # one of the two followed (both heard together: the first heard), the other dropped
        gate = sim.command_publishers.gate
        assert sim.command_publishers.dropped >= 1
        assert len([s for s in gate.live_series() if s.passed]) == 1
    reported = [e for e in errors if 'joint_commands' in e]
    assert len(reported) == 1 and "the other's commands are ignored" in reported[0]


@pytest.mark.timeout(120)
def test_one_command_source_restarted_is_not_two() -> None:
    """... and the respawn is followed: a respawned gait node sends its first command at
    least its ``startup_listen_s`` (0.5 s, not below FOLLOWED_QUIET_S) after it started, so
    the driver hears the old series silent that long and drops nothing."""
    from hexapod_bench_drivers.sim_nodes import SimRobotNode
    from hexapod_common.publishers import FOLLOWED_QUIET_S

    with ros_env('one_commander') as env:
        sim = env.make(SimRobotNode, parameter_overrides=[])
        errors = capture_errors(sim)
        names = list(sim.live.joint_names)
        watch = sim.command_publishers
        applied = []
        for respawn in range(2):  # a gait node, then its respawn: a new writer, numbers anew
            if respawn:           # (its start-up listen)
                assert env.spin_until(lambda: watch.clock() - watch.gate.series().last_arrival
                                      >= FOLLOWED_QUIET_S, 20)
            applied.append(watch.gate.passed)
            [pub] = _commands(env, 1)
            assert env.spin_until(lambda: pub.get_subscription_count() >= 1, 20)
            for k in range(150):
                pub.publish(JointState(name=names, position=[0.0] * len(names)))
                env.executor.spin_once(timeout_sec=0.0)
            env.spin_until(lambda: False, 0.2)
            env.nodes[-1].destroy_publisher(pub)
        assert sim.command_publishers.sequences.numbered
        assert sim.command_publishers.reported == 0, errors
        # the respawn followed: nothing dropped (the old one silent the quiet time before);
        # every message that arrived applied (best effort: a busy machine may lose some)
        assert watch.gate.dropped == 0 and watch.gate.passed > applied[1] > 0


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
    assert len([e for e in errors if "the other's commands are ignored" in e]) == 1


@pytest.mark.timeout(120)
def test_sim_robot_applies_only_the_first_source_then_the_one_left() -> None:
    """A gait node sends 0.1 rad, a second source 0.5 rad interleaved: the simulated joints'
    targets stay at 0.1 while the first lives; once it is gone and the quiet time passed
    (FOLLOWED_QUIET_S), the one left is followed. Before, each message of either was applied
    (the targets jumped between 0.1 and 0.5)."""
    from hexapod_bench_drivers.sim_nodes import SimRobotNode
    from hexapod_common.publishers import FOLLOWED_QUIET_S

    with ros_env('first_source') as env:
        sim = env.make(SimRobotNode, parameter_overrides=[])
        names = list(sim.live.joint_names)
        applied: list[float] = []
        update = sim.live.commands.update

        def record(t_s, names_, position, velocity):
            applied.append(float(position[0]))
            return update(t_s, names_, position, velocity)
        sim.live.commands.update = record
        warnings: list[str] = []
        log = sim.get_logger()
        warn = log.warning
        log.warning = lambda msg, **kw: warnings.append(msg) or warn(msg, **kw)
        errors = capture_errors(sim)

        def source(name: str, q: float) -> Any:
            """A node sending ``q`` to every joint at 100 Hz (a gait node, a teleop)."""
            node = rclpy.create_node(name, context=env.context, namespace=env.namespace)
            pub = node.create_publisher(JointState, 'joint_commands', KEEP_ALL_QOS)
            node.create_timer(0.01, lambda: pub.publish(
                JointState(name=names, position=[q] * len(names))))
            return node

        first = source('gait_first', 0.1)
        env.executor.add_node(first)                 # destroyed below, not by ros_env
        assert env.spin_until(lambda: len(applied) >= 20, 30)
        env.add(source('gait_second', 0.5))
        watch = sim.command_publishers
        assert env.spin_until(lambda: watch.reported >= 1 and watch.dropped >= 50, 30)
        # the second's first one or two commands pass before its numbers have interleaved
        # twice (one publisher's are never dropped), then none while the first lives
        early = [k for k, q in enumerate(applied) if q == 0.5]
        assert len(early) <= 2 and (not early or early[-1] - early[0] <= 4)
        tail = len(applied)
        env.executor.remove_node(first)              # the first gait node gone
        first.destroy_node()
        n = len(applied)
        assert set(applied[tail - 20:n]) == {0.1}
        assert env.spin_until(lambda: 0.5 in applied[n:], 30)
        after = applied[applied.index(0.5, n):]
        assert set(after) == {0.5}                   # the one left, from then on
        [switch] = [w for w in warnings if 'silent for' in w]
        silent = float(switch.split('silent for ')[1].split(' s')[0])
        assert silent >= FOLLOWED_QUIET_S
    assert len(errors) == 1 and "the other's commands are ignored" in errors[0]
    assert "applied" in errors[0]
