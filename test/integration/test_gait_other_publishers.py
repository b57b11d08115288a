"""One gait node per robot (review K left it): a second ``gait_scheduler``, or a lab's own node
publishing ``gait/phase`` / ``joint_commands``, interleaved its commands with the first's
without a word. Now a node that finds another publisher before its first command, or one
that walked first (more messages sent, by the sequence numbers), refuses to walk (exit 2,
nothing more published); one that walked first logs an error and keeps walking; a publisher listed in the graph that sends nothing (a crashed node's
endpoint until its DDS lease runs out) is waited for, then walked past."""

from __future__ import annotations

from typing import Any

import pytest
import rclpy
from harness import KEEP_ALL_QOS, capture_errors, ros_env
from hexapod_interfaces.msg import GaitPhase
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState


def _gait(env: Any, name: str, **params: Any) -> Any:
    from hexapod_gait.gait_node import GaitSchedulerNode

    return env.make(GaitSchedulerNode, node_name=name, parameter_overrides=[
        Parameter(k, value=v) for k, v in params.items()])


def _feeder(env: Any) -> tuple[Any, Any, Any]:
    node = env.add(rclpy.create_node('lab_gait', context=env.context,
                                     namespace=env.namespace))
    return (node, node.create_publisher(GaitPhase, 'gait/phase', KEEP_ALL_QOS),
            node.create_publisher(JointState, 'joint_commands', KEEP_ALL_QOS))


@pytest.mark.timeout(120)
def test_a_second_gait_node_refuses_to_walk_and_the_first_walks_on() -> None:
    from hexapod_gait.gait_node import EXIT_ANOTHER_GAIT

    with ros_env('gait_two') as env:
        first = _gait(env, 'gait_a', startup_listen_s=0.0)
        first_errors = capture_errors(first)
        assert env.spin_until(lambda: first.ticks >= 10, 30)
        second = _gait(env, 'gait_b')
        errors = capture_errors(second)
        assert env.spin_until(lambda: second.finished.done(), 30)
        assert second.finished.result() == EXIT_ANOTHER_GAIT
        assert second.ticks == 0            # not one command of a second schedule
        ticks = first.ticks
        assert env.spin_until(lambda: first.ticks >= ticks + 20, 30)
    assert len(errors) == 1 and 'refusing to walk' in errors[0]
    assert '/gait_a' in errors[0]           # the other named
    assert first_errors == [] and not first.finished.done()


def _hear(node: Any, seqs: list[int], t0_s: float, rate_hz: float) -> None:
    """Another publisher's messages as the node's own-topic subscription takes them: its
    numbers and send times (a node discovered late, walking since ``t0_s`` at ``rate_hz``)."""
    for n in seqs:
        node._on_own_topic('gait/phase', b'', {
            'publication_sequence_number': n,
            'source_timestamp': int((t0_s + (n - 1) / rate_hz) * 1e9)})
        if node.finished.done():
            return


@pytest.mark.timeout(120)
@pytest.mark.parametrize('rate_hz,walked_s', [(100.0, 3.0), (10.0, 4.0)])
def test_a_newcomer_that_walked_before_it_heard_the_other_stops_at_once(rate_hz,
                                                                       walked_s) -> None:
    """Discovery can take longer than the start-up listen (1.4 s measured on a busy machine):
    the newcomer hears the other by the interleaved sequence numbers and stops. Who walked
    first is judged by the publishers' starts, not their message counts (a review: a 10 Hz
    node walking 4 s stopped for a 100 Hz newcomer's 107 messages)."""
    import time

    from hexapod_gait.gait_node import EXIT_ANOTHER_GAIT

    with ros_env('gait_late') as env:
        node = _gait(env, 'gait_late', startup_listen_s=0.0)
        errors = capture_errors(node)
        assert env.spin_until(lambda: node.ticks >= 30, 30)
        now = time.time()
        t0 = now - walked_s                      # the other started walked_s ago
        sent = int(walked_s * rate_hz)
        for k in range(10):                      # its messages interleave with ours
            _hear(node, [sent + k], t0, rate_hz)
            env.executor.spin_once(timeout_sec=0.02)
            if node.finished.done():
                break
        assert env.spin_until(lambda: node.finished.done(), 20)
        assert node.finished.result() == EXIT_ANOTHER_GAIT
        ticks = node.ticks
        env.spin_until(lambda: node.ticks > ticks, 0.3)
        assert node.ticks == ticks           # nothing published after the refusal
    assert len(errors) == 1 and 'stops publishing' in errors[0]
    assert 'walking longer, keeps the robot' in errors[0]


