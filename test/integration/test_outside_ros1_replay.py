"""Another lab's ROS 1 bag (``rosbag record`` on Noetic) replayed into the project's ROS 2 nodes.

The ROS 1 bag is written with rosbags' ROS 1 writer and the Noetic typestore (``header.seq``,
ROS 1 serialisation) from the rosbag2 bag of a simulated robot run without ``/gait/phase``
(``/joint_states``, ``/battery_state``, ``/odom``), as ``test/unit/test_outside_ros1.py`` does.
Before the ROS 1 -> CDR conversion, replaying such a bag handed ROS 1 bytes to the CDR decoder.
"""

from __future__ import annotations

import math
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from harness import Collector, ros_env
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter
from rosbags.rosbag1 import Writer as Ros1Writer
from sensor_msgs.msg import BatteryState, JointState

from hexapod_common.bags import iter_messages, open_reader
from hexapod_common.replay import ReplaySource, run_offline
from hexapod_energy.energy_node import EnergyMonitorNode

sys.path.insert(0, str(Path(__file__).parents[1] / 'unit'))
from test_outside_nogait_bag import simulated_run, write_lab_bag  # noqa: E402
from test_outside_ros1 import ROS1, to_ros1_bag  # noqa: E402
from test_outside_ros1 import _to_ros1 as to_ros1_msg  # noqa: E402

BIN = Path(sys.executable).parent
ENV = dict(os.environ, PYTHONUNBUFFERED='1')
TOPICS = ('/joint_states', '/battery_state', '/odom')
FIELDS = ('window', 'mass', 'speed', 'power_in', 'power_out', 'power_loss', 'efficiency',
          'cost_of_transport', 'specific_cost_of_transport', 'specific_resistance')


@pytest.fixture(scope='module')
def twins(tmp_path_factory) -> tuple[Path, Path]:
    """(rosbag2 bag, ROS 1 twin) of an 8 s simulated tripod run without /gait/phase."""
    tmp = tmp_path_factory.mktemp('ros1_twins')
    write_lab_bag(tmp / 'lab', simulated_run(duration_s=8.0))
    ros1 = to_ros1_bag(tmp / 'lab', tmp / 'lab.bag', TOPICS)
    with open_reader(ros1) as reader:
        assert not reader.is2
    return tmp / 'lab', ros1


def _offline(bag: Path, prefix: str) -> list[Any]:
    with ros_env(prefix) as env:
        node = EnergyMonitorNode(context=env.context, parameter_overrides=[
            Parameter('current_sign', value='ros'), Parameter('mass', value=2.183)])
        env.nodes.append(node)
        captured = run_offline([node], str(bag))
        assert node.dropped == 0
    return captured['/energy/descriptors']


@pytest.mark.timeout(120)
def test_run_offline_ros1_bag_equals_its_rosbag2_twin(twins):
    ref = _offline(twins[0], 'ros1_ref')
    got = _offline(twins[1], 'ros1_got')
    assert len(ref) >= 6 and len(got) == len(ref)
    for a, b in zip(got, ref):
        assert (a.header.stamp.sec, a.header.stamp.nanosec) == \
            (b.header.stamp.sec, b.header.stamp.nanosec)
        for field in FIELDS:
            va, vb = getattr(a, field), getattr(b, field)
            if math.isnan(vb):
                assert math.isnan(va), field
            else:
                assert va == pytest.approx(vb, rel=1e-9, abs=1e-9), field
        assert a.power_in > 0 and a.speed == pytest.approx(0.3, rel=0.02)


def _reference(bag: Path) -> dict[str, list[Any]]:
    """Messages of the rosbag2 twin, decoded with rosbags, per topic in bag order."""
    out: dict[str, list[Any]] = {t: [] for t in TOPICS}
    with open_reader(bag) as reader:
        for m in iter_messages(reader, list(TOPICS)):
            out[m.topic].append(reader.deserialize(m.data, m.msgtype))
    return out


def _stamp(msg: Any) -> tuple[int, int]:
    return msg.header.stamp.sec, msg.header.stamp.nanosec


def _with_rosout(src: Path, dst: Path) -> Path:
    """The ROS 1 twin plus ``/rosout`` (``rosgraph_msgs/Log``, no ROS 2 counterpart)."""
    T = ROS1.types
    with open_reader(src) as reader, Ros1Writer(dst) as writer:
        conns: dict[str, Any] = {}
        for k, m in enumerate(iter_messages(reader, list(TOPICS))):
            if m.topic not in conns:
                conns[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=ROS1)
            msg = reader.deserialize(m.data, m.msgtype)
            writer.write(conns[m.topic], m.stamp_ns,
                         ROS1.serialize_ros1(to_ros1_msg(msg, m.msgtype), m.msgtype))
            if k % 100 == 0:
                if '/rosout' not in conns:
                    conns['/rosout'] = writer.add_connection('/rosout', 'rosgraph_msgs/msg/Log',
                                                             typestore=ROS1)
                log = T['rosgraph_msgs/msg/Log'](
                    header=to_ros1_msg(msg.header, 'std_msgs/msg/Header'),
                    level=2, name='/lab_driver', msg=f'tick {k}', file='driver.py',
                    function='loop', line=k, topics=list(TOPICS))
                writer.write(conns['/rosout'], m.stamp_ns,
                             ROS1.serialize_ros1(log, 'rosgraph_msgs/msg/Log'))
    return dst


