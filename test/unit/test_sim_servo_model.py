"""Servo electromechanics: datasheet points, holding, heat, reporting, vectorisation."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.servo_model import (
    ERROR_OVERHEATING,
    ServoModel,
    ServoParams,
    ServoParamsError,
)


def run(model: ServoModel, seconds: float, goal, tau=0.0, volts=12.0, dt=0.01):
    out = None
    for _ in range(int(round(seconds / dt))):
        out = model.step(dt, goal, tau, volts)
    return out


def test_derived_constants_from_datasheet_points() -> None:
    p = ServoParams.ax18a()
    assert_allclose(p.winding_resistance_ohm, 12.0 / 2.15)
    assert_allclose(p.torque_constant_nm_a, 1.8 / 2.15)
    # k_e from the no-load point: V = R i_nl + k_e w_nl
    assert_allclose(p.back_emf_constant_v_s * p.no_load_speed_rad_s
                    + p.winding_resistance_ohm * p.no_load_current_a, 12.0)
    assert 0.6 < p.gear_efficiency < 0.97   # most gear loss is the constant Coulomb part
    for preset in (ServoParams.ax12a(), ServoParams.xl430(), ServoParams.xm430()):
        assert 0.3 < preset.gear_efficiency <= 1.0
    assert ServoParams.by_name('AX-18A') == p


def test_no_load_speed_is_reached_at_full_duty() -> None:
    model = ServoModel(count=1, initial_position_rad=-2.5)
    out = run(model, 0.3, 2.6, dt=0.001)
    assert_allclose(out.velocity_rad_s, 97 * 2 * math.pi / 60, rtol=0.01)


def test_stall_current_and_torque_at_rated_voltage() -> None:
    p = ServoParams.ax18a()
    model = ServoModel(p, count=1)
    # A load a little under the stall torque is still lifted; the full duty current is drawn.
    out = run(model, 0.5, 2.0, tau=-(p.stall_torque_nm - p.coulomb_friction_nm - 0.05),
              dt=0.001)
    assert out.velocity_rad_s[0] > 0.0
    # Datasheet resistance holds at 25 degC; 0.2 s of stall heats the winding by < 0.3 K.
    model = ServoModel(p, count=1, initial_temperature_c=25.0, ambient_temperature_c=25.0)
    out = run(model, 0.2, 2.0, tau=-(p.stall_torque_nm + 0.1), dt=0.001)
    assert_allclose(out.velocity_rad_s, 0.0, atol=1e-9)
    assert_allclose(out.current_a, 2.2, rtol=2e-3)
    assert_allclose(out.load_fraction, 1.0)


def test_idle_servo_draws_standby_current_only() -> None:
    model = ServoModel(count=2, initial_position_rad=0.3)
    out = run(model, 1.0, 0.3)
    assert_allclose(out.current_a, 0.05, rtol=1e-9)
    assert_allclose(out.power_w, 0.6, rtol=1e-9)
    unpowered = run(model, 0.1, 0.3, volts=0.0)
    assert_allclose(unpowered.current_a, 0.0)


def test_holding_a_load_costs_joule_power_and_leaves_a_static_error() -> None:
    model = ServoModel(count=1)
    out = run(model, 2.0, 0.0, tau=-0.6)
    assert out.position_rad[0] < -0.02          # sags under load: finite stiffness
    assert_allclose(out.torque_nm, 0.6, rtol=1e-6)   # at rest the gear balances the load
    # At rest all bridge power is Joule loss in the winding (energy balance).
    assert out.winding_loss_w[0] > 0.5
    assert_allclose(out.power_w - 0.6, out.winding_loss_w, rtol=1e-4)
    # The gear's stiction carries part of the load: less current than k_t would need.
    p = ServoParams.ax18a()
    i_w = math.sqrt(out.winding_loss_w[0] / model.winding_resistance_ohm()[0])
    assert i_w < 0.6 / p.torque_constant_nm_a


def test_vectorised_equals_single_servos() -> None:
    goals = np.array([0.4, -0.2, 0.1])
    taus = np.array([-0.3, 0.2, 0.0])
    many = ServoModel(count=3)
    outs = [ServoModel(count=1) for _ in range(3)]
    for k in range(100):
        g = goals * math.sin(0.1 * k)
        a = many.step(0.01, g, taus)
        b = [m.step(0.01, g[i], taus[i]) for i, m in enumerate(outs)]
    assert_allclose(a.position_rad, [o.position_rad[0] for o in b], rtol=1e-12)
    assert_allclose(a.power_w, [o.power_w[0] for o in b], rtol=1e-12)


def test_copper_resistance_and_heating_time_constant() -> None:
    p = ServoParams.ax18a()
    model = ServoModel(p, count=1, initial_temperature_c=35.0, ambient_temperature_c=25.0)
    assert_allclose(model.winding_resistance_ohm(), p.winding_resistance_ohm * (1 + 0.00393 * 10))
    # A stalled servo at 30 % duty (torque limit) held by gear stiction: constant voltage on
    # the winding, first-order approach to T_amb + P R_th.
    model = ServoModel(p, count=1, initial_temperature_c=25.0, ambient_temperature_c=25.0,
                       max_substep_s=0.5)
    model.torque_limit[:] = 0.3
    out = run(model, p.thermal_time_constant_s, 2.0, tau=-0.6, dt=0.5)
    assert_allclose(out.velocity_rad_s, 0.0)
    i2r0 = (0.3 * 12.0) ** 2 / p.winding_resistance_ohm
    rise = out.temperature_c[0] - 25.0
    # The resistance rises, so at constant voltage the loss falls a little: the rise lies just
    # under the constant-resistance value (1 - 1/e) P R_th.
    expected = (1 - math.exp(-1)) * i2r0 * p.thermal_resistance_k_w
    assert 0.9 * expected < rise < expected
    assert out.reported_temperature_c.dtype.kind == 'i'
    assert out.reported_temperature_c[0] == round(out.temperature_c[0])


def test_hot_servo_needs_more_power_for_the_same_work() -> None:
    def cycle_power(temp_c: float) -> float:
        m = ServoModel(count=1, initial_temperature_c=temp_c, ambient_temperature_c=temp_c)
        energy = 0.0
        for k in range(300):
            o = m.step(0.01, 0.4 * math.sin(2 * math.pi * 2 * k * 0.01), -0.5)
            energy += o.power_w[0] * 0.01
        return energy / 3.0
    assert cycle_power(60.0) > cycle_power(26.0) * 1.03


def test_torque_disabled_servo_is_backdriven_and_draws_no_bridge_current() -> None:
    model = ServoModel(count=1, torque_enabled=False)
    out = run(model, 0.5, 1.0, tau=-0.3)
    assert out.position_rad[0] < -0.2
    assert_allclose(out.current_a, 0.05)
    assert not out.torque_enabled[0]


def test_moving_speed_limits_the_slew() -> None:
    model = ServoModel(count=1)
    model.moving_speed_rad_s[:] = 1.0
    out = run(model, 0.5, 2.0, dt=0.01)
    assert_allclose(out.position_rad, 0.5, atol=0.12)
    assert out.velocity_rad_s[0] < 1.2


def test_overheating_shuts_torque_off_and_sets_error_bit() -> None:
    p = ServoParams.ax18a()
    model = ServoModel(p, count=2, initial_temperature_c=[30.0, p.temperature_limit_c + 1])
    out = model.step(0.01, [0.5, 0.5])
    assert out.error[1] & ERROR_OVERHEATING
    assert not out.error[0] & ERROR_OVERHEATING
    assert out.torque_enabled.tolist() == [True, False]


def test_bad_inputs_are_refused_with_their_names() -> None:
    with pytest.raises(ServoParamsError, match='stall_current_a'):
        ServoParams.ax18a().with_changes(stall_current_a=-1.0)
    model = ServoModel(count=2)
    with pytest.raises(ServoParamsError, match='goal_position_rad'):
        model.step(0.01, [0.0, 0.0, 0.0])
    with pytest.raises(ServoParamsError, match='dt_s'):
        model.step(0.0, 0.0)
    with pytest.raises(ServoParamsError, match='servo model'):
        ServoParams.by_name('mx64')


def test_loss_breakdown_balances_supply_power() -> None:
    """Every watt of supply power is in one loss term (fine sub-steps: the integrator's own
    dissipation vanishes); recording the breakdown does not change the simulation."""
    def goals(t: float) -> list[float]:
        return [0.8 * math.sin(6 * t), 0.5 * math.copysign(1.0, math.sin(3 * t)),
                0.3 * math.sin(20 * t)]

    kw = dict(count=3, load_inertia_kgm2=3e-4, max_substep_s=1e-4, extra_power_w=0.2)
    rec = ServoModel(record_losses=True, **kw)
    plain = ServoModel(**kw)
    supply, parts = [], []
    for k in range(200):
        out = rec.step(0.01, goals(0.01 * k), [-0.3, 0.1, -0.5], 11.9)
        ref = plain.step(0.01, goals(0.01 * k), [-0.3, 0.1, -0.5], 11.9)
        assert ref.losses is None
        assert_allclose(out.power_w, ref.power_w, rtol=0, atol=0)
        supply.append(out.power_w)
        parts.append(sum(out.losses.values()))
    assert set(out.losses) == {'standby', 'extra', 'copper', 'brake', 'coulomb', 'gear',
                               'viscous', 'kinetic', 'load'}
    assert_allclose(np.mean(parts, axis=0), np.mean(supply, axis=0), rtol=2e-3)
    assert_allclose(out.losses['standby'], 0.05 * 11.9)
    assert_allclose(out.losses['load'], out.mechanical_power_w)


def test_goal_faster_than_the_no_load_speed_is_not_followed() -> None:
    """A goal ramp at 13.4 rad/s (the femur's peak in a 0.165 s swing of the AntBot gait) is
    beyond the AX-18A at 11.9 V: the servo saturates at full duty and its speed stays at the
    no-load speed for that voltage, so the tracking error grows."""
    p = ServoParams.ax18a()
    w_max = (11.9 - p.winding_resistance_ohm * p.no_load_current_a) / p.back_emf_constant_v_s
    model = ServoModel(p, count=1, initial_position_rad=-1.0)
    speeds, errors = [], []
    for k in range(1, 13):
        goal = -1.0 + 13.4 * 0.01 * k
        out = model.step(0.01, goal, 0.0, 11.9)
        speeds.append(out.velocity_rad_s[0])
        errors.append(goal - out.position_rad[0])
    assert max(speeds) <= w_max * 1.01     # 26 degC winding: magnet flux 0.35 % lower
    assert_allclose(speeds[-1], w_max, rtol=0.01)
    assert errors[-1] > errors[5] > math.radians(10)
    assert_allclose(out.load_fraction, 1.0)


def test_dithered_friction_holds_a_static_load_with_the_motor() -> None:
    """Karnopp stick-slip lets the gear friction carry part of a static load (the shaft rests at
    the band edge it was pushed to); with friction smoothing the joint creeps until the motor
    carries all of it, and the loss terms still balance the supply power."""
    base = ServoParams.ax18a()
    torques = {}
    for w_s in (0.0, 0.2):
        p = base.with_changes(friction_smoothing_rad_s=w_s)
        model = ServoModel(p, count=1, record_losses=True)
        out = run(model, 3.0, 0.0, tau=-0.5, volts=11.9)
        ke = p.back_emf_constant_v_s * (1.0 + p.magnet_temp_coeff_per_k
                                        * (26.0 - p.reference_temperature_c))
        torques[w_s] = float(out.load_fraction[0] * 11.9 / model.winding_resistance_ohm()[0]
                             * ke)
        assert abs(out.velocity_rad_s[0]) < 1e-3
    # band edge (0.5 - c) / (2 - eta) against the whole load
    assert_allclose(torques[0.0], (0.5 - base.coulomb_friction_nm) / (2 - base.gear_efficiency),
                    rtol=0.05)
    assert_allclose(torques[0.2], 0.5, rtol=0.02)
    with pytest.raises(ServoParamsError, match='friction_smoothing_rad_s'):
        base.with_changes(friction_smoothing_rad_s=-0.1)
    p = base.with_changes(friction_smoothing_rad_s=0.2)
    model = ServoModel(p, count=1, record_losses=True, max_substep_s=1e-4,
                       load_inertia_kgm2=3e-4)
    supply, parts = [], []
    for k in range(300):
        out = model.step(0.01, 0.5 * math.sin(0.05 * k), -0.4, 11.9)
        supply.append(out.power_w[0])
        parts.append(sum(v[0] for v in out.losses.values()))
    assert_allclose(np.mean(parts), np.mean(supply), rtol=2e-3)


@pytest.mark.parametrize('changes', [{}, {'coulomb_friction_nm': 0.07,
                                          'viscous_friction_nm_s': 0.01}])
def test_gear_loss_follows_the_direction_of_power_flow(changes) -> None:
    """Load-dependent gear friction on both sides of the power flow. Lifting a 0.5 N m load at
    1 rad/s the motor drives it through the gear: ``k_e i = (T + c + b w) / eta``; lowering it
    at 1 rad/s the load back-drives the gear against the motor: ``k_e i = (T - c - b w) / (2 -
    eta)`` (the gear friction ``(1 - eta) |k_e i|`` opposes the motion either way, so the
    back-driving efficiency is ``1 / (2 - eta)``). With the datasheet-honest no-load current
    (0.2 A: c 0.07 N m, b 0.01 N m s/rad) the AX-18A points give eta = 0.78."""
    p = ServoParams.ax18a().with_changes(**changes)
    c, b, eta = p.coulomb_friction_nm, p.viscous_friction_nm_s, p.gear_efficiency
    if changes:
        assert_allclose(p.no_load_current_a, 0.2, rtol=0.05)
        assert_allclose(eta, 0.78, atol=0.01)
    motor_nm = {}
    for speed in (1.0, -1.0):
        model = ServoModel(p, count=1, initial_position_rad=-0.9 * speed,
                           initial_temperature_c=25.0, ambient_temperature_c=25.0,
                           record_losses=True, max_substep_s=2e-4)
        copper, gear, positions = [], [], []
        for k in range(1, 1801):        # goal ramp updated every 1 ms
            out = model.step(0.001, -0.9 * speed + speed * 0.001 * k, -0.5, 12.0)
            if k > 1000:
                copper.append(out.losses['copper'][0])
                gear.append(out.losses['gear'][0])
                positions.append(out.position_rad[0])
        assert_allclose(np.mean(np.diff(positions)) / 0.001, speed, rtol=0.01)
        r = model.winding_resistance_ohm()[0]
        motor_nm[speed] = p.back_emf_constant_v_s * math.sqrt(np.mean(copper) / r)
        # the gear term is (1 - eta) |k_e i| |w| whichever side drives
        assert_allclose(np.mean(gear), (1 - eta) * motor_nm[speed], rtol=0.02)
    assert_allclose(motor_nm[1.0], (0.5 + c + b) / eta, rtol=0.02)
    assert_allclose(motor_nm[-1.0], (0.5 - c - b) / (2 - eta), rtol=0.02)


@pytest.mark.parametrize('compiled', [True, False])
def test_static_friction_ratio_raises_the_breakaway_band_only(compiled) -> None:
    """Stiction (``static_friction_ratio``): a limp shaft at rest under a load between the
    sliding friction ``c`` and ``ratio c`` stays put, but once moving it slides against ``c``
    alone. A servo holding its goal unloaded, then loaded with 0.5 N m: with one friction level
    the shaft gives way until the motor holds ``(T - c) / (2 - eta)``; with a breakaway band
    wider than the load the motor side stays put and the gear holds nearly all of it. (A shaft
    that comes to rest while sliding stops at the sliding band's edge either way.) Ratios below
    1 are refused."""
    base = ServoParams.ax18a()
    c = base.coulomb_friction_nm
    stiff = base.with_changes(static_friction_ratio=2.0)
    moved = {}
    for name, p in (('one level', base), ('stiction', stiff)):
        model = ServoModel(p, count=2, torque_enabled=False, max_substep_s=1e-4)
        model.compiled = compiled
        model.velocity_rad_s[1] = -0.5       # the second one already sliding the load's way
        out = run(model, 0.2, 0.0, tau=-1.5 * c)
        moved[name] = out.velocity_rad_s
    assert moved['one level'][0] < -0.1      # breaks away at once: 1.5 c > c
    assert moved['stiction'][0] == 0.0       # held: 1.5 c < 2 c
    # sliding, the band is the sliding one: the load 1.5 c keeps accelerating it
    assert moved['stiction'][1] < -0.5 and moved['one level'][1] < -0.5
    mu = 1.0 - base.gear_efficiency
    held = {}
    for ratio in (1.0, 2.2):
        p = base.with_changes(static_friction_ratio=ratio)
        model = ServoModel(p, count=1, initial_position_rad=0.3)
        model.compiled = compiled
        run(model, 0.5, 0.3, volts=11.9)               # at its goal, unloaded
        start = model.output_position_rad(np.zeros(1))[0]
        out = run(model, 2.0, 0.3, tau=-0.5, volts=11.9)
        assert abs(out.velocity_rad_s[0]) < 1e-3
        ke = p.back_emf_constant_v_s * (1.0 + p.magnet_temp_coeff_per_k
                                        * (26.0 - p.reference_temperature_c))
        held[ratio] = (float(out.load_fraction[0] * 11.9 / model.winding_resistance_ohm()[0]
                             * ke), model.motor_position_rad[0] - start)
    assert_allclose(held[1.0][0], (0.5 - c) / (1.0 + mu), rtol=0.05)
    assert held[1.0][1] < -0.01                         # gave way under the load
    # the gear holds it: the motor side does not move, and the motor carries only what the
    # horn's deflection under the load (compliance and backlash, 0.7 degrees) asks of the P
    # controller, 0.08 N m
    assert held[2.2][1] == 0.0 and 0.0 < held[2.2][0] < 0.1
    for bad in (0.99, float('nan'), float('inf')):
        with pytest.raises(ServoParamsError, match='static_friction_ratio'):
            base.with_changes(static_friction_ratio=bad)
