"""The emulator's newer instructions against the real dynamixel_sdk 4.1.0 (and raw bytes).

Protocol 1.0 Bulk Read (MX only), Protocol 2.0 Fast Sync / Fast Bulk Read, Factory Reset on both
protocols, Clear (multi-turn) and the Instruction Error for anything else. Wire examples are the
ROBOTIS e-Manual's (Protocol 2.0 page, Fast Sync Read and Fast Bulk Read sections).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest
import serial
from dynamixel_sdk import (
    BROADCAST_ID,
    COMM_NOT_AVAILABLE,
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupSyncRead,
    PacketHandler,
)

from hexapod_bench_drivers.control_tables import (
    AX12A,
    MX28,
    MX28_2,
    XL430,
    XM430,
    ControlTable,
)
from hexapod_bench_drivers.dynamixel_bus import FastPortHandler
from hexapod_bench_drivers.servo_bus_emulator import (
    EmulatedServo,
    ServoBusEmulator,
    p2_packet,
)

pytestmark = pytest.mark.timeout(120)

# Protocol 2.0 XM430 addresses
P2_OPERATING_MODE, P2_TORQUE, P2_GOAL, P2_MOVING, P2_POSITION = 11, 64, 116, 122, 132
# Protocol 1.0 MX/AX addresses
P1_RETURN_DELAY, P1_TEMPERATURE_LIMIT, P1_TORQUE = 5, 11, 24


def _port(emu: ServoBusEmulator, margin_ms: float = 200.0) -> FastPortHandler:
    """A real SDK port on the emulator's pty; generous deadline (2 busy cores share it)."""
    port = FastPortHandler(emu.port_name, timeout_margin_ms=margin_ms)
    assert port.openPort()
    return port


def _bus(table: ControlTable, ids: list[int], **kw: object) -> ServoBusEmulator:
    """Servos of one model, each at its own still position (torque off), first-order physics."""
    servos = [EmulatedServo(i, table, initial_position_rad=0.05 * i) for i in ids]
    return ServoBusEmulator(servos, prefer_model=False, **kw)


def _stamp_reads(emu: ServoBusEmulator) -> list[int]:
    """Install a read_hook on every servo; the returned list gets each answering ID in order."""
    log: list[int] = []
    for s in emu.servos.values():
        s.read_hook = lambda servo: log.append(servo.servo_id)
    return log


def _s32(raw: int) -> int:
    return raw - (1 << 32) if raw & 0x80000000 else raw


def _poll(read: Callable[[], int], done: Callable[[int], bool], tries: int = 30000) -> int:
    """Read until ``done`` (each read advances the emulator's clock-driven physics)."""
    for _ in range(tries):
        value = read()
        if done(value):
            return value
    raise AssertionError(f'condition not reached; last value {value}')


def _p1_bulk_read(port: FastPortHandler, ph: Any, group: GroupBulkRead) -> int:
    """Protocol 1.0 GroupBulkRead with the real SDK.

    dynamixel_sdk 4.1.0's ``GroupBulkRead.txPacket`` passes a ``fast_option`` argument that
    ``Protocol1PacketHandler.bulkReadTx`` does not take (TypeError before anything is sent);
    then the group's own parameters go out through the packet handler's ``bulkReadTx`` and the
    group's ``rxPacket`` receives: SDK code on both sides.
    """
    try:
        return group.txRxPacket()
    except TypeError:
        group.makeParam()
        result = ph.bulkReadTx(port, group.param, len(group.param))
        return result if result != COMM_SUCCESS else group.rxPacket()


def _raw_txrx(ph: Any, port: FastPortHandler, servo_id: int, instruction: int,
              params: list[int]) -> tuple[Any, int, int]:
    """One instruction packet through the SDK's own txRxPacket (either protocol)."""
    if ph.getProtocolVersion() == 1.0:
        packet = [0, 0, servo_id, len(params) + 2, instruction, *params, 0]
    else:
        length = len(params) + 3
        packet = [0, 0, 0, 0, servo_id, length & 0xFF, length >> 8, instruction, *params, 0, 0]
    return ph.txRxPacket(port, packet)


