"""``hexapod-analyze slip`` on bags whose ``/joint_states`` is split over several messages.

A simulated EduBot bag (``hexapod_bench_drivers.edubot_bag``) is rewritten with rosbags' own
``Writer``: its ``/joint_states`` become two messages per sample (hips L1-L3 and R1-R3, one
per servo bus), or six single-joint messages with jittered stamps (each joint's own read
time, +-0.4 ms; the commands split likewise). Before the assembler, ``read_run`` kept only
messages naming the first message's joints and the run lost half its legs (a refusal or wrong
tripods). The assembled
runs must give the unsplit run's stances (touchdown and lift-off within 2 ms, same count
+-1) and stiffness medians within 2 %.
"""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from slip_identification.cli import add_cli, read_run
from slip_identification.errors import MissingTopicError

edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')

JS = 'sensor_msgs/msg/JointState'


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('split')
    ref = edubot_bag.write_edubot_bag(root / 'ref', 'running', duration_s=4.0, seed=1)
    return {'ref': ref,
            'two': _rewrite(ref, root / 'two', [(0, 1, 2), (3, 4, 5)], jitter_s=0.0),
            'six': _rewrite(ref, root / 'six', [(i,) for i in (3, 0, 4, 1, 5, 2)],
                            jitter_s=4e-4, topics=('/joint_states', '/joint_commands')),
            'left_only': _rewrite(ref, root / 'left_only', [(0, 1, 2)], jitter_s=0.0)}


def _rewrite(src, dst, groups, *, jitter_s: float, seed: int = 5,
             topics=('/joint_states',)):
    """Copy bag ``src`` to ``dst`` with each message of ``topics`` (JointState) split into
    ``groups`` (tuples of column indices), each part stamped with its own jitter."""
    from hexapod_common.bags import open_reader, typestore

    store = typestore()
    rng = np.random.default_rng(seed)
    with open_reader(src) as reader, \
            Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for c in reader.connections:
            conns[c.topic] = w.add_connection(c.topic, c.msgtype, typestore=store)
        for conn, t_ns, data in reader.messages():
            if conn.topic not in topics:
                w.write(conns[conn.topic], t_ns, data)
                continue
            msg = store.deserialize_cdr(data, JS)
            stamp_ns = msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec
            for g in groups:
                idx = list(g)
                ns = stamp_ns + int(round(rng.uniform(-jitter_s, jitter_s) * 1e9))
                part = store.types[JS](
                    header=store.types['std_msgs/msg/Header'](
                        stamp=store.types['builtin_interfaces/msg/Time'](
                            sec=ns // 10**9, nanosec=ns % 10**9), frame_id=''),
                    name=[msg.name[i] for i in idx],
                    position=msg.position[idx] if len(msg.position) else msg.position,
                    velocity=msg.velocity[idx],
                    effort=msg.effort[idx] if len(msg.effort) else msg.effort)
                w.write(conns[conn.topic], t_ns, store.serialize_cdr(part, JS))
    return dst


def _slip(tmp_path, bag, name):
    """``slip`` on ``bag``: (exit code, slip.json). Without figures (--no-plots): these tests
    read slip.json only."""
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(['slip', str(bag), '--out', str(tmp_path / name), '--no-plots'])
    code = args.func(args)
    return code, json.loads((tmp_path / name / 'slip.json').read_text())


def _matched(ref, doc):
    """Per reference stance, the split run's stance of the same tripod nearest in touchdown."""
    out = []
    for s in ref['stances']:
        same = [x for x in doc['stances'] if x['tripod'] == s['tripod']]
        out.append((s, min(same, key=lambda x: abs(x['touchdown'] - s['touchdown']))))
    return out


def test_read_run_assembles_split_frames(bags):
    ref = read_run(bags['ref'])
    runs = {}
    for key, groups in (('two', 2), ('six', 6)):
        run = runs[key] = read_run(bags[key])
        assert set(run.joint_names) == set(ref.joint_names)
        note = [n for n in run.notes if 'split over' in n]
        assert note and f'split over {groups} name groups: assembled at 100 Hz' in note[0]
        assert run.joint_t_s.size >= ref.joint_t_s.size - 2
        assert run.joint_effort is not None and run.joint_position is not None
        assert run.command_velocity.shape[1] == 6
    notes = runs['six'].notes
    assert any('/joint_commands: joint states split over 6' in n for n in notes)
    # same stamps on both buses: the frames are the reference's own samples
    run = runs['two']
    cols = [run.joint_names.index(n) for n in ref.joint_names]
    np.testing.assert_array_equal(run.joint_t_s, ref.joint_t_s)
    for field in ('joint_velocity', 'joint_position', 'joint_effort'):
        np.testing.assert_allclose(getattr(run, field)[:, cols], getattr(ref, field),
                                   rtol=0, atol=1e-12)


def test_split_bags_give_the_unsplit_stances(tmp_path, bags):
    code, ref = _slip(tmp_path, bags['ref'], 'ref')
    assert code == 0 and len(ref['stances']) >= 10
    k_ref = float(np.median([s['stiffness'] for s in ref['stances']]))
    for key in ('two', 'six'):
        code, doc = _slip(tmp_path, bags[key], key)
        assert code == 0 and not doc['failed_bags']
        assert abs(len(doc['stances']) - len(ref['stances'])) <= 1
        pairs = _matched(ref, doc)
        td = np.array([abs(a['touchdown'] - b['touchdown']) for a, b in pairs])
        lo = np.array([abs(a['liftoff'] - b['liftoff']) for a, b in pairs])
        # a stance present in one run only (count +-1) is the one allowed outlier
        assert np.sort(td)[:len(td) - 1].max() <= 2e-3, (key, td)
        assert np.sort(lo)[:len(lo) - 1].max() <= 2e-3, (key, lo)
        k = float(np.median([s['stiffness'] for s in doc['stances']]))
        assert k == pytest.approx(k_ref, rel=0.02), key
        run = doc['runs'][0]
        assert any('joint states split over' in n for n in run['notes'])
        assert run['edges'] == 'geometry'


def test_a_bag_with_one_bus_only_is_refused_naming_the_missing_joints(tmp_path, bags):
    with pytest.raises(MissingTopicError, match=r"\['R1_hip', 'R2_hip', 'R3_hip'\]"):
        read_run(bags['left_only'])
    code, doc = _slip(tmp_path, bags['left_only'], 'left_only')
    # was: 15 stances fitted, the right tripod's speed being L2's alone
    assert code == 2 and not doc["stances"]
    assert "never names joint(s) ['R1_hip', 'R2_hip', 'R3_hip']" in doc['failed_bags'][0]['error']
