"""Bags: the typestore, the split writer, the reader's typed errors, other tools' bags."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hexapod_common.bags import BagWriter, iter_messages, new_msg, open_reader, stamp, typestore
from hexapod_common.conversions import battery_from_msg, joint_state_from_msg
from hexapod_common.errors import BagExistsError, BagNotFoundError, BagReadError
from hexapod_common.testbags import write_mixed_bag

THIRD_PARTY = Path(__file__).resolve().parents[3] / 'shared' / 'thirdparty-bags'


def test_custom_types_registered_from_msg_text():
    store = typestore()
    for name in ('GaitPhase', 'ServoStatus', 'BenchSession', 'EnergeticDescriptors', 'SlipFit'):
        assert f'hexapod_interfaces/msg/{name}' in store.types
    fields = [f[0] for f in store.fielddefs['hexapod_interfaces/msg/SlipFit'][1]]
    assert fields[:4] == ['header', 'liftoff', 'tripod', 'model']
    assert fields[-3:] == ['nerr', 'samples', 'converged']


@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_split_writer_merges_metadata_and_keeps_every_message(tmp_path, storage):
    bag = tmp_path / 'b'
    with BagWriter(bag, storage=storage, split_every_s=0.0) as writer:
        writer.set_custom_data('hexapod_sim.effects', '{"basal_power": 1.0}')
        for k in range(7):
            msg = new_msg('sensor_msgs/msg/BatteryState', header=stamp(k * 10**7),
                          voltage=12.0, current=-1.0 - k)
            writer.write('/battery_state', 'sensor_msgs/msg/BatteryState', msg, k * 10**7)
        writer.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase',
                     new_msg('hexapod_interfaces/msg/GaitPhase', gait='wave'), 10**8)
    files = sorted(p.name for p in bag.iterdir() if p.suffix in ('.mcap', '.db3'))
    assert len(files) == 8
    with open_reader(bag) as reader:
        assert reader.message_count == 8
        assert reader.duration == 10**8 + 1
        msgs = list(iter_messages(reader))
        currents = [battery_from_msg(reader.deserialize(m.data, m.msgtype)).current_a
                    for m in msgs if m.topic == '/battery_state']
    assert currents == [-1.0 - k for k in range(7)]
    meta = (bag / 'metadata.yaml').read_text()
    assert 'hexapod_sim.effects' in meta


def test_writer_refuses_to_overwrite(tmp_path):
    write_mixed_bag(tmp_path / 'x', 9)
    with pytest.raises(BagExistsError, match='refusing to overwrite'):
        BagWriter(tmp_path / 'x')


def test_reader_errors_are_typed_and_name_the_path(tmp_path):
    with pytest.raises(BagNotFoundError, match='no such bag'):
        open_reader(tmp_path / 'missing')
    (tmp_path / 'plain').mkdir()
    with pytest.raises(BagReadError, match='no metadata.yaml'):
        open_reader(tmp_path / 'plain')


def test_mcap_files_without_metadata_are_read_with_a_note(tmp_path):
    """A recording whose metadata.yaml was lost (copied without it, or killed before rosbag2
    wrote it): the mcap splits carry their own schemas, so every message is still read; sqlite3
    splits cannot be read without it and are refused with the fix named."""
    bag = tmp_path / 'b'
    with BagWriter(bag, storage='mcap', split_every_s=0.0) as writer:
        for k in range(5):
            msg = new_msg('sensor_msgs/msg/BatteryState', header=stamp(k * 10**7),
                          voltage=12.0, current=-1.0 - k)
            writer.write('/battery_state', 'sensor_msgs/msg/BatteryState', msg, k * 10**7)
    (bag / 'metadata.yaml').unlink()
    with open_reader(bag) as reader:
        currents = [battery_from_msg(reader.deserialize(m.data, m.msgtype)).current_a
                    for m in iter_messages(reader)]
        assert reader.notes and 'no metadata.yaml' in reader.notes[0]
    assert currents == [-1.0 - k for k in range(5)]
    db = tmp_path / 'd'
    with BagWriter(db, storage='sqlite3') as writer:
        writer.write('/battery_state', 'sensor_msgs/msg/BatteryState',
                     new_msg('sensor_msgs/msg/BatteryState', voltage=12.0), 1)
    (db / 'metadata.yaml').unlink()
    with pytest.raises(BagReadError, match='ros2 bag reindex'):
        open_reader(db)


def test_new_msg_fills_defaults_and_rejects_unknown_fields():
    msg = new_msg('sensor_msgs/msg/JointState', name=['a'], position=[1.5])
    assert msg.position.dtype == np.float64 and msg.velocity.size == 0
    sample = joint_state_from_msg(msg)
    assert sample.names == ('a',) and sample.position.tolist() == [1.5]
    with pytest.raises(TypeError, match='no field'):
        new_msg('sensor_msgs/msg/JointState', torque=[1.0])


@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason='shared/thirdparty-bags not present')
@pytest.mark.parametrize('name', ['rosbags-rs_test_bag_sqlite3', 'rosbags-rs_test_bag_mcap',
                                  'plotjuggler_rosbag2_test'])
def test_other_tools_bags_are_read(name):
    with open_reader(THIRD_PARTY / name) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        battery = [c for c in reader.connections
                   if c.msgtype == 'sensor_msgs/msg/BatteryState']
        assert battery, topics
        first = next(iter_messages(reader, topics=[battery[0].topic]))
        sample = battery_from_msg(reader.deserialize(first.data, first.msgtype))
    assert np.isfinite(sample.voltage_v)
