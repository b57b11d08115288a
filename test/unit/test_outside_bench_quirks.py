"""Another lab's bench bags, from an outside review that wrote its own (rosbags, a known phase
power law): each case gave wrong phase powers with no word before.

- sessions named by load, the frequencies following back to back under one id: 42 sessions
  read as 7 of 48 s, each labelled with its first frequency (Eq. 1 115.7 W for 39.0);
- a load cell negative in compression on a bench plan without 0 Hz sessions: the sign was
  not checked (wave prediction -48 %); the tip decides now (the force falls as it rises);
- a leg tip recorded in a y-up frame (z a constant lateral coordinate): the force was shifted
  by the alignment's maximum lag and the phases split on a flat height; refused now;
- a sessions file without the duty factor: 0.5 was assumed in silence (a bench at 0.6 read
  stance +20 %, swing -20 %); now said, with the sensed stance fraction.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag
from hexapod_energy.errors import BagContentError


@pytest.fixture(scope='module')
def data(tmp_path_factory):
    root = tmp_path_factory.mktemp('bench')
    plan = BenchPlan(loads_kg=(0.0, 0.3), frequencies_hz=(0.0, 1.0, 2.0), walk_s=5.0)
    write_trace(simulate_bench(plan, seed=4), root / 'b')
    return read_bench_bag(root / 'b')


def _by_key(samples):
    return {(s.load_kg, round(s.frequency_hz, 3)): s for s in samples}


def test_sessions_split_on_a_parameter_change_under_one_id(data):
    ref, _ = bench_phase_samples(data)
    # the lab's ids name the load only
    sessions = [dict(s, session_id=f"load{s.get('load_kg', 0.0)}") if 'load_kg' in s else s
                for s in data.sessions]
    got, _ = bench_phase_samples(dataclasses.replace(data, sessions=sessions))
    assert len(got) == len(ref)
    r, g = _by_key(ref), _by_key(got)
    assert set(r) == set(g)
    for k in r:
        np.testing.assert_allclose([g[k].p_stance_w, g[k].p_swing_w],
                                   [r[k].p_stance_w, r[k].p_swing_w], rtol=1e-9)
    # back to back: a new 'walking' message at each frequency, nothing in between
    b2b = [s for s in sessions if s['state'] == 'walking'] + [sessions[-1]]
    got, _ = bench_phase_samples(dataclasses.replace(data, sessions=b2b))
    assert sorted(_by_key(got)) == sorted(r)


def test_force_sign_from_the_tip_without_static_sessions(data):
    walking = [s for s in data.sessions if not (s['state'] == 'walking' and
                                                 s['frequency_hz'] <= 0)]
    pos = dataclasses.replace(data, sessions=walking, schedule_t_s=np.zeros(0),
                              schedule_stance=np.zeros(0, bool))
    ref, d_ref = bench_phase_samples(pos)
    assert d_ref['force_sign'] == 1.0
    neg = dataclasses.replace(pos, force_z_n=-pos.force_z_n)
    got, diag = bench_phase_samples(neg)
    assert diag['force_sign'] == -1.0
    assert any('rises with the leg tip' in n for n in diag['notes'])
    r, g = _by_key(ref), _by_key(got)
    for k in r:
        np.testing.assert_allclose([g[k].p_stance_w, g[k].p_swing_w],
                                   [r[k].p_stance_w, r[k].p_swing_w], rtol=1e-6)


def test_flat_tip_height_is_refused(data):
    flat = dataclasses.replace(data, tip_z_m=np.full(data.tip_z_m.shape, 0.031),
                               schedule_t_s=np.zeros(0), schedule_stance=np.zeros(0, bool))
    with pytest.raises(BagContentError, match='y-up motion-capture frame'):
        bench_phase_samples(flat)


def test_missing_duty_factor_is_said(data):
    sessions = [dict(s, duty_factor=0.0) if 'duty_factor' in s else s for s in data.sessions]
    bare = dataclasses.replace(data, sessions=sessions, schedule_t_s=np.zeros(0),
                               schedule_stance=np.zeros(0, bool))
    ref, _ = bench_phase_samples(dataclasses.replace(bare, sessions=data.sessions))
    got, diag = bench_phase_samples(bare)
    [note] = [n for n in diag['notes'] if 'duty factor not given' in n]
    assert '0.5 assumed' in note and 'sensed stance fraction' in note
    r, g = _by_key(ref), _by_key(got)
    for k in r:   # the simulated bench walked at 0.5: the same powers
        np.testing.assert_allclose(g[k].p_stance_w, r[k].p_stance_w, rtol=1e-9)
