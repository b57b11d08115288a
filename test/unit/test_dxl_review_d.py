"""Fixes from a third outside review of the Dynamixel driver (its own emulator), at bus level on
the project's emulator: a servo coming back as another model, torque lost between two reads,
the cost of a persistent Protocol 2.0 alert, and a refused instruction told from noise."""

from __future__ import annotations

import dataclasses

import pytest

from hexapod_bench_drivers.control_tables import XL430
from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator
from test_dxl_review_fixes import _poll_until

pytestmark = pytest.mark.timeout(60)

#: (first model, the model that comes back at the ID, protocol)
SWAPS = [('ax18a', 'mx28', 1), ('xm430', 'xl430', 2)]
P1P2 = [('ax18a', 1), ('xl430', 2)]


def _bus(emu, n, protocol, **kw):
    kw.setdefault('timeout_margin_ms', 40.0)   # a loaded machine delays the emulator thread
    joints = [JointConfig(f'j{i}', i) for i in range(1, n + 1)]
    return DynamixelBus(emu.port_name, joints, protocol=protocol, **kw)


# --- 1: a servo that comes back as another model -----------------------------------------------
@pytest.mark.parametrize('first,other,protocol', SWAPS)
def test_servo_back_as_another_model_left_out_naming_both(first, other, protocol):
    """Servo 2 goes silent and another model answers at its ID. Before: read with the first
    model's table and published as valid (AX-18A -> MX-28: 9.909 rad; XM430 -> XL430: effort
    2.4 N m for 0.75). Now its model number is read when it answers again: left out, named
    with both models, also when probed again; the first model answering again is taken back
    (and its lost torque reported)."""
    with ServoBusEmulator.of_model(first, [1, 2, 3]) as emu, \
            _bus(emu, 3, protocol, silent_after=2, probe_interval_cycles=2) as bus:
        first_name = bus.health()[1].model
        assert all(bus.set_torque(True).values())
        bus.take_events()
        emu.inject(2, 'no_answer')
        _poll_until(bus, lambda r: bus.health()[1].silent)
        new = emu.replace(2, other, initial_position_rad=1.0)
        results = [bus.poll() for _ in range(8)]
        assert not any(r.readings[1].ok for r in results)
        assert all(r.readings[0].ok and r.readings[2].ok for r in results)
        why = bus.refused['j2']
        assert why.startswith(f'model changed: first detected as {first_name}')
        assert f'now answers as {new.table.model_name} (model number ' in why
        assert 'left out until the driver is restarted' in why
        warnings = [m for lv, m in bus.take_events() if lv == 'warning' and 'model changed' in m]
        assert len(warnings) == 1 and warnings[0].startswith('j2 (id 2) model changed')
        assert bus.write_goals({'j1': 0.1, 'j2': 0.1}) == 1     # never commanded either
        emu.replace(2, first)                                   # the first model again
        _poll_until(bus, lambda r: r.readings[1].ok)
        assert 'j2' not in bus.refused
        assert 'came back with torque off' in bus.health()[1].torque_lost


def test_refused_read_of_an_unknown_model_left_out():
    """Protocol 2.0: a servo of a model the driver does not know (an XL-320 stand-in, model
    number 350) answers the Sync Read with Access Error and no data, without ever going
    silent. Its model number is read at once: left out naming both."""
    unknown = dataclasses.replace(XL430, model_number=350, model_name='XL-320 stand-in')
    with ServoBusEmulator.of_model('xl430', [1, 2]) as emu, _bus(emu, 2, 2) as bus:
        bus.poll()
        emu.replace(2, unknown)
        emu.inject(2, 'refuse', count=1, error_bits=0x07)
        result = bus.poll()
        assert result.readings[0].ok and not result.readings[1].ok
        assert bus.refused['j2'].startswith('model changed: first detected as XL430-W250 '
                                            '(model number 1060), now answers as model '
                                            'number 350, not a model the driver knows')


