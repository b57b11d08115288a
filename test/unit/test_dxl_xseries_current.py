"""X-series Present Current on the emulated bus, and the driver's X-series effort path.

A real XM430 reports in Present Current (126) "the current value flowing through the device's
motor" (e-Manual), 2.69 mA per unit: torque-like, positive while the motor drives the positive
way, negative while it brakes a load that back-drives it. The emulator wrote the servo model's
PWM duty there (scaled by the stall current), which carries the back-EMF: the efforts had the
velocity's sign (a joint lowering a load read -0.25 N m for a +1 N m holding torque, so its
joint power was positive) and ``energy_monitor`` refused them as torques. Now it writes the
model's signed winding current; the driver turns it into torque with the datasheet's N m/A
(stall torque / (stall current - standby current) at 12 V: 4.1 / 2.26 = 1.814 N m/A for the
XM430-W350), divided by eta^2 when the load back-drives the servo (eta 0.739: the gear's
losses are then on the load's side). With one constant (4.1 / 2.3 = 1.783 N m/A, no gear
model) a servo lowering 1 N m at 1 rad/s read 0.55 N m and the joints of a leg absorbed about
half the power they truly did.

These tests talk to the emulator's pty thread: they are in ``scripts/test.sh``'s ``timed``
list."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.control_tables import (
    ALL_MODELS,
    AX18A,
    BACK_DRIVE_DEAD_BAND_RAD_S,
    MX64,
    XL430,
    XM430,
    table_by_name,
)
from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator
from hexapod_bench_drivers.servo_model import ServoModel, ServoParams
from hexapod_energy.descriptors import implausible_effort_power

pytestmark = pytest.mark.timeout(60)

#: the driver's torque per ampere while driving: the e-Manual's stall torque over its stall
#: current less the standby current (the electronics' 40 mA are not in Present Current) [N m/A]
K_DRIVER = XM430.stall_torque_nm / (XM430.stall_current_a - 0.04)
#: the XM430's gear efficiency (its ServoModel preset's, from the datasheet points)
ETA = XM430.gear_efficiency


def _poll_until(bus, predicate, max_cycles=20000):
    for _ in range(max_cycles):
        result = bus.poll()
        if predicate(result.readings[0]):
            return result.readings[0]
    raise AssertionError('condition not reached')


#: the e-Manual's standby current of every Present Current model [A] (Specifications, rendered
#: from github.com/ROBOTIS-GIT/emanual _data/dxl_x_info.yml and _data/dxl_mx_info.yml)
STANDBY_A = {'XM430-W350': 0.04, 'XM430-W210': 0.04, 'XH430-W210': 0.04, 'XH430-W350': 0.04,
             'XM540-W150': 0.04, 'XM540-W270': 0.04, 'XL330-M077': 0.017, 'XL330-M288': 0.017,
             'MX-64(2.0)': 0.1, 'MX-106(2.0)': 0.1}


@pytest.mark.parametrize('model,nm_per_a', [
    ('XM540-W150', 7.3 / 4.36), ('XM540-W270', 10.6 / 4.36), ('XM430-W350', 4.1 / 2.26),
    ('XH430-W350', 3.4 / 1.26), ('MX-64(2.0)', 6.0 / 4.0), ('XL330-M288', 0.52 / 1.453)])
def test_present_current_to_torque_is_the_datasheet_torque_per_ampere(model, nm_per_a):
    """The driver's effort from Present Current while driving: the current times stall torque
    / (stall current - standby current) at the rated voltage. The e-Manual prints stall torque
    / stall current beside the XM540's and MX(2.0)'s stall torques (1.659 N m/A for the
    XM540-W150, 1.463 for the MX-64(2.0)), but the standby current is the electronics', not
    in Present Current. Only the XM430-W350 had it taken out (the others were 0.9-3.2 % low:
    XH430 2.615 for 2.698 N m/A). The stall torque is at the output, so the gear's losses when
    driving are in it."""
    table = table_by_name(model)
    raw = 1000
    effort = table.current_to_torque_nm(raw * table.current_unit_a, 1.0)
    assert_allclose(effort, raw * table.current_unit_a * nm_per_a, rtol=5e-4)
    assert_allclose(table.torque_per_amp_nm_a, nm_per_a, rtol=5e-4)


def test_standby_current_and_gear_efficiency_are_the_servo_model_presets():
    """The XM430-W350 and XL430-W250 take both figures from their ServoModel presets; every
    other Present Current model has the e-Manual's standby current (it had 0) and no gear
    efficiency (1: no back-drive correction; no page gives one), the other Present Load models
    neither."""
    for table, params in ((XM430, ServoParams.xm430()), (XL430, ServoParams.xl430())):
        assert table.standby_current_a == params.standby_current_a
        assert_allclose(table.gear_efficiency, params.gear_efficiency, atol=1e-3)
    current = [t for t in ALL_MODELS if 'present_current' in t.registers]
    assert sorted(t.model_name for t in current) == sorted(STANDBY_A)
    for table in current:
        assert table.standby_current_a == STANDBY_A[table.model_name], table.model_name
        assert table.gear_efficiency == (1.0 if table is not XM430 else ETA)
    for table in ALL_MODELS:
        if table not in current and table is not XL430:
            assert (table.standby_current_a, table.gear_efficiency) == (0.0, 1.0), table
    assert_allclose(XM430.torque_per_amp_nm_a, ServoParams.xm430().torque_constant_nm_a)


def test_back_driven_current_is_divided_by_eta_squared_beyond_a_dead_band():
    """The load back-drives the servo (current against the velocity): the motor's torque
    k i passes the gear the other way, so the output torque is k i / eta^2 (k = the datasheet's
    N m/A, which holds one eta). Within the dead band about rest the driving form stays; the
    correction grows linearly to its full value at twice the band (no jump of 1.83 at one
    speed for a velocity reading that flickers); eta can be overridden, 1 = none."""
    band = BACK_DRIVE_DEAD_BAND_RAD_S
    i = 0.5
    drive = i * K_DRIVER
    assert XM430.current_to_torque_nm(i, 1.0) == drive
    assert XM430.current_to_torque_nm(-i, -1.0) == -drive
    assert_allclose(XM430.current_to_torque_nm(i, -1.0), drive / ETA ** 2)
    assert_allclose(XM430.current_to_torque_nm(-i, 1.0), -drive / ETA ** 2)
    for v in (0.0, 0.5 * band, band, -band):
        assert XM430.current_to_torque_nm(i, v) == drive
    assert_allclose(XM430.current_to_torque_nm(i, -1.5 * band),
                    drive * (1 + 0.5 * (ETA ** -2 - 1)))
    assert_allclose(XM430.current_to_torque_nm(i, -2.0 * band), drive / ETA ** 2)
    speeds = -np.linspace(0.0, 3 * band, 301)
    torques = np.array([XM430.current_to_torque_nm(i, v) for v in speeds])
    assert np.all(np.diff(torques) >= 0) and np.max(np.diff(torques)) < 0.01 * drive
    assert_allclose(XM430.current_to_torque_nm(i, -1.0, gear_efficiency=0.9), drive / 0.81)
    assert XM430.current_to_torque_nm(i, -1.0, gear_efficiency=1.0) == drive
    assert_allclose(XM430.current_to_torque_nm(i, -band * 1.01, dead_band_rad_s=0.0),
                    drive / ETA ** 2)
    xm540 = table_by_name('XM540-W150')                    # no preset: no correction
    assert_allclose(xm540.current_to_torque_nm(i, -1.0), i * 7.3 / 4.36)
    assert_allclose(xm540.current_to_torque_nm(i, -1.0, gear_efficiency=0.7),
                    i * 7.3 / 4.36 / 0.49)


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


def _lift_and_lower(load_nm: float, speed_rad_s: float = 1.0, **bus_kw):
    """An XM430 at 1 rad/s up to +0.6 rad and down to -0.6 rad under a constant load pulling
    the negative way (gravity): (velocity, effort) of every reading. The emulator's clock
    advances 5 ms a cycle (no wall clock)."""
    rows = []
    now = [0.0]
    with ServoBusEmulator.of_model('XM430-W350', [1], clock=lambda: now[0]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1)], protocol=2,
                         timeout_margin_ms=10.0, **bus_kw) as bus:
        emu.servo(1).external_torque_nm = load_nm
        assert all(bus.set_torque(True).values())
        for target in (0.6, -0.6):
            bus.write_goals({'a': target}, {'a': speed_rad_s})
            stop = target - math.copysign(0.1, target)   # (held off the goal by the load)
            for _ in range(20000):
                now[0] += 0.005
                r = bus.poll().readings[0]
                rows.append((r.velocity_rad_s, r.effort_nm))
                if (r.position_rad - stop) * math.copysign(1.0, target) > 0:
                    break
    return np.array(rows)


def _steady(vel):
    speed = XM430.speed_limit_to_rad_s(XM430.rad_s_to_speed_limit(1.0))
    steady = np.abs(np.abs(vel) - speed) < 0.03 * speed
    up, down = steady & (vel > 0), steady & (vel < 0)
    assert up.sum() > 50 and down.sum() > 50
    return speed, up, down


def test_xm430_effort_is_the_joint_torque_lifting_and_lowering():
    """Lifting a 1 N m load the motor drives (effort and velocity positive); lowering it, it
    brakes: the effort stays positive while the velocity is negative, so the joint absorbs
    power. Old emulator: +1.87 N m lifting (the duty's back-EMF part), -0.25 N m lowering
    (positive joint power both ways). The model's motor current, with the gear's losses on
    the model's side: lifting ``k_t i = T + c + b w`` (k_t = eta k_e = 1.814 N m/A, the
    driver's N m/A), lowering ``(2 - eta) k_e i = T - c - b |w|`` (the load back-drives the
    lossy gear), which the driver divides by eta^2. One constant (4.1 / 2.3 N m/A, no gear
    model) read 1.03 N m lifting and 0.55 N m lowering; now 1.05 and 1.03 (the excess: the
    gear's Coulomb and viscous friction c + b w = 0.044 N m, in the current both ways)."""
    load = -1.0
    rows = _lift_and_lower(load)
    vel, effort = rows.T
    speed, up, down = _steady(vel)
    # Present Current in whole 2.69 mA units, turned into torque with the datasheet's N m/A,
    # divided by eta^2 while lowering
    units = effort / (XM430.current_unit_a * K_DRIVER)
    assert_allclose(units[up], np.rint(units[up]), atol=1e-6)
    assert_allclose(units[down] * ETA ** 2, np.rint(units[down] * ETA ** 2), atol=1e-6)
    assert np.all(effort[up] > 0) and np.all(effort[down] > 0)
    p = ServoParams.xm430()
    ke = p.back_emf_constant_v_s * (1.0 + p.magnet_temp_coeff_per_k * (26.0 - 25.0))
    eta = p.gear_efficiency
    c, b = p.coulomb_friction_nm, p.viscous_friction_nm_s
    lift = K_DRIVER * (-load + c + b * speed) / (eta * ke)                     # 1.049 N m
    lower = K_DRIVER * (-load - c - b * speed) / ((2.0 - eta) * ke) / ETA ** 2   # 1.028 N m
    assert_allclose(np.median(effort[up]), lift, rtol=0.02)
    assert_allclose(np.median(effort[down]), lower, rtol=0.02)
    # both within 6 % of the load (one constant: 0.55 N m lowering)
    assert_allclose(np.median(effort[up | down]), -load, rtol=0.06)
    assert_allclose(np.median(effort[down]), -load, rtol=0.06)
    # the joint's power is negative while lowering; energy_monitor takes such efforts as
    # torques (net / positive joint power well under 0.9, P_out below a 20 W P_in)
    power = vel * effort
    assert np.all(power[down] < 0)
    positive, net = float(np.mean(np.clip(power, 0, None))), float(np.mean(power))
    assert net < 0.9 * positive
    assert implausible_effort_power(positive, 20.0, net) == ''


def test_the_bus_gear_efficiency_overrides_the_model_s():
    """``gear_efficiency=1`` (a driver parameter) turns the back-drive correction off: the
    lowering servo reads the driving form, 0.56 N m for 1 N m; 0.9 divides it by 0.81."""
    for eta, expected in ((1.0, 0.559), (0.9, 0.559 / 0.81)):
        vel, effort = _lift_and_lower(-1.0, gear_efficiency=eta).T
        down = _steady(vel)[2]
        assert_allclose(np.median(effort[down]), expected, rtol=0.02)
    with pytest.raises(ValueError, match='gear_efficiency'):
        DynamixelBus('/dev/null', [JointConfig('a', 1)], protocol=2, gear_efficiency=1.5)
    for typo in (0.07, 0.0, float('nan')):  # 0.07 for 0.7: back-driven efforts x200
        with pytest.raises(ValueError, match='gear_efficiency'):
            DynamixelBus('/dev/null', [JointConfig('a', 1)], protocol=2, gear_efficiency=typo)
    with pytest.raises(ValueError, match='back_drive_dead_band_rad_s'):
        DynamixelBus('/dev/null', [JointConfig('a', 1)], protocol=2,
                     back_drive_dead_band_rad_s=-1.0)


def _back_drive_notes(bus):
    return [n for n in bus.take_notes() if 'back-drive correction' in n]


def test_models_without_a_gear_efficiency_are_noted_at_open_with_their_ids():
    """A bus of Present Current servos whose model has no gear efficiency (XH430-W350, MX-64
    (2.0), XM540-W150) and none given to the bus: one note at open names them with their IDs,
    says their back-driven efforts are not corrected and how to give one (the driver logs the
    notes as warnings); the XM430-W350 (its preset's 0.739) and the XL430 (Present Load) are
    not named. A servo silent at open is named when it answers. With the bus's
    ``gear_efficiency``, no note. Before, nothing said which servos went uncorrected."""
    models = [(1, 'XH430-W350'), (2, 'XH430-W350'), (3, 'MX-64(2.0)'), (4, 'XM430-W350'),
              (5, 'XL430-W250'), (6, 'XM540-W150')]
    joints = [JointConfig(f'j{k}', k) for k, _ in models]
    with ServoBusEmulator.of_models(models) as emu:
        emu.inject(6, 'no_answer')
        bus = DynamixelBus(emu.port_name, joints, protocol=2, timeout_margin_ms=10.0,
                           silent_after=1, probe_interval_cycles=1)
        with bus:
            (note,) = _back_drive_notes(bus)
            assert note.startswith('XH430-W350 (ids 1, 2), MX-64(2.0) (id 3): no gear '
                                   'efficiency is known for these models')
            assert 'XM430-W350 (' not in note and 'XL430' not in note and 'XM540' not in note
            assert '-p gear_efficiency:=' in note
            emu.clear_faults(6)
            for _ in range(20):
                if bus.poll().readings[5].ok:
                    break
            assert bus.poll().readings[5].ok
            (late,) = _back_drive_notes(bus)
            assert late.startswith('XM540-W150 (id 6): no gear efficiency is known for this '
                                   'model')
            for _ in range(5):
                bus.poll()
            assert _back_drive_notes(bus) == []                  # each model once
        with DynamixelBus(emu.port_name, joints, protocol=2, timeout_margin_ms=10.0,
                          gear_efficiency=0.7) as bus:
            assert _back_drive_notes(bus) == []


@pytest.mark.parametrize('model', ['XH430-W350', 'MX-64(2.0)', 'XL330-M288'])
def test_the_driver_s_gear_efficiency_corrects_models_without_one(model):
    """A servo of a model without a gear efficiency raising a joint against a load that pulls
    it the same way (the load back-drives it: current against the velocity) reads the load's
    torque (the emulator's stand-in physics holds it exactly, its current over the table's
    N m/A) without correction, and that torque over 0.7^2 with the bus's gear_efficiency 0.7:
    the driver's parameter applies to every Present Current model."""
    table = table_by_name(model)
    torque = 0.25 * table.stall_torque_nm     # pulls the positive way: held by -torque
    unit = table.current_unit_a * table.torque_per_amp_nm_a
    for eta in (None, 0.7):
        now = [0.0]
        with ServoBusEmulator.of_model(table, [1], clock=lambda: now[0]) as emu, \
                DynamixelBus(emu.port_name, [JointConfig('a', 1)], protocol=2,
                             timeout_margin_ms=10.0, gear_efficiency=eta) as bus:
            emu.servo(1).external_torque_nm = torque
            assert all(bus.set_torque(True).values())
            bus.write_goals({'a': 0.5}, {'a': 1.0})
            for _ in range(400):
                now[0] += 0.005
                r = bus.poll().readings[0]
                if r.ok and r.velocity_rad_s > 0.5 and r.position_rad > 0.1:
                    break
            else:
                raise AssertionError('the servo did not move')
            assert r.velocity_rad_s * r.effort_nm < 0            # back-driven
            assert_allclose(r.effort_nm, -torque / (eta or 1.0) ** 2, atol=unit / 0.49)


def test_present_current_saturates_at_the_current_limit():
    """Present Current stays within the e-Manual's range, +-Current Limit (38) of the servo:
    with Current Limit 100 (0.269 A) a servo under 2 N m reads -100 and is back-driven (the
    joint torque -0.49 N m / eta^2 = -0.89 N m; -0.48 with one constant), with the default
    1193 it reads its current."""
    with ServoBusEmulator.of_model('XM430-W350', [1, 2]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1), JointConfig('b', 2)],
                         protocol=2, timeout_margin_ms=10.0) as bus:
        emu.servo(1).set('current_limit', 100)
        for k in (1, 2):
            emu.servo(k).external_torque_nm = 2.0
        assert all(bus.set_torque(True).values())
        driving = -100 * XM430.current_unit_a * K_DRIVER         # -0.4876 N m
        floor = driving / ETA ** 2                               # -0.8929 N m
        done = _poll_until(bus, lambda r: r.effort_nm < driving + 1e-9
                           and r.velocity_rad_s > 2 * BACK_DRIVE_DEAD_BAND_RAD_S, 5000)
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


