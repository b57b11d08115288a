"""metadata.yaml that disagrees with its storage, and type hashes that are not their
definitions' (outside review of other labs' bags, defects 3 and 5).

rosbags pairs each storage connection with a metadata.yaml topic by topic, type, type hash and
the parsed offered QoS; a topic whose QoS is written differently in metadata.yaml (another
tool, another distro, a hand merge) was read as empty, silently. A stored type hash that is
not its definition's made the whole bag unreadable. The bags here are written with the rosbags
Writer, then metadata.yaml is edited as those tools leave it.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
from rosbags.interfaces import (
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore
from ruamel.yaml import YAML

from hexapod_common.bags import (
    iter_messages,
    new_msg,
    open_reader,
    stamp,
    typestore,
)
from hexapod_common.errors import BagReadError
from hexapod_common.testbags import write_two_battery_robot_bag

INF = QosTime(9223372036, 854775807)           # Jazzy's infinite duration
FOXY_INF = QosTime(2147483647, 4294967295)      # as Foxy/Galactic wrote it
FOREIGN = 'RIHS01_' + '0123456789abcdef' * 4
T0 = 1_700_000_000_000_000_000
N_JOINT, N_BATTERY = 20, 10


def _qos(reliability: QosReliability, depth: int = 10, inf: QosTime = INF) -> Qos:
    return Qos(QosHistory.UNKNOWN, depth, reliability, QosDurability.VOLATILE, inf, inf,
               QosLiveliness.AUTOMATIC, inf, False)


QOS = {'/joint_states': [_qos(QosReliability.RELIABLE), _qos(QosReliability.BEST_EFFORT, 5)],
       '/battery_state': [_qos(QosReliability.BEST_EFFORT, 5)]}
TYPES = {'/joint_states': 'sensor_msgs/msg/JointState',
         '/battery_state': 'sensor_msgs/msg/BatteryState'}


def _write(path: Path, storage: str = 'mcap', *, digest: dict[str, str] | None = None,
           msgdefs: dict[str, str] | None = None, empty: tuple[str, ...] = (),
           qos: dict[str, list[Qos]] | None = None, t0: int = T0) -> Path:
    """A small bag as ``ros2 bag record`` writes it: QoS lists, definitions, type hashes.

    ``digest`` replaces a type's stored hash (definition kept), ``msgdefs`` gives a topic
    another definition (its messages are then written as that definition says), ``empty``
    adds topics (PoseStamped) without messages, ``qos`` replaces topics' offered QoS."""
    store = typestore()
    qos = {**QOS, **(qos or {})}
    plugin = StoragePlugin.MCAP if storage == 'mcap' else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as w:
        conns = {}
        for topic, msgtype in TYPES.items():
            kw: dict = {'typestore': store}
            if msgdefs and topic in msgdefs:
                kw = {'msgdef': msgdefs[topic], 'rihs01': FOREIGN}
            elif digest and msgtype in digest:
                md, _ = store.generate_msgdef(msgtype, ros_version=2)
                kw = {'msgdef': md, 'rihs01': digest[msgtype]}
            conns[topic] = w.add_connection(topic, msgtype, offered_qos_profiles=qos[topic],
                                            **kw)
        for topic in empty:
            w.add_connection(topic, 'geometry_msgs/msg/PoseStamped', typestore=store,
                             offered_qos_profiles=[_qos(QosReliability.BEST_EFFORT)])
        for k in range(N_JOINT):
            t = t0 + k * 10_000_000
            q = np.sin(0.1 * k + np.arange(3))
            msg = new_msg('sensor_msgs/msg/JointState', header=stamp(t), name=['a', 'b', 'c'],
                          position=q, velocity=q, effort=q)
            w.write(conns['/joint_states'], t, store.serialize_cdr(msg, TYPES['/joint_states']))
            if k % 2 == 0:
                if msgdefs and '/battery_state' in msgdefs:
                    other = get_typestore(Stores.EMPTY)
                    other.register(get_types_from_msg(msgdefs['/battery_state'],
                                                      TYPES['/battery_state']))
                    cls = other.types[TYPES['/battery_state']]
                    data = other.serialize_cdr(cls(voltage=12.0, current=-1.0),
                                               TYPES['/battery_state'])
                else:
                    data = store.serialize_cdr(new_msg(
                        'sensor_msgs/msg/BatteryState', header=stamp(t), voltage=12.0,
                        current=-1.0), TYPES['/battery_state'])
                w.write(conns['/battery_state'], t + 1000, data)
    return path


