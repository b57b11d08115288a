"""Replay as fast as possible loses nothing: received count == recorded count, per topic."""

from __future__ import annotations

import threading

import pytest
import rclpy
from harness import KEEP_ALL_QOS, ros_env

from hexapod_common.replay import ReplayOptions
from hexapod_common.replay_node import BagReplayNode
from hexapod_common.ros_types import ros_message_class
from hexapod_common.testbags import write_mixed_bag

TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
         '/battery_state': 'sensor_msgs/msg/BatteryState',
         '/gait/phase': 'hexapod_interfaces/msg/GaitPhase'}


@pytest.mark.timeout(240)
def test_100k_mixed_messages_none_dropped(tmp_path):
    bag = tmp_path / 'mixed'
    recorded = write_mixed_bag(bag, int(__import__("os").environ.get("REPLAY_N", "100000")))
    with ros_env('replay') as env:
        ns = env.namespace
        sub = env.add(rclpy.create_node('counter', context=env.context, namespace=ns))
        counts = dict.fromkeys(TYPES, 0)
        for topic, msgtype in TYPES.items():
            def cb(_msg, _t=topic):
                counts[_t] += 1
            sub.create_subscription(ros_message_class(msgtype), ns + topic, cb, KEEP_ALL_QOS,
                                    raw=True)
        remap = {t: ns + t for t in TYPES}
        replay = BagReplayNode(str(bag), ReplayOptions(remap=remap, publish_clock=False),
                               context=env.context)
        env.nodes.append(replay)
        assert replay.wait_for_subscribers(1)
        # the receiver spins in its own thread, as a separate process would
        stop = threading.Event()

        def spin() -> None:
            while not stop.is_set():
                env.executor.spin_once(timeout_sec=0.02)
        receiver = threading.Thread(target=spin)
        receiver.start()
        try:
            replay.run()
            deadline = __import__('time').monotonic() + 60
            while counts != recorded and __import__('time').monotonic() < deadline:
                stop.wait(0.05)
        finally:
            stop.set()
            receiver.join(10)
    assert counts == recorded
    assert replay.published == recorded
    assert replay.ack_timeouts == 0


@pytest.mark.timeout(60)
def test_window_filter_and_remap(tmp_path):
    """Start/end offsets and a topic filter select exactly the expected messages."""
    bag = tmp_path / 'mixed'
    write_mixed_bag(bag, 3000, rate_hz=100.0)  # 1000 ticks over 10 s
    with ros_env('replay_window') as env:
        options = ReplayOptions(topics=('/joint_states',), start_offset_s=2.0,
                                end_offset_s=4.0, remap={'/joint_states': '/joints'},
                                publish_clock=False)
        replay = BagReplayNode(str(bag), options, context=env.context)
        env.nodes.append(replay)
        assert list(replay.pubs) == ['/joint_states']
        assert replay.pubs['/joint_states'].topic_name == '/joints'
        stamps = [m.stamp_ns for m in replay.source.messages()]
    assert len(stamps) == 201  # ticks 200..400 inclusive
    assert (stamps[-1] - stamps[0]) == pytest.approx(2e9, abs=1e7)