@pytest.mark.parametrize('model', ['AX-18A', 'MX-64', 'XL430-W250'])
def test_present_load_efforts_have_no_gear_correction(model):
    """Present Load (Protocol 1.0 AX and MX, whose Current register is not read; the XL430's
    PWM duty) stays load fraction * stall torque, whatever the gear efficiency: moving both
    ways under a load, with the bus's ``gear_efficiency`` 0.5."""
    table = table_by_name(model)
    assert table in (AX18A, MX64, XL430)
    now = [0.0]
    seen = set()
    with ServoBusEmulator.of_model(table, [1], clock=lambda: now[0]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1)], protocol=table.protocol,
                         timeout_margin_ms=10.0, gear_efficiency=0.5) as bus:
        emu.servo(1).external_torque_nm = -0.2 * table.stall_torque_nm
        assert all(bus.set_torque(True).values())
        for target in (0.4, -0.4):
            bus.write_goals({'a': target}, {'a': 1.0})
            for _ in range(150):
                now[0] += 0.005
                r = bus.poll().readings[0]
                if not r.ok:   # (a reply late behind a slow physics step: retried next cycle)
                    continue
                assert r.effort_nm == r.load_fraction * table.stall_torque_nm
                seen.add((np.sign(r.velocity_rad_s), np.sign(r.effort_nm)))
    assert (-1.0, 1.0) in seen or (1.0, -1.0) in seen or (-1.0, -1.0) in seen


