"""The geometric offset fit when the first (proprioceptive) estimate is far off: the fit from
the other estimate, and a note when the residual stays above the noise.

A reviewer's Buehler clock (10.5 rad/s, sweep 1.0 rad, offset 0.2 rad, duty 0.5, kp 0.7, kd 0)
on the simulated EduBot, 6 s runs: the hip-effort contact estimate of the stream offset is
75-92 ms off, beyond the fit's +-60 ms search, and the fit settled 108-159 ms off. A fit left
above the noise is now searched again from a grid of offsets and grounds (``_grid_start``),
which finds both runs; the fit from the other estimate is tested with the grid off.
"""

from __future__ import annotations

import pytest

from hexapod_gait.buehler import BuehlerClock
from slip_identification import pipeline
from slip_identification.geometry import LegGeometry
from slip_identification.pipeline import (
    GEOMETRY_RESIDUAL_HIGH,
    analyze_run,
    run_data_from_sim,
)

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

CLOCK = BuehlerClock(period_s=2 * 3.141592653589793 / 10.5, duty_factor=0.5,
                     sweep_angle_rad=1.0, leg_offset_rad=0.2, kp_norm=0.7, kd_norm=0.0)


def _analyze(run):
    return analyze_run(run_data_from_sim(run), offset_s='auto',
                       geometry=LegGeometry.from_params(run.params))


@pytest.fixture
def no_grid(monkeypatch):
    monkeypatch.setattr(pipeline, '_grid_start', lambda *a, **k: None)


def test_a_far_first_estimate_hands_over_to_the_other_one(no_grid):
    run = edubot_sim.simulate_edubot(CLOCK, duration_s=6.0, seed=1)
    res = _analyze(run)
    truth = run.truth['clock_offset_s']
    starts = res.frame['offset_other_starts']
    print(f"first {1e3 * (starts['first_offset_s'] - truth):+.1f} ms, "
          f"final {1e3 * (res.offset_s - truth):+.2f} ms")
    assert res.frame['offset_initial'] == 'contact'
    assert abs(starts['first_offset_s'] - truth) > 0.1       # 118 ms off before
    assert 'joint' in starts
    assert abs(res.offset_s - truth) < 2e-3                  # 0.2 ms
    assert any(n.startswith('the offset estimates disagree') for n in res.notes)
    assert res.frame['geometry_residual_ratio'] < GEOMETRY_RESIDUAL_HIGH


@pytest.mark.parametrize('seed', [1, 2])
def test_a_fit_left_above_the_noise_is_searched_again_from_a_grid(seed):
    """Seed 2 has no joint estimate to hand over to: it stayed 159 ms off (said); seed 1 was
    found from the joint estimate. The grid finds both, within 0.3 ms. (Seed 3, the case
    here before, has no aerial phase by its body height: 'contact' refuses it and the fit
    from the cross-correlation is within 0.2 ms without the grid, test_slip_contact_flight.)"""
    run = edubot_sim.simulate_edubot(CLOCK, duration_s=6.0, seed=seed)
    res = _analyze(run)
    truth = run.truth['clock_offset_s']
    grid = res.frame['offset_grid']
    assert grid['kept'] and abs(grid['first_offset_s'] - truth) > 0.05
    assert abs(res.offset_s - truth) < 2e-3
    assert res.frame['geometry_residual_ratio'] < GEOMETRY_RESIDUAL_HIGH
    assert any('a grid of offsets' in n for n in res.notes)


def test_a_fit_left_above_the_noise_is_said(no_grid):
    run = edubot_sim.simulate_edubot(CLOCK, duration_s=6.0, seed=2)
    res = _analyze(run)
    # no joint estimate on this run: nothing to hand over to; the residual says so
    assert abs(res.offset_s - run.truth['clock_offset_s']) > 0.05
    assert res.frame['geometry_residual_ratio'] > GEOMETRY_RESIDUAL_HIGH
    assert any('times the motion-capture noise' in n for n in res.notes)
    # a steady simulated pace: neither note
    pace = _analyze(edubot_sim.simulate_edubot('pace', duration_s=4.5, seed=1))
    assert pace.frame['geometry_residual_ratio'] < GEOMETRY_RESIDUAL_HIGH
    assert not any('times the motion-capture noise' in n or 'estimates disagree' in n
                   for n in pace.notes)
    assert 'offset_other_starts' not in pace.frame
