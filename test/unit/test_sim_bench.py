"""MiMiC-Ant bench simulator: sessions, basal power, load/frequency trends, phase split."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchConfig, BenchPlan, simulate_bench
from hexapod_bench_drivers.effects import EffectSet


@lru_cache(maxsize=1)
def plan_trace():
    plan = BenchPlan(loads_kg=(0.0, 0.515), frequencies_hz=(0.0, 1.0, 2.0), walk_s=4.0,
                     max_cool_s=20.0)
    return simulate_bench(plan, effects=EffectSet.none()), plan


def walking_windows(tr):
    recs = tr.sessions
    out = {}
    for a, b in zip(recs, recs[1:]):
        if a.state == 'walking':
            mask = (tr.t_s > a.t_s + 1.0) & (tr.t_s <= b.t_s)
            out[(a.load_mass_kg, a.frequency_hz)] = mask
    return out


def stance_power(tr, mask):
    stance = tr.ground_force_n > 0.5
    p = -tr.battery_voltage_v * tr.battery_current_a
    return float(p[mask & stance].mean())


def test_sessions_cycle_heating_walking_cooling_done() -> None:
    tr, plan = plan_trace()
    states = [r.state for r in tr.sessions]
    assert states == ['heating', 'walking', 'cooling'] * 6 + ['done']
    ids = {r.session_id for r in tr.sessions}
    assert len(ids) == len(plan.sessions())
    assert all(np.diff([r.t_s for r in tr.sessions]) >= 0)
    # powered off while cooling: no current, no force
    cooling = ~tr.powered
    assert cooling.any()
    assert np.all(tr.battery_current_a[cooling] == 0.0)
    assert np.all(tr.ground_force_n[cooling] == 0.0)


def test_zero_hz_session_gives_the_basal_power() -> None:
    tr, _ = plan_trace()
    win = walking_windows(tr)
    p = -tr.battery_voltage_v * tr.battery_current_a
    basal = p[win[(0.0, 0.0)]]
    # three servos' electronics (50 mA each at 11.9 V) plus holding power (the gear's stiction
    # carries most of the leg's weight), and steady
    assert 3 * 0.05 * 11.9 - 0.01 <= basal.mean() <= 3.0
    assert basal.std() < 0.05 * basal.mean()
    assert np.all(tr.in_stance[win[(0.0, 0.0)], 0])


def test_stance_power_rises_with_load_and_frequency() -> None:
    tr, _ = plan_trace()
    win = walking_windows(tr)
    for load in (0.0, 0.515):
        assert stance_power(tr, win[(load, 2.0)]) > stance_power(tr, win[(load, 1.0)])
    for f in (1.0, 2.0):
        assert stance_power(tr, win[(0.515, f)]) > stance_power(tr, win[(0.0, f)])


def test_swing_and_stance_are_separable_from_force_and_tip_height() -> None:
    tr, _ = plan_trace()
    win = walking_windows(tr)
    for (load, f), mask in win.items():
        if f == 0.0:
            continue
        force_stance = tr.ground_force_n[mask] > 0.5
        on_ground = tr.tip_m[mask, 2] < 1e-4           # noise-free motion capture: on the belt
        planned = tr.in_stance[mask, 0]
        # the two sensors agree but for the few samples of touchdown and lift-off
        assert np.mean(force_stance == on_ground) > 0.9
        # the servos lag the plan a little, so contact and plan agree most of the time
        assert np.mean(force_stance == planned) > 0.75
        weight = (0.166 + load) * 9.81
        np.testing.assert_allclose(tr.ground_force_n[mask][force_stance], weight, rtol=0.01)
        assert tr.tip_m[mask, 2].max() > 0.025          # lifted in swing (40 mm step height)
        assert np.ptp(tr.tip_m[mask, 0]) == pytest.approx(0.10, abs=0.02)


def test_cold_start_heats_to_the_gate_before_walking() -> None:
    plan = BenchPlan(loads_kg=(0.0,), frequencies_hz=(1.0,), walk_s=1.0, max_cool_s=10.0,
                     gate_temperature_c=26.0)
    tr = simulate_bench(plan, BenchConfig(initial_temperature_c=26.0,
                                          ambient_temperature_c=26.0),
                        effects=EffectSet.none())
    walk = [r for r in tr.sessions if r.state == 'walking'][0]
    assert walk.t_s >= plan.heat_s
