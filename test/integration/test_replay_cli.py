"""bag_replay and bag_recorder as commands: bad input gives one clear line and a non-zero exit."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from ruamel.yaml import YAML

from hexapod_common.bags import BagWriter, open_reader
from hexapod_common.testbags import write_mixed_bag

BIN = Path(sys.executable).parent
ENV = dict(os.environ, PYTHONUNBUFFERED='1')


def run(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / args[0]), *args[1:]], capture_output=True, text=True,
                          timeout=timeout, env=ENV)


def assert_one_line_error(proc: subprocess.CompletedProcess, *words: str) -> None:
    assert proc.returncode != 0
    assert 'Traceback' not in proc.stderr, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if 'error' in ln]
    assert len(lines) == 1, proc.stderr
    for word in words:
        assert word in lines[0], lines[0]


@pytest.mark.timeout(60)
def test_missing_path(tmp_path):
    assert_one_line_error(run('bag_replay', str(tmp_path / 'nope')), 'no such bag')


@pytest.mark.timeout(60)
def test_folder_that_is_not_a_bag(tmp_path):
    (tmp_path / 'notes.txt').write_text('hello')
    assert_one_line_error(run('bag_replay', str(tmp_path)), 'not a rosbag2 bag')


@pytest.mark.timeout(60)
@pytest.mark.parametrize('storage', ['mcap', 'sqlite3'])
def test_truncated_bag(tmp_path, storage):
    bag = tmp_path / 'cut'
    write_mixed_bag(bag, 3000, storage=storage)
    data_file = next(p for p in bag.iterdir() if p.suffix in ('.mcap', '.db3'))
    size = data_file.stat().st_size
    with data_file.open('r+b') as fh:
        fh.truncate(size // 2)
    proc = run('bag_replay', str(bag))
    assert_one_line_error(proc, 'bag')
    # the file on disk is left as it was: replay never writes
    assert data_file.stat().st_size == size // 2


@pytest.mark.timeout(60)
def test_bag_with_only_unknown_types(tmp_path):
    bag = tmp_path / 'alien'
    msgdef = 'float64 torque_nm\nstring joint\n'
    from rosbags.typesys import get_types_from_msg
    from rosbags.typesys.store import Typestore

    from hexapod_common.bags import typestore
    store: Typestore = typestore()
    types = get_types_from_msg(msgdef, 'other_lab_msgs/msg/Torque')
    fresh = type(store)()
    fresh.register(store.fielddefs)
    fresh.register(types)
    with BagWriter(bag, store=fresh) as writer:
        msg = fresh.types['other_lab_msgs/msg/Torque'](torque_nm=1.5, joint='hip')
        writer.write('/torque', 'other_lab_msgs/msg/Torque', msg, 1_000)
    proc = run('bag_replay', str(bag))
    assert_one_line_error(proc, 'other_lab_msgs/msg/Torque')


@pytest.mark.timeout(60)
def test_recorder_refuses_to_overwrite(tmp_path):
    bag = tmp_path / 'exists'
    write_mixed_bag(bag, 30)
    before = sorted(p.name for p in bag.iterdir())
    proc = run('bag_recorder', '-o', str(bag))
    assert_one_line_error(proc, 'refusing to overwrite')
    assert proc.returncode == 2        # refused input, as every command (it said 1)
    assert sorted(p.name for p in bag.iterdir()) == before
    with open_reader(bag) as reader:
        assert reader.message_count == 30


def _flushed_message_count(bag: Path) -> int:
    """The bag's message count as its last flushed ``metadata.yaml`` states it (0 before)."""
    try:
        text = (bag / 'metadata.yaml').read_text()
    except FileNotFoundError:
        return 0
    return int(YAML(typ='safe').load(text)['rosbag2_bagfile_information']['message_count'])


