"""Motion capture broadcast as tf: a lab whose bags have no pose topic, only ``/tf`` carrying
``world -> base_link`` among other transforms (odometry, the legs).

``hexapod-analyze --mocap-tf world:base_link slip BAG`` reads that transform as
``/mocap/body``: the same stances and fits as the bag with the pose topic, from rosbag2 and
ROS 1 bags alike. A pair that /tf does not hold is refused in one line naming those it has.
Before, such a bag was refused for lacking ``/mocap/body``.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hexapod_common.analyze_cli import main as analyze
from hexapod_common.bags import BagWriter, iter_messages, new_msg, open_reader

edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')

TF = 'tf2_msgs/msg/TFMessage'
TS = 'geometry_msgs/msg/TransformStamped'


def _as_tf(src: Path, dst: Path) -> Path:
    """The bag with ``/mocap/body`` replaced by ``/tf`` messages holding ``odom -> base_link``
    (a drifting odometry) and ``world -> base_link`` (the motion capture), in that order, plus
    a leg's transform on every other message."""
    with open_reader(src) as reader, BagWriter(dst) as w:
        for k, m in enumerate(iter_messages(reader)):
            if m.topic != '/mocap/body':
                w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
                continue
            pose = reader.deserialize(m.data, m.msgtype)
            p, q = pose.pose.position, pose.pose.orientation

            def tr(parent, child, dx=0.0):
                return new_msg(TS, header=new_msg('std_msgs/msg/Header', stamp=pose.header.stamp,
                                                  frame_id=parent),
                               child_frame_id=child, transform=new_msg(
                                   'geometry_msgs/msg/Transform',
                                   translation=new_msg('geometry_msgs/msg/Vector3',
                                                       x=p.x + dx, y=p.y, z=p.z),
                                   rotation=new_msg('geometry_msgs/msg/Quaternion',
                                                    x=q.x, y=q.y, z=q.z, w=q.w)))
            transforms = [tr('odom', 'base_link', 0.01 * k), tr('/world', 'base_link')]
            if k % 2:
                transforms.append(tr('base_link', 'L1_leg'))
            w.write('/tf', TF, new_msg(TF, transforms=transforms), m.stamp_ns)
    return dst


def _slip(bag: Path, out: Path, *pre: str) -> dict:
    """slip.json of ``slip`` on ``bag`` (exit 0), without figures (--no-plots): these tests
    read slip.json only."""
    assert analyze([*pre, 'slip', str(bag), '--out', str(out), '--no-plots']) == 0
    return json.loads((out / 'slip.json').read_text())


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('tf')
    ref = edubot_bag.write_edubot_bag(root / 'ref', 'running', duration_s=3.0, seed=1)
    return root, ref, _as_tf(ref, root / 'tf')


@pytest.fixture(scope='module')
def ref_doc(bags):
    """slip.json of the bag with the pose topic, the reference of the rosbag2 and the ROS 1
    tf bags alike (one analysis for both)."""
    root, ref_bag, _ = bags
    return _slip(ref_bag, root / 'ref_out')


def test_slip_reads_the_pose_from_tf(bags, ref_doc, capsys):
    root, _, tf_bag = bags
    ref = ref_doc
    got = _slip(tf_bag, root / 'tf_out', '--mocap-tf', 'world:base_link')
    assert len(ref['stances']) >= 5
    assert [s['touchdown'] for s in got['stances']] == [s['touchdown'] for s in ref['stances']]
    assert [s['stiffness'] for s in got['stances']] == [s['stiffness'] for s in ref['stances']]
    # without the option: refused, naming the missing topic
    assert analyze(['slip', str(tf_bag), '--out', str(root / 'plain')]) != 0
    err = json.loads((root / 'plain' / 'slip.json').read_text())['failed_bags'][0]['error']
    assert "lacks topic(s) ['/mocap/body']" in err and '--mocap-tf PARENT:CHILD' in err
    # a pair /tf does not hold: one line naming those it has
    assert analyze(['--mocap-tf', 'map:base_link', 'slip', str(tf_bag), '--out',
                    str(root / 'wrong')]) != 0
    doc = json.loads((root / 'wrong' / 'slip.json').read_text())
    err = doc['failed_bags'][0]['error']
    assert 'no transform map -> base_link' in err and '/world -> base_link' in err
    assert '\n' not in err
    with pytest.raises(SystemExit) as exc:
        analyze(['--mocap-tf', 'base_link', 'slip', str(tf_bag), '--out', str(root / 'bad')])
    assert exc.value.code == 2
    assert 'PARENT:CHILD' in capsys.readouterr().err


