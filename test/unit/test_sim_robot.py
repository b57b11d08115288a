"""Servo hexapod simulator against Brodoline et al. 2024 (AntBot, tripod, beta 0.5, no load)."""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import pytest

from hexapod_bench_drivers.effects import EffectSet
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot

SETTLE_S = 1.0


@lru_cache(maxsize=None)
def figures(speed_mps: float, step_length_m: float = 0.10, duration_s: float = 3.0):
    """Mean P_in [W], P_out [W] (positive joint work rate), speed, CoT/M of a clean run."""
    cfg = RobotConfig(speed_mps=speed_mps, step_length_m=step_length_m,
                      period_s=0.0 if speed_mps == 0 else 1.0)
    tr = simulate_robot(duration_s, cfg, effects=EffectSet.none())
    m = tr.t_s > SETTLE_S
    p_in = tr.mean_power_in_w(m)
    p_out = float(np.clip(tr.true_mechanical_power_w[m], 0.0, None).sum(axis=1).mean())
    cot = (p_in - p_out) / (cfg.total_mass_kg * speed_mps) if speed_mps > 0 else np.inf
    return p_in, p_out, cot, tr


def test_standing_still_draws_8_to_20_w() -> None:
    p_in, p_out, _, tr = figures(0.0)
    assert 8.0 <= p_in <= 20.0
    assert p_out == pytest.approx(0.0, abs=0.01)
    assert np.all(tr.supporting_legs == 6)


def test_power_at_0_60_mps_is_35_to_80_w() -> None:
    p_in, _, _, tr = figures(0.60)
    assert 35.0 <= p_in <= 80.0
    assert tr.speed_mps[0] == pytest.approx(0.60)
    assert tr.period_s[0] == pytest.approx(0.10 / (0.5 * 0.60))
    assert np.all(tr.supporting_legs == 3)


def test_cot_per_mass_at_0_84_mps_with_140_mm_steps() -> None:
    _, _, cot, _ = figures(0.84, 0.14)
    assert 25.0 <= cot <= 50.0      # paper: 35 J/(m kg)


@pytest.mark.parametrize('speed_mps', [0.2, 0.3, 0.45, 0.6])
def test_efficiency_between_half_and_six_percent(speed_mps: float) -> None:
    p_in, p_out, _, _ = figures(speed_mps)
    assert 0.005 <= p_out / p_in <= 0.06


def test_input_power_rises_with_step_frequency_and_cot_falls_with_speed() -> None:
    speeds = (0.2, 0.3, 0.45, 0.6)
    p = [figures(v)[0] for v in speeds]
    cot = [figures(v)[2] for v in speeds]
    assert np.all(np.diff(p) > 0.0)
    assert np.all(np.diff(cot) < 0.0)


def test_same_seed_same_data_other_seed_other_noise() -> None:
    cfg = RobotConfig(speed_mps=0.3)
    a = simulate_robot(0.5, cfg, seed=3)
    b = simulate_robot(0.5, cfg, seed=3)
    c = simulate_robot(0.5, cfg, seed=4)
    np.testing.assert_array_equal(a.battery_current_a, b.battery_current_a)
    np.testing.assert_array_equal(a.position_rad, b.position_rad)
    assert not np.array_equal(a.battery_current_a, c.battery_current_a)


def test_four_and_eight_legs_and_payload() -> None:
    four = simulate_robot(1.0, RobotConfig(leg_count=4, period_s=0.0), effects=EffectSet.none())
    eight = simulate_robot(1.0, RobotConfig(leg_count=8, period_s=0.0), effects=EffectSet.none())
    assert len(four.joint_names) == 12 and len(eight.joint_names) == 24
    assert four.mean_power_in_w() < eight.mean_power_in_w()   # basal power per servo
    light = simulate_robot(2.0, RobotConfig(speed_mps=0.3), effects=EffectSet.none())
    heavy = simulate_robot(2.0, RobotConfig(speed_mps=0.3, payload_kg=1.0),
                           effects=EffectSet.none())
    assert heavy.mean_power_in_w(heavy.t_s > 1) > light.mean_power_in_w(light.t_s > 1)


def test_battery_supply_sags_with_charge_and_current_sign_is_ros() -> None:
    tr = simulate_robot(2.0, RobotConfig(speed_mps=0.3, supply='battery'),
                        effects=EffectSet.none())
    assert np.all(tr.battery_current_a < 0.0)          # discharging: negative
    assert 11.0 < tr.battery_voltage_v.mean() < 12.7
    sup = simulate_robot(0.5, RobotConfig(period_s=0.0), effects=EffectSet.none())
    np.testing.assert_allclose(sup.battery_voltage_v, 11.9)