def _edit_metadata(path: Path, edit) -> None:
    yaml = YAML()
    yaml.default_flow_style = False
    p = path / 'metadata.yaml'
    doc = yaml.load(p.read_text())
    edit(doc['rosbag2_bagfile_information'])
    with p.open('w') as f:
        yaml.dump(doc, f)


def _topic(info, name: str) -> dict:
    return next(t for t in info['topics_with_message_count']
                if t['topic_metadata']['name'] == name)


def _counts(path: Path) -> tuple[dict[str, int], list[str]]:
    with open_reader(path) as reader:
        counts: dict[str, int] = {}
        for m in iter_messages(reader):
            counts[m.topic] = counts.get(m.topic, 0) + 1
        return counts, list(reader.notes)


FULL = {'/joint_states': N_JOINT, '/battery_state': N_BATTERY}


# -- defect 3: metadata.yaml and storage disagree on a topic's QoS ----------------------------

@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_one_topic_with_another_depth_in_metadata_is_read_with_a_note(tmp_path, storage):
    bag = _write(tmp_path / 'bag', storage)
    assert _counts(bag) == (FULL, [])     # as written: nothing to note

    def depth(info):
        _topic(info, '/joint_states')['topic_metadata']['offered_qos_profiles'][0]['depth'] += 1
    _edit_metadata(bag, depth)
    counts, notes = _counts(bag)
    assert counts == FULL                 # was {'/battery_state': 10}: /joint_states empty
    assert len(notes) == 1
    assert '/joint_states' in notes[0] and '/battery_state' not in notes[0]
    assert 'depth of profile 1: 11 in metadata.yaml, 10 in the storage' in notes[0]
    assert 'ros2 bag reindex' in notes[0]


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_infinite_durations_written_the_foxy_way_in_metadata(tmp_path, storage):
    """Every topic's deadline, lifespan and lease as 2147483647 s 4294967295 ns in
    metadata.yaml (regenerated by an older tool), the storage's as Jazzy writes them."""
    bag = _write(tmp_path / 'bag', storage)

    def foxy(info):
        for t in info['topics_with_message_count']:
            for q in t['topic_metadata']['offered_qos_profiles']:
                for key in ('deadline', 'lifespan', 'liveliness_lease_duration'):
                    q[key] = {'sec': FOXY_INF.sec, 'nsec': FOXY_INF.nsec}
    _edit_metadata(bag, foxy)
    counts, notes = _counts(bag)
    assert counts == FULL                 # was {}: every topic empty
    assert len(notes) == 1
    assert '/joint_states' in notes[0] and '/battery_state' in notes[0]
    assert '2147483647 s 4294967295 ns in metadata.yaml' in notes[0]


def test_humble_qos_string_in_metadata_only(tmp_path):
    """Humble's QoS string (one profile, integer enums) in metadata.yaml beside a storage
    written with Jazzy's profiles."""
    bag = _write(tmp_path / 'bag', 'sqlite3')

    def humble(info):
        info['version'] = 5
        for t in info['topics_with_message_count']:
            t['topic_metadata'].pop('type_description_hash', None)
            t['topic_metadata']['offered_qos_profiles'] = (
                '- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n'
                '    sec: 9223372036\n    nsec: 854775807\n  lifespan:\n    sec: 9223372036\n'
                '    nsec: 854775807\n  liveliness: 1\n  liveliness_lease_duration:\n'
                '    sec: 9223372036\n    nsec: 854775807\n'
                '  avoid_ros_namespace_conventions: false')
    _edit_metadata(bag, humble)
    counts, notes = _counts(bag)
    assert counts == FULL
    assert len(notes) == 1 and '1 profile(s) in metadata.yaml, 2 in the storage' in notes[0]


