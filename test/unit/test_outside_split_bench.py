"""Bench bags whose drivers leave ``header.stamp`` at zero (another lab's bench).

A simulated bench plan (``hexapod_bench_drivers.bench_sim``) is written into a bag and
rewritten with rosbags' own ``Writer`` with every header stamp of the four bench topics set to
zero and their receive times late by 1-3 ms per topic, +-0.5 ms jitter. The bag receive times
then stand in (as for robot and SLIP bags): the phase powers must equal the original's within
1 %, with a note per topic in the diagnostics that ``energy.json`` carries
(``bench.diagnostics[].notes``). Before, every sample was at t = 0: the sessions collapsed and
the bag gave no phase powers.
"""

from __future__ import annotations

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from hexapod_energy.bag_io import BENCH_TOPICS, bench_phase_samples, read_bench_bag

LATENCY_NS = {'/battery_state': 3e6, '/bench/ground_force': 1e6, '/bench/leg_tip': 2e6,
              '/bench/session': 2e6}

bench_sim = pytest.importorskip('hexapod_bench_drivers.bench_sim')


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    from hexapod_bench_drivers.sim_bag import write_trace

    root = tmp_path_factory.mktemp('bench_zero')
    plan = bench_sim.BenchPlan(loads_kg=(0.1, 0.3), frequencies_hz=(0.0, 1.0, 2.0),
                               walk_s=3.0, max_cool_s=5.0)
    write_trace(bench_sim.simulate_bench(plan, seed=2), root / 'ref')
    return root / 'ref', _zero_stamps(root / 'ref', root / 'zero')


def _zero_stamps(src, dst, *, seed: int = 4):
    """Copy ``src`` to ``dst`` with every header stamp of the bench topics set to 0 and the
    bag (receive) time of each of their messages late by a per-topic latency (1-3 ms) plus
    +-0.5 ms of jitter (receive times are not the stamps)."""
    from hexapod_common.bags import open_reader, typestore

    store = typestore()
    rng = np.random.default_rng(seed)
    zero = store.types['builtin_interfaces/msg/Time'](sec=0, nanosec=0)
    with open_reader(src) as reader, \
            Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {c.topic: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in reader.connections}
        for conn, t_ns, data in reader.messages():
            if conn.topic in BENCH_TOPICS:
                msg = store.deserialize_cdr(data, conn.msgtype)
                msg.header.stamp = zero
                data = store.serialize_cdr(msg, conn.msgtype)
                t_ns += int(LATENCY_NS[conn.topic] + rng.uniform(-5e5, 5e5))
            w.write(conns[conn.topic], t_ns, data)
    return dst


def test_zero_stamped_bench_bag_gives_the_same_phase_powers_with_a_note(bags):
    ref_path, zero_path = bags
    ref, d_ref = bench_phase_samples(read_bench_bag(ref_path))
    zero_data = read_bench_bag(zero_path)
    got, diag = bench_phase_samples(zero_data)
    assert len(ref) == len(got) == 6
    for a, b in zip(ref, got):
        assert (a.session_id, a.load_kg, a.frequency_hz) == (b.session_id, b.load_kg,
                                                             b.frequency_hz)
        # the same whole cycles: a session a few ms short by the receive times' jitter keeps
        # its last cycle (bag_io.CYCLE_TOLERANCE; it lost it, 150 of 200 samples at 2 Hz)
        assert b.samples == pytest.approx(a.samples, abs=1)
        for f in ('p_stance_w', 'p_swing_w', 'p_mean_w'):
            x, y = getattr(a, f), getattr(b, f)
            if np.isfinite(x):
                assert y == pytest.approx(x, rel=0.01), (a.session_id, f)
            else:
                assert not np.isfinite(y)
    assert diag['force_offset_s'] == pytest.approx(d_ref['force_offset_s'], abs=0.011)
    notes = ' '.join(diag['notes'])
    for topic in BENCH_TOPICS:
        assert f'{topic} message(s) with a zero header stamp: bag receive time used' in notes
    assert not any('zero header stamp' in n for n in d_ref['notes'])
