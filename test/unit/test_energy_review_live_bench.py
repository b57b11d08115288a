"""A bench /gait/phase at 50 Hz covers its sessions (a label per 20 ms counted exactly failed
it by one sample in 24 sessions of 30, which took the contact split in silence under a note
saying 'no /gait/phase there'); a sparse one is named as sparse."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag, schedule_coverage


@pytest.fixture(scope='module')
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp('bench50')
    plan = BenchPlan(loads_kg=(0.0, 0.3), frequencies_hz=(0.0, 0.75, 1.5, 2.25), walk_s=4.0)
    write_trace(simulate_bench(plan, seed=2), root / 'bench')
    return read_bench_bag(root / 'bench')


def _resampled(data, rate_hz: float, offset_s: float):
    t = data.schedule_t_s
    grid = np.arange(t[0] + offset_s, t[-1], 1.0 / rate_hz)
    idx = np.clip(np.searchsorted(t, grid), 0, t.size - 1)
    return dataclasses.replace(data, schedule_t_s=grid, schedule_stance=data.schedule_stance[idx])


@pytest.mark.parametrize('offset_s', [0.003, 0.011, 0.017])
def test_a_50_hz_schedule_covers_every_walking_session(data, offset_s):
    fifty = _resampled(data, 50.0, offset_s)
    _, diag = bench_phase_samples(fifty)
    assert diag['phase_split'] == 'schedule', diag['notes']


def test_a_sparse_schedule_is_said_sparse_not_absent(data):
    ten = _resampled(data, 10.0, 0.003)
    _, diag = bench_phase_samples(ten)
    assert diag['phase_split'] == 'contact'
    # every session sparse: nothing mixed to explain; mixed with covered ones, the note says why
    walk = [s for s in data.sessions if s.get('state') == 'walking']
    assert walk
    t = data.schedule_t_s
    cut = (t > t[0] + 0.4 * (t[-1] - t[0])) & (t < t[0] + 0.6 * (t[-1] - t[0]))
    keep = ~cut | (np.arange(t.size) % 10 == 0)
    part = dataclasses.replace(data, schedule_t_s=t[keep],
                               schedule_stance=data.schedule_stance[keep])
    _, diag = bench_phase_samples(part)
    assert diag['phase_split'] == 'mixed'
    note = [n for n in diag['notes'] if 'split by the commanded schedule' in n]
    assert note and 'too sparse' in note[0] and 'no /gait/phase there' not in note[0], note


def test_schedule_coverage_rule():
    t = (np.arange(0.0, 4.0, 0.02) + 0.011)[:-1]   # 50 Hz, one label short: 199 in [0, 4)
    assert t.size == 199 and schedule_coverage(t, 0.0, 4.0) == ''
    assert 'too sparse' in schedule_coverage(t[::2], 0.0, 4.0)
    holed = t[(t < 1.0) | (t > 1.3)]
    assert 'silent for 0.3' in schedule_coverage(holed, 0.0, 4.0)
    assert schedule_coverage(np.zeros(0), 0.0, 4.0) == 'no /gait/phase there'