def test_split_bag_with_one_file_disagreeing(tmp_path):
    """Two storage files; only the second one's /battery_state QoS differs from
    metadata.yaml's (its publisher set up with another depth)."""
    def split(second_qos):
        a = _write(tmp_path / 'a')
        b = _write(tmp_path / 'b', t0=T0 + 10**9, qos=second_qos)
        bag = tmp_path / 'bag'
        bag.mkdir()
        shutil.move(next(a.glob('*.mcap')), bag / 'bag_0.mcap')
        shutil.move(next(b.glob('*.mcap')), bag / 'bag_1.mcap')
        yaml = YAML()
        doc = yaml.load((a / 'metadata.yaml').read_text())
        info = doc['rosbag2_bagfile_information']
        info['relative_file_paths'] = ['bag_0.mcap', 'bag_1.mcap']
        info['files'] = [dict(info['files'][0], path='bag_0.mcap'),
                         dict(info['files'][0], path='bag_1.mcap')]
        info['duration']['nanoseconds'] += 10**9
        info['message_count'] *= 2
        for t in info['topics_with_message_count']:
            t['message_count'] *= 2
        with (bag / 'metadata.yaml').open('w') as f:
            yaml.dump(doc, f)
        shutil.rmtree(a)
        shutil.rmtree(b)
        return bag

    both = {k: 2 * v for k, v in FULL.items()}
    assert _counts(split(None)) == (both, [])
    shutil.rmtree(tmp_path / 'bag')
    bag = split({'/battery_state': [_qos(QosReliability.BEST_EFFORT, 7)]})
    counts, notes = _counts(bag)
    assert counts == both                 # was 10 /battery_state: the second file's left out
    assert len(notes) == 1
    assert '/battery_state (offered QoS depth: 5 in metadata.yaml, 7 in the storage)' in notes[0]


def test_bag_replay_source_reads_the_topic_and_warns(tmp_path):
    pytest.importorskip('rclpy')
    from hexapod_common.replay import ReplaySource

    bag = _write(tmp_path / 'bag')

    def depth(info):
        _topic(info, '/battery_state')['topic_metadata']['offered_qos_profiles'][0]['depth'] = 1
    _edit_metadata(bag, depth)
    warnings: list[str] = []
    with ReplaySource(str(bag), warn=warnings.append) as source:
        got: dict[str, int] = {}
        for m in source.messages():
            got[m.topic] = got.get(m.topic, 0) + 1
    assert got == FULL
    assert len(warnings) == 1 and '/battery_state' in warnings[0]


def test_energy_figures_unchanged_by_a_qos_mismatch(tmp_path):
    from hexapod_energy.bag_io import read_robot_bag

    ref = tmp_path / 'ref'
    # the project's writer: no offered QoS in metadata.yaml nor in the storage
    write_two_battery_robot_bag(ref)
    bag = tmp_path / 'bag'
    shutil.copytree(ref, bag)

    def qos(info):   # metadata.yaml regenerated by a tool that writes a default profile
        _topic(info, '/battery_state')['topic_metadata']['offered_qos_profiles'] = [
            {'history': 'keep_last', 'depth': 10, 'reliability': 'reliable',
             'durability': 'volatile', 'deadline': {'sec': 0, 'nsec': 0},
             'lifespan': {'sec': 0, 'nsec': 0}, 'liveliness': 'automatic',
             'liveliness_lease_duration': {'sec': 0, 'nsec': 0},
             'avoid_ros_namespace_conventions': False}]
    _edit_metadata(bag, qos)
    want = read_robot_bag(ref, mass_kg=2.2)
    got = read_robot_bag(bag, mass_kg=2.2)   # raised: no /battery_state message
    assert got.power_in_w == pytest.approx(want.power_in_w, rel=1e-12)
    assert got.windows == want.windows
    new = [n for n in got.extra['notes'] if n not in want.extra['notes']]
    assert len(new) == 1 and '/battery_state' in new[0] and 'offered QoS' in new[0]


# -- what cannot be paired: an error naming the topic, the counts and `ros2 bag reindex` -----

