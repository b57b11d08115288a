"""Fixes from the outside hardware review of the Dynamixel driver against an independent
emulator (/tmp/rev_dxl/REPORT.md, findings 1-5), at bus level on the project's emulator: a stop
during the torque-on pass, the Protocol 1.0 Alarm Shutdown (Torque Limit 0), goals beyond the
angle limits, torque off at shutdown, -0.0 at rest."""

from __future__ import annotations

import math
import threading

import pytest

from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

pytestmark = pytest.mark.timeout(60)

P1P2 = [('ax18a', 1), ('xl430', 2)]


def _joints(n, **kw):
    return [JointConfig(f'j{i}', i, **kw) for i in range(1, n + 1)]


def _bus(emu, n, protocol, joints=None, **kw):
    kw.setdefault('timeout_margin_ms', 40.0)   # a loaded machine delays the emulator thread
    return DynamixelBus(emu.port_name, joints or _joints(n), protocol=protocol, **kw)


# --- 1: a stop requested during the torque-on pass ---------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_set_torque_stops_writing_once_stop_is_requested(model, protocol):
    """``stop`` is asked before each servo's write; once True, nothing more is written and
    the skipped joints are named (before: no way to stop the pass)."""
    n, k = 5, 2
    written: list[int] = []
    with ServoBusEmulator.of_model(model, range(1, n + 1)) as emu, _bus(emu, n, protocol) as bus:
        address = emu.servo(1).table.reg('torque_enable').address
        for i in range(1, n + 1):
            emu.servo(i).write_hook = lambda s, at, data: written.append(s.servo_id) if (
                at == address) else None
        result = bus.set_torque(True, stop=lambda: len(written) >= k)
        assert result == {f'j{i}': i <= k for i in range(1, n + 1)}
        assert bus.not_written == [f'j{i}' for i in range(k + 1, n + 1)]
        assert written == list(range(1, k + 1))
        assert [emu.read_register(i, 'torque_enable') for i in range(1, n + 1)] == \
            [1] * k + [0] * (n - k)
        # an unstopped call clears the list
        assert all(bus.set_torque(False).values()) and bus.not_written == []


# --- 2: Protocol 1.0 Alarm Shutdown sets Torque Limit to 0 ------------------------------------
def _poll_until(bus, predicate, max_cycles=100):
    for _ in range(max_cycles):
        result = bus.poll()
        if predicate(result):
            return result
    raise AssertionError('condition not reached')


def test_p1_alarm_shutdown_is_torque_lost_and_torque_on_restores_torque_limit():
    """AX-18A id 2 overloads: its firmware sets Torque Limit (34) to 0 and keeps Torque Enable
    1 (e-Manual); the flag then clears with the load, Torque Limit stays 0. Before: torque
    'ok', set_torque(True) 'success' with the servo limp. Now torque lost naming register 34,
    and torque on writes Torque Limit back from Max Torque."""
    with ServoBusEmulator.of_model('ax18a', [1, 2, 3]) as emu, _bus(emu, 3, 1) as bus:
        assert all(bus.set_torque(True).values())
        bus.take_events()
        emu.inject(2, 'error_bits', error_bits=0x20)            # overload: Alarm Shutdown
        bus.poll()
        assert emu.read_register(2, 'torque_limit') == 0
        assert emu.read_register(2, 'torque_enable') == 1
        h = bus.health()[1]
        assert not h.torque_enabled
        assert "turned torque off itself with hardware error ['overload']" in h.torque_lost
        assert 'Torque Limit (register 34) reads 0' in h.torque_lost
        assert any('j2 (id 2)' in m and 'register 34' in m for _lv, m in bus.take_events())
        emu.clear_faults(2)                                     # the load is gone
        for _ in range(6):                                      # twice round the servos
            bus.poll()
        assert emu.read_register(2, 'torque_limit') == 0
        assert not bus.health()[1].torque_enabled and bus.health()[1].torque_lost
        bus.take_notes()
        assert bus.set_torque(True) == {'j1': True, 'j2': True, 'j3': True}
        assert emu.read_register(2, 'torque_limit') == 1023 == emu.read_register(2, 'max_torque')
        assert bus.health()[1].torque_enabled and bus.health()[1].torque_lost == ''
        assert any('j2 (id 2) Torque Limit (register 34) read 0' in n
                   and 'written back to Max Torque 1023' in n for n in bus.take_notes())
        for _ in range(6):
            bus.poll()
        assert bus.health()[1].torque_enabled and bus.health()[1].torque_lost == ''


def test_p1_torque_on_after_an_alarm_keeps_a_torque_limit_set_by_hand():
    """A Torque Limit set lower by hand (512 of Max Torque 1023) before the driver started is
    written back after an Alarm Shutdown zeroed it (it became 1023, full torque)."""
    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu:
        emu.servo(2).set('torque_limit', 512)
        with _bus(emu, 2, 1) as bus:
            assert all(bus.set_torque(True).values())
            emu.inject(2, 'error_bits', error_bits=0x20)        # overload: Alarm Shutdown
            bus.poll()
            assert emu.read_register(2, 'torque_limit') == 0
            emu.clear_faults(2)
            bus.take_notes()
            assert bus.set_torque(True) == {'j1': True, 'j2': True}
            assert emu.read_register(2, 'torque_limit') == 512
            assert any('j2 (id 2) Torque Limit (register 34) read 0' in n and
                       'written back to 512, its value before (Max Torque 1023)' in n
                       for n in bus.take_notes())