def test_a_leg_of_three_xm430s_absorbs_the_power_its_loads_put_in():
    """A leg of three XM430s (loads 0, -1 and 0.6 N m, gravity-like) swinging 0.3-0.35 rad at
    1.25 Hz, its goals written every 10 ms (the emulator's clock advanced by as much): the
    work the joints absorb (the negative part of effort * velocity) against the emulator's
    truth, -load * velocity. One constant (no gear model): 0.68 W for 1.24 W (the back-driven
    current read 0.55 of the torque), now 1.27 W. The positive part (P_out) is above its
    truth either way, 1.49 W then, 1.52 W now (the standby current: +1.7 %) for 1.27 W: the
    gear's Coulomb and viscous friction and the rotor's inertia are in the motor's current,
    not in the joint's torque, and the datasheet gives neither."""
    loads, amplitudes, period, dt = (0.0, -1.0, 0.6), (0.3, 0.35, 0.3), 0.8, 0.01
    names = ('coxa', 'femur', 'tibia')
    now = [0.0]
    rows = []
    with ServoBusEmulator.of_model('XM430-W350', [1, 2, 3], clock=lambda: now[0]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig(n, k + 1) for k, n in enumerate(names)],
                         protocol=2, timeout_margin_ms=10.0) as bus:
        for k, load in enumerate(loads):
            emu.servo(k + 1).external_torque_nm = load
        assert all(bus.set_torque(True).values())
        for i in range(int(round(6 * period / dt))):
            phase = 2.0 * math.pi * i * dt / period
            # the clock first: the physics then steps when the goals arrive, before they are
            # applied, whenever the emulator's thread reads them (the Sync Write has no reply)
            now[0] += dt
            bus.write_goals({n: a * math.sin(phase - k)
                             for k, (n, a) in enumerate(zip(names, amplitudes))})
            readings = bus.poll().readings
            if now[0] > 2 * period:            # four whole cycles after two to settle
                rows.append([(r.velocity_rad_s, r.effort_nm) for r in readings])
    vel, effort = np.moveaxis(np.array(rows), 2, 0)
    ok = np.all(np.isfinite(vel), axis=1)   # (a reply late behind a slow physics step: NaN)
    assert ok.sum() > 0.95 * int(round(4 * period / dt))
    vel, effort = vel[ok], effort[ok]
    power, truth = vel * effort, -np.array(loads) * vel

    def absorbed(p):
        return float(np.mean(np.clip(-p, 0.0, None).sum(axis=1)))

    def p_out(p):
        return float(np.mean(np.clip(p, 0.0, None).sum(axis=1)))

    assert 1.1 < absorbed(truth) < 1.5
    assert_allclose(absorbed(power), absorbed(truth), rtol=0.05)
    assert_allclose(p_out(power), 1.2 * p_out(truth), rtol=0.05)
