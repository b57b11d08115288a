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
from hexapod_common.testbags import MIXED_TYPES as TYPES
from hexapod_common.testbags import RAW_COUNT_RECEIVER as RECEIVER
from hexapod_common.testbags import write_mixed_bag

use_replay_profile()  # before any ROS context of this process

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