@pytest.mark.timeout(120)
def test_an_older_slow_node_keeps_walking_beside_a_fast_newcomer() -> None:
    """The reverse of the review's case: this node (10 Hz) walked 3 s, a 100 Hz newcomer
    with many more messages appears: this node keeps walking and says so."""
    import time

    with ros_env('gait_slow_old') as env:
        node = _gait(env, 'gait_slow', startup_listen_s=0.0, rate=10.0)
        errors = capture_errors(node)
        assert env.spin_until(lambda: node.ticks >= 30, 30)
        t0 = time.time() - 0.5                   # the newcomer: 0.5 s at 100 Hz
        for k in range(20):
            _hear(node, [50 + k], t0, 100.0)
            env.executor.spin_once(timeout_sec=0.1)
        assert not node.finished.done()
        assert node.other_publishers_reported == 1
    assert len(errors) == 1 and 'keeps walking' in errors[0]


@pytest.mark.timeout(120)
def test_a_walking_node_reports_another_publisher_once_and_walks_on() -> None:
    with ros_env('gait_old') as env:
        node = _gait(env, 'gait_old', startup_listen_s=0.0)
        errors = capture_errors(node)
        assert env.spin_until(lambda: node.ticks >= 50, 60)
        _, _, commands = _feeder(env)
        assert env.spin_until(lambda: commands.get_subscription_count() >= 1, 20)
        for _ in range(60):
            commands.publish(JointState(name=['L1_coxa'], position=[0.0]))
            env.executor.spin_once(timeout_sec=0.02)
        assert not node.finished.done()
        assert node.other_publishers_reported == 1
    assert len(errors) == 1 and 'joint_commands' in errors[0] and 'keeps walking' in errors[0]


@pytest.mark.timeout(120)
def test_two_gait_nodes_started_together_never_both_walk() -> None:
    """An outside review: two nodes started in one executor both refused, each saying "the
    other keeps the robot". Now either the one whose listen ended first walks and the other
    refuses, or (their first commands in one tick) both stop saying so; never both walk."""
    from hexapod_gait.gait_node import EXIT_ANOTHER_GAIT

    with ros_env('gait_twins') as env:
        a = _gait(env, 'gait_a', startup_listen_s=0.0)
        b = _gait(env, 'gait_b', startup_listen_s=0.0)
        errors = {'a': capture_errors(a), 'b': capture_errors(b)}
        nodes = {'a': a, 'b': b}
        assert env.spin_until(lambda: a.finished.done() or b.finished.done(), 30)
        stopped = [k for k, n in nodes.items() if n.finished.done()]
        if len(stopped) == 1:      # the other walks on, or stops a moment later (a tie)
            [walker] = [n for k, n in nodes.items() if k not in stopped]
            ticks = walker.ticks
            assert env.spin_until(lambda: walker.ticks >= ticks + 30 or walker.finished.done(),
                                  30)
        stopped = [k for k, n in nodes.items() if n.finished.done()]
    assert all(nodes[k].finished.result() == EXIT_ANOTHER_GAIT for k in stopped)
    if len(stopped) == 2:
        assert all(len(errors[k]) == 1 and 'both stop' in errors[k][0] for k in stopped)
    else:
        [k] = stopped
        assert len(errors[k]) == 1 and ('already publishes' in errors[k][0]
                                        or 'walking longer' in errors[k][0])


