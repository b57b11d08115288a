"""Replay as fast as possible loses nothing: received count == recorded count, per topic."""

from __future__ import annotations

import pytest
from harness import ros_env

from hexapod_common.replay import ReplayOptions
from hexapod_common.replay_node import BagReplayNode, use_replay_profile
from hexapod_common.testbags import MIXED_TYPES as TYPES
from hexapod_common.testbags import RAW_COUNT_RECEIVER as RECEIVER
from hexapod_common.testbags import write_mixed_bag

use_replay_profile()  # before any ROS context of this process


@pytest.mark.timeout(240)
def test_100k_mixed_messages_none_dropped(tmp_path):
    """bag_replay and a reliable KEEP_ALL receiver in another process, as in a real graph."""
    import json
    import subprocess
    import sys

    bag = tmp_path / 'mixed'
    recorded = write_mixed_bag(bag, int(__import__('os').environ.get('REPLAY_N', '100000')))
    with ros_env('replay') as env:
        ns = env.namespace
        receiver = subprocess.Popen(
            [sys.executable, '-c', RECEIVER, ns, str(sum(recorded.values())), '0',
             json.dumps(TYPES)],
            stdout=subprocess.PIPE, text=True)
        try:
            assert receiver.stdout.readline().strip() == 'ready'
            remap = {t: ns + t for t in TYPES}
            replay = BagReplayNode(str(bag), ReplayOptions(remap=remap, publish_clock=False),
                                   context=env.context)
            env.nodes.append(replay)
            assert replay.wait_for_subscribers(1, timeout_s=30)
            replay.run()
            out, _ = receiver.communicate(timeout=200)
        finally:
            if receiver.poll() is None:
                receiver.kill()
    counts = json.loads(out.strip().splitlines()[-1])
    assert counts == recorded
    assert replay.published == recorded


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
