"""DynamixelBus (real dynamixel_sdk) against the emulator: reads, commands, faults, overheating."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.dynamixel_bus import (
    BusError,
    DynamixelBus,
    JointConfig,
    JointMapError,
    load_joint_map,
    parse_joint_map,
)
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

pytestmark = pytest.mark.timeout(60)

CASES = [('ax18a', 1, 18), ('xl430', 2, 4)]


def _joints(n):
    return [JointConfig(f'j{i}', i, -1 if i == 2 else 1, 0.1 if i == 2 else 0.0)
            for i in range(1, n + 1)]


def _poll_until(bus, predicate, max_cycles=3000):
    for _ in range(max_cycles):
        result = bus.poll()
        if predicate(result):
            return result
    raise AssertionError('condition not reached')


@pytest.mark.parametrize('model,protocol,n', CASES)
def test_reads_all_and_commands_move(model, protocol, n):
    with ServoBusEmulator.of_model(model, range(1, n + 1)) as emu, \
            DynamixelBus(emu.port_name, _joints(n), protocol=protocol,
                         timeout_margin_ms=10.0) as bus:
        assert {h.model for h in bus.health()} == {emu.servo(1).table.model_name}
        result = bus.poll()
        assert [r.ok for r in result.readings] == [True] * n
        assert_allclose([r.voltage_v for r in result.readings], 12.0)
        assert_allclose([r.temperature_c for r in result.readings], 26.0)
        assert_allclose(result.readings[1].position_rad, 0.1, atol=0.01)  # offset applied
        assert all(bus.set_torque(True).values())
        targets = {f'j{i}': 0.3 if i % 2 else -0.25 for i in range(1, n + 1)}
        assert bus.write_goals(targets) == n
        done = _poll_until(bus, lambda r: all(
            abs(x.position_rad - targets[x.name]) < 0.05 for x in r.readings))
        # The emulated servo turned the other way for the reversed joint j2.
        assert_allclose(emu.present_position_rad(2), -(targets['j2'] - 0.1), atol=0.05)
        assert all(x.ok for x in done.readings)


@pytest.mark.parametrize('model,protocol,n', CASES)
def test_moving_speed_limits_motion(model, protocol, n):
    # the emulator's physics on a clock the test advances, 10 ms a poll: simulated time, not
    # the wall clock (a loaded machine cannot move the figure)
    now = [0.0]
    with ServoBusEmulator.of_model(model, range(1, n + 1), clock=lambda: now[0]) as emu, \
            DynamixelBus(emu.port_name, _joints(n), protocol=protocol,
                         timeout_margin_ms=10.0) as bus:
        bus.set_torque(True)
        t0 = now[0]
        bus.write_goals({'j1': 0.5}, {'j1': 1.0})       # 0.5 rad at 1 rad/s: ~0.5 s

        def reached(r):
            now[0] += 0.01
            return abs(r.readings[0].position_rad - 0.5) < 0.05

        _poll_until(bus, reached, 1000)
        elapsed = now[0] - t0
        print(f'0.5 rad at 1 rad/s took {elapsed:.2f} s simulated')
        assert 0.45 < elapsed < 0.6


@pytest.mark.parametrize('model,protocol,n', CASES)
def test_each_fault_counted_others_served(model, protocol, n):
    ids = list(range(1, n + 1))
    silent, corrupt, flagged, late = ids[0], ids[1], ids[2], ids[-1]
    with ServoBusEmulator.of_model(model, ids) as emu, \
            DynamixelBus(emu.port_name, _joints(n), protocol=protocol, timeout_margin_ms=80.0,
                         retries=1, silent_after=3, probe_interval_cycles=5) as bus:
        # (an 80 ms margin: a loaded machine delays the emulator thread's replies by tens of
        # ms, which a 20 ms margin turned into extra timeouts and a failed cycle)
        emu.inject(silent, 'no_answer')
        emu.inject(corrupt, 'bad_checksum', count=1)
        emu.inject(flagged, 'error_bits', error_bits=0x20)      # overload
        emu.inject(late, 'late_reply', count=1, delay_s=0.120)  # 1.5 x the deadline
        results = [bus.poll() for _ in range(12)]
        h = {x.servo_id: x for x in bus.health()}
        assert h[silent].silent and h[silent].timeouts >= 3 and h[silent].reads_ok == 0
        assert h[corrupt].corrupt == 1 and h[corrupt].failed_cycles == 0
        assert h[late].timeouts >= 1 and h[late].failed_cycles == 0
        assert emu.servo(late).fault_hits['late_reply'] == 1
        assert h[flagged].last_error_flags == 0x20 and h[flagged].error_replies == 12
        assert results[-1].readings[flagged - 1].error_flags == 0x20
        others = [i for i in ids if i != silent]
        for r in results:
            assert [x.ok for x in r.readings if x.servo_id in others] == [True] * len(others)
            assert not r.readings[silent - 1].ok
            assert math.isnan(r.readings[silent - 1].position_rad)
        # Once silent, the servo no longer costs a timeout every cycle: only on probes.
        before = h[silent].timeouts
        for _ in range(10):
            bus.poll()
        assert h[silent].timeouts - before <= 2 * (1 + bus.retries)
        emu.clear_faults(silent)
        _poll_until(bus, lambda r: r.readings[silent - 1].ok, 20)
        assert not h[silent].silent


@pytest.mark.parametrize('model,protocol,n,temp', [('ax18a', 1, 18, 72), ('xl430', 2, 4, 71)])
def test_overheating_torque_off_within_one_cycle(model, protocol, n, temp):
    # Between the driver limit (70) and the servo's own (75 / 72): only the driver acts.
    with ServoBusEmulator.of_model(model, range(1, n + 1)) as emu, \
            DynamixelBus(emu.port_name, _joints(n), protocol=protocol, timeout_margin_ms=10.0,
                         temperature_limit_c=70.0) as bus:
        bus.set_torque(True)
        assert bus.poll().aborted_now is False
        emu.inject(3, 'overheat', temperature_c=temp)
        result = bus.poll()
        assert result.aborted_now and 'j3 (id 3)' in result.abort_reason
        assert [emu.read_register(i, 'torque_enable') for i in range(1, n + 1)] == [0] * n
        assert bus.write_goals({'j1': 0.3}) == 0                 # commands refused
        assert not any(bus.set_torque(True).values())            # still hot
        emu.clear_faults(3)
        assert all(bus.set_torque(True).values()) and not bus.aborted


def test_no_servo_raises_bus_error():
    with ServoBusEmulator.of_model('ax18a', [1]) as emu:
        with pytest.raises(BusError, match=r'no servo answered .* expected IDs \[7, 8\]'):
            DynamixelBus(emu.port_name, [JointConfig('a', 7), JointConfig('b', 8)],
                         timeout_margin_ms=2.0).open()


def test_joint_map_yaml(tmp_path):
    path = tmp_path / 'joints.yaml'
    path.write_text('joints:\n  L1_coxa: {id: 1}\n  L1_femur: {id: 2, direction: -1, '
                    'offset_rad: 0.5}\n')
    joints = load_joint_map(path)
    assert joints[1] == JointConfig('L1_femur', 2, -1, 0.5)
    assert_allclose(joints[1].to_joint(joints[1].to_servo(0.3)), 0.3)
    with pytest.raises(JointMapError, match='unique'):
        parse_joint_map({'joints': {'a': {'id': 1}, 'b': {'id': 1}}})
    with pytest.raises(JointMapError, match='direction 2'):
        parse_joint_map({'joints': {'a': {'id': 1, 'direction': 2}}})


def test_a_bus_without_sync_read_is_read_servo_by_servo():
    """An adapter, emulator or firmware that never answers Sync Read (single READs work):
    every servo is still read from the first cycle (the sync miss is retried singly), and after
    three such cycles the bus stops sending Sync Read, noted once."""
    from hexapod_bench_drivers.dynamixel_bus import SYNC_READ_GIVE_UP
    from hexapod_bench_drivers.servo_bus_emulator import INST_SYNC_READ

    class NoSyncRead(ServoBusEmulator):
        def _handle(self, pkt):
            return [] if pkt.instruction == INST_SYNC_READ else super()._handle(pkt)

    emu = NoSyncRead.of_model('xl430', range(1, 5))
    with emu, DynamixelBus(emu.port_name, _joints(4), protocol=2,
                           timeout_margin_ms=80.0) as bus:
        for cycle in range(SYNC_READ_GIVE_UP + 3):
            result = bus.poll()
            assert [r.ok for r in result.readings] == [True] * 4
            assert bus.sync_read == (cycle < SYNC_READ_GIVE_UP - 1)
        # (a loaded machine may add a note that the reply margin was raised)
        [note] = [n for n in bus.take_notes() if 'Sync Read' in n]
        assert not [n for n in bus.take_notes() if 'Sync Read' in n]
        before = emu.packets_received
        bus.poll()
        # four READs, no Sync Read (one of them starts at Torque Enable: no extra request)
        assert emu.packets_received - before == 4


def test_a_bus_that_answers_sync_read_keeps_it():
    with ServoBusEmulator.of_model('xl430', range(1, 5)) as emu, \
            DynamixelBus(emu.port_name, _joints(4), protocol=2,
                         timeout_margin_ms=10.0) as bus:
        for _ in range(SYNC_CYCLES):
            assert all(r.ok for r in bus.poll().readings)
        assert bus.sync_read and not any('Sync Read' in n for n in bus.take_notes())
        before = emu.packets_received
        for _ in range(bus.torque_check_interval_cycles):
            bus.poll()
        # one Sync Read for all four a cycle; their Torque Enable in one more every 10 cycles
        assert emu.packets_received - before == bus.torque_check_interval_cycles + 1


SYNC_CYCLES = 6


def _count_reads(emu, ids):
    """Stamp every reply: Present Position = centre + number of reads the servo answered."""
    counts = dict.fromkeys(ids, 0)

    def hook(servo):
        counts[servo.servo_id] += 1
        servo.set('present_position', servo.table.center_tick + counts[servo.servo_id])
    for i in ids:
        emu.servo(i).read_hook = hook
    return counts


def _stamp(bus, reading):
    t = bus.servos[reading.servo_id - 1].table
    return round(reading.position_rad / t.rad_per_tick)


@pytest.mark.parametrize('model,protocol', [('ax18a', 1), ('xl430', 2)])
def test_adapter_latency_no_stale_reading_taken(model, protocol):
    """Replies reach the host 10 ms late (a USB adapter's latency timer) with a 5 ms margin:
    the round trips at open raise the margin, and no reading carries the reply to an earlier
    request (before: P2 open failed, P1 readings were a cycle old yet ok)."""
    ids = [1, 2, 3]
    with ServoBusEmulator.of_model(model, ids) as emu:
        emu.adapter_latency_s = 0.010
        counts = _count_reads(emu, ids)
        with DynamixelBus(emu.port_name, [JointConfig(f'j{i}', i) for i in ids],
                          protocol=protocol, timeout_margin_ms=5.0) as bus:
            assert bus.reply_margin_ms >= 10.0
            assert any('margin raised from 5' in n for n in bus.take_notes())
            stale, ok = [], 0
            for _ in range(30):
                before = dict(counts)
                for r in bus.poll().readings:
                    if r.ok:
                        ok += 1
                        if _stamp(bus, r) <= before[r.servo_id]:
                            stale.append((r.servo_id, _stamp(bus, r), before[r.servo_id]))
            assert stale == []
            assert ok >= 0.9 * 30 * len(ids)


def test_late_sync_read_reply_never_taken_for_the_retry():
    """A servo answering 12 ms late (holding the bus) with a 5 ms margin: its Sync Read reply
    misses the deadline, the single READ retry asks for one byte more, so the late reply is
    counted and skipped, never taken as the retry's; the margin is raised and later cycles
    read it fresh (before: 3 of 15 readings were an earlier request's, marked ok)."""
    with ServoBusEmulator.of_model('xl430', [1, 2]) as emu, \
            DynamixelBus(emu.port_name, [JointConfig('a', 1), JointConfig('b', 2)], protocol=2,
                         timeout_margin_ms=5.0, silent_after=1000) as bus:
        counts = _count_reads(emu, [1, 2])
        bus.take_notes()
        emu.inject(2, 'late_reply', delay_s=0.012)
        stale, oks = [], []
        for _ in range(15):
            before = dict(counts)
            r = bus.poll().readings[1]
            oks.append(r.ok)
            if r.ok and _stamp(bus, r) <= before[2]:
                stale.append((_stamp(bus, r), before[2]))
        assert stale == []
        h = bus.health()[1]
        assert h.late_replies >= 1 and bus.reply_margin_ms >= 12.0
        # the raise is noted (unless a loaded machine raised the margin earlier)
        assert any('a reply of id 2 came' in n or 'margin' in n for n in bus.take_notes()) \
            or bus.reply_margin_ms > 12.0
        assert all(oks[-5:])


@pytest.mark.parametrize('delay_s', [0.007, 0.060])
@pytest.mark.parametrize('model,protocol,name', [('ax12a', 1, 'AX-12A'),
                                                 ('xm430w350', 2, 'XM430-W350')])
def test_late_ping_reply_at_open(model, protocol, name, delay_s):
    """The first PING reply comes late (7 ms: inside the open probe margin; 60 ms: beyond
    it). Before, the late PING reply was taken for the READ that followed: Protocol 2.0
    recorded Status Return Level 252 (the model number's low byte), Protocol 1.0 refused the
    servo as 'Status Return Level 0'. Now the model and level are right and torque on works."""
    with ServoBusEmulator.of_model(model, [1]) as emu:
        # warm the emulator's and the bus's code paths first: a cold first reply (imports,
        # compiled physics) once came beyond the 40 ms probe margin in a fresh clone's CI
        with DynamixelBus(emu.port_name, _joints(1), protocol=protocol, timeout_margin_ms=5.0):
            pass
        emu.inject(1, 'late_reply', count=1, delay_s=delay_s)
        with DynamixelBus(emu.port_name, _joints(1), protocol=protocol,
                          timeout_margin_ms=5.0) as bus:
            [h] = bus.health()
            assert (h.model, h.status_return_level) == (name, 2)
            assert h.late_replies == (1 if delay_s > 0.040 else 0)
            assert bus.set_torque(True) == {'j1': True}
            assert emu.read_register(1, 'torque_enable') == 1
            assert bus.poll().readings[0].ok


def test_usb_latency_timer_warned_and_in_margin(tmp_path, monkeypatch):
    """A /dev/ttyUSB* adapter whose sysfs latency_timer is 16 ms: noted with the command that
    sets it to 1, and the margin covers it (here a link named ttyUSB0 to the emulator pty)."""
    from hexapod_bench_drivers import dynamixel_bus

    sysfs = tmp_path / 'sys'
    (sysfs / 'ttyUSB0').mkdir(parents=True)
    (sysfs / 'ttyUSB0' / 'latency_timer').write_text('16\n')
    monkeypatch.setattr(dynamixel_bus, 'SYSFS_USB_SERIAL', sysfs)
    with ServoBusEmulator.of_model('xl430', [1]) as emu:
        link = tmp_path / 'ttyUSB0'
        link.symlink_to(emu.port_name)
        assert dynamixel_bus.usb_latency_timer_ms(str(link)) == 16
        with DynamixelBus(str(link), _joints(1), protocol=2, timeout_margin_ms=5.0) as bus:
            notes = bus.take_notes()
            [note] = [n for n in notes if 'latency timer' in n.lower() and 'USB' in n]
            assert '16 ms' in note and f'echo 1 | sudo tee {sysfs}/ttyUSB0/latency_timer' in note
            assert bus.reply_margin_ms >= 16.0 + 5.0
            assert bus.poll().readings[0].ok
    (sysfs / 'ttyUSB0' / 'latency_timer').write_text('1\n')
    with ServoBusEmulator.of_model('xl430', [1]) as emu:
        link.unlink()
        link.symlink_to(emu.port_name)
        with DynamixelBus(str(link), _joints(1), protocol=2, timeout_margin_ms=5.0) as bus:
            assert not any('latency timer 1' in n for n in bus.take_notes())


@pytest.mark.parametrize('model,protocol,n', CASES)
def test_status_return_level_1_torque_written_and_checked(model, protocol, n):
    """Status Return Level 1 (a common setting on real robots: writes are not acknowledged).
    Torque writes used to wait out a reply deadline per attempt and report failure (the
    overheating abort said torque off failed); now they are sent, read back and reported
    done, and the bus notes the level once."""
    with ServoBusEmulator.of_model(model, range(1, n + 1)) as emu:
        for i in range(1, n + 1):
            emu.servo(i).set('status_return_level', 1)
        with DynamixelBus(emu.port_name, _joints(n), protocol=protocol,
                          timeout_margin_ms=10.0) as bus:
            assert {h.status_return_level for h in bus.health()} == {1}
            notes = [x for x in bus.take_notes() if 'Status Return Level' in x]
            assert len(notes) == n and all('Status Return Level 1' in x for x in notes)
            assert all(r.ok for r in bus.poll().readings)
            timeouts = sum(h.timeouts for h in bus.health())
            assert all(bus.set_torque(True).values())
            assert [emu.read_register(i, 'torque_enable') for i in range(1, n + 1)] == [1] * n
            assert all(h.torque_enabled for h in bus.health())
            assert sum(h.timeouts for h in bus.health()) == timeouts
            assert all(bus.set_torque(False, ['j2']).values())
            assert emu.read_register(2, 'torque_enable') == 0


@pytest.mark.parametrize('model,protocol', [('ax18a', 1), ('xl430', 2)])
def test_status_return_level_0_refused_by_name(model, protocol):
    """A servo at Status Return Level 0 answers only PING, so nothing can be read from it:
    refused naming the level and the register (it was 'no servo answered a ping' on
    Protocol 1.0, whose SDK ping also READs the model number); the others are served."""
    with ServoBusEmulator.of_model(model, [1, 2]) as emu:
        emu.servo(2).set('status_return_level', 0)
        # a margin a loaded CI machine keeps (this test is not about timing)
        with DynamixelBus(emu.port_name, _joints(2), protocol=protocol, timeout_margin_ms=80.0,
                          retries=0) as bus:
            h = bus.health()
            assert h[0].status_return_level == 2 and 'Level 0' in h[1].model
            result = bus.poll()
            assert [r.ok for r in result.readings] == [True, False]
        emu.servo(1).set('status_return_level', 0)
        with pytest.raises(BusError, match=r'id 1: answers PING but no READ.*Status Return '
                                           r'Level is 0.*register (16|68)'):
            DynamixelBus(emu.port_name, _joints(2), protocol=protocol, timeout_margin_ms=80.0,
                         retries=0).open()


@pytest.mark.parametrize('model,protocol,tail', [('xl430', 2, 'REBOOT'),
                                                 ('ax18a', 1, 'Alarm Shutdown')])
def test_torque_on_refused_by_a_servo_in_hardware_error_shutdown(model, protocol, tail):
    """Overload (0x20, in the Shutdown register): the servo acknowledges the torque write and
    keeps Torque Enable 0 (Protocol 2.0) or Torque Limit 0 (Protocol 1.0 Alarm Shutdown).
    Reported as a failure naming the error (before: success), the others turned on; once the
    fault is gone, torque on succeeds."""
    held = 'torque_enable' if protocol == 2 else 'torque_limit'
    with ServoBusEmulator.of_model(model, [1, 2]) as emu, \
            DynamixelBus(emu.port_name, _joints(2), protocol=protocol,
                         timeout_margin_ms=10.0) as bus:
        bus.take_notes()
        emu.inject(1, 'error_bits', error_bits=0x20)
        assert bus.set_torque(True) == {'j1': False, 'j2': True}
        assert [emu.read_register(i, held) > 0 for i in (1, 2)] == [False, True]
        h = bus.health()
        assert not h[0].torque_enabled and h[0].last_error_flags == 0x20
        assert 'overload' in h[0].torque_error and tail in h[0].torque_error
        assert any(n.startswith('j1 (id 1) torque on refused') for n in bus.take_notes())
        emu.clear_faults(1)
        assert bus.set_torque(True) == {'j1': True, 'j2': True}
        assert bus.health()[0].torque_error == ''


def test_operating_mode_multi_turn_goals_and_goal_ignoring_modes_refused():
    """XL430 in Extended Position mode (4) one turn past centre (6144 ticks): holding the
    angle read commands 6144 (before: clipped to 4095, a turn back). A servo in velocity mode
    (1) ignores Goal Position: it is still read, but its goals and torque on are refused, named
    (before: written and silently ignored)."""
    from hexapod_bench_drivers.control_tables import XL430
    from hexapod_bench_drivers.servo_bus_emulator import EmulatedServo

    servos = [EmulatedServo(i, XL430) for i in (1, 2, 3)]
    servos[0].set('operating_mode', 4)
    servos[0].set('goal_position', 6144)
    servos[0].set('present_position', 6144)
    servos[1].set('operating_mode', 1)
    with ServoBusEmulator(servos) as emu, \
            DynamixelBus(emu.port_name, _joints(3), protocol=2, timeout_margin_ms=10.0) as bus:
        assert [h.operating_mode for h in bus.health()] == [4, 1, 3]
        assert list(bus.refused) == ['j2'] and 'Operating Mode 1 (velocity' in bus.refused['j2']
        assert any('j2 (id 2): Operating Mode 1' in n for n in bus.take_notes())
        result = bus.poll()
        assert all(r.ok for r in result.readings)
        assert_allclose(result.readings[0].position_rad, 2 * math.pi, atol=1e-9)
        assert bus.set_torque(True) == {'j1': True, 'j2': False, 'j3': True}
        assert 'ignores Goal Position' in bus.health()[1].torque_error
        assert emu.read_register(2, 'torque_enable') == 0
        # j2 has direction -1 and offset 0.1 (see _joints): its goal would be written if taken
        assert bus.write_goals({'j1': result.readings[0].position_rad, 'j2': 0.5,
                                'j3': 0.2}) == 2
        bus.poll()
        assert emu.read_register(1, 'goal_position') == 6144
        assert emu.read_register(2, 'goal_position') == 2048
        assert emu.read_register(3, 'goal_position') == 2048 + round(0.2 / (2 * math.pi / 4096))
        bus.write_goals({'j1': 3 * 2 * math.pi})
        bus.poll()
        assert emu.read_register(1, 'goal_position') == 2048 + 3 * 4096


def test_abort_reason_says_why():
    """The overheating flag at 26 degC aborts too; the reason says the servo reports it, not
    that 26 degC is above the 70 degC limit (it read "at 26 degC, flags ['overheating'] >
    limit 70 degC")."""
    with ServoBusEmulator.of_model('xl430', [1, 2]) as emu, \
            DynamixelBus(emu.port_name, _joints(2), protocol=2, timeout_margin_ms=10.0) as bus:
        bus.set_torque(True)
        emu.inject(2, 'error_bits', error_bits=0x04)
        result = bus.poll()
        assert result.aborted_now
        assert result.abort_reason == ("j2 (id 2) reports overheating (flags ['overheating']) "
                                       'at 26 degC (limit 70 degC): torque off, aborted')
    with ServoBusEmulator.of_model('xl430', [1, 2]) as emu, \
            DynamixelBus(emu.port_name, _joints(2), protocol=2, timeout_margin_ms=10.0,
                         temperature_limit_c=60.0) as bus:
        emu.inject(1, 'overheat', temperature_c=61)
        assert bus.poll().abort_reason == ('j1 (id 1) at 61 degC > limit 60 degC: torque off, '
                                           'aborted')