# --- Protocol 1.0 Bulk Read ---------------------------------------------------------------------

def test_p1_bulk_read_on_mx28_equals_single_reads():
    with _bus(MX28, [1, 2, 3, 4]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        log = _stamp_reads(emu)
        br = GroupBulkRead(port, ph)
        blocks = {1: (36, 8), 2: (30, 2), 3: (43, 1), 4: (0, 3)}
        for sid, (address, length) in blocks.items():
            assert br.addParam(sid, address, length)
        assert _p1_bulk_read(port, ph, br) == COMM_SUCCESS
        assert log == [1, 2, 3, 4]          # read_hook before each answer, in the listed order
        bulk = {sid: [br.getData(sid, a + k, 1) for k in range(n)]
                for sid, (a, n) in blocks.items()}
        single = {}
        for sid, (address, length) in blocks.items():
            data, result, error = ph.readTxRx(port, sid, address, length)
            assert (result, error) == (COMM_SUCCESS, 0)
            single[sid] = list(data)
        assert bulk == single
        assert br.getData(4, 0, 2) == 29                               # MX-28 model number
        assert br.getData(1, 36, 2) == MX28.rad_to_position(0.05)      # its present position
        port.closePort()


def test_p1_bulk_read_chain_stops_at_a_silent_servo():
    # e-Manual: each servo sends its status after the previous one's, so a silent one stops
    # the servos after it too.
    with _bus(MX28, [1, 2, 3]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        log = _stamp_reads(emu)
        br = GroupBulkRead(port, ph)
        for sid in (1, 2, 3):
            br.addParam(sid, 36, 2)
        emu.inject(2, 'no_answer', count=1)
        assert _p1_bulk_read(port, ph, br) == COMM_RX_TIMEOUT
        assert log == [1, 2]
        assert _p1_bulk_read(port, ph, br) == COMM_SUCCESS      # fault used up
        assert [br.getData(i, 36, 2) for i in (1, 2, 3)] == [
            MX28.rad_to_position(0.05 * i) for i in (1, 2, 3)]
        port.closePort()


def test_p1_bulk_read_refused_by_ax12a():
    # AX servos have no Bulk Read; the packet is a broadcast, so they stay silent.
    with _bus(AX12A, [1, 2]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        log = _stamp_reads(emu)
        br = GroupBulkRead(port, ph)
        br.addParam(1, 36, 2)
        br.addParam(2, 36, 2)
        assert _p1_bulk_read(port, ph, br) == COMM_RX_TIMEOUT
        assert log == [] and emu.replies_sent == 0
        assert ph.ping(port, 2)[:2] == (12, COMM_SUCCESS)       # the bus still works
        port.closePort()
    # On a mixed bus the MX servo listed after an AX waits for a status that never comes.
    with ServoBusEmulator.of_models([(1, 'mx28'), (2, 'ax12a'), (3, 'mx28')]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        log = _stamp_reads(emu)
        br = GroupBulkRead(port, ph)
        for sid in (1, 2, 3):
            br.addParam(sid, 43, 1)
        assert _p1_bulk_read(port, ph, br) == COMM_RX_TIMEOUT
        assert log == [1]
        port.closePort()


# --- Protocol 2.0 Fast Sync Read / Fast Bulk Read ------------------------------------------------

def _raw_exchange(emu: ServoBusEmulator, packet: bytes, reply_len: int) -> bytes:
    with serial.Serial(emu.port_name, timeout=10.0) as ser:
        ser.write(packet)
        return ser.read(reply_len)


def test_fast_reads_reply_the_emanual_examples_byte_for_byte():
    ticks = {3: 166, 7: 2079, 4: 1023}
    servos = [EmulatedServo(i, XM430, initial_position_rad=XM430.position_to_rad(t),
                            initial_temperature_c=31.0 if i == 4 else 26.0)
              for i, t in ticks.items()]
    with ServoBusEmulator(servos, prefer_model=False) as emu:
        fast_sync = p2_packet(BROADCAST_ID, 0x8A, bytes([0x84, 0x00, 0x04, 0x00, 3, 7, 4]))
        assert fast_sync == bytes.fromhex('fffffd00fe0a008a84000400030704 20f2'.replace(' ', ''))
        expected = bytes.fromhex(
            'fffffd00fe19005500 03a6000000 8408'   # header, ID 3's error, ID, data, CRC
            '00 07 1f080000 16ca'                    # ID 7's segment, CRC so far
            '00 04 ff030000 d19e'.replace(' ', ''))  # ID 4's segment: its CRC ends the packet
        assert _raw_exchange(emu, fast_sync, len(expected)) == expected
        emu.servo(7).set('present_pwm', 421)
        fast_bulk = p2_packet(BROADCAST_ID, 0x9A, bytes.fromhex('038400040007 7c000200 04920001 00'
                                                                .replace(' ', '')))
        # (the e-Manual prints this instruction's CRC as 20 F2, the Fast Sync Read example's)
        assert fast_bulk[:-2].hex() == 'fffffd00fe12009a038400040007 7c000200 04920001 00'.replace(
            ' ', '')
        expected = bytes.fromhex(
            'fffffd00fe14005500 03a6000000 67a4'
            '00 07 a501 2474'
            '00 04 1f d9c1'.replace(' ', ''))
        assert _raw_exchange(emu, fast_bulk, len(expected)) == expected


def test_fast_sync_read_equals_sync_read_on_four_xm430():
    with _bus(XM430, [1, 2, 3, 4]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        log = _stamp_reads(emu)
        fast, plain = GroupSyncRead(port, ph, 126, 10), GroupSyncRead(port, ph, 126, 10)
        for sid in (1, 2, 3, 4):
            assert fast.addParam(sid) and plain.addParam(sid)
        assert fast.fastSyncRead() == COMM_SUCCESS
        assert log == [1, 2, 3, 4]
        assert plain.txRxPacket() == COMM_SUCCESS

        def items(group):
            return [(group.getData(i, 126, 2), group.getData(i, 128, 4), group.getData(i, 132, 4))
                    for i in (1, 2, 3, 4)]

        assert items(fast) == items(plain)
        assert [p for _, _, p in items(fast)] == [XM430.rad_to_position(0.05 * i)
                                                  for i in (1, 2, 3, 4)]
        # A fast status packet is not byte-stuffed (e-Manual): data holding FF FF FD arrives
        # as it is, where the plain Sync Read stuffs and the SDK unstuffs.
        with emu.lock:
            emu.servo(2).set('goal_position', 0x00FDFFFF)
        goal_fast, goal_plain = GroupSyncRead(port, ph, 116, 4), GroupSyncRead(port, ph, 116, 4)
        for sid in (1, 2, 3):
            goal_fast.addParam(sid)
            goal_plain.addParam(sid)
        assert goal_fast.fastSyncRead() == COMM_SUCCESS and goal_plain.txRxPacket() == COMM_SUCCESS
        assert goal_fast.getData(2, 116, 4) == goal_plain.getData(2, 116, 4) == 0x00FDFFFF
        assert goal_fast.getData(3, 116, 4) == XM430.rad_to_position(0.15)
        port.closePort()


def test_fast_bulk_read_equals_bulk_read_on_four_xm430():
    with _bus(XM430, [1, 2, 3, 4]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        emu.servo(3).set('present_pwm', 421)
        log = _stamp_reads(emu)
        blocks = {1: (132, 4), 2: (146, 1), 3: (124, 2), 4: (0, 7)}
        group = GroupBulkRead(port, ph)
        for sid, (address, length) in blocks.items():
            assert group.addParam(sid, address, length)
        assert group.txRxPacket() == COMM_SUCCESS

        def values():
            return {sid: [group.getData(sid, a + k, 1) for k in range(n)]
                    for sid, (a, n) in blocks.items()}

        plain = values()
        assert group.fastBulkRead() == COMM_SUCCESS
        assert values() == plain
        assert log == [1, 2, 3, 4] * 2
        assert group.getData(3, 124, 2) == 421 and group.getData(2, 146, 1) == 26
        assert group.getData(4, 0, 2) == XM430.model_number
        port.closePort()


def test_fast_read_faults_break_the_packet_then_recover():
    with _bus(XM430, [1, 2, 3, 4]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        group = GroupSyncRead(port, ph, 132, 4)
        for sid in (1, 2, 3, 4):
            group.addParam(sid)
        emu.inject(2, 'bad_checksum', count=1)    # a segment corrupted on the wire
        assert group.fastSyncRead() == COMM_RX_CORRUPT
        log = _stamp_reads(emu)
        emu.inject(3, 'no_answer', count=1)       # the chain stops: shorter than its LEN
        assert group.fastSyncRead() == COMM_RX_CORRUPT
        assert log == [1, 2, 3]
        emu.inject(1, 'error_bits', error_bits=0x20, count=1)
        assert group.fastSyncRead() == COMM_SUCCESS
        assert group.getData(4, 132, 4) == XM430.rad_to_position(0.2)
        assert emu.servo(2).fault_hits == {'bad_checksum': 1}
        assert emu.servo(1).fault_hits == {'error_bits': 1}
        port.closePort()


def test_fast_read_on_a_model_without_it_fails_cleanly():
    # MX(2.0) firmware has no Fast Sync/Bulk Read (e-Manual lists X430/540 v45+, X330 v46+);
    # the instruction is a broadcast, so it stays silent.
    with _bus(MX28_2, [1, 2]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        log = _stamp_reads(emu)
        sync = GroupSyncRead(port, ph, 132, 4)
        bulk = GroupBulkRead(port, ph)
        for sid in (1, 2):
            sync.addParam(sid)
            bulk.addParam(sid, 132, 4)
        assert sync.fastSyncRead() == COMM_RX_TIMEOUT
        assert bulk.fastBulkRead() == COMM_RX_TIMEOUT
        assert log == []
        assert sync.txRxPacket() == COMM_SUCCESS        # plain Sync Read still served
        assert sync.getData(2, 132, 4) == MX28_2.rad_to_position(0.1)
        port.closePort()
    # A servo without it in the middle of the list cuts the combined packet short.
    with ServoBusEmulator.of_models([(1, 'xm430'), (2, 'mx28_2'), (3, 'xm430')]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        sync = GroupSyncRead(port, ph, 132, 4)
        for sid in (1, 2, 3):
            sync.addParam(sid)
        assert sync.fastSyncRead() == COMM_RX_CORRUPT
        port.closePort()
    # X-series firmware older than v45 has no fast reads either.
    with _bus(XL430, [1]) as emu:
        emu.servo(1).set('firmware_version', 44)
        port = _port(emu)
        sync = GroupSyncRead(port, PacketHandler(2.0), 132, 4)
        sync.addParam(1)
        assert sync.fastSyncRead() == COMM_RX_TIMEOUT
        port.closePort()


# --- Factory Reset ------------------------------------------------------------------------------

def test_p2_factory_reset_options():
    with _bus(XM430, [5, 6, 7, 8]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        for sid in (5, 6, 7, 8):
            assert ph.write1ByteTxRx(port, sid, 9, 100) == (COMM_SUCCESS, 0)   # return delay
            assert ph.write1ByteTxRx(port, sid, 31, 60) == (COMM_SUCCESS, 0)   # temp. limit
            assert ph.write1ByteTxRx(port, sid, 8, 1) == (COMM_SUCCESS, 0)     # baud 57 600
            assert ph.write1ByteTxRx(port, sid, P2_OPERATING_MODE, 4) == (COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, 6, P2_TORQUE, 1) == (COMM_SUCCESS, 0)
        # 0x02: all but ID and baud rate
        assert ph.factoryReset(port, 5, 0x02) == (COMM_SUCCESS, 0)
        assert [ph.read1ByteTxRx(port, 5, a)[0] for a in (7, 8, 9, 11, 31)] == [5, 1, 0, 3, 80]
        # 0x01: all but ID (torque on is not refused; torque is off after the reset)
        assert ph.factoryReset(port, 6, 0x01) == (COMM_SUCCESS, 0)
        assert [ph.read1ByteTxRx(port, 6, a)[0] for a in (7, 8, 9, 11, 31, 64)] == [
            6, 3, 0, 3, 80, 0]
        # 0xFF: everything, the ID back to 1
        assert ph.factoryReset(port, 7, 0xFF) == (COMM_SUCCESS, 0)
        assert ph.ping(port, 7)[1] == COMM_RX_TIMEOUT
        assert ph.ping(port, 1)[:2] == (XM430.model_number, COMM_SUCCESS)
        assert [ph.read1ByteTxRx(port, 1, a)[0] for a in (7, 8, 9, 31)] == [1, 3, 0, 80]
        assert emu.servo(1).servo_id == 1 and 7 not in emu.servos and emu.displaced == []
        # Broadcast + Reset all is ignored (firmware v42+); broadcast 0x01 resets every servo.
        assert ph.factoryReset(port, BROADCAST_ID, 0xFF)[0] == COMM_SUCCESS
        assert ph.read1ByteTxRx(port, 8, 31)[:2] == (60, COMM_SUCCESS)
        assert ph.factoryReset(port, BROADCAST_ID, 0x01)[0] == COMM_SUCCESS
        assert ph.read1ByteTxRx(port, 8, 31)[:2] == (80, COMM_SUCCESS)
        assert ph.read1ByteTxRx(port, 8, 8)[:2] == (3, COMM_SUCCESS)
        assert sorted(emu.servos) == [1, 5, 6, 8]
        port.closePort()


def test_p1_factory_reset_sets_id_1_and_defaults():
    with ServoBusEmulator.of_models([(2, 'ax12a'), (3, 'mx28')]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        for sid in (2, 3):
            assert ph.write1ByteTxRx(port, sid, P1_TEMPERATURE_LIMIT, 60) == (COMM_SUCCESS, 0)
            assert ph.write1ByteTxRx(port, sid, P1_RETURN_DELAY, 20) == (COMM_SUCCESS, 0)
            assert ph.write1ByteTxRx(port, sid, P1_TORQUE, 1) == (COMM_SUCCESS, 0)
        mx, ax = emu.servo(3), emu.servo(2)
        assert ph.factoryReset(port, 3) == (COMM_SUCCESS, 0)      # reply from the old ID
        assert ph.ping(port, 3)[1] == COMM_RX_TIMEOUT
        assert ph.ping(port, 1)[:2] == (MX28.model_number, COMM_SUCCESS)
        assert [ph.read1ByteTxRx(port, 1, a)[0]
                for a in (3, P1_RETURN_DELAY, P1_TEMPERATURE_LIMIT, P1_TORQUE)] == [1, 0, 80, 0]
        assert ph.read1ByteTxRx(port, 2, P1_TEMPERATURE_LIMIT)[0] == 60   # the AX untouched
        # The AX reset to ID 1 too: it takes the ID, the MX holding it is displaced.
        assert ph.factoryReset(port, 2) == (COMM_SUCCESS, 0)
        assert ph.ping(port, 1)[:2] == (AX12A.model_number, COMM_SUCCESS)
        assert ph.read1ByteTxRx(port, 1, P1_TEMPERATURE_LIMIT)[0] == 70
        assert emu.servo(1) is ax and emu.displaced == [mx]
        port.closePort()


# --- Clear (multi-turn) -------------------------------------------------------------------------

def test_clear_multi_turn_in_extended_position_mode():
    with ServoBusEmulator.of_model('xm430w210', [1], prefer_model=False) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)

        def position():
            value, result, _ = ph.read4ByteTxRx(port, 1, P2_POSITION)
            assert result == COMM_SUCCESS
            return _s32(value)

        def moving():
            return ph.read1ByteTxRx(port, 1, P2_MOVING)[0]

        def go_and_settle(goal: int) -> None:
            assert ph.write4ByteTxRx(port, 1, P2_GOAL, goal & 0xFFFFFFFF) == (COMM_SUCCESS, 0)
            _poll(position, lambda p: abs(p - goal) <= 2)
            _poll(moving, lambda m: m == 0)

        assert ph.write1ByteTxRx(port, 1, P2_OPERATING_MODE, 4) == (COMM_SUCCESS, 0)
        assert ph.write1ByteTxRx(port, 1, P2_TORQUE, 1) == (COMM_SUCCESS, 0)
        # While the servo moves: Result Fail (e-Manual), nothing cleared.
        assert ph.write4ByteTxRx(port, 1, P2_GOAL, 1_000_000) == (COMM_SUCCESS, 0)
        _poll(moving, lambda m: m == 1)
        assert ph.clearMultiTurn(port, 1) == (COMM_SUCCESS, 0x01)
        # One turn and 3000 ticks out, stopped with torque on: cleared to 3000.
        go_and_settle(4096 + 3000)
        assert ph.clearMultiTurn(port, 1) == (COMM_SUCCESS, 0)
        assert abs(position() - 3000) <= 2
        assert _s32(ph.read4ByteTxRx(port, 1, P2_GOAL)[0]) == 3000   # goal shifted with it
        for _ in range(50):                                          # and it holds there
            assert abs(position() - 3000) <= 2 and moving() == 0
        # A negative revolution count clears to the position within one turn, too.
        go_and_settle(-1000)
        assert ph.clearMultiTurn(port, 1) == (COMM_SUCCESS, 0)
        assert abs(position() - 3096) <= 2
        # Reserved Clear options: the emulator answers Data Range Error (not in the e-Manual).
        assert _raw_txrx(ph, port, 1, 0x10, [0x02, 0x44, 0x58, 0x4C, 0x22])[1:] == (
            COMM_SUCCESS, 0x04)
        # Firmware older than v42 has no Clear.
        emu.servo(1).set('firmware_version', 41)
        assert ph.clearMultiTurn(port, 1) == (COMM_SUCCESS, 0x02)
        port.closePort()


# --- anything else ------------------------------------------------------------------------------

def test_unknown_instructions_get_instruction_error():
    with _bus(MX28, [1]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        assert _raw_txrx(ph, port, 1, 0x7F, [])[1:] == (COMM_SUCCESS, 0x40)
        # REBOOT is not a Protocol 1.0 MX instruction; the SDK does not even send it.
        assert _raw_txrx(ph, port, 1, 0x08, [])[1:] == (COMM_SUCCESS, 0x40)
        assert ph.reboot(port, 1) == (COMM_NOT_AVAILABLE, 0)
        assert ph.ping(port, 1)[:2] == (MX28.model_number, COMM_SUCCESS)
        port.closePort()
    with _bus(XM430, [1]) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        assert _raw_txrx(ph, port, 1, 0x7F, [])[1:] == (COMM_SUCCESS, 0x02)
        # Fast Sync Read addressed to one servo instead of the broadcast ID
        assert _raw_txrx(ph, port, 1, 0x8A, [0x84, 0, 4, 0, 1])[1:] == (COMM_SUCCESS, 0x02)
        assert ph.ping(port, 1)[:2] == (XM430.model_number, COMM_SUCCESS)
        port.closePort()
