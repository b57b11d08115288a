"""Fixes from the outside review of the Dynamixel driver (FINDINGS.md F1-F8), at bus level on
the project's emulator: power-cycled servo, wheel mode, port lost, overheating flag at torque
on, run-time events for the log, adapter echo, duplicate IDs, rejected instructions."""

from __future__ import annotations

import pytest

from hexapod_bench_drivers.dynamixel_bus import (
    DynamixelBus,
    EventLog,
    JointConfig,
    PortLostError,
    RateMonitor,
)
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

pytestmark = pytest.mark.timeout(60)

P1P2 = [('ax18a', 1), ('xl430', 2)]


def _joints(n):
    return [JointConfig(f'j{i}', i) for i in range(1, n + 1)]


def _bus(emu, n, protocol, **kw):
    kw.setdefault('timeout_margin_ms', 40.0)   # a loaded machine delays the emulator thread
    return DynamixelBus(emu.port_name, _joints(n), protocol=protocol, **kw)


def _poll_until(bus, predicate, max_cycles=200):
    for _ in range(max_cycles):
        result = bus.poll()
        if predicate(result):
            return result
    raise AssertionError('condition not reached')


def _events(bus, level=None):
    return [m for lv, m in bus.take_events() if level is None or lv == level]


# --- F1: power-cycled servo, hardware-error shutdown -------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_power_cycled_servo_reported_torque_off(model, protocol):
    """Servo 2 goes silent and comes back with its power-on RAM (Torque Enable 0). Before:
    torque_enabled stayed True and nothing was reported; now the bus reads Torque Enable back
    on its recovery, reports the lost torque and does not turn it on by itself."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, \
            _bus(emu, 2, protocol, silent_after=2, probe_interval_cycles=2) as bus:
        assert bus.set_torque(True) == {'j1': True, 'j2': True}
        bus.take_events()
        emu.inject(2, 'no_answer')
        _poll_until(bus, lambda r: bus.health()[1].silent)
        emu.power_cycle(2)            # clears the fault too: it answers again, torque 0
        _poll_until(bus, lambda r: r.readings[1].ok)
        h = bus.health()
        assert h[0].torque_enabled and h[0].torque_lost == ''
        assert not h[1].torque_enabled
        assert 'came back with torque off (power cycled or hardware error?)' in h[1].torque_lost
        assert 'register 24' in h[1].torque_lost or 'register 64' in h[1].torque_lost
        warnings = _events(bus, 'warning')
        assert any(w.startswith('j2 (id 2) came back with torque off') for w in warnings)
        for _ in range(3):
            bus.poll()
        assert emu.read_register(2, 'torque_enable') == 0   # not turned on behind the user
        assert bus.set_torque(True) == {'j1': True, 'j2': True}
        assert bus.health()[1].torque_lost == '' and bus.health()[1].torque_enabled


@pytest.mark.parametrize('model,protocol', P1P2)
def test_hardware_error_shutdown_torque_state_follows_register(model, protocol):
    """Overload with Alarm Shutdown: the servo turns torque off (Protocol 1.0: Torque Limit
    0, Torque Enable kept). Before, torque_enabled stayed True; now it follows the registers
    and the loss names the error."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, _bus(emu, 2, protocol) as bus:
        assert all(bus.set_torque(True).values())
        emu.inject(1, 'error_bits', error_bits=0x20)
        bus.poll()
        held = 'torque_enable' if protocol == 2 else 'torque_limit'
        assert emu.read_register(1, held) == 0
        h = bus.health()
        assert not h[0].torque_enabled and h[1].torque_enabled
        assert "turned torque off itself with hardware error ['overload']" in h[0].torque_lost