@pytest.mark.timeout(120)
def test_bag_replay_delivers_every_ros1_message_with_its_values(twins, tmp_path):
    ref = _reference(twins[0])
    bag = _with_rosout(twins[0], tmp_path / 'lab_rosout.bag')
    with ReplaySource(str(bag)) as source:
        assert set(source.types) == set(TOPICS) and set(source.skipped) == {'/rosout'}
    with ros_env('ros1_replay') as env:
        ns = env.namespace
        got = {'/joint_states': Collector(env, JointState, f'{ns}/joint_states'),
               '/battery_state': Collector(env, BatteryState, f'{ns}/battery_state'),
               '/odom': Collector(env, Odometry, f'{ns}/odom')}
        proc = subprocess.Popen(
            [str(BIN / 'bag_replay'), str(bag), '--no-clock', '--wait-subscribers', '1',
             '--remap', *(f'{t}:={ns}{t}' for t in TOPICS)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV)
        try:
            for topic, col in got.items():
                col.wait_for(env, len(ref[topic]), timeout_s=60)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait(10)
    assert proc.returncode == 0, err
    assert 'Traceback' not in err
    rosout = [ln for ln in err.splitlines() if '/rosout' in ln]
    assert len(rosout) == 1 and 'rosgraph_msgs/msg/Log' in rosout[0], err
    total = sum(len(v) for v in ref.values())
    assert f'replayed {total} messages' in out, out
    assert len(ref['/joint_states']) == 800 and len(ref['/battery_state']) == 400
    for topic in TOPICS:
        assert len(got[topic].messages) == len(ref[topic]), topic
    for a, b in zip(got['/joint_states'].messages, ref['/joint_states']):
        assert _stamp(a) == _stamp(b) and a.header.frame_id == b.header.frame_id
        assert list(a.name) == list(b.name)
        np.testing.assert_array_equal(a.position, b.position)
        np.testing.assert_array_equal(a.velocity, b.velocity)
        np.testing.assert_array_equal(a.effort, b.effort)
    for a, b in zip(got['/battery_state'].messages, ref['/battery_state']):
        assert _stamp(a) == _stamp(b)
        assert (a.voltage, a.current, a.temperature) == (b.voltage, b.current, b.temperature)
        assert math.isnan(a.charge) and a.present is True and a.power_supply_status == 2
    for a, b in zip(got['/odom'].messages, ref['/odom']):
        assert _stamp(a) == _stamp(b) and a.header.frame_id == 'odom'
        assert a.child_frame_id == 'base_link'
        assert a.pose.pose.position.x == b.pose.pose.position.x
        assert a.pose.pose.orientation.w == 1.0
        assert a.twist.twist.linear.x == b.twist.twist.linear.x
        np.testing.assert_array_equal(a.pose.covariance, b.pose.covariance)


@pytest.mark.timeout(60)
def test_a_ros1_message_that_cannot_be_converted_is_dropped_with_one_warning(twins, tmp_path):
    """Two cut JointState messages in the middle of a ROS 1 bag: the replay source drops them,
    warns once, counts them, and yields every other message in order."""
    bag = tmp_path / 'cut.bag'
    with open_reader(twins[1]) as reader, Ros1Writer(bag) as writer:
        conns: dict[str, Any] = {}
        cut = 0
        for k, m in enumerate(iter_messages(reader, list(TOPICS))):
            if m.topic not in conns:
                conns[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=ROS1)
            data = m.data
            if m.topic == '/joint_states' and k in (300, 301, 302, 303, 304, 305) and cut < 2:
                data, cut = data[:len(data) // 2], cut + 1
            writer.write(conns[m.topic], m.stamp_ns, data)
        total = reader.message_count
    warnings: list[str] = []
    with ReplaySource(str(bag), warn=warnings.append) as source:
        items = list(source.messages())
        dropped = dict(source.dropped)
    assert dropped == {'/joint_states': 2}
    assert len(warnings) == 1 and '/joint_states' in warnings[0]
    assert len(items) == total - 2
    stamps = [m.stamp_ns for m in items]
    assert stamps == sorted(stamps)
