"""Fixes from an outside review of the Torque Enable round robin and the cached Protocol 2.0
alert, at bus level on the project's emulator: overheating during a persistent alert aborts
in its cycle again, and Torque Enable is read at no extra request a cycle (Protocol 1.0, 2.0
without Sync Read) or one every 10 cycles (2.0 Sync Read)."""

from __future__ import annotations

import dataclasses

import pytest

from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import INST_SYNC_READ, ServoBusEmulator

pytestmark = pytest.mark.timeout(60)

N = 6


def _bus(emu, protocol, **kw):
    kw.setdefault('timeout_margin_ms', 40.0)   # a loaded machine delays the emulator thread
    joints = [JointConfig(f'j{i}', i) for i in range(1, N + 1)]
    return DynamixelBus(emu.port_name, joints, protocol=protocol, **kw)


class NoSyncRead(ServoBusEmulator):
    """Servos (or an adapter) that never answer Sync Read."""

    def _handle(self, pkt):
        return [] if pkt.instruction == INST_SYNC_READ else super()._handle(pkt)


def test_overheating_while_every_servo_alerts_aborts_in_that_cycle():
    """Every servo flags Input Voltage (a sagging battery), then one flags Overheating too
    (below the temperature limit: only the flag tells). Before: the cached flags were read
    again only in the round robin, so the abort came 1 to 6 cycles later depending on the
    servo (cycles 3, 4, 5, 6, 1, 2 for servos 1-6). Now the alerted servos' Hardware Error
    Status is read every cycle in one Sync Read: torque off and abort in that cycle, for
    whichever servo, at two requests a cycle."""
    for hot in range(1, N + 1):
        with ServoBusEmulator.of_model('xl430', range(1, N + 1)) as emu, \
                _bus(emu, 2) as bus:
            assert all(bus.set_torque(True).values())
            bus.poll()
            for i in range(1, N + 1):
                emu.inject(i, 'error_bits', error_bits=0x01)
            before = emu.packets_received
            for _ in range(3):
                result = bus.poll()
                assert not result.aborted_now
                assert [r.error_flags for r in result.readings] == [0x01] * N
            requests = emu.packets_received - before
            emu.inject(hot, 'error_bits', error_bits=0x05)
            result = bus.poll()
            assert result.aborted_now and bus.aborted, f'servo {hot}'
            assert requests == 3 * 2   # the alert appearing too (64-70 read then)
            assert result.readings[hot - 1].error_flags == 0x05
            assert bus.abort_reason.startswith(f'j{hot} (id {hot}) reports overheating')
            assert [emu.read_register(i, 'torque_enable') for i in range(1, N + 1)] == [0] * N


@pytest.mark.parametrize('model,protocol', [('ax18a', 1), ('xl430', 2)])
def test_torque_enable_read_without_a_request_a_cycle(model, protocol):
    """Before: one READ of Torque Enable a cycle beside the present values (Protocol 1.0, 6
    servos: 7 requests a cycle; 2.0: 2). Now Protocol 1.0 reads it in one servo's READ a
    cycle, which starts at register 24 (6 requests a cycle), and 2.0 reads registers 64-70 of
    every servo in one Sync Read every 10 cycles (11 requests in 10 cycles); a torque loss
    without a missed reply is still reported within those cycles."""
    with ServoBusEmulator.of_model(model, range(1, N + 1)) as emu, \
            _bus(emu, protocol) as bus:
        assert all(bus.set_torque(True).values())
        k = 10   # bus.torque_check_interval_cycles
        for _ in range(k):
            bus.poll()
        bus.take_events()
        before = emu.packets_received
        for _ in range(2 * k):
            assert all(r.ok for r in bus.poll().readings)
        assert emu.packets_received - before == (2 * k * N if protocol == 1 else 2 * k + 2)
        assert all(h.torque_enabled and not h.torque_lost for h in bus.health())
        emu.power_cycle(5)
        for _ in range(N if protocol == 1 else k):
            assert all(r.ok for r in bus.poll().readings)
        h = bus.health()
        assert not h[4].torque_enabled
        assert h[4].torque_lost.startswith('torque off between two reads, no reply missed')
        assert all(x.torque_enabled for i, x in enumerate(h) if i != 4)


def test_torque_enable_without_sync_read_in_the_single_reads():
    """A Protocol 2.0 bus without Sync Read, read servo by servo: one servo's READ a cycle
    starts at Torque Enable (64, Hardware Error Status at 70 with it), no extra request; a
    torque loss is reported within 6 cycles."""
    emu = NoSyncRead.of_model('xl430', range(1, N + 1))
    with emu, _bus(emu, 2, timeout_margin_ms=80.0) as bus:
        assert all(bus.set_torque(True).values())
        while bus.sync_read:
            bus.poll()
        before = emu.packets_received
        for _ in range(N):
            assert all(r.ok for r in bus.poll().readings)
        assert emu.packets_received - before == N * N
        emu.power_cycle(2)
        for _ in range(N):
            bus.poll()
        assert bus.health()[1].torque_lost.startswith('torque off between two reads')


def test_a_persistent_alert_without_sync_read_costs_no_extra_request():
    """A review of the change: on a Protocol 2.0 bus that never answers Sync Read, every
    servo with a persistent alert cost a READ of register 70 a cycle beside its present
    values (6 alerted servos: 11 requests a cycle). Its READ now starts at Torque Enable
    while its alert stays, Hardware Error Status with it: 6 requests, and overheating still
    aborts in its cycle."""
    with NoSyncRead.of_model('xl430', range(1, N + 1)) as emu, _bus(emu, 2) as bus:
        assert all(bus.set_torque(True).values())
        for _ in range(3):
            bus.poll()
        for i in range(1, N + 1):
            emu.inject(i, 'error_bits', error_bits=0x01)
        bus.poll()
        bus.poll()
        before = emu.packets_received
        for _ in range(10):
            result = bus.poll()
            assert [r.error_flags for r in result.readings] == [0x01] * N
        assert emu.packets_received - before == 10 * N
        emu.inject(3, 'error_bits', error_bits=0x05)
        result = bus.poll()
        assert result.aborted_now and bus.abort_reason.startswith('j3 (id 3) reports overheat')


class DropStatusOnce(ServoBusEmulator):
    """Drops one servo from the next Sync Read of registers 64-70 (its reply lost)."""

    drop: int | None = None

    def _handle(self, pkt):
        if (self.drop is not None and pkt.instruction == INST_SYNC_READ
                and bytes(pkt.params[0:2]) == bytes([64, 0])):
            ids = bytes(i for i in pkt.params[4:] if i != self.drop)
            self.drop = None
            pkt = dataclasses.replace(pkt, params=bytes(pkt.params[:4]) + ids)
        return super()._handle(pkt)


def test_a_servo_that_misses_the_torque_check_is_asked_again_the_next_cycle():
    """A review of the change: a servo whose reply to the every-10-cycles Sync Read of
    registers 64-70 was lost had its Torque Enable checked again only 10 cycles later. It
    is asked again in the next cycle: a reboot right after is seen within 2 cycles."""
    emu = DropStatusOnce.of_model('xl430', range(1, N + 1))
    with emu, _bus(emu, 2) as bus:
        assert all(bus.set_torque(True).values())
        while (bus.cycle + 1) % bus.torque_check_interval_cycles:
            bus.poll()
        emu.drop = 3
        bus.poll()                       # the torque check, servo 3's reply lost
        emu.power_cycle(3)               # rebooted: Torque Enable 0, no reply missed
        for _ in range(2):
            bus.poll()
        assert bus.health()[2].torque_lost.startswith('torque off between two reads')