# --- 2: torque lost between two reads ----------------------------------------------------------
@pytest.mark.parametrize('model,protocol', P1P2)
def test_torque_lost_between_two_reads_found_by_the_round_robin(model, protocol):
    """Servo 2 rebooted between two cycles (Torque Enable back to 0, no reply missed). Before:
    torque_enabled stayed True for ever. Now Torque Enable is read in turn (Protocol 1.0: one
    servo's READ a cycle starts at it, within 3 cycles here, no extra request) or of every
    servo every 10 cycles (Protocol 2.0: one more Sync Read then)."""
    with ServoBusEmulator.of_model(model, [1, 2, 3]) as emu, _bus(emu, 3, protocol) as bus:
        assert all(bus.set_torque(True).values())
        for _ in range(3):
            bus.poll()
        bus.take_events()
        emu.power_cycle(2)
        before = emu.packets_received
        cycles = 3 if protocol == 1 else bus.torque_check_interval_cycles
        for _ in range(cycles):
            assert all(r.ok for r in bus.poll().readings)
        h = bus.health()
        assert h[0].torque_enabled and h[2].torque_enabled
        assert not h[1].torque_enabled
        assert h[1].torque_lost.startswith('torque off between two reads, no reply missed')
        assert any(lv == 'warning' and m.startswith('j2 (id 2) torque off between two reads')
                   for lv, m in bus.take_events())
        # a READ per servo, or one Sync Read a cycle and one of registers 64-70
        assert emu.packets_received - before == (9 if protocol == 1 else cycles + 1)


# --- 3: a persistent Protocol 2.0 alert --------------------------------------------------------
def test_persistent_alert_costs_one_read_per_cycle_and_flags_stay_published():
    """Every servo flags Input Voltage (a sagging battery): the alert bit on every reply.
    Before: one READ of Hardware Error Status per servo per cycle (7 + 1 requests a cycle
    here). Now all alerted servos' in one Sync Read: 2 a cycle; the flags are published every
    cycle, and a flag added while the alert lasts is seen in that cycle."""
    n = 6
    with ServoBusEmulator.of_model('xl430', range(1, n + 1)) as emu, _bus(emu, n, 2) as bus:
        assert all(bus.set_torque(True).values())
        bus.poll()
        for i in range(1, n + 1):
            emu.inject(i, 'error_bits', error_bits=0x01)   # not in Shutdown: torque stays
        assert [r.error_flags for r in bus.poll().readings] == [0x01] * n   # read at once
        before = emu.packets_received
        for _ in range(2 * n):
            assert [r.error_flags for r in bus.poll().readings] == [0x01] * n
        assert emu.packets_received - before == 2 * n * 2
        emu.inject(3, 'error_bits', error_bits=0x21)       # overload too: shutdown
        assert bus.poll().readings[2].error_flags == 0x21
        assert "hardware error ['input_voltage', 'overload']" in bus.health()[2].torque_lost
        assert all(h.torque_enabled for k, h in enumerate(bus.health()) if k != 2)


# --- 4: a refused instruction is not noise -----------------------------------------------------
@pytest.mark.parametrize('sync_read', [True, False])
def test_access_error_said_as_such_not_noise(sync_read):
    """A READ (or Sync Read) answered with Access Error (0x07) and no data. Before: 'a
    corrupted instruction ... noise on the way to the servo (cabling)', retried (a Sync Read's
    reply counted late). Now said to be an access error (a register this model does not
    have), counted apart, not retried: the model number is read instead (the same model here:
    read again on the next cycle)."""
    with ServoBusEmulator.of_model('xl430', [1, 2]) as emu, _bus(emu, 2, 2) as bus:
        bus.sync_read = sync_read
        margin = bus.reply_margin_ms
        bus.poll()
        bus.take_events()
        emu.inject(2, 'refuse', count=1, error_bits=0x07)
        bus.poll()
        lines = [m for lv, m in bus.take_events() if lv == 'warning']
        assert len(lines) == 1
        assert lines[0].startswith('j2 (id 2) reports access_error (status error 0x07) on an '
                                   'instruction it received intact: a register this model '
                                   'does not have')
        assert 'noise' not in lines[0] and 'cabling' not in lines[0]
        h = bus.health()[1]
        assert h.refused_instructions == 1 and h.rejected_instructions == 0
        assert bus.late_replies == 0 and bus.reply_margin_ms == margin
        assert bus.poll().readings[1].ok and 'j2' not in bus.refused