@pytest.mark.timeout(120)
def test_a_listed_publisher_that_sends_nothing_is_walked_past() -> None:
    """A crashed gait node stays in the graph for its DDS lease: a respawned one listens
    for its messages, hears none, and walks."""
    with ros_env('gait_stale') as env:
        _feeder(env)                              # listed, never publishes
        node = _gait(env, 'gait_respawned', startup_listen_s=0.0)
        warnings: list[str] = []
        infos: list[str] = []
        log = node.get_logger()
        log.warning = lambda msg, **kw: warnings.append(msg)
        log.info = lambda msg, **kw: infos.append(msg)
        assert env.spin_until(lambda: node.ticks >= 5, 30)
        assert not node.finished.done()
    assert any('listening' in w and 'lab_gait' in w for w in warnings), warnings
    assert any('nothing came' in i for i in infos), infos


def _stating(start_s: float, seq_t: float) -> bytes:
    """Another gait node's message: its frame_id states its start (node@pid@ns)."""
    from rclpy.serialization import serialize_message

    msg = GaitPhase(gait='tripod', period=1.0)
    msg.header.frame_id = f'/other_gait@4242@{int(start_s * 1e9)}'
    msg.header.stamp.sec = int(seq_t)
    return serialize_message(msg)


@pytest.mark.timeout(120)
def test_a_start_another_gait_node_states_is_believed_over_its_numbers() -> None:
    """A review: a node paused (SIGSTOP) and resumed sent numbers that extrapolate to a later
    start than its real one, and both nodes kept walking. Gait nodes now state their start
    in their frame_id; this node (walking 0.3 s) hears one that says it started 10 s ago
    with numbers that look new: it stops."""
    import time

    from hexapod_gait.gait_node import EXIT_ANOTHER_GAIT

    with ros_env('gait_stated') as env:
        node = _gait(env, 'gait_new', startup_listen_s=0.0)
        errors = capture_errors(node)
        assert env.spin_until(lambda: node.ticks >= 30, 30)
        now = time.time()
        for n in range(1, 6):
            node._on_own_topic('gait/phase', _stating(now - 10.0, now + 0.01 * n), {
                'publication_sequence_number': n,
                'source_timestamp': int((now + 0.01 * n) * 1e9)})
            if node.finished.done():
                break
        assert node.finished.done() and node.finished.result() == EXIT_ANOTHER_GAIT
    assert 'walking longer, keeps the robot' in errors[0]
    ahead = float(errors[0].split('it started ')[1].split(' s')[0])
    assert 9.0 < ahead < 10.0          # 10 s ago, this node 0.3-1 s ago


@pytest.mark.timeout(120)
def test_a_publisher_slower_than_the_quiet_time_is_reported_once(monkeypatch) -> None:
    """A review: a 0.45 Hz lab node beside a walking gait node was reported on every
    message (its 2.2 s gaps were each taken for a new episode)."""
    import time as real_time

    import hexapod_gait.gait_node as gait_node

    with ros_env('gait_slow_lab') as env:
        node = _gait(env, 'gait_busy', startup_listen_s=0.0)
        errors = capture_errors(node)
        assert env.spin_until(lambda: node.ticks >= 30, 30)
        clock = [real_time.time()]
        fake = type('T', (), {'time': staticmethod(lambda: clock[0]),
                              'time_ns': staticmethod(lambda: int(clock[0] * 1e9))})
        monkeypatch.setattr(gait_node, 'time', fake)
        for n in range(1, 8):                 # 0.45 Hz, started now
            clock[0] += 2.2
            node._on_own_topic('joint_commands', b'', {
                'publication_sequence_number': n, 'source_timestamp': int(clock[0] * 1e9)})
        assert not node.finished.done()
        assert node.other_publishers_reported == 1
    assert len(errors) == 1