@pytest.mark.timeout(120)
def test_recorder_killed_keeps_all_but_the_last_second(tmp_path):
    """SIGKILL once 1,000 messages at 100 Hz were flushed: the bag opens and holds them all.

    No fixed sleep: the test waits for the recorder's own flushed ``metadata.yaml`` to count
    1,000 messages (the recorder closes a split every second), then kills it; whatever a flush
    had stated before the kill must be readable after it.
    """
    bag = tmp_path / 'killed'
    topic = '/kill_test_' + str(os.getpid())
    rec = subprocess.Popen([str(BIN / 'bag_recorder'), '-o', str(bag), '--topics', topic],
                           env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    # a 100 Hz source (the publisher paces itself; the test waits on the recorder's output)
    pub = subprocess.Popen([sys.executable, '-c', f'''
import rclpy, time
from sensor_msgs.msg import BatteryState
rclpy.init()
n = rclpy.create_node("kill_pub")
p = n.create_publisher(BatteryState, "{topic}", 10)
t0 = time.monotonic(); k = 0
while time.monotonic() - t0 < 100:
    m = BatteryState(); m.voltage = 12.0; m.current = -1.0
    p.publish(m); k += 1
    time.sleep(max(0.0, t0 + k / 100 - time.monotonic()))
'''], env=ENV)
    try:
        flushed = 0
        deadline = time.monotonic() + 100
        while flushed < 1000 and time.monotonic() < deadline and rec.poll() is None:
            time.sleep(0.05)  # polling the recorder's output, not timing the scenario
            flushed = _flushed_message_count(bag)
        assert flushed >= 1000, f'recorder flushed {flushed} messages (exit {rec.poll()})'
        rec.send_signal(signal.SIGKILL)
        rec.wait(10)
    finally:
        pub.kill()
        pub.wait(10)
        if rec.poll() is None:
            rec.kill()
    with open_reader(bag) as reader:
        span_s = (reader.end_time - reader.start_time) * 1e-9
        count = reader.message_count
    assert count >= flushed, (count, flushed)
    # 1,000 messages at 100 Hz span about 10 s: the flushed splits hold them in time order
    assert span_s >= 9.0, span_s


@pytest.mark.timeout(60)
@pytest.mark.parametrize('args,word', [
    (['--rate', '-1'], '--rate'),
    (['--rate', 'nan'], '--rate'),
    (['--start', '-2'], '--start'),
    (['--end', '-1'], '--end'),
    (['--start', '5', '--end', '2'], '--end'),
    (['--wait-subscribers', '-1'], '--wait-subscribers'),
    (['--progress-every', '-1'], '--progress-every'),
])
def test_bad_numbers_are_refused_in_one_line_with_exit_2(tmp_path, args, word):
    bag = tmp_path / 'b'
    write_mixed_bag(bag, 30)
    proc = run('bag_replay', str(bag), *args)
    assert proc.returncode == 2
    assert_one_line_error(proc, word)
    assert 'replayed' not in proc.stdout


@pytest.mark.timeout(60)
def test_start_past_the_end_names_the_bag_span(tmp_path):
    bag = tmp_path / 'b20'
    write_mixed_bag(bag, 6000, rate_hz=100.0)   # 2000 ticks: the bag spans 19.99 s
    proc = run('bag_replay', str(bag), '--start', '30')
    assert proc.returncode == 2
    assert_one_line_error(proc, '--start 30', 'spans 19.99')


@pytest.mark.timeout(60)
def test_an_empty_window_inside_the_bag_says_so(tmp_path):
    bag = tmp_path / 'b'
    write_mixed_bag(bag, 30, rate_hz=1.0)   # one tick a second, 10 ticks
    proc = run('bag_replay', str(bag), '--start', '2.5', '--end', '2.9')
    assert proc.returncode == 2
    assert 'replayed 0 messages' in proc.stdout
    assert_one_line_error(proc, 'no message', 'spans 9.000')


@pytest.mark.timeout(60)
def test_rate_zero_is_still_as_fast_as_possible(tmp_path):
    bag = tmp_path / 'b'
    counts = write_mixed_bag(bag, 30)
    proc = run('bag_replay', str(bag), '--rate', '0', '--start', '0.05')
    assert proc.returncode == 0, proc.stderr
    assert f'replayed {sum(counts.values()) - 15} messages' in proc.stdout


@pytest.mark.timeout(60)
def test_a_long_replay_prints_progress_lines(tmp_path):
    """Every --progress-every seconds (checked after each batch of 64 messages) a stderr line:
    messages sent of the bag's total, bag time reached of its span, rate."""
    import re

    bag = tmp_path / 'b'
    counts = write_mixed_bag(bag, 3000, rate_hz=100.0)   # 1000 ticks: 9.99 s of bag (10.0)
    total = sum(counts.values())
    proc = run('bag_replay', str(bag), '--progress-every', '0.000001')
    assert proc.returncode == 0, proc.stderr
    lines = [ln for ln in proc.stderr.splitlines() if 'messages sent' in ln]
    assert len(lines) == total // 64, proc.stderr
    first = re.match(r'bag_replay: (\d+) / ([\d,]+) \((\d+) %\) messages sent, bag time '
                     r'([\d.]+) / 10\.0 s, [\d,]+ msg/s$', lines[0])
    assert first, lines[0]
    assert int(first.group(1)) == 64 and first.group(2) == f'{total:,}'
    assert f'replayed {total} messages' in proc.stdout
    quiet = run('bag_replay', str(bag), '--progress-every', '0')
    assert quiet.returncode == 0 and 'messages sent' not in quiet.stderr
    # a --start/--end window: progress through the window (it gave the whole bag's 7 %)
    win = run('bag_replay', str(bag), '--progress-every', '0.000001', '--start', '2',
              '--end', '4')
    assert win.returncode == 0, win.stderr
    last = [ln for ln in win.stderr.splitlines() if 'messages sent' in ln][-1]
    m = re.search(r'of the window 2\.0-4\.0 s \((\d+) %\)', last)
    assert m and int(m.group(1)) >= 90, last
