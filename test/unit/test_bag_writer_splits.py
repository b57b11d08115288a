"""BagWriter's metadata over many splits: merged in place, written as JSON (which is YAML), and
read back exactly by rosbags (an outside review: re-dumping every split's entry with ruamel
made each flush cost 0.4 ms more per split so far; the recorder fell behind after 10-20 min)."""

from __future__ import annotations

import json

import pytest

from ruamel.yaml import YAML

from hexapod_common.bags import BagWriter, new_msg, open_reader, stamp


def _battery(t_ns: int):
    return new_msg('sensor_msgs/msg/BatteryState', header=stamp(t_ns), voltage=12.0,
                   current=-1.0)


def test_metadata_over_splits_with_an_empty_one(tmp_path):
    bag = tmp_path / 'b'
    t = 5_000_000_000
    with BagWriter(bag) as w:
        for split in range(6):
            if split == 2:
                w._ensure_writer()          # a split that closes with nothing in it
            else:
                for _ in range(10):
                    w.write('/battery_state', 'sensor_msgs/msg/BatteryState', _battery(t), t)
                    if split == 4:
                        w.write('/other', 'sensor_msgs/msg/BatteryState', _battery(t), t)
                    t += 10_000_000
            w.flush()
    text = (bag / 'metadata.yaml').read_text()
    info = json.loads(text)['rosbag2_bagfile_information']        # JSON ...
    assert YAML(typ='safe').load(text)['rosbag2_bagfile_information'] == info   # ... is YAML
    assert len(info['files']) == len(info['relative_file_paths']) == 6
    assert info['message_count'] == 60
    counts = {x['topic_metadata']['name']: x['message_count']
              for x in info['topics_with_message_count']}
    assert counts == {'/battery_state': 50, '/other': 10}
    assert info['starting_time']['nanoseconds_since_epoch'] == 5_000_000_000
    assert info['duration']['nanoseconds'] == 49 * 10_000_000
    with open_reader(bag) as reader:
        assert reader.message_count == 60
        assert reader.start_time == 5_000_000_000
        stamps = [m[1] for m in reader.messages()]
    assert len(stamps) == 60 and stamps == sorted(stamps)


def _interrupt_once(monkeypatch, owner, name, *, after: bool):
    """``owner.name`` raises KeyboardInterrupt once (a second Ctrl-C), before or after running."""
    original = getattr(owner, name)
    calls = []

    def patched(*args, **kwargs):
        calls.append(1)
        if len(calls) == 1 and not after:
            raise KeyboardInterrupt
        result = original(*args, **kwargs)
        if len(calls) == 1:
            raise KeyboardInterrupt
        return result
    monkeypatch.setattr(owner, name, patched)
    return calls


@pytest.mark.parametrize('where', ['after the split closed', 'in the merge',
                                   'in the metadata write'])
def test_a_close_interrupted_then_called_again_keeps_every_split(tmp_path, monkeypatch, where):
    """A second SIGINT during the recorder's close raised KeyboardInterrupt between the split's
    close and its merge; close() again opened `.split_0` anew (WriterError, exit 1, no
    metadata.yaml) or, later in a recording, dropped the last split and left `.split_N` (an
    outside review). Now close() again finishes the cut split."""
    from rosbags.rosbag2 import Writer

    from hexapod_common import bags

    bag = tmp_path / 'b'
    w = BagWriter(bag)
    t = 1_000_000_000
    for split in range(2):
        for _ in range(5):
            w.write('/battery_state', 'sensor_msgs/msg/BatteryState', _battery(t), t)
            t += 10_000_000
        if split == 0:
            w.flush()
    if where == 'after the split closed':
        calls = _interrupt_once(monkeypatch, Writer, 'close', after=True)
    elif where == 'in the merge':
        calls = _interrupt_once(monkeypatch, bags, '_merge_info', after=False)
    else:   # merged in memory, metadata.yaml not yet replaced: merged twice (review J5)
        from pathlib import Path
        calls, original = [], Path.write_text

        def write_text(self, *args, **kwargs):
            result = original(self, *args, **kwargs)
            if self == bag / 'metadata.yaml.tmp' and not calls:
                calls.append(self)
                raise KeyboardInterrupt
            return result
        monkeypatch.setattr(Path, 'write_text', write_text)
    with pytest.raises(KeyboardInterrupt):
        w.close()
    w.close()          # what close_node's retry does
    w.close()          # and idempotent after that
    assert calls
    assert sorted(p.name for p in bag.iterdir()) == ['b_0.mcap', 'b_1.mcap', 'metadata.yaml']
    with open_reader(bag) as reader:
        assert reader.message_count == 10
        assert len(list(reader.messages())) == 10
