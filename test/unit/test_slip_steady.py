"""Steady-state start from cycle-to-cycle consistency (slip_identification.steady)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slip_identification.errors import SlipDataError
from slip_identification.steady import (
    cycle_differences,
    steady_start_s,
    steady_windows,
    white_noise_std,
)


def test_steady_start_after_a_decaying_transient():
    rng = np.random.default_rng(0)
    period = 0.5
    t = np.arange(0.0, 6.0, 1 / 120)
    # periodic pitch (1 deg) plus a 3 deg transient at 1.3 x the clock frequency that dies
    # out at 2.0 s, plus 0.8 mrad white noise
    transient = np.radians(3.0) * np.sin(2 * np.pi * t / (0.77 * period)) * (t < 2.0)
    pitch = (np.radians(1.0) * np.sin(2 * np.pi * t / period) + transient
             + 8e-4 * rng.standard_normal(t.size))
    t0 = steady_start_s(t, pitch, period)
    # the last window that still holds the transient starts before 2.0 s; the steady part
    # starts one period after it
    assert 2.0 <= t0 <= 2.0 + period + 1e-9
    # a periodic run is steady from its first sample; gaps split the windows
    steady = np.radians(1.0) * np.sin(2 * np.pi * t / period) + 8e-4 * rng.standard_normal(t.size)
    assert steady_start_s(t, steady, period) == t[0]
    keep = (t < 2.0) | (t > 2.2)
    w0, d = cycle_differences(t[keep], steady[keep], period)
    assert np.all((w0 + 2 * period <= 2.0 + 1e-9) | (w0 >= 2.2 - 1e-9))
    assert np.all(d < math.radians(0.1))
    # too short for two periods: steadiness unknown
    assert steady_start_s(t[:100], steady[:100], period) == math.inf
    with pytest.raises(SlipDataError, match='period_s'):
        steady_start_s(t, steady, 0.0)


def test_pipeline_skips_the_transient_of_a_simulated_pace():
    edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from slip_identification.geometry import LegGeometry
    from slip_identification.pipeline import analyze_run, run_data_from_sim
    from slip_identification.preprocess import Box

    box = Box((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))
    pace, running = (edubot_sim.simulate_edubot(g, duration_s=4.5, seed=s)
                     for g, s in (('pace', 2), ('running', 3)))
    out = {}
    for run in (pace, running):
        res = analyze_run(run_data_from_sim(run, with_effort=True), box=box,
                          offset_s=run.truth['clock_offset_s'], position_fit=False,
                          geometry=LegGeometry.from_params(run.params), steady_only=True)
        out[run.gait] = res
        print(f"{run.gait}: steady from {res.frame['steady_start_s']:.2f} s, "
              f'{len(res.fits)} fits, skipped {dict(res.skipped_counts)}')
    # pace seed 2 settles into its gait over its first 2 s in the volume (1.5 .. 3.4 s)
    assert out['pace'].skipped_counts['transient'] >= 5
    assert out['pace'].frame['steady_start_s'] > 2.5
    assert all(f.touchdown_s >= out['pace'].frame['steady_start_s'] for f in out['pace'].fits)
    # running seed 3 is steady as it enters the volume
    assert out['running'].skipped_counts['transient'] == 0
    assert len(out['running'].fits) >= 10


def test_a_run_wholly_inside_a_transient_is_not_called_steady():
    rng = np.random.default_rng(1)
    period = 0.5
    t = np.arange(0.0, 1.2, 1 / 120)
    periodic = np.radians(1.0) * np.sin(2 * np.pi * t / period)
    # a 3 deg transient at 1.3 x the clock frequency, decaying over 4 s: still there at the end
    transient = np.radians(3.0) * np.sin(2 * np.pi * t / (0.77 * period)) * np.exp(-t / 4.0)
    pitch = periodic + transient + 8e-4 * rng.standard_normal(t.size)
    # one window only: the plain rule compares it with itself
    assert cycle_differences(t, pitch, period)[0].size == 1
    assert steady_start_s(t, pitch, period) == t[0]
    assert steady_start_s(t, pitch, period, check_floor=True) == math.inf
    _, d, swing, steady = steady_windows(t, pitch, period)
    assert d[0] > swing[0] and not steady[0]
    # a periodic run, and a pitch that is only noise (0.5 deg), pass the check
    quiet = periodic + 8e-4 * rng.standard_normal(t.size)
    noise = np.radians(0.5) * rng.standard_normal(t.size)
    for y in (quiet, noise):
        assert steady_start_s(t, y, period, check_floor=True) == t[0]
    # white noise read from fourth differences (10 s at 120 Hz)
    long_noise = np.radians(0.5) * rng.standard_normal(1200)
    assert white_noise_std(long_noise) == pytest.approx(np.radians(0.5), rel=0.1)


def test_pipeline_notes_a_run_without_steady_state():
    """Simulated pace, 3 s runs: the mocap covers the last 1.5 s; seed 2 is still settling
    there (mean pitch 0.7 -> 3.2 deg, speed 0.19 -> 0.32 m/s), seed 1 is steady."""
    edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')
    from slip_identification.geometry import LegGeometry
    from slip_identification.pipeline import analyze_run, run_data_from_sim

    out = {}
    for seed in (1, 2):
        run = edubot_sim.simulate_edubot('pace', duration_s=3.0, seed=seed)
        out[seed] = analyze_run(run_data_from_sim(run), offset_s=run.truth['clock_offset_s'],
                                geometry=LegGeometry.from_params(run.params), steady_only=True)
    notes = {s: [n for n in r.notes if n.startswith('no steady state')] for s, r in out.items()}
    assert out[1].frame['steady_state_seen'] is True and not notes[1]
    assert out[1].fits and math.isfinite(out[1].frame['steady_start_s'])
    assert out[2].frame['steady_state_seen'] is False and len(notes[2]) == 1
    # --steady-only skips every stance of it
    assert out[2].frame['steady_start_s'] == math.inf and not out[2].fits
    assert out[2].skipped_counts['transient'] >= 3