def test_p1_torque_limit_zero_found_by_the_round_robin_without_a_flag():
    """The flag came and went between two reads: Torque Limit 0 alone is found by the
    READ that starts at Torque Enable (one servo a cycle), no extra request."""
    with ServoBusEmulator.of_model('ax18a', [1, 2, 3]) as emu, _bus(emu, 3, 1) as bus:
        assert all(bus.set_torque(True).values())
        bus.poll()
        before = emu.packets_received
        emu.servo(3).set('torque_limit', 0)
        _poll_until(bus, lambda r: not bus.health()[2].torque_enabled, max_cycles=3)
        assert emu.packets_received - before <= 3 * 3     # one READ per servo a cycle
        lost = bus.health()[2].torque_lost
        assert lost.startswith('lost its torque in an Alarm Shutdown (its error flag already '
                               'cleared): Torque Limit (register 34) reads 0')
        assert all(h.torque_enabled for h in bus.health()[:2])


def test_p1_torque_on_refused_when_max_torque_is_zero_too():
    """Torque Limit 0 and Max Torque 0 (nothing to restore from): torque on fails with the
    reason, nothing written to EEPROM (before: 'torque on', the servo limp)."""
    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu, _bus(emu, 2, 1) as bus:
        emu.servo(1).set('max_torque', 0)
        emu.servo(1).set('torque_limit', 0)
        assert bus.set_torque(True) == {'j1': False, 'j2': True}
        why = bus.health()[0].torque_error
        assert 'Torque Limit (register 34) reads 0' in why
        assert 'Max Torque (register 14, EEPROM)' in why and 'is 0 too' in why
        assert emu.read_register(1, 'max_torque') == 0 == emu.read_register(1, 'torque_limit')
        assert not bus.health()[0].torque_enabled


# --- 3: goals beyond the servo's angle / position limits ---------------------------------------
def test_p1_goals_clipped_to_cw_ccw_angle_limits_counted_and_said_once():
    """AX-18A ids 1 and 2 limited to ticks 300..700 (id 2 mounted reversed, direction -1). A
    goal of 1.2 rad (tick 922) was written as is: the servo refuses it (Angle Limit Error, no
    status to a Sync Write) and nobody was told. Now clipped to the limit, counted, one
    warning per joint per episode in the joint frame, info when goals are inside again."""
    from hexapod_bench_drivers.control_tables import AX18A

    joints = [JointConfig('j1', 1), JointConfig('j2', 2, direction=-1), JointConfig('j3', 3)]
    with ServoBusEmulator.of_model('ax18a', [1, 2, 3]) as emu:
        for i in (1, 2):
            emu.servo(i).set('cw_angle_limit', 300)
            emu.servo(i).set('ccw_angle_limit', 700)
        with _bus(emu, 3, 1, joints=joints) as bus:
            bus.take_events()
            for _ in range(5):
                assert bus.write_goals({'j1': 1.2, 'j2': 1.2, 'j3': 0.5}) == 3
                bus.poll()
            assert [emu.read_register(i, 'goal_position') for i in (1, 2, 3)] == [
                700, 300, AX18A.rad_to_position(0.5)]
            h = bus.health()
            assert [x.goals_clipped for x in h] == [5, 5, 0]
            tick = AX18A.rad_per_tick
            warnings = [m for lv, m in bus.take_events() if lv == 'warning']
            assert len(warnings) == 2
            assert warnings[0].startswith(
                f'j1 (id 1) goal 1.200 rad beyond its limit {188 * tick:.3f} rad (joint frame; '
                f'limits {-212 * tick:.3f}..{188 * tick:.3f} rad from CW/CCW Angle Limit '
                '(registers 6/8), ticks 300..700): clipped to the limit')
            assert warnings[1].startswith(f'j2 (id 2) goal 1.200 rad beyond its limit '
                                          f'{212 * tick:.3f} rad')
            assert 'goal 1.200 rad' in h[0].goal_clip and h[2].goal_clip == ''
            bus.write_goals({'j1': 0.1, 'j2': 1.2})
            bus.poll()
            assert h[0].goal_clip == '' and h[1].goal_clip and h[1].goals_clipped == 6
            infos = [m for lv, m in bus.take_events() if lv == 'info']
            assert infos == ['j1 (id 1) goals inside its limits again (5 clipped so far)']


