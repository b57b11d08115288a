"""Step period and whole-cycle boundaries from the joint positions alone
(:mod:`hexapod_energy.cycles`), on simulated AntBot runs and on signals that have no period."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_common.conversions import JointStateSample
from hexapod_energy.cycles import (
    CycleSettings,
    JointCycleTracker,
    estimate_period,
    resample_uniform,
)
from hexapod_energy.descriptors import DescriptorAccumulator


def _track(t, names, positions, tracker=None):
    tracker = tracker or JointCycleTracker()
    out = []
    for k in range(len(t)):
        out += tracker.add(float(t[k]), names, positions[k])
    return tracker, np.array(out)


@pytest.mark.parametrize('legs,gait,speed', [
    (6, 'tripod', 0.1), (6, 'tripod', 0.6), (6, 'wave', 0.1), (6, 'wave', 0.25),
    (4, 'tripod', 0.3), (8, 'wave', 0.2), (8, 'tripod', 0.5)])
def test_period_of_simulated_gaits_within_1_percent(legs, gait, speed):
    cfg = RobotConfig(leg_count=legs, gait=gait, speed_mps=speed,
                      duty_factor=0.5 if gait == 'tripod' else 1 - 1 / legs)
    period = cfg.effective_period_s
    trace = simulate_robot(max(10.0, 6 * period), cfg, seed=3)
    grid = resample_uniform(trace.t_s, trace.position_rad, 0.01)
    est = estimate_period(grid)
    assert est.periodic and est.peak > 0.9
    np.testing.assert_allclose(est.period_s, period, rtol=0.01)
    # streaming: every laid cycle is one period, from the first joint sample on
    tracker, b = _track(trace.t_s, trace.joint_names, trace.position_rad)
    assert not np.isnan(b).any() and len(b) >= 4
    assert b[0] == trace.t_s[0]
    np.testing.assert_allclose(np.diff(b), period, rtol=0.01)
    np.testing.assert_allclose(tracker.period_s_, period, rtol=0.01)


def test_standing_robot_claims_no_cycle():
    trace = simulate_robot(15.0, RobotConfig(period_s=0.0), seed=1)
    tracker, b = _track(trace.t_s, trace.joint_names, trace.position_rad)
    assert b.size == 0 and tracker.estimate_.status == 'standing'
    # servo jitter of one position step (AX-18A: 0.0051 rad) is still standing
    rng = np.random.default_rng(0)
    jitter = trace.position_rad + 0.0051 * rng.integers(-1, 2, trace.position_rad.shape)
    assert estimate_period(resample_uniform(trace.t_s, jitter, 0.01)).status == 'standing'


def test_white_noise_claims_no_cycle():
    rng = np.random.default_rng(1)
    t = np.arange(0.0, 30.0, 0.01)
    x = rng.normal(0.0, 0.2, (t.size, 18))
    tracker, b = _track(t, [f'j{i}' for i in range(18)], x)
    assert b.size == 0 and tracker.evaluations_ >= 50
    est = estimate_period(x)
    assert est.status == 'weak' and est.peak < 0.5 and math.isnan(est.period_s)


def _gait_like(t, phase):
    """12 joints of a periodic gait at cycle phase ``phase`` (a fundamental and a harmonic)."""
    return 0.3 * np.column_stack([np.sin(2 * np.pi * (phase + i / 7))
                                  + 0.3 * np.sin(4 * np.pi * (phase + i / 5))
                                  for i in range(12)])


def test_change_of_step_frequency_is_followed():
    t = np.arange(0.0, 60.0, 0.02)
    phase = np.where(t < 30.0, t / 1.0, 30.0 + (t - 30.0) / 0.7)
    _, b = _track(t, [f'j{i}' for i in range(12)], _gait_like(t, phase))
    d = np.diff(b)
    np.testing.assert_allclose(d[b[1:] < 29.0], 1.0, rtol=0.01)
    late = b[1:] > 30.0 + 10 * 2.1  # one span (10 periods) after the change
    assert late.sum() >= 5
    np.testing.assert_allclose(d[late], 0.7, rtol=0.01)


def test_stop_breaks_the_chain_and_walking_again_restarts_it():
    t = np.arange(0.0, 50.0, 0.02)
    x = _gait_like(t, t / 0.8)
    still = (t > 20.0) & (t < 32.0)
    x[still] = x[np.argmax(still) - 1]
    tracker, b = _track(t, [f'j{i}' for i in range(12)], x)
    breaks = np.nonzero(np.isnan(b))[0]
    assert len(breaks) == 1
    before, after = b[:breaks[0]], b[breaks[0] + 1:]
    assert before[-1] <= 20.0 + 1e-9 and after[0] >= 20.0
    np.testing.assert_allclose(np.diff(after), 0.8, rtol=0.01)
    assert after[-1] > 45.0


def test_split_joint_messages_and_late_joint_names():
    """Joints published in two messages per stamp (one per servo bus) give the same cycles."""
    t = np.arange(0.0, 20.0, 0.01)
    x = _gait_like(t, t / 0.9)
    names = [f'j{i}' for i in range(12)]
    _, whole = _track(t, names, x)
    tracker = JointCycleTracker()
    split = []
    for k in range(t.size):
        split += tracker.add(t[k], names[:6], x[k, :6])
        split += tracker.add(t[k], names[6:], x[k, 6:])
    np.testing.assert_allclose(np.array(split), whole, rtol=0, atol=1e-12)


def test_accumulator_windows_on_joint_cycles_and_break():
    """DescriptorAccumulator on the joint path: windows of whole cycles, none across a stop."""
    t = np.arange(0.0, 50.0, 0.01)
    x = _gait_like(t, t / 0.8)
    still = (t > 20.0) & (t < 32.0)
    x[still] = x[np.argmax(still) - 1]
    names = tuple(f'j{i}' for i in range(12))
    from hexapod_common.conversions import BatterySample

    acc = DescriptorAccumulator(mass_kg=2.0, cycle_source='auto', speed_mps=0.2)
    out = []
    for k, tk in enumerate(t):
        out += acc.add_joint_state(JointStateSample(tk, names, x[k], np.zeros(0), np.zeros(0)))
        if k % 5 == 0:
            out += acc.add_battery(BatterySample(tk, 12.0, -(5.0 + math.sin(2 * math.pi * tk /
                                                                              0.8)), 25.0))
    assert len(out) >= 30
    for d in out:
        assert d.cycle_source == 'joints' and d.speed_source == 'given'
        np.testing.assert_allclose(d.window_s, 0.8, rtol=0.01)
        # no window over the stop (20-32 s), beyond the last re-estimate hop before walking
        overlap = min(d.t_end_s, 32.0) - max(d.t_end_s - d.window_s, 20.0)
        assert overlap <= 0.5
        # whole periods of the sinusoid: P_in = 60 W up to the 50 ms trapezoid and the
        # period error
        np.testing.assert_allclose(d.power_in_w, 60.0, rtol=3e-3)
        assert math.isnan(d.power_out_w) and d.warnings


def test_settings_validated():
    with pytest.raises(ValueError, match='max_span_s'):
        CycleSettings(max_span_s=5.0, max_period_s=4.0)
