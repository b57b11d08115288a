"""Replay throughput: 100,000 mixed messages as fast as possible, none lost.

Prints messages/second of ``BagReplayNode`` with ack-based flow control into a reliable KEEP_ALL
subscriber in another thread, and the baseline: a tight publish loop with no flow control into a
depth-100 subscriber (what is lost, and how fast).
"""

from __future__ import annotations

import sys
import tempfile
import threading
import time
from pathlib import Path

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

from hexapod_common.replay import ReplayOptions
from hexapod_common.replay_node import BagReplayNode, use_replay_profile
from hexapod_common.ros_types import ros_message_class
from hexapod_common.testbags import write_mixed_bag

use_replay_profile()  # before any ROS context of this process


def count_subscriber(ctx, topics, qos):
    node = rclpy.create_node('bench_counter', context=ctx)
    counts = dict.fromkeys(topics, 0)
    for topic, msgtype in topics.items():
        def cb(_msg, _t=topic):
            counts[_t] += 1
        node.create_subscription(ros_message_class(msgtype), topic, cb, qos, raw=True)
    return node, counts


def run(bag: Path, expected: dict[str, int], flow_control: bool) -> tuple[float, dict]:
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    types = {'/joint_states': 'sensor_msgs/msg/JointState',
             '/battery_state': 'sensor_msgs/msg/BatteryState',
             '/gait/phase': 'hexapod_interfaces/msg/GaitPhase'}
    qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE) \
        if flow_control else QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)
    sub_node, counts = count_subscriber(ctx, types, qos)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(sub_node)
    stop = threading.Event()

    def spin():
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.05)
    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    replay = BagReplayNode(str(bag), ReplayOptions(publish_clock=False), context=ctx,
                           ack_every=64 if flow_control else 10**9)
    replay.wait_for_subscribers(1)
    t0 = time.perf_counter()
    if flow_control:
        replay.run()
    else:  # baseline: tight loop, no acks
        for item in replay.source.messages():
            replay.pubs[item.topic].publish(item.data)
    elapsed = time.perf_counter() - t0
    deadline = time.monotonic() + 10
    while sum(counts.values()) < sum(expected.values()) and time.monotonic() < deadline:
        time.sleep(0.05)
    stop.set()
    thread.join()
    replay.destroy_node()
    sub_node.destroy_node()
    executor.shutdown()
    ctx.try_shutdown()
    return sum(expected.values()) / elapsed, dict(counts)


def main(n: int = 100_000) -> int:
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / 'mixed'
        expected = write_mixed_bag(bag, n)
        rate_fc, got_fc = run(bag, expected, flow_control=True)
        rate_bl, got_bl = run(bag, expected, flow_control=False)
    lost_fc = sum(expected.values()) - sum(got_fc.values())
    lost_bl = sum(expected.values()) - sum(got_bl.values())
    print(f'replay of {n} mixed messages (JointState x18, BatteryState, GaitPhase)')
    print(f'  flow-controlled replay: {rate_fc:,.0f} msg/s, lost {lost_fc} '
          f'(per topic received {got_fc}, recorded {expected})')
    print(f'  baseline tight loop:    {rate_bl:,.0f} msg/s, lost {lost_bl}')
    print(f'  speed ratio flow-controlled / baseline: {rate_fc / rate_bl:.2f}')
    return 0 if lost_fc == 0 else 1


if __name__ == '__main__':
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 100_000))