# --- F2: Protocol 1.0 wheel mode ---------------------------------------------------------------
def test_p1_wheel_mode_refused_and_no_moving_speed_written():
    """AX-18A servo 2 with CW = CCW Angle Limit = 0 (wheel mode). Before: torque on and Moving
    Speed written (a continuous rotation command); now refused like Protocol 2.0 velocity
    mode, naming both registers."""
    with ServoBusEmulator.of_model('ax18a', [1, 2]) as emu:
        emu.servo(2).set('ccw_angle_limit', 0)
        with _bus(emu, 2, 1) as bus:
            assert list(bus.refused) == ['j2']
            why = bus.refused['j2']
            assert 'wheel mode' in why and 'register 6' in why and 'register 8' in why
            assert any(n.startswith('j2 (id 2): wheel mode') for n in bus.take_notes())
            assert bus.set_torque(True) == {'j1': True, 'j2': False}
            assert emu.read_register(2, 'torque_enable') == 0
            assert bus.write_goals({'j1': 0.2, 'j2': 0.2}, {'j1': 1.0, 'j2': 1.0}) == 1
            bus.poll()
            assert emu.read_register(1, 'moving_speed') > 0
            assert emu.read_register(2, 'moving_speed') == 0
            assert emu.read_register(2, 'goal_position') == 512


# --- F4: the USB adapter pulled ----------------------------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_port_lost_is_one_named_error_and_no_write_after(model, protocol):
    """The pty master closed (an unplugged adapter: EIO). Before: a raw OSError from poll and
    again from the shutdown torque off; now PortLostError naming the port, the bus closed, and
    later writes skipped without touching the dead port."""
    emu = ServoBusEmulator.of_model(model, [1, 2]).start()
    bus = _bus(emu, 2, protocol).open()
    try:
        assert bus.poll().readings[0].ok
        emu.stop()
        with pytest.raises(PortLostError, match=rf'port {emu.port_name} lost: .*Errno 5'):
            bus.poll()
        assert not bus.is_open and emu.port_name in bus.port_lost
        assert bus.set_torque(False) == {'j1': False, 'j2': False}
        assert bus.write_goals({'j1': 0.1}) == 0
        with pytest.raises(PortLostError):
            bus.poll()
    finally:
        emu.stop()
        bus.close()


# --- F7: torque on while a servo still flags overheating ---------------------------------------
def test_torque_on_refused_while_overheating_flag_or_at_limit():
    """Servo 2 reports the overheating flag at 26 degC, then sits exactly at the limit. Before:
    set_torque(True) cleared the abort (torque pulse until the next poll); now refused with the
    reason while the flag is set or the temperature is not below the limit."""
    with ServoBusEmulator.of_model('xl430', [1, 2]) as emu, \
            _bus(emu, 2, 2, temperature_limit_c=70.0) as bus:
        bus.set_torque(True)
        emu.inject(2, 'error_bits', error_bits=0x04)
        assert bus.poll().aborted_now
        writes = []
        emu.servo(1).read_hook = lambda s: writes.append(s.get('torque_enable'))
        assert bus.set_torque(True) == {'j1': False, 'j2': False}
        assert bus.aborted and 'still aborted' in bus.abort_reason
        assert 'j2 (id 2) reports overheating' in bus.abort_reason
        assert emu.read_register(1, 'torque_enable') == 0 and set(writes) == {0}
        emu.clear_faults(2)
        emu.inject(2, 'overheat', temperature_c=70)
        assert bus.set_torque(True) == {'j1': False, 'j2': False}
        assert 'not below the limit 70 degC' in bus.abort_reason
        emu.inject(2, 'overheat', temperature_c=69)
        assert bus.set_torque(True) == {'j1': True, 'j2': True}
        assert not bus.aborted


# --- F8: run-time events for the log -----------------------------------------------------------
def test_event_log_once_per_transition_throttled():
    now = [0.0]
    log = EventLog(interval_s=5.0, clock=lambda: now[0])
    log.event('a', 'warning', 'down')
    assert log.take() == [('warning', 'down')]
    now[0] = 1.0
    log.event('a', 'info', 'up')                  # down and up: both at once
    assert log.take() == [('info', 'up')]
    log.event('a', 'warning', 'down')             # flapping: held back
    log.event('a', 'info', 'up')
    log.event('a', 'warning', 'down')
    log.event('b', 'warning', 'other')
    assert log.take() == [('warning', 'other')]
    now[0] = 4.9
    assert log.take() == []
    now[0] = 5.0
    assert log.take() == [('warning', 'down (3 transitions within 5 s logged as one)')]
    assert log.take() == []