def test_p2_goals_clipped_to_min_max_position_limit_in_position_mode_only():
    """XM430 ids 1 and 2 with Min/Max Position Limit 1536..2560; id 2 in extended position
    mode (4), where the limits do not apply. 1.2 rad is tick 2830: a Data Limit Error on id
    1 (not applied, not said) before; now clipped to 2560, written as is on id 2."""
    from hexapod_bench_drivers.control_tables import XM430
    from hexapod_bench_drivers.servo_bus_emulator import EmulatedServo

    servos = [EmulatedServo(i, XM430) for i in (1, 2)]
    for s in servos:
        s.set('min_position_limit', 1536)
        s.set('max_position_limit', 2560)
    servos[1].set('operating_mode', 4)
    with ServoBusEmulator(servos) as emu, _bus(emu, 2, 2) as bus:
        bus.take_events()
        assert bus.write_goals({'j1': 1.2, 'j2': 1.2}) == 2
        bus.poll()
        assert emu.read_register(1, 'goal_position') == 2560
        assert emu.read_register(2, 'goal_position') == XM430.rad_to_position(1.2) == 2830
        h = bus.health()
        assert (h[0].goals_clipped, h[1].goals_clipped) == (1, 0)
        assert 'Min/Max Position Limit (registers 52/48), ticks 1536..2560' in h[0].goal_clip
        assert [lv for lv, m in bus.take_events()] == ['warning']


# --- 4: torque off at shutdown -----------------------------------------------------------------
def test_torque_off_at_shutdown_names_what_it_did_to_each_servo():
    """XL430 bus: j1 answers; j2 is at Status Return Level 0 (model known from its PING,
    torque on from an earlier run); j3 is an unknown model (number 1240, XC330); j4 goes
    silent after torque on. Before: 'not confirmed by j2, j3, j4' for all three. Now j2 gets
    Torque Enable 0 without a reply, j3 is named as never written, j4 as not confirmed."""
    import dataclasses

    from hexapod_bench_drivers.control_tables import XL430
    from hexapod_bench_drivers.servo_bus_emulator import EmulatedServo

    servos = [EmulatedServo(1, XL430), EmulatedServo(2, XL430),
              EmulatedServo(3, dataclasses.replace(XL430, model_number=1240)),
              EmulatedServo(4, XL430)]
    servos[1].set('status_return_level', 0)
    servos[1].set('torque_enable', 1)
    servos[2].set('torque_enable', 1)
    written = threading.Event()   # the blind write, which no reply tells the bus about
    servos[1].write_hook = lambda s, at, data: written.set()
    with ServoBusEmulator(servos) as emu, _bus(emu, 4, 2, retries=0) as bus:
        assert set(bus.refused) == {'j2', 'j3'}
        assert bus.set_torque(True) == {'j1': True, 'j2': False, 'j3': False, 'j4': True}
        emu.inject(4, 'no_answer')
        report = bus.torque_off_at_shutdown()
        assert written.wait(10.0)
        assert (report.confirmed, report.unconfirmed, report.blind, report.never_written) == (
            ('j1',), ('j4',), ('j2',), ('j3',))
        assert not report.ok
        assert [emu.read_register(i, 'torque_enable') for i in (1, 2, 3)] == [0, 0, 1]
        lines = report.lines()
        assert lines == [
            ('error', 'torque off at shutdown not confirmed by j4: they may still hold their '
                      'position'),
            ('warning', 'torque off at shutdown sent without a reply to j2 (left out at Status '
                        'Return Level 0: the servo carries out writes but never answers): not '
                        'confirmed'),
            ('warning', 'j3: left out, never written; torque state unknown'),
            ('info', 'torque off on 1 servo(s)')]


def test_p1_level_0_servo_gets_torque_off_at_24_and_is_ok():
    """Protocol 1.0 reads the model by a READ, which a Status Return Level 0 servo never
    answers, but every described 1.0 model has Torque Enable at 24: it is sent Torque Enable 0
    without a reply (it was left torqued, "never written; torque state unknown"); the servos
    the driver wrote all confirmed: ok (exit 0)."""
    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu:
        emu.servo(2).set('status_return_level', 0)
        emu.servo(2).set('torque_enable', 1)      # torqued by an earlier program
        written = threading.Event()
        emu.servo(2).write_hook = lambda s, at, data: written.set()
        with _bus(emu, 2, 1, retries=0) as bus:
            bus.set_torque(True)
            report = bus.torque_off_at_shutdown()
            assert written.wait(10.0)
            assert report.confirmed == ('j1',) and report.blind == ('j2',)
            assert report.ok and not report.never_written and not report.unconfirmed
            assert emu.read_register(2, 'torque_enable') == 0


# --- 5: no -0.0 --------------------------------------------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_reversed_joint_at_rest_reads_plus_zero(model, protocol):
    """A direction -1 joint at rest published velocity and effort -0.0."""
    joints = [JointConfig('j1', 1, direction=-1)]
    with ServoBusEmulator.of_model(model, [1]) as emu, _bus(emu, 1, protocol,
                                                            joints=joints) as bus:
        r = bus.poll().readings[0]
        assert r.ok
        for value in (r.position_rad, r.velocity_rad_s, r.effort_nm, r.load_fraction):
            assert value == 0.0 and math.copysign(1.0, value) == 1.0
