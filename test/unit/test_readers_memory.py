"""The bag readers keep what they read as compact columns (``hexapod_common.bags.
SampleColumns``), not one sample object per message (docs/known_gaps_history.md: a 60 min
18-joint robot bag took 2 GB in ``energy``). Checked by what each reader's traced peak memory
grows per second of bag between a short and a longer bag of the same robot (imports and fixed
costs cancel): the old readers grew 249 kB/s (robot), 157 kB/s (residuals) and 275 kB/s (slip)
on these bags, the column readers 89, 51 and 103 kB/s. Deterministic: tracemalloc, no wall clock.
"""

from __future__ import annotations

import dataclasses
import gc
import tracemalloc

import numpy as np
import pytest

from hexapod_common.bags import SampleColumns
from hexapod_common.conversions import BatterySample, JointStateSample
from hexapod_common.testbags import write_foreign_robot_bag

SHORT_S, LONG_S = 12.0, 48.0


def _peak_bytes(fn):
    # garbage left by earlier tests in this worker is collected first: a collection that
    # falls inside the traced read once made a CI run read 304 kB/s (89 alone)
    gc.collect()
    tracemalloc.start()
    try:
        out = fn()
        return tracemalloc.get_traced_memory()[1], out
    finally:
        tracemalloc.stop()


def _growth_per_s(read, bags, limit):
    """Traced peak of ``read(bag)``: its growth per second of bag, and the longer bag's
    result. Measured again, and the smaller kept, only when the first is over ``limit``: a
    one-off allocation elsewhere is not growth."""
    read(bags[SHORT_S])   # imports and caches outside the measurement
    growth, out = [], None
    for _ in range(2):
        short, _ = _peak_bytes(lambda: read(bags[SHORT_S]))
        long, out = _peak_bytes(lambda: read(bags[LONG_S]))
        growth.append((long - short) / (LONG_S - SHORT_S))
        if growth[-1] < limit:
            break
    return min(growth), out


@pytest.fixture(scope='module')
def robot_bags(tmp_path_factory):
    """Wave gait on 6 legs (18 joints): joint states and /gait/phase at 50 Hz, battery 10 Hz."""
    root = tmp_path_factory.mktemp('mem')
    for s in (SHORT_S, LONG_S):
        write_foreign_robot_bag(root / f'r{s:g}', legs=6, duration_s=s, storage='mcap')
    return {s: root / f'r{s:g}' for s in (SHORT_S, LONG_S)}


def test_robot_reader_memory_does_not_grow_per_message_object(robot_bags):
    from hexapod_energy.bag_io import read_robot_bag

    growth, run = _growth_per_s(lambda b: read_robot_bag(b, mass_kg=2.0), robot_bags, 140e3)
    assert run.windows > 10 and np.isfinite(run.power_in_w)
    assert growth < 140e3, f'{growth / 1e3:.0f} kB per second of bag'


def test_residual_reader_memory_does_not_grow_per_message_object(robot_bags):
    from hexapod_energy.residuals import read_residual_run

    growth, run = _growth_per_s(read_residual_run, robot_bags, 100e3)
    assert run.t_s.size > 400 and run.joint_abs_effort and run.joint_features is not None
    assert growth < 100e3, f'{growth / 1e3:.0f} kB per second of bag'


def test_slip_reader_memory_does_not_grow_per_message_object(tmp_path):
    edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from slip_identification.cli import read_run

    bags = {s: edubot_sim.write_edubot_bag(tmp_path / f'e{s:g}', 'jogging', duration_s=s,
                                           seed=1) for s in (SHORT_S, LONG_S)}
    growth, run = _growth_per_s(lambda b: read_run(str(b)), bags, 160e3)
    assert run.joint_t_s.size > 1000 and run.mocap_t_s.size and run.battery_t_s.size
    assert growth < 160e3, f'{growth / 1e3:.0f} kB per second of bag'


def test_sample_columns_rebuild_equal_samples():
    cols = SampleColumns()
    given = []
    for k in range(40):
        n = 0 if k % 7 == 0 else 3
        names = ('a', 'b', 'c')[:n] if k % 5 else ('x', 'y', 'z')[:n]
        s = JointStateSample(0.1 * k, names, np.arange(n, dtype=float) + k,
                             np.zeros(n) if k % 3 else np.zeros(0), np.ones(n))
        given.append(s)
        cols.append(s)
    assert len(cols) == len(given)
    for a, b in zip(given, cols):
        assert type(b.t_s) is float and a.t_s == b.t_s and a.names == b.names
        for f in ('position', 'velocity', 'effort'):
            assert getattr(a, f).dtype == getattr(b, f).dtype
            np.testing.assert_array_equal(getattr(a, f), getattr(b, f))
            assert not getattr(b, f).flags.writeable
    assert cols.distinct('names') == [(), ('a', 'b', 'c'), ('x', 'y', 'z')]
    assert cols.stacked('effort') is None   # rows of 0 and 3 joints
    bat = SampleColumns()
    for k in range(5):   # a field whose type changes (an int current) falls back to a list
        bat.append(BatterySample(float(k), 12.0, -1.0 if k != 3 else 2, 25.0, 'pack'))
    bat.shift('t_s', 0.5)
    assert [b.t_s for b in bat] == [0.5, 1.5, 2.5, 3.5, 4.5]
    assert bat[3] == BatterySample(3.5, 12.0, 2, 25.0, 'pack') and type(bat[3].current_a) is int
    assert dataclasses.astuple(bat[-1]) == (4.5, 12.0, -1.0, 25.0, 'pack', True)
    with pytest.raises(RuntimeError):
        bat.append(BatterySample(5.0, 12.0, -1.0, 25.0, 'pack'))
