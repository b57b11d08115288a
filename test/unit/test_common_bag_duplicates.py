"""Messages recorded twice (same topic, log time and bytes: a recorder that wrote some messages
twice) count once in every bag reader: ``iter_messages`` drops them and counts them, and the
bench, residual-run and slip readers give the clean bag's numbers with a note saying how many
were ignored; ``bag_replay`` still publishes what is stored."""

from __future__ import annotations

import random
import re
from pathlib import Path

import numpy as np
import pytest

from hexapod_common.bags import BagWriter, duplicates_note, iter_messages, open_reader


def write_with_duplicates(src: Path, dst: Path, frac: float = 0.3, seed: int = 0
                          ) -> dict[str, int]:
    """Copy ``src`` to ``dst`` writing ``frac`` of the messages twice (same log time, same
    bytes); returns topic -> number written twice."""
    rng = random.Random(seed)
    twice: dict[str, int] = {}
    with open_reader(src) as reader, BagWriter(dst) as out:
        for conn in reader.connections:
            out.add_topic(conn.topic, conn.msgtype)
        for conn, t_ns, data in reader.messages(connections=reader.connections):
            out.write(conn.topic, conn.msgtype, bytes(data), t_ns)
            if rng.random() < frac:
                out.write(conn.topic, conn.msgtype, bytes(data), t_ns)
                twice[conn.topic] = twice.get(conn.topic, 0) + 1
    return twice


def _ignored(notes: list[str]) -> int:
    """The count of the duplicates note (0 without one)."""
    found = [int(m.group(1)) for n in notes
             for m in [re.match(r'(\d+) duplicated message\(s\) ignored', n)] if m]
    assert len(found) <= 1, notes
    return found[0] if found else 0


def _assert_same_arrays(a: object, b: object) -> None:
    for name, va in vars(a).items():
        if isinstance(va, np.ndarray):
            np.testing.assert_array_equal(va, getattr(b, name), err_msg=name)


@pytest.fixture(scope='module')
def bench_bags(tmp_path_factory):
    from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
    from hexapod_bench_drivers.sim_bag import write_trace

    root = tmp_path_factory.mktemp('dup_bench')
    plan = BenchPlan(loads_kg=(0.0, 0.4), frequencies_hz=(0.0, 1.25), walk_s=3.0)
    write_trace(simulate_bench(plan, seed=1), root / 'clean')
    return root / 'clean', root / 'dup', write_with_duplicates(root / 'clean', root / 'dup')


@pytest.fixture(scope='module')
def robot_bags(tmp_path_factory):
    from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
    from hexapod_bench_drivers.sim_bag import write_trace

    root = tmp_path_factory.mktemp('dup_robot')
    write_trace(simulate_robot(6.0, RobotConfig(period_s=0.7), seed=3), root / 'clean')
    return root / 'clean', root / 'dup', write_with_duplicates(root / 'clean', root / 'dup')


def test_iter_messages_drops_exact_duplicates_and_counts_them(robot_bags):
    clean, dup, twice = robot_bags
    assert sum(twice.values()) > 100
    with open_reader(clean) as reader:
        want = [(m.topic, m.stamp_ns, m.data) for m in iter_messages(reader)]
    counts: dict[str, int] = {}
    with open_reader(dup) as reader:
        got = [(m.topic, m.stamp_ns, m.data) for m in iter_messages(reader, duplicates=counts)]
        every = sum(1 for _ in iter_messages(reader, dedupe=False))
    assert got == want
    assert counts == twice
    assert every == len(want) + sum(twice.values())
    note, = duplicates_note(counts)
    assert note.startswith(f'{sum(twice.values())} duplicated message(s) ignored')
    assert duplicates_note({}) == []


def test_bench_reader_counts_a_duplicate_once(bench_bags):
    from hexapod_energy.bag_io import BENCH_TOPICS, read_bench_bag

    clean, dup, twice = bench_bags
    a, b = read_bench_bag(clean), read_bench_bag(dup)
    _assert_same_arrays(a, b)
    assert a.sessions == b.sessions
    assert _ignored(a.notes) == 0
    read = set(BENCH_TOPICS) | {'/gait/phase'}
    assert _ignored(b.notes) == sum(n for t, n in twice.items() if t in read) > 0


def test_residual_run_reader_counts_a_duplicate_once(robot_bags):
    from hexapod_energy.residuals import read_residual_run

    clean, dup, twice = robot_bags
    a, b = read_residual_run(clean), read_residual_run(dup)
    _assert_same_arrays(a, b)
    assert _ignored(a.notes) == 0
    read = {'/battery_state', '/gait/phase', '/servo_status', '/joint_states'}
    assert _ignored(b.notes) == sum(n for t, n in twice.items() if t in read) > 0


def test_energy_robot_reader_keeps_its_note(robot_bags):
    from hexapod_energy.bag_io import read_robot_bag

    clean, dup, twice = robot_bags
    a = read_robot_bag(clean, mass_kg=2.183)
    b = read_robot_bag(dup, mass_kg=2.183)
    assert (a.windows, a.power_in_w, a.power_out_w, a.speed_mps) == \
        (b.windows, b.power_in_w, b.power_out_w, b.speed_mps)
    read = {'/battery_state', '/gait/phase', '/joint_states', '/mocap/body', '/odom'}
    assert _ignored(b.extra['notes']) == sum(n for t, n in twice.items() if t in read) > 0


def test_slip_reader_counts_a_duplicate_once(tmp_path):
    edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from slip_identification.cli import TOPICS, read_run

    clean = edubot_sim.write_edubot_bag(tmp_path / 'clean', 'running', duration_s=3.0, seed=1)
    twice = write_with_duplicates(Path(clean), tmp_path / 'dup')
    a, b = read_run(clean), read_run(tmp_path / 'dup')
    _assert_same_arrays(a, b)
    assert _ignored(a.notes) == 0
    read = set(TOPICS) | {'/gait/phase'}
    assert _ignored(b.notes) == sum(n for t, n in twice.items() if t in read) > 0


def test_the_bench_reader_keeps_the_readers_notes(bench_bags, tmp_path):
    """The bench reader dropped what opening the bag said (metadata.yaml lost or disagreeing
    with its storage, a foreign type hash): energy.json's bench notes lacked it."""
    import shutil

    from hexapod_energy.bag_io import read_bench_bag

    clean = bench_bags[0]
    bare = tmp_path / 'bare'
    bare.mkdir()
    for f in clean.glob('*.mcap'):
        shutil.copy(f, bare / f.name)
    notes = read_bench_bag(bare).notes
    assert any('no metadata.yaml' in n for n in notes), notes


def test_the_residual_reader_keeps_the_readers_notes(robot_bags, tmp_path):
    """As the bench reader: residuals.json's run notes lacked what opening the bag said."""
    import shutil

    from hexapod_energy.residuals import read_residual_run

    bare = tmp_path / 'bare'
    bare.mkdir()
    for f in robot_bags[0].glob('*.mcap'):
        shutil.copy(f, bare / f.name)
    notes = read_residual_run(bare).notes
    assert any('no metadata.yaml' in n for n in notes), notes
