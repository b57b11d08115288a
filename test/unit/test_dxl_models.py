"""Dynamixel models beyond AX/XL430/XM430: e-Manual figures, table layout, conversions, and the
real dynamixel_sdk driver (DynamixelBus) against the emulator for MX (1.0), MX(2.0), XL330 and a
mixed AX-18A + MX-28 bus."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose
from test_dxl_bus import _joints, _poll_until

from hexapod_bench_drivers.control_tables import (
    ALL_MODELS,
    MODELS_BY_NUMBER,
    MX28,
    MX64,
    MX64_2,
    RPM_TO_RAD_S,
    XL330_M288,
    ControlTableError,
    table_by_name,
    table_for_model,
)
from hexapod_bench_drivers.dynamixel_bus import BusError, DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import EmulatedServo, ServoBusEmulator

pytestmark = pytest.mark.timeout(60)

# e-Manual (emanual.robotis.com/docs/en/dxl/<page>): protocol, model number, ticks, span [deg],
# centre tick, velocity unit [rpm], stall torque [N m], stall current [A], no-load speed [rpm],
# rated voltage [V], Present Current unit [mA] (None: Present Load), Temperature Limit [degC].
EXPECTED = {
    'AX-12A': (1, 12, 1024, 300, 512, 0.111, 1.5, 1.5, 59, 12, None, 70),
    'AX-18A': (1, 18, 1024, 300, 512, 0.111, 1.8, 2.2, 97, 12, None, 75),
    'AX-12W': (1, 300, 1024, 300, 512, 0.111, 0.2, 1.4, 54, 12, None, 70),
    'MX-28': (1, 29, 4096, 360, 2048, 0.114, 2.5, 1.4, 55, 12, None, 80),
    'MX-64': (1, 310, 4096, 360, 2048, 0.114, 6.0, 4.1, 63, 12, None, 80),
    'MX-106': (1, 320, 4096, 360, 2048, 0.114, 8.4, 5.2, 45, 12, None, 80),
    'RX-24F': (1, 24, 1024, 300, 512, 0.111, 2.6, 2.4, 126, 12, None, 80),
    'RX-28': (1, 28, 1024, 300, 512, 0.111, 3.7, 1.9, 85, 18.5, None, 80),
    'RX-64': (1, 64, 1024, 300, 512, 0.111, 5.3, 2.6, 64, 18.5, None, 80),
    'MX-28(2.0)': (2, 30, 4096, 360, 2048, 0.229, 2.5, 1.4, 55, 12, None, 80),
    'MX-64(2.0)': (2, 311, 4096, 360, 2048, 0.229, 6.0, 4.1, 63, 12, 3.36, 80),
    'MX-106(2.0)': (2, 321, 4096, 360, 2048, 0.229, 8.4, 5.2, 45, 12, 3.36, 80),
    'XL430-W250': (2, 1060, 4096, 360, 2048, 0.229, 1.5, 1.4, 61, 12, None, 72),
    'XM430-W350': (2, 1020, 4096, 360, 2048, 0.229, 4.1, 2.3, 46, 12, 2.69, 80),
    'XM430-W210': (2, 1030, 4096, 360, 2048, 0.229, 3.0, 2.3, 77, 12, 2.69, 80),
    'XH430-W210': (2, 1010, 4096, 360, 2048, 0.229, 2.5, 1.3, 50, 12, 2.69, 80),
    'XH430-W350': (2, 1000, 4096, 360, 2048, 0.229, 3.4, 1.3, 30, 12, 2.69, 80),
    'XC430-W150': (2, 1070, 4096, 360, 2048, 0.229, 1.6, 1.4, 106, 12, None, 80),
    'XC430-W240': (2, 1080, 4096, 360, 2048, 0.229, 1.9, 1.4, 70, 12, None, 80),
    'XM540-W150': (2, 1130, 4096, 360, 2048, 0.229, 7.3, 4.4, 53, 12, 2.69, 80),
    'XM540-W270': (2, 1120, 4096, 360, 2048, 0.229, 10.6, 4.4, 30, 12, 2.69, 80),
    'XL330-M077': (2, 1190, 4096, 360, 2048, 0.229, 0.215, 1.47, 383, 5, 1.0, 70),
    'XL330-M288': (2, 1200, 4096, 360, 2048, 0.229, 0.52, 1.47, 103, 5, 1.0, 70),
}
BY_NAME = {t.model_name: t for t in ALL_MODELS}


def test_every_model_matches_the_emanual_figures():
    assert set(BY_NAME) == set(EXPECTED)
    for name, (proto, number, ticks, span_deg, centre, rpm_unit, stall_nm, stall_a, no_load_rpm,
               volts, current_ma, temp_limit) in EXPECTED.items():
        t = BY_NAME[name]
        assert (t.protocol, t.model_number, t.ticks_per_span, t.center_tick) == (
            proto, number, ticks, centre), name
        assert_allclose(math.degrees(t.position_span_rad), span_deg, err_msg=name)
        assert_allclose([t.velocity_unit_rpm, t.stall_torque_nm, t.stall_current_a,
                         t.no_load_speed_rad_s / RPM_TO_RAD_S, t.rated_voltage_v],
                        [rpm_unit, stall_nm, stall_a, no_load_rpm, volts], err_msg=name)
        if current_ma is None:
            assert 'present_current' not in t.registers and t.current_unit_a == 0.0, name
            assert 'present_load' in t.registers, name
        else:
            assert_allclose(t.current_unit_a, current_ma * 1e-3, err_msg=name)
            assert t.reg('present_current').address == 126, name
        assert t.reg('temperature_limit').default == temp_limit, name
        assert t.page.startswith('https://emanual.robotis.com/docs/en/dxl/'), name
        assert table_for_model(proto, number) is t
        assert table_by_name(name) is t
    # The MX-64/106 Protocol 1.0 Current register: 2048 = 0 A, 4.5 mA per unit (e-Manual).
    assert MX64.reg('current').address == 68 and MX64.reg('current').default == 2048
    assert_allclose(MX64.p1_current_to_a(2148), 0.45)
    assert MX64.a_to_p1_current(0.45) == 2148
    with pytest.raises(ControlTableError, match='MX-28 has no Protocol 1.0 Current'):
        MX28.p1_current_to_a(2048)


def test_registers_do_not_overlap_and_blocks_are_contiguous():
    for t in ALL_MODELS:
        regs = sorted(t.registers.items(), key=lambda kv: kv[1].address)
        for (name_a, a), (name_b, b) in zip(regs, regs[1:]):
            assert a.address + a.size <= b.address, (t.model_name, name_a, name_b)
        for reg in t.registers.values():
            reg_bytes = reg.default.to_bytes(reg.size, 'little', signed=reg.signed)
            assert len(reg_bytes) == reg.size
        # The read block is filled by registers with no gap (one READ / Sync Read per servo) and
        # holds position, speed, load/current, voltage and temperature.
        start, length = t.read_block
        covered = sorted(b for r in t.registers.values()
                         if start <= r.address < start + length
                         for b in range(r.address, r.address + r.size))
        assert covered == list(range(start, start + length)), t.model_name
        assert (start, length) == ((36, 8) if t.protocol == 1 else (126, 21)), t.model_name
        # Goal block: speed limit and goal position adjacent, written in one Sync Write.
        goal, limit = t.reg('goal_position'), t.reg(t.speed_limit_register)
        g_start, g_len = t.goal_block
        assert g_len == goal.size + limit.size, t.model_name
        assert {goal.address, limit.address} == {g_start, g_start + min(goal.size, limit.size)}
        assert (g_start, g_len) == ((30, 4) if t.protocol == 1 else (112, 8)), t.model_name


def test_mx_protocol1_has_gains_not_compliance():
    for t in (MX28, MX64, BY_NAME['MX-106']):
        assert not [n for n in t.registers if 'compliance' in n], t.model_name
        assert [t.reg(n).address for n in ('d_gain', 'i_gain', 'p_gain')] == [26, 27, 28]
        assert t.reg('p_gain').default == 32
        assert t.reg('ccw_angle_limit').default == 4095
    for t in (BY_NAME['AX-12A'], BY_NAME['AX-12W'], BY_NAME['RX-28'], BY_NAME['RX-64']):
        assert t.reg('cw_compliance_slope').address == 28
        assert t.reg('ccw_angle_limit').default == 1023
    assert BY_NAME['AX-12W'].reg('cw_compliance_slope').default == 64


def test_unit_conversions_round_trip():
    for t in ALL_MODELS:
        # Positions: half a tick, whole range; 0 rad is the centre tick.
        assert t.position_to_rad(t.center_tick) == 0.0
        for rad in (-2.5, -1.0, -0.01, 0.0, 0.37, 2.5):
            if abs(rad) < t.position_span_rad / 2:
                assert abs(t.position_to_rad(t.rad_to_position(rad)) - rad) <= t.rad_per_tick / 2
        for tick in (0, 1, t.center_tick, t.max_tick):
            assert t.rad_to_position(t.position_to_rad(tick)) == tick
        # Speeds and loads: raw -> SI -> raw, both signs.
        for units in (0, 1, 37, 500, 1023):
            for sign in (1, -1):
                raw = t.rad_s_to_velocity(sign * units * t.velocity_unit_rad_s)
                assert_allclose(t.velocity_to_rad_s(raw), sign * units * t.velocity_unit_rad_s)
                assert t.rad_s_to_velocity(t.velocity_to_rad_s(raw)) == raw
            if units:
                limit = t.rad_s_to_speed_limit(units * t.velocity_unit_rad_s)
                assert limit == units
                assert_allclose(t.speed_limit_to_rad_s(limit), units * t.velocity_unit_rad_s)
        for fraction in (-0.8, -0.25, 0.0, 0.1, 0.6):
            raw = t.fraction_to_load(fraction)
            step = (t.current_unit_a / t.stall_current_a if t.current_unit_a else 1e-3)
            assert abs(t.load_to_fraction(raw) - fraction) <= step / 2 + 1e-12, t.model_name
    # MX on Protocol 1.0: 4096 ticks over a full turn, 0.114 rpm units, bit 10 = clockwise.
    assert_allclose(MX28.position_to_rad(3072), math.pi / 2)
    assert_allclose(MX28.velocity_to_rad_s(1024 + 100), -100 * 0.114 * RPM_TO_RAD_S)
    assert_allclose(MX28.load_to_fraction(1024 + 300), -0.3)
    # Present Current in its own unit: 3.36 mA (MX(2.0)), 1 mA (XL330).
    assert_allclose(MX64_2.load_to_fraction(-1220) * MX64_2.stall_current_a, -1220 * 0.00336)
    assert_allclose(XL330_M288.load_to_fraction(735), 0.735 / 1.47)


def test_unknown_model_is_refused_with_the_known_names():
    with pytest.raises(ControlTableError) as err:
        table_for_model(1, 9999)
    msg = str(err.value)
    assert 'unknown Dynamixel model number 9999 on Protocol 1.0' in msg
    for name in ('AX-18A', 'MX-28', 'MX-64(2.0)', 'XM430-W210', 'XL330-M288'):
        assert name in msg
    assert '(P1' not in msg and '1060' not in msg          # names only, no numbers
    assert len(msg) < 400
    with pytest.raises(ControlTableError, match='expected one of AX-12A'):
        table_by_name('MX-12W')
    assert table_by_name('mx-64 (2.0)') is MX64_2 and table_by_name('ax18a').model_number == 18
    assert len(MODELS_BY_NUMBER) == len(ALL_MODELS)


def test_driver_reports_an_unknown_model_by_name():
    stranger = EmulatedServo(1, MX28)
    stranger.set('model_number', 360)           # an MX-12W: not described here
    with ServoBusEmulator([stranger]) as emu:
        bus = DynamixelBus(emu.port_name, [JointConfig('a', 1)], timeout_margin_ms=10.0)
        with pytest.raises(BusError, match=r'id 1: unknown Dynamixel model number 360 .*MX-28'):
            bus.open()
        assert bus.health()[0].model == 'unsupported model 360'


# (model, protocol, servos, external torque [N m]) for the driver-against-emulator tests.
DRIVER_CASES = [('MX-28', 1, 4, 0.5), ('MX-64(2.0)', 2, 4, 1.2), ('XL330-M288', 2, 3, 0.13),
                ('RX-28', 1, 4, 0.7)]


@pytest.mark.parametrize('model,protocol,n,torque_nm', DRIVER_CASES)
def test_sdk_driver_reads_model_correctly(model, protocol, n, torque_nm):
    table = table_by_name(model)
    volts = table.rated_voltage_v
    with ServoBusEmulator.of_model(table, range(1, n + 1)) as emu, \
            DynamixelBus(emu.port_name, _joints(n), protocol=protocol,
                         timeout_margin_ms=10.0) as bus:
        assert {h.model for h in bus.health()} == {model}
        first = bus.poll()
        assert [r.ok for r in first.readings] == [True] * n
        assert_allclose([r.voltage_v for r in first.readings], volts)
        assert_allclose([r.temperature_c for r in first.readings], 26.0)
        assert_allclose(first.readings[1].position_rad, 0.1, atol=table.rad_per_tick)  # offset
        assert_allclose([r.load_fraction for r in first.readings], 0.0)   # torque off: no load
        assert all(bus.set_torque(True).values())
        for k in range(1, n + 1):
            emu.servo(k).external_torque_nm = torque_nm
        # j1 moves 0.5 rad at a 1 rad/s speed limit: mid-way the servo reports that speed.
        assert bus.write_goals({'j1': 0.5}, {'j1': 1.0}) == 1
        speed = table.speed_limit_to_rad_s(table.rad_s_to_speed_limit(1.0))   # 1 rad/s in units
        mid = _poll_until(bus, lambda r: 0.15 < r.readings[0].position_rad < 0.35, 20000)
        assert_allclose(mid.readings[0].velocity_rad_s, speed, atol=table.velocity_unit_rad_s)
        goal_rad = table.position_to_rad(table.rad_to_position(0.5))   # the goal tick
        done = _poll_until(bus, lambda r: abs(r.readings[0].position_rad - goal_rad)
                           < table.rad_per_tick / 2 and r.readings[0].velocity_rad_s == 0.0,
                           20000)
        r1 = done.readings[0]
        # Load (Present Load 0.1 % or Present Current in the model's unit) -> effort: the
        # torque the servo holds its load with, minus the external torque (it read +torque).
        # Present Current: load is the current over the stall current, the effort the current
        # times the table's N m/A (the standby current out of the stall current).
        load_step = (table.current_unit_a / table.stall_current_a if table.current_unit_a
                     else 1e-3)
        expected = -torque_nm / table.stall_torque_nm
        if table.current_unit_a:
            expected = -torque_nm / table.torque_per_amp_nm_a / table.stall_current_a
        assert_allclose(r1.load_fraction, expected, atol=load_step)
        assert_allclose(r1.effort_nm, -torque_nm, atol=load_step * table.stall_torque_nm)
        assert_allclose(emu.present_position_rad(1), r1.position_rad, atol=table.rad_per_tick)
        # The reversed joint j2 reports the servo's load with its sign flipped.
        assert_allclose(done.readings[1].load_fraction, -expected, atol=load_step)
        assert_allclose(done.readings[1].voltage_v, volts)


def test_mx64_protocol1_current_register_follows_the_load():
    with ServoBusEmulator.of_model('MX-64', [1]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1)], timeout_margin_ms=10.0) as bus:
        bus.set_torque(True)
        emu.servo(1).external_torque_nm = -1.5    # 0.25 of 6.0 N m, held by +1.5 N m
        reading = _poll_until(bus, lambda r: r.readings[0].effort_nm > 1.0, 2000).readings[0]
        assert_allclose(reading.effort_nm, 1.5, atol=0.006)
        current = MX64.p1_current_to_a(emu.read_register(1, 'current'))
        assert_allclose(current, 0.25 * 4.1, atol=0.0045)


def test_mixed_ax18a_and_mx28_bus_and_no_gain_writes():
    servos = [(1, 'AX-18A'), (2, 'AX-18A'), (3, 'AX-18A'), (4, 'MX-28'), (5, 'MX-28'),
              (6, 'MX-28')]
    with ServoBusEmulator.of_models(servos) as emu, \
            DynamixelBus(emu.port_name, _joints(6), protocol=1, timeout_margin_ms=10.0) as bus:
        before = {i: bytes(emu.servo(i).memory[26:30]) for i in range(1, 7)}
        assert [h.model for h in bus.health()] == ['AX-18A'] * 3 + ['MX-28'] * 3
        assert all(r.ok for r in bus.poll().readings)
        assert all(bus.set_torque(True).values())
        targets = {f'j{i}': 0.3 if i % 2 else -0.25 for i in range(1, 7)}
        assert bus.write_goals(targets, {f'j{i}': 2.0 for i in range(1, 7)}) == 6
        # The AX-18A physics (the simulator's ServoModel) holds within its compliance and static
        # friction; the MX-28 (first-order stand-in) reaches its goal tick.
        atol = [0.05] * 3 + [1.5 * MX28.rad_per_tick] * 3
        done = _poll_until(bus, lambda r: all(
            abs(x.position_rad - targets[x.name]) < tol for x, tol in zip(r.readings, atol)))
        # Each servo holds the goal tick of its own table (1024 over 300 deg or 4096 over 360).
        for i in range(1, 7):
            t = emu.servo(i).table
            servo_rad = bus.servos[i - 1].joint.to_servo(targets[f'j{i}'])
            assert emu.read_register(i, 'goal_position') == t.rad_to_position(servo_rad)
            assert_allclose(done.readings[i - 1].position_rad, targets[f'j{i}'], atol=atol[i - 1])
        # 26-29 (AX compliance, MX gains) still hold their power-on defaults.
        assert {i: bytes(emu.servo(i).memory[26:30]) for i in range(1, 7)} == before
        assert before[4] == bytes([0, 0, 32, 0]) and before[1] == bytes([1, 1, 32, 32])
