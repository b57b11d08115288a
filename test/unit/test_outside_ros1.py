"""ROS 1 bags (another lab's older recordings, ``rosbag record``): the offline analyses read
them through rosbags' AnyReader and give the numbers of the same run recorded with rosbag2.

The ROS 1 bags are written with rosbags' own ROS 1 writer and the Noetic typestore (the messages
carry ``header.seq``, ROS 1 serialisation, ROS 1 message definitions) from the project's
rosbag2 bags of a simulated run. Before the SLIP reader used the reader's own deserialiser, a
ROS 1 bag failed in the CDR decoder.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag1 import Writer as Ros1Writer
from rosbags.typesys import Stores, get_typestore

from hexapod_common.bags import iter_messages, open_reader
from hexapod_energy.bag_io import read_robot_bag

edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')
ROS1 = get_typestore(Stores.ROS1_NOETIC)


def _to_ros1(msg: Any, typename: str) -> Any:
    """The ROS 1 message of ``typename`` with every field copied from a ROS 2 message (ROS 1
    headers get ``seq`` 0)."""
    cls = ROS1.types[typename]
    fields = {}
    for name, (kind, sub) in ROS1.fielddefs[typename][1]:
        if not hasattr(msg, name):
            fields[name] = 0  # header.seq
            continue
        value = getattr(msg, name)
        if kind == 2:  # a nested message
            fields[name] = _to_ros1(value, sub[0] if isinstance(sub, tuple) else sub)
        else:
            fields[name] = value
    return cls(**fields)


def to_ros1_bag(src: Path, dst: Path, topics: tuple[str, ...]) -> Path:
    """Rewrite ``topics`` of the rosbag2 bag ``src`` as the ROS 1 bag ``dst``."""
    with open_reader(src) as reader, Ros1Writer(dst) as writer:
        conns: dict[str, Any] = {}
        for m in iter_messages(reader, list(topics)):
            msg = reader.deserialize(m.data, m.msgtype)
            if m.topic not in conns:
                conns[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=ROS1)
            writer.write(conns[m.topic], m.stamp_ns,
                         ROS1.serialize_ros1(_to_ros1(msg, m.msgtype), m.msgtype))
    return dst


def test_energy_reads_a_ros1_bag_like_its_rosbag2_twin(tmp_path):
    from test_outside_nogait_bag import simulated_run, write_lab_bag

    run = simulated_run(duration_s=8.0)
    write_lab_bag(tmp_path / 'lab', run)
    bag1 = to_ros1_bag(tmp_path / 'lab', tmp_path / 'lab.bag',
                       ('/joint_states', '/battery_state', '/odom'))
    with open_reader(bag1) as reader:
        assert not reader.is2
    ref = read_robot_bag(tmp_path / 'lab', mass_kg=2.183)
    got = read_robot_bag(bag1, mass_kg=2.183)
    assert got.windows == ref.windows >= 6
    for field in ('power_in_w', 'power_out_w', 'speed_mps'):
        np.testing.assert_allclose(getattr(got, field), getattr(ref, field), rtol=1e-12)


def test_slip_reads_a_ros1_bag_like_its_rosbag2_twin(tmp_path):
    from slip_identification.cli import add_cli

    ref_bag = edubot_bag.write_edubot_bag(tmp_path / 'ref', 'running', duration_s=3.0, seed=1)
    bag1 = to_ros1_bag(ref_bag, tmp_path / 'edubot.bag',
                       ('/joint_states', '/joint_commands', '/mocap/body', '/battery_state'))
    docs = []
    for bag, name in ((ref_bag, 'ref'), (bag1, 'ros1')):
        ap = argparse.ArgumentParser()
        add_cli(ap.add_subparsers(dest='command', required=True))
        args = ap.parse_args(['slip', str(bag), '--out', str(tmp_path / name)])
        assert args.func(args) == 0
        docs.append(json.loads((tmp_path / name / 'slip.json').read_text()))
    ref, got = docs
    assert len(ref['stances']) >= 5
    assert [s['touchdown'] for s in got['stances']] == [s['touchdown'] for s in ref['stances']]
    assert [s['stiffness'] for s in got['stances']] == [s['stiffness'] for s in ref['stances']]
