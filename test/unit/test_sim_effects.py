"""Every named effect changes the simulated data the way its name says, and is off by default."""

from __future__ import annotations

import json

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.effects import (
    EFFECTS,
    EffectError,
    EffectSet,
    effect_table_markdown,
    parse_effects,
)
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot

STAND = RobotConfig(period_s=0.0)
WALK = RobotConfig(period_s=0.5)          # 2 Hz tripod, 0.4 m/s


def run(cfg: RobotConfig, *effects: str, duration_s: float = 2.0, **kw):
    eff = parse_effects(effects, defaults=False)
    return simulate_robot(duration_s, cfg if not kw else
                          RobotConfig(**{**cfg.__dict__, **kw}), effects=eff, seed=1)


def mean_p(tr, after_s: float = 1.0) -> float:
    return tr.mean_power_in_w(tr.t_s > after_s)


def test_only_sensor_noise_is_on_by_default() -> None:
    assert set(parse_effects([]).active) == {'sensor_noise'}
    assert EffectSet.none().active == {}
    for name in ('basal_power', 'supply_resistance', 'leg_anomaly', 'time_offset'):
        assert not EFFECTS[name].default_on
    assert '| `basal_power` | W | off |' in effect_table_markdown()


def test_effect_parsing_errors_name_the_effect() -> None:
    with pytest.raises(EffectError, match='bogus'):
        parse_effects(['bogus=1'])
    with pytest.raises(EffectError, match='LEG:WATTS'):
        parse_effects(['leg_anomaly=2'])
    with pytest.raises(EffectError, match='supply_resistance'):
        parse_effects(['supply_resistance=-1'])
    with pytest.raises(EffectError, match='not implemented by the robot'):
        parse_effects(['leg_damping=1'], simulator='robot')
    eff = parse_effects(['sensor_noise=off', 'leg_anomaly=L2:1.5'])
    assert eff.active == {'leg_anomaly': ('L2', 1.5)}
    assert EffectSet.from_json(eff.to_json()) == eff
    assert json.loads(eff.to_json())['leg_anomaly'] == {'value': ['L2', 1.5], 'unit': 'leg:W'}


def test_basal_power_adds_a_constant() -> None:
    base, extra = run(STAND), run(STAND, 'basal_power=3')
    assert_allclose(mean_p(extra) - mean_p(base), 3.0, rtol=1e-6)


def test_thermal_drift_is_watts_per_kelvin_of_winding_rise() -> None:
    hot = dict(initial_temperature_c=40.0)
    base = run(STAND, duration_s=1.0, **hot)
    drift = run(STAND, 'thermal_drift=0.05', duration_s=1.0, **hot)
    rise_k = (base.true_temperature_c - 26.0).sum(axis=1)       # sum over the 18 servos
    extra = drift.true_power_in_w - base.true_power_in_w
    # the extra power uses the temperature at the start of each sample
    assert_allclose(extra[1:], 0.05 * rise_k[:-1], rtol=2e-3)


def test_kinematic_error_costs_watts_per_hertz_and_overshoots() -> None:
    base, err = run(WALK), run(WALK, 'kinematic_error=2')
    assert_allclose(mean_p(err) - mean_p(base), 2.0 * 2.0, rtol=0.15)
    swing = lambda tr: np.ptp(tr.position_rad[tr.t_s > 1.0], axis=0)  # noqa: E731
    assert np.mean(swing(err) / swing(base)) > 1.003
    stand_base, stand_err = run(STAND), run(STAND, 'kinematic_error=2')
    assert_allclose(mean_p(stand_err), mean_p(stand_base), rtol=1e-9)   # no steps, no cost


def test_supply_resistance_drops_the_voltage_by_r_i() -> None:
    tr = run(WALK, 'supply_resistance=0.4')
    current = -tr.battery_current_a
    # voltage and current of a sample solved together (sim_core.powered_step; the voltage
    # followed the previous sample's current, a one-sample lag an outside review found)
    slope, intercept = np.polyfit(current, tr.battery_voltage_v, 1)
    assert_allclose(-slope, 0.4, rtol=1e-3)
    assert_allclose(intercept, 11.9, rtol=1e-4)
    assert np.max(np.abs(tr.battery_voltage_v - (11.9 - 0.4 * current))) < 2e-3
    clean = run(WALK)
    assert np.ptp(clean.battery_voltage_v) == 0.0


def test_speed_friction_costs_power_only_when_moving() -> None:
    base, fric = run(WALK), run(WALK, 'speed_friction=20')
    v = 0.4
    extra = mean_p(fric) - mean_p(base)
    assert extra > 20 * v * v             # mechanical c v^2 plus the drive losses
    assert extra < 6 * 20 * v * v
    assert_allclose(mean_p(run(STAND, 'speed_friction=20')), mean_p(run(STAND)), rtol=1e-9)


def test_leg_anomaly_draws_watts_while_that_leg_is_in_stance() -> None:
    base, anom = run(WALK), run(WALK, 'leg_anomaly=L1:2')
    leg = anom.leg_names.index('L1')
    stance = anom.in_stance[:, leg]
    extra = anom.true_power_in_w - base.true_power_in_w
    assert_allclose(extra[stance], 2.0, rtol=1e-6)
    assert_allclose(extra[~stance], 0.0, atol=1e-9)
    with pytest.raises(ValueError, match='X9'):
        run(WALK, 'leg_anomaly=X9:1')


def test_time_offset_and_latency_shift_only_their_streams() -> None:
    tr = run(STAND, 'time_offset=0.25', 'sensor_latency=0.004', duration_s=0.2)
    assert tr.battery_stamp_offset_s == 0.25
    assert tr.servo_stamp_offset_s == 0.004
    clean = run(STAND, duration_s=0.2)
    assert clean.battery_stamp_offset_s == 0.0 and clean.servo_stamp_offset_s == 0.0
    np.testing.assert_array_equal(tr.battery_current_a, clean.battery_current_a)


def test_sensor_noise_scales_the_measurement_noise() -> None:
    quiet = run(STAND, duration_s=1.0)
    noisy = run(STAND, 'sensor_noise=1', duration_s=1.0)
    loud = run(STAND, 'sensor_noise=3', duration_s=1.0)
    assert np.std(quiet.battery_current_a) < 1e-9
    s1 = np.std(noisy.battery_current_a - quiet.battery_current_a)
    s3 = np.std(loud.battery_current_a - quiet.battery_current_a)
    assert_allclose(s1, 0.008, rtol=0.2)
    assert_allclose(s3 / s1, 3.0, rtol=0.05)
