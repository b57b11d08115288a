"""A recording cut short (a recorder killed, a disk full, a copy interrupted) leaves its last
mcap file without footer and summary. rosbags refuses such a file ("File end magic is
invalid"), so the whole bag was refused, the intact splits with it (an outside review). The
complete records of the cut file are now read, noted (`bags.salvage_mcap`)."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.bags import iter_messages, mcap_is_complete, open_reader, salvage_mcap
from hexapod_common.errors import BagReadError
from hexapod_common.testbags import P0_W
from hexapod_common.testbags import write_foreign_robot_bag as write_outside_bag
from hexapod_energy.bag_io import read_robot_bag


def _stamps(bag):
    with open_reader(bag) as reader:
        got = [(m.topic, m.stamp_ns) for m in iter_messages(reader)]
        dirs = list(reader.salvage_dirs)
    # the salvaged copies live in a temporary directory removed on close
    assert not any(d.exists() for d in dirs)
    return got, list(reader.notes)


@pytest.fixture(scope='module')
def long_bag(tmp_path_factory):
    """A 40 s mcap robot bag of another lab (1.4 MiB: one complete 1 MiB chunk), its
    receive order swapped every 5 messages (log times out of order, as a recorder with
    several threads writes them: rosbags refuses such a file without an index)."""
    bag = tmp_path_factory.mktemp('cut') / 'bag'
    write_outside_bag(bag, legs=6, duration_s=40.0, storage='mcap', swap_every=5)
    return bag


def test_a_salvaged_whole_file_reads_every_message(long_bag, tmp_path):
    """The salvaged copy's own summary (chunk and message indexes, statistics) indexes
    every message of a file that was not cut: the same messages, in the same order."""
    [f] = sorted(long_bag.glob('*.mcap'))
    (tmp_path / 'copy').mkdir()
    kept, size = salvage_mcap(f, tmp_path / 'copy' / f.name)
    assert size == f.stat().st_size and kept < size   # the original's summary is not copied
    full, _ = _stamps(long_bag)
    got, _ = _stamps(tmp_path / 'copy')
    assert got == full


def test_a_cut_short_mcap_bag_reads_its_complete_chunks(long_bag, tmp_path):
    import shutil

    bag = tmp_path / 'cut'
    shutil.copytree(long_bag, bag)
    [f] = sorted(bag.glob('*.mcap'))
    data = f.read_bytes()
    f.write_bytes(data[:int(0.7 * len(data))])
    assert mcap_is_complete(long_bag / f.name) and not mcap_is_complete(f)
    full, _ = _stamps(long_bag)
    got, notes = _stamps(bag)
    # a prefix of the messages (whole chunks), in the same order
    assert 0.3 * len(full) < len(got) < 0.7 * len(full)
    assert got == full[:len(got)]
    [note] = [n for n in notes if 'cut short' in n]
    assert str(f) in note and 'complete records read' in note
    assert 'metadata.yaml ignored' in note
    run = read_robot_bag(bag, mass_kg=2.0)
    assert run.windows >= 4
    np.testing.assert_allclose(run.power_in_w, P0_W, rtol=3e-3)
    assert any('cut short' in n for n in run.extra['notes'])


def test_salvage_refuses_what_is_not_mcap_and_keeps_nothing_of_a_cut_first_chunk(tmp_path):
    (tmp_path / 'x.mcap').write_bytes(b'not an mcap file at all')
    with pytest.raises(BagReadError, match='not an mcap file'):
        salvage_mcap(tmp_path / 'x.mcap', tmp_path / 'y.mcap')
    write_outside_bag(tmp_path / 'small', legs=4, duration_s=4.0, storage='mcap')
    [f] = sorted((tmp_path / 'small').glob('*.mcap'))
    f.write_bytes(f.read_bytes()[:2000])   # inside the first (only) chunk
    kept, size = salvage_mcap(f, tmp_path / 'salvaged.mcap')
    assert kept < 1024 and size == 2000
    assert mcap_is_complete(tmp_path / 'salvaged.mcap')
    # nothing complete in the bag's only file: refused in one line, as before
    with pytest.raises(BagReadError, match='cut short .* before any complete record'):
        open_reader(tmp_path / 'small')