def test_another_type_in_metadata_is_refused_naming_topic_and_counts(tmp_path):
    bag = _write(tmp_path / 'bag')

    def retype(info):
        _topic(info, '/battery_state')['topic_metadata']['type'] = 'sensor_msgs/msg/Imu'
    _edit_metadata(bag, retype)
    with open_reader(bag) as reader:
        # the other topics read as before
        assert sum(1 for _ in iter_messages(reader, ['/joint_states'])) == N_JOINT
        with pytest.raises(BagReadError) as err:
            list(iter_messages(reader, ['/battery_state']))   # was: nothing, silently
    text = str(err.value)
    assert f'counts {N_BATTERY} /battery_state' in text
    assert 'sensor_msgs/msg/Imu in metadata.yaml' in text
    assert 'ros2 bag reindex' in text


def test_topic_counted_in_metadata_but_in_no_storage_file(tmp_path):
    bag = _write(tmp_path / 'bag')

    def add(info):
        entry = {'message_count': 5, 'topic_metadata': dict(
            _topic(info, '/battery_state')['topic_metadata'], name='/mocap/body',
            type='geometry_msgs/msg/PoseStamped')}
        info['topics_with_message_count'].append(entry)
    _edit_metadata(bag, add)
    with open_reader(bag) as reader:
        with pytest.raises(BagReadError, match=r'counts 5 /mocap/body .*no storage file has '
                                               r'the topic.*ros2 bag reindex'):
            list(iter_messages(reader))


def test_counted_topic_that_gives_no_message_is_an_error(tmp_path):
    """The storage declares the topic but holds none of the messages metadata.yaml counts."""
    bag = _write(tmp_path / 'bag', empty=('/mocap/body',))

    def count(info):
        _topic(info, '/mocap/body')['message_count'] = 5
    _edit_metadata(bag, count)
    with open_reader(bag) as reader:
        with pytest.raises(BagReadError, match=r'counts 5 /mocap/body message\(s\) but the '
                                               r'storage gave none.*ros2 bag reindex'):
            list(iter_messages(reader, ['/mocap/body', '/joint_states']))
        # a window of the bag: no claim about the whole topic
        start = reader.start_time + 1
        assert sum(1 for _ in iter_messages(reader, ['/mocap/body'], start_ns=start)) == 0


# -- defect 5: a stored type hash that is not its definition's -------------------------------

@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_foreign_hash_with_jazzy_fields_is_read_with_a_note(tmp_path, storage):
    bag = _write(tmp_path / 'bag', storage, digest={'sensor_msgs/msg/JointState': FOREIGN})
    counts, notes = _counts(bag)          # was: BagReadError "... hash mismatch ..."
    assert counts == FULL
    assert len(notes) == 1
    assert 'sensor_msgs/msg/JointState on /joint_states' in notes[0]
    assert 'same fields' in notes[0] and 'BatteryState' not in notes[0]


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_type_hash_only_in_metadata_differs(tmp_path, storage):
    bag = _write(tmp_path / 'bag', storage)

    def rehash(info):
        _topic(info, '/battery_state')['topic_metadata']['type_description_hash'] = FOREIGN
    _edit_metadata(bag, rehash)
    counts, notes = _counts(bag)          # was: BagReadError "... hash mismatch ..."
    assert counts == FULL
    assert len(notes) == 1
    assert 'sensor_msgs/msg/BatteryState' in notes[0] and '/battery_state' in notes[0]
    assert 'RIHS01_0123456789ab' in notes[0]


def test_foreign_hash_of_a_definition_with_other_fields_is_refused(tmp_path):
    bag = _write(tmp_path / 'bag', msgdefs={'/battery_state': 'float32 voltage\n'
                                                              'float32 current\n'})
    with pytest.raises(BagReadError) as err:
        open_reader(bag)
    text = str(err.value)
    assert 'topic /battery_state' in text and 'sensor_msgs/msg/BatteryState' in text
    assert "fields ['voltage', 'current'] in the bag" in text
    assert 'ros2 bag reindex' in text and 're-record' in text


def test_topics_absent_from_the_bag_yield_nothing(tmp_path):
    """Asked only for topics the bag lacks, rosbags (given no connection) read every topic."""
    bag = _write(tmp_path / 'bag')
    with open_reader(bag) as reader:
        assert list(iter_messages(reader, ['/mocap/body'])) == []    # was all 30 messages
        assert sum(1 for _ in iter_messages(reader, ['/battery_state'])) == N_BATTERY