def test_ros1_bag_with_tf(bags, ref_doc):
    from rosbags.typesys import get_types_from_msg
    from test_outside_ros1 import ROS1

    if TF not in ROS1.types:   # not in rosbags' Noetic store: tf2_msgs' ROS 1 definition
        ROS1.register(get_types_from_msg('geometry_msgs/TransformStamped[] transforms', TF))
    from rosbags.rosbag1 import Writer as Ros1Writer
    from test_outside_ros1 import _to_ros1

    root, _, tf_bag = bags
    bag1 = root / 'tf.bag'
    with open_reader(tf_bag) as reader, Ros1Writer(bag1) as writer:
        conns: dict = {}
        for m in iter_messages(reader, ['/joint_states', '/joint_commands', '/tf',
                                        '/battery_state']):
            msg = reader.deserialize(m.data, m.msgtype)
            if m.topic not in conns:
                conns[m.topic] = writer.add_connection(m.topic, m.msgtype, typestore=ROS1)
            ros1 = (ROS1.types[TF](transforms=[_to_ros1(t, TS) for t in msg.transforms])
                    if m.msgtype == TF else _to_ros1(msg, m.msgtype))
            writer.write(conns[m.topic], m.stamp_ns, ROS1.serialize_ros1(ros1, m.msgtype))
    got = _slip(bag1, root / 'ros1', '--mocap-tf', 'world:base_link')
    assert [s['touchdown'] for s in got['stances']] == \
        [s['touchdown'] for s in ref_doc['stances']]


def test_truncated_bags_are_refused_in_one_line(bags, capsys):
    """A bag cut short (a recorder killed, a copy interrupted): ``slip`` lists it under
    ``failed_bags`` and ``energy`` exits with one line; both crashed with a traceback (the
    bag reader's error was not one the commands caught)."""
    import shutil

    root, ref_bag, _ = bags
    cut = root / 'cut'
    shutil.copytree(ref_bag, cut)
    data = next(p for p in cut.iterdir() if p.suffix == '.mcap')
    raw = data.read_bytes()
    data.write_bytes(raw[:len(raw) // 2])
    assert analyze(['slip', str(cut), '--out', str(root / 'cut_out')]) == 2
    doc = json.loads((root / 'cut_out' / 'slip.json').read_text())
    assert 'cut' in doc['failed_bags'][0]['bag'] and '\n' not in doc['failed_bags'][0]['error']
    from test_energy_cli import _write_bench
    _write_bench(root / 'bench_ok')
    code = analyze(['energy', '--bench', str(root / 'bench_ok'), '--robot', str(cut),
                    '--out', str(root / 'cut_energy')])
    err = capsys.readouterr().err
    assert code != 0 and 'cannot read bag' in err and 'Traceback' not in err


def test_an_unforeseen_failure_is_one_line(monkeypatch, capsys, tmp_path):
    """A bug or an input nobody foresaw (here an AttributeError from a reader): one line with
    the exception and how to get the traceback, exit 1; HEXAPOD_DEBUG=1 raises it."""
    import slip_identification.cli as slip_cli

    def broken(path):
        raise AttributeError("'GaitPhase' object has no attribute 'supporting_legs'")

    monkeypatch.setattr(slip_cli, 'read_run', broken)
    monkeypatch.setattr(slip_cli, 'analyze_bag', lambda path, options: broken(path))
    argv = ['slip', str(tmp_path), '--out', str(tmp_path / 'o')]
    assert analyze(argv) == 1
    err = capsys.readouterr().err
    assert "failed: AttributeError: 'GaitPhase' object" in err and 'HEXAPOD_DEBUG=1' in err
    monkeypatch.setenv('HEXAPOD_DEBUG', '1')
    with pytest.raises(AttributeError):
        analyze(argv)


def test_energy_points_to_mocap_tf_when_the_bag_has_tf_only(bags, monkeypatch):
    """An outside review: `energy` on such a bag gave a null speed without pointing to
    --mocap-tf as `slip` does; now its notes say it, and not once the option is given."""
    from hexapod_common.conversions import MOCAP_TF_ENV
    from hexapod_energy.bag_io import read_robot_bag

    _, _, tf_bag = bags
    monkeypatch.delenv(MOCAP_TF_ENV, raising=False)
    run = read_robot_bag(tf_bag, mass_kg=3.31)
    assert any('--mocap-tf PARENT:CHILD' in n for n in run.extra['notes'])
    # what hexapod-analyze --mocap-tf world:base_link sets
    from hexapod_common.bags import REMAP_ENV
    monkeypatch.setenv(MOCAP_TF_ENV, 'world:base_link')
    monkeypatch.setenv(REMAP_ENV, json.dumps({'remap': {'/tf': '/mocap/body'},
                                              'namespace': ''}))
    run = read_robot_bag(tf_bag, mass_kg=3.31)
    assert not any('--mocap-tf PARENT:CHILD' in n for n in run.extra['notes'])
    assert run.speed_mps > 0.3