def test_rate_monitor_warns_once_and_recovers():
    mon = RateMonitor(50.0, window_s=1.0)
    lines = [mon.tick(k / 20.0, 45.0, 6) for k in range(60)]           # 20 Hz for 3 s
    said = [x for x in lines if x is not None]
    assert len(said) == 1 and said[0][0] == 'warning'
    assert 'requested 50 Hz' in said[0][1] and 'read loop at 20.0 Hz' in said[0][1]
    assert 'the bus cannot keep up' in said[0][1]        # 45 ms cycles of a 20 ms period
    lines = [mon.tick(3.0 + k / 50.0) for k in range(150)]             # 50 Hz again
    said = [x for x in lines if x is not None]
    assert len(said) == 1 and said[0][0] == 'info' and 'back at' in said[0][1]


def test_rate_monitor_blames_the_host_when_the_bus_has_time_to_spare():
    """An outside review: 1.6 ms read cycles of a 10 ms period at 60 Hz achieved were
    blamed on the bus (USB latency timer, baud rate); the host was the bottleneck."""
    mon = RateMonitor(100.0, window_s=1.0)
    said = [x for x in (mon.tick(k / 60.0, 1.6, 18) for k in range(120)) if x is not None]
    assert len(said) == 1 and 'the bus has time to spare (1.6 of 10.0 ms' in said[0][1]
    assert 'cannot keep up' not in said[0][1]


