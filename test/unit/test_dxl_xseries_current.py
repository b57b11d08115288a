"""X-series Present Current on the emulated bus, and the driver's X-series effort path.

A real XM430 reports in Present Current (126) "the current value flowing through the device's
motor" (e-Manual), 2.69 mA per unit: torque-like, positive while the motor drives the positive
way, negative while it brakes a load that back-drives it. The emulator wrote the servo model's
PWM duty there (scaled by the stall current), which carries the back-EMF: the efforts had the
velocity's sign (a joint lowering a load read -0.25 N m for a +1 N m holding torque, so its
joint power was positive) and ``energy_monitor`` refused them as torques. Now it writes the
model's signed winding current; the driver turns it into torque with the datasheet's N m/A
(stall torque / stall current at 12 V: 4.1 / 2.3 = 1.783 N m/A for the XM430-W350).

These tests talk to the emulator's pty thread: they are in ``scripts/test.sh``'s ``timed``
list."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.control_tables import XM430, table_by_name
from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator
from hexapod_bench_drivers.servo_model import ServoModel, ServoParams
from hexapod_energy.descriptors import implausible_effort_power

pytestmark = pytest.mark.timeout(60)

#: the driver's torque per ampere: the e-Manual's stall torque over stall current (N m/A)
K_DRIVER = XM430.stall_torque_nm / XM430.stall_current_a


def _poll_until(bus, predicate, max_cycles=20000):
    for _ in range(max_cycles):
        result = bus.poll()
        if predicate(result.readings[0]):
            return result.readings[0]
    raise AssertionError('condition not reached')


@pytest.mark.parametrize('model,nm_per_a', [('XM540-W150', 1.659), ('XM540-W270', 2.409),
                                             ('XM430-W350', 4.1 / 2.3)])
def test_present_current_to_torque_is_the_datasheet_torque_per_ampere(model, nm_per_a):
    """The driver's effort from Present Current: the current times stall torque / stall
    current at the rated voltage, the N m/A the e-Manual prints beside the XM540's stall
    torque (12 V). The stall torque and current are at the output, so the gear is in it."""
    table = table_by_name(model)
    raw = 1000
    effort = table.load_to_fraction(raw) * table.stall_torque_nm
    assert_allclose(effort, raw * table.current_unit_a * nm_per_a, rtol=5e-4)


def test_servo_model_reports_its_signed_winding_current():
    """ServoOutput.winding_current_a is the motor current of the model's own state:
    ``i = (u V - k_e(T) w) / R(T)``, whose square is the winding loss; its sign is that of the
    motor torque (holding a load that pulls the positive way: negative), 0 with torque off."""
    p = ServoParams.xm430()
    m = ServoModel(p, count=3, max_substep_s=1e-3, initial_temperature_c=25.0,
                   ambient_temperature_c=25.0)
    m.torque_enabled[2] = False
    tau = np.array([1.0, -1.0, 1.0])
    for _ in range(300):                      # settle: held at rest under the loads
        m.step(0.01, 0.0, tau, 12.0)
    r = m.winding_resistance_ohm()            # R(T) and k_e(T) of the next step
    ke = p.back_emf_constant_v_s * (1.0 + p.magnet_temp_coeff_per_k
                                    * (m.temperature_c - p.reference_temperature_c))
    out = m.step(0.01, 0.0, tau, 12.0)
    assert_allclose(out.velocity_rad_s[:2], 0.0)
    i = out.winding_current_a
    assert i[0] < 0 < i[1] and i[2] == 0.0
    assert_allclose(i[:2], out.load_fraction[:2] * 12.0 / r[:2], rtol=1e-9)   # w = 0
    assert_allclose(out.winding_loss_w, i * i * r, rtol=1e-9)
    # the gear's static friction carries the rest of the load: the motor torque k_e i is
    # within c + (1 - eta) |k_e i| of the load
    motor = ke[:2] * i[:2]
    band = p.coulomb_friction_nm + (1.0 - p.gear_efficiency) * np.abs(motor)
    assert np.all(np.abs(motor + tau[:2]) <= band + 1e-6)
    # at stall (goal far off, shaft blocked): the datasheet's stall current less the standby
    m2 = ServoModel(p, count=1, initial_temperature_c=25.0, ambient_temperature_c=25.0)
    out = m2.step(1e-3, 3.0, -20.0, 12.0)
    assert_allclose(out.winding_current_a, p.stall_current_a - p.standby_current_a, rtol=1e-3)


def _lift_and_lower(load_nm: float, speed_rad_s: float = 1.0):
    """An XM430 at 1 rad/s up to +0.6 rad and down to -0.6 rad under a constant load pulling
    the negative way (gravity): (velocity, effort) of every reading."""
    rows = []
    with ServoBusEmulator.of_model('XM430-W350', [1]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1)], protocol=2,
                         timeout_margin_ms=10.0) as bus:
        emu.servo(1).external_torque_nm = load_nm
        assert all(bus.set_torque(True).values())
        for target in (0.6, -0.6):
            bus.write_goals({'a': target}, {'a': speed_rad_s})
            stop = target - math.copysign(0.1, target)   # (held off the goal by the load)
            for _ in range(20000):
                r = bus.poll().readings[0]
                rows.append((r.velocity_rad_s, r.effort_nm))
                if (r.position_rad - stop) * math.copysign(1.0, target) > 0:
                    break
    return np.array(rows)


def test_xm430_effort_is_the_joint_torque_lifting_and_lowering():
    """Lifting a 1 N m load the motor drives (effort and velocity positive); lowering it, it
    brakes: the effort stays positive while the velocity is negative, so the joint absorbs
    power. Old emulator: +1.87 N m lifting (the duty's back-EMF part), -0.25 N m lowering
    (positive joint power both ways). Magnitudes: the model's motor current through the
    driver's 1.783 N m/A, with the gear's losses on the model's side: lifting
    ``k_t i = T + c + b w`` (k_t = eta k_e = 1.814 N m/A), lowering ``(2 - eta) k_e i =
    T - c - b |w|`` (the load back-drives the lossy gear: 0.55 N m read for 1 N m)."""
    load = -1.0
    rows = _lift_and_lower(load)
    vel, effort = rows.T
    speed = XM430.speed_limit_to_rad_s(XM430.rad_s_to_speed_limit(1.0))
    steady = np.abs(np.abs(vel) - speed) < 0.03 * speed
    up, down = steady & (vel > 0), steady & (vel < 0)
    assert up.sum() > 50 and down.sum() > 50
    # Present Current in whole 2.69 mA units, turned into torque with the datasheet's N m/A
    units = effort / (XM430.current_unit_a * K_DRIVER)
    assert_allclose(units, np.rint(units), atol=1e-6)
    assert np.all(effort[up] > 0) and np.all(effort[down] > 0)
    p = ServoParams.xm430()
    ke = p.back_emf_constant_v_s * (1.0 + p.magnet_temp_coeff_per_k * (26.0 - 25.0))
    eta = p.gear_efficiency
    c, b = p.coulomb_friction_nm, p.viscous_friction_nm_s
    lift = K_DRIVER * (-load + c + b * speed) / (eta * ke)      # 1.026 N m
    lower = K_DRIVER * (-load - c - b * speed) / ((2.0 - eta) * ke)   # 0.551 N m
    assert_allclose(np.median(effort[up]), lift, rtol=0.02)
    assert_allclose(np.median(effort[down]), lower, rtol=0.02)
    # the joint's power is negative while lowering; energy_monitor takes such efforts as
    # torques (net / positive joint power well under 0.9, P_out below a 20 W P_in)
    power = vel * effort
    assert np.all(power[down] < 0)
    positive, net = float(np.mean(np.clip(power, 0, None))), float(np.mean(power))
    assert net < 0.9 * positive
    assert implausible_effort_power(positive, 20.0, net) == ''


def test_present_current_saturates_at_the_current_limit():
    """Present Current stays within the e-Manual's range, +-Current Limit (38) of the servo:
    with Current Limit 100 (0.269 A) a servo holding 2 N m reads -100 (the joint torque
    -0.48 N m), with the default 1193 it reads its current."""
    with ServoBusEmulator.of_model('XM430-W350', [1, 2]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1), JointConfig('b', 2)],
                         protocol=2, timeout_margin_ms=10.0) as bus:
        emu.servo(1).set('current_limit', 100)
        for k in (1, 2):
            emu.servo(k).external_torque_nm = 2.0
        assert all(bus.set_torque(True).values())
        floor = -100 * XM430.current_unit_a * K_DRIVER           # -0.4795 N m
        done = _poll_until(bus, lambda r: r.effort_nm < floor + 1e-9, 5000)
        assert emu.read_register(1, 'present_current') == -100
        assert_allclose(done.effort_nm, floor)
        for _ in range(20):
            assert bus.poll().readings[0].effort_nm >= floor - 1e-12
        for _ in range(5000):                                   # servo 2 at rest
            held = bus.poll().readings[1]
            if held.velocity_rad_s == 0.0:
                break
        assert -1193 < emu.read_register(2, 'present_current') < -200
        assert held.effort_nm < -200 * XM430.current_unit_a * K_DRIVER


@pytest.mark.parametrize('model', ['XL330-M288', 'MX-64(2.0)', 'XM540-W150', 'AX-18A',
                                   'MX-28', 'XL430-W250'])
def test_a_load_pulling_the_positive_way_reads_a_negative_effort(model):
    """Every model reports the torque it applies, whatever its physics: a load pulling the
    positive way is held with a negative torque. The stand-in physics (no ServoModel preset:
    XL330, MX(2.0), XM540, MX-28) reported the external torque itself (+0.25 of stall, where
    the AX-18A, XM430 and XL430 with the servo model read negative)."""
    table = table_by_name(model)
    torque = 0.25 * table.stall_torque_nm
    with ServoBusEmulator.of_model(table, [1]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1)], protocol=table.protocol,
                         timeout_margin_ms=10.0) as bus:
        assert all(bus.set_torque(True).values())
        emu.servo(1).external_torque_nm = torque
        reading = _poll_until(bus, lambda r: r.effort_nm < -0.1 * torque, 5000)
        assert reading.effort_nm < 0
        if 'present_current' in table.registers and model != 'XM430-W350':
            # the stand-in's current is its torque over the datasheet's N m/A
            assert_allclose(reading.effort_nm, -torque,
                            atol=table.current_unit_a / table.stall_current_a
                            * table.stall_torque_nm)
