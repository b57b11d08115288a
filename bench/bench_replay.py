"""Replay throughput: 100,000 mixed messages as fast as possible, none lost.

Prints messages/second of ``BagReplayNode`` with ack-based flow control into a reliable KEEP_ALL
subscriber in another process (as in a real graph), and the baseline: a tight publish loop with
no flow control into a depth-100 subscriber (what is lost, and how fast). The receiver runs in a
child process: a receiving thread in the replaying process competes with it for the GIL and
could stall the acknowledgement waits on a loaded machine.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import rclpy

from hexapod_common.replay import ReplayOptions
from hexapod_common.replay_node import BagReplayNode, use_replay_profile
from hexapod_common.testbags import write_mixed_bag

use_replay_profile()  # before any ROS context of this process

TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
         '/battery_state': 'sensor_msgs/msg/BatteryState',
         '/gait/phase': 'hexapod_interfaces/msg/GaitPhase'}

RECEIVER = """
import json, sys, time
import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from hexapod_common.ros_types import ros_message_class
ns, total, depth = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
types = json.loads(sys.argv[4])
rclpy.init()
node = rclpy.create_node('bench_receiver')
qos = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE) \\
    if depth == 0 else QoSProfile(depth=depth, reliability=ReliabilityPolicy.RELIABLE)
counts = dict.fromkeys(types, 0)
last = [None]
for topic, msgtype in types.items():
    def cb(_m, _t=topic):
        counts[_t] += 1
        last[0] = time.monotonic()
    node.create_subscription(ros_message_class(msgtype), ns + topic, cb, qos, raw=True)
ex = SingleThreadedExecutor()
ex.add_node(node)
print('ready', flush=True)
deadline = time.monotonic() + 300
while sum(counts.values()) < total and time.monotonic() < deadline:
    ex.spin_once(timeout_sec=0.05)
    if last[0] is not None and time.monotonic() - last[0] > 3.0:
        break  # the sender is done (the baseline loses messages)
print(json.dumps(counts), flush=True)
"""


def run(bag: Path, expected: dict[str, int], flow_control: bool) -> tuple[float, dict]:
    ns = f'/bench_replay_{os.getpid()}_{int(flow_control)}'
    receiver = subprocess.Popen(
        [sys.executable, '-c', RECEIVER, ns, str(sum(expected.values())),
         '0' if flow_control else '100', json.dumps(TYPES)], stdout=subprocess.PIPE, text=True)
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        if receiver.stdout.readline().strip() != 'ready':
            raise RuntimeError('the receiver process did not start')
        replay = BagReplayNode(str(bag), ReplayOptions(remap={t: ns + t for t in TYPES},
                                                       publish_clock=False),
                               context=ctx, ack_every=64 if flow_control else 10**9)
        if not replay.wait_for_subscribers(1, timeout_s=60):
            raise RuntimeError('the receiver did not subscribe within 60 s')
        t0 = time.perf_counter()
        if flow_control:
            replay.run()
        else:  # baseline: tight loop, no acks
            for item in replay.source.messages():
                replay.pubs[item.topic].publish(item.data)
        elapsed = time.perf_counter() - t0
        out, _ = receiver.communicate(timeout=320)
        replay.destroy_node()
    finally:
        if receiver.poll() is None:
            receiver.kill()
        ctx.try_shutdown()
    counts = json.loads(out.strip().splitlines()[-1])
    return sum(expected.values()) / elapsed, counts


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