@pytest.mark.parametrize('model,protocol', P1P2)
def test_silent_back_and_new_flags_are_events_once(model, protocol):
    """Before: only /diagnostics showed these. Now one warning per transition, info back."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, \
            _bus(emu, 2, protocol, silent_after=2, probe_interval_cycles=2) as bus:
        bus.take_events()
        bus.events.interval_s = 0.0   # this test is about transitions, not the throttle
        emu.inject(2, 'no_answer')
        lines = []
        for _ in range(8):
            bus.poll()
            lines += bus.take_events()
        assert [lv for lv, m in lines if 'went silent' in m] == ['warning']
        assert lines[0][1].startswith('j2 (id 2) went silent')
        emu.clear_faults(2)
        _poll_until(bus, lambda r: r.readings[1].ok)
        assert any(lv == 'info' and m.startswith('j2 (id 2) answers again')
                   for lv, m in bus.take_events())
        emu.inject(1, 'error_bits', error_bits=0x01)      # input voltage: no shutdown
        lines = []
        for _ in range(5):
            bus.poll()
            lines += bus.take_events()
        assert [m for _, m in lines] == ["j1 (id 1) reports hardware error ['input_voltage'] ("
                                         + ('status error byte' if protocol == 1
                                            else 'Hardware Error Status') + ' 0x01)']
        emu.clear_faults(1)
        bus.poll()
        assert bus.take_events() == [('info', 'j1 (id 1) hardware error flags cleared')]


def test_low_loop_rate_is_an_event_of_the_bus():
    """A bus polled at a third of the rate it was given reports it once (through poll)."""
    with ServoBusEmulator.of_model('ax18a', [1]) as emu, _bus(emu, 1, 1, rate_hz=50.0) as bus:
        bus.rate = RateMonitor(50.0, window_s=0.3)
        t = [0.0]
        import hexapod_bench_drivers.dynamixel_bus as mod
        real = mod.time.monotonic
        try:
            mod.time.monotonic = lambda: t[0]
            for k in range(30):
                t[0] = k / 15.0
                bus.poll()
        finally:
            mod.time.monotonic = real
        lines = [m for lv, m in bus.take_events() if lv == 'warning']
        assert len(lines) == 1 and 'requested 50 Hz' in lines[0]


# --- F5: adapter echo --------------------------------------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_adapter_echo_detected_skipped_and_noted_once(model, protocol):
    """An adapter that echoes every transmitted byte. Before (Protocol 1.0): every servo
    refused as 'unknown Dynamixel model number 512'; now the echo is recognised, skipped and
    noted once; readings, torque and goals work and no reply counts as late."""
    with ServoBusEmulator.of_model(model, [1, 2, 3]) as emu:
        emu.echo = True
        with _bus(emu, 3, protocol) as bus:
            margin = bus.reply_margin_ms
            assert {h.model for h in bus.health()} == {emu.servo(1).table.model_name}
            notes = [n for n in bus.take_notes() if 'echoes' in n]
            if protocol == 1:   # the echo of the first PING passed for its reply
                assert bus.echo and len(notes) == 1 and 'half-duplex' in notes[0]
            assert all(bus.set_torque(True).values())
            for _ in range(10):
                assert all(r.ok for r in bus.poll().readings)
                bus.write_goals({'j1': 0.2, 'j2': -0.2, 'j3': 0.1})
            notes += [n for n in bus.take_notes() if 'echoes' in n]
            # said once (Protocol 2.0: the SDK drops the echo itself, so it may go unnoticed)
            assert len(notes) == (1 if protocol == 1 else bus.echo)
            assert bus.late_replies == 0 and bus.reply_margin_ms == margin
            assert [emu.read_register(i, 'torque_enable') for i in (1, 2, 3)] == [1, 1, 1]


# --- F3 / F6: duplicate IDs, rejected instructions ---------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_duplicate_id_reported_not_late(model, protocol):
    """Two servos answer at ID 2 (two intact replies to one request). Before: the second reply
    counted as late, the margin raised, the joint reported ok; now counted as a duplicate,
    noted naming it, its readings withheld, and the margin kept."""
    with ServoBusEmulator.of_model(model, [1, 2, 3]) as emu, _bus(emu, 3, protocol) as bus:
        margin = bus.reply_margin_ms
        bus.take_notes()
        emu.duplicate_ids = {2}
        results = [bus.poll() for _ in range(10)]
        h = bus.health()
        assert h[1].duplicate_replies >= 5 and h[1].late_replies == 0
        assert bus.late_replies == 0 and bus.reply_margin_ms == margin
        assert not any(r.readings[1].ok for r in results[2:])
        assert all(r.readings[0].ok and r.readings[2].ok for r in results)
        assert any(n.startswith('j2 (id 2) duplicate id?') for n in bus.take_notes())


@pytest.mark.parametrize('model,protocol', P1P2)
def test_colliding_replies_of_two_servos_at_one_id_said_garbled_not_no_reply(model, protocol):
    """Two servos at ID 2 answering at the same moment: their status packets collide on the
    wire and arrive with a broken checksum (a PING's, identical, intact, so detection passes).
    Before: the servo went silent with 'no reply ... check its cable and power'; now the
    silence says the replies came garbled and names a second servo at the ID first. The
    other servos read on every cycle, and the servo comes back when the twin is gone."""
    with ServoBusEmulator.of_model(model, [1, 2, 3]) as emu, _bus(emu, 3, protocol) as bus:
        bus.take_events()
        emu.colliding_ids = {2}
        results = [bus.poll() for _ in range(6)]
        h = bus.health()[1]
        assert h.silent and h.silence() == 'garbled replies'
        assert h.streak_garbled >= 3 and h.streak_no_reply == 0 and h.corrupt >= 3
        assert not any(r.readings[1].ok for r in results)
        assert all(r.readings[0].ok and r.readings[2].ok for r in results)
        assert bus.late_replies == 0
        warning, = [m for m in _events(bus, 'warning') if 'went silent' in m]
        assert warning.startswith('j2 (id 2) went silent: garbled replies')
        assert 'a second servo at this ID' in warning
        emu.colliding_ids = set()
        _poll_until(bus, lambda r: r.readings[1].ok)
        h = bus.health()[1]
        assert not h.silent and h.streak_garbled == h.streak_no_reply == 0


@pytest.mark.parametrize('model,protocol', P1P2)
def test_twins_present_at_start_up_are_left_out_as_twins_not_level_0(model, protocol):
    """Twins on the bus when the driver opens (a new servo from the box at the same ID): their
    PING replies are identical and pass, the READs collide. An outside review: the servo was
    refused as 'Status Return Level 0 ... set it to 1 or 2', a register already 2. Now it is
    left out naming a second servo at the ID; the others run."""
    with ServoBusEmulator.of_model(model, [1, 2, 3]) as emu:
        emu.colliding_ids = {2}
        with _bus(emu, 3, protocol) as bus:
            assert bus.health()[1].model == 'unreadable (garbled replies)'
            assert 'a second servo at this ID' in bus.refused['j2']
            assert 'Status Return Level' not in bus.refused['j2']
            assert any(n.startswith('j2 (id 2) left out: answers PING, but its READ replies '
                                    'arrive garbled') for n in bus.take_notes())
            r = bus.poll()
            assert r.readings[0].ok and r.readings[2].ok and not r.readings[1].ok


@pytest.mark.parametrize('model,protocol', P1P2)
def test_garbled_burst_then_silence_reads_as_silence(model, protocol):
    """Two colliding cycles, then the servo stops answering: the silence is decided by the
    recent failures, so it ends as 'no reply' (the whole streak's majority had said
    'garbled' in the warning and flipped later in the diagnostics)."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, \
            _bus(emu, 2, protocol, retries=1, silent_after=3, probe_interval_cycles=2) as bus:
        bus.take_events()
        emu.colliding_ids = {2}
        bus.poll()
        bus.poll()
        emu.colliding_ids = set()
        emu.inject(2, 'no_answer', count=10000)
        _poll_until(bus, lambda r: bus.health()[1].silent)
        assert bus.health()[1].silence() == 'no reply'
        warning, = [m for m in _events(bus, 'warning') if 'went silent' in m]
        assert 'no reply in 3 cycles' in warning and 'cable and power' in warning
        for _ in range(6):
            bus.poll()
        assert bus.health()[1].silence() == 'no reply'


@pytest.mark.parametrize('model,protocol', P1P2)
def test_torque_not_confirmed_through_a_twin_says_why(model, protocol):
    """Torque on while a twin answers at the ID: the write lands, its read-back comes
    garbled. It had failed with an empty torque_error."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, _bus(emu, 2, protocol) as bus:
        emu.colliding_ids = {2}
        assert bus.set_torque(True) == {'j1': True, 'j2': False}
        assert 'garbled' in bus.health()[1].torque_error
        assert 'second servo at this ID' in bus.health()[1].torque_error


@pytest.mark.parametrize('model,protocol', P1P2)
def test_a_servo_that_stops_answering_is_still_said_to_give_no_reply(model, protocol):
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, _bus(emu, 2, protocol) as bus:
        bus.take_events()
        emu.inject(2, 'no_answer', count=1000)
        _poll_until(bus, lambda r: bus.health()[1].silent)
        h = bus.health()[1]
        assert h.silence() == 'no reply' and h.streak_garbled == 0
        warning, = [m for m in _events(bus, 'warning') if 'went silent' in m]
        assert 'no reply in' in warning and 'check its cable and power' in warning


@pytest.mark.parametrize('model,protocol', P1P2)
def test_rejected_instruction_not_a_late_reply(model, protocol):
    """Six instructions reach the servo corrupted; it answers with a checksum (1.0) or CRC
    (2.0) error and no data. Before (1.0): counted as late replies and the margin raised;
    now counted as rejected instructions and retried, margin kept."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, \
            _bus(emu, 2, protocol, retries=2) as bus:
        margin = bus.reply_margin_ms
        bus.set_torque(True)
        if protocol == 2:
            bus.sync_read = False   # corrupt single instructions (a Sync Read is broadcast)
        for _ in range(3):
            emu.corrupt_instructions = 2   # the retries cover two in a row
            for _ in range(3):
                bus.poll()
        h = bus.health()
        assert sum(x.rejected_instructions for x in h) == 6
        assert bus.late_replies == 0 and bus.reply_margin_ms == margin
        assert sum(x.failed_cycles for x in h) == 0
        error = 'checksum' if protocol == 1 else 'crc_error'
        assert any(lv == 'warning' and f'reports a {error} error on an instruction' in m
                   for lv, m in bus.take_events())


# --- second review: a Protocol 1.0 PING reply with Input Voltage Error is the PING's twin ------
@pytest.mark.parametrize('echo', [False, True])
def test_input_voltage_error_ping_reply_is_not_an_echo(echo):
    """An AX servo with Input Voltage Error (bit 0x01: a 4S pack, a sagging battery) answers
    a PING with the very bytes of the PING. The echo fix took it for the adapter's echo: the
    servo was left silent and the port said to echo (every servo flagged: exit 2). Now such a
    packet is the echo only when another one follows it."""
    with ServoBusEmulator.of_model('ax18a', [1, 2, 3]) as emu:
        emu.echo = echo
        for sid in ((2,) if not echo else (1, 2, 3)):
            emu.inject(sid, 'error_bits', error_bits=0x01)
        with _bus(emu, 3, 1) as bus:
            assert all(not h.silent for h in bus.health())
            assert {h.model for h in bus.health()} == {emu.servo(1).table.model_name}
            assert bus.echo == echo
            assert all(r.ok for r in bus.poll().readings)
