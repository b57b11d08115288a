"""Servo-bus emulator: packet codecs, and the real dynamixel_sdk talking to it over a pty."""

from __future__ import annotations

import pytest
from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupBulkRead,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
)
from numpy.testing import assert_allclose

from hexapod_bench_drivers.control_tables import AX18A, XL430
from hexapod_bench_drivers.dynamixel_bus import FastPortHandler
from hexapod_bench_drivers.servo_bus_emulator import (
    EmulatedServo,
    ServoBusEmulator,
    _parse_p2,
    crc16,
    p1_packet,
    p2_packet,
)

pytestmark = pytest.mark.timeout(60)


def test_codecs_match_emanual_examples():
    # e-Manual: Protocol 1.0 PING to ID 1 -> FF FF 01 02 01 FB
    assert p1_packet(1, 0x01) == bytes.fromhex('ffff010201fb')
    # e-Manual: Protocol 2.0 PING to ID 1 -> FF FF FD 00 01 03 00 01 19 4E
    assert p2_packet(1, 0x01) == bytes.fromhex('fffffd0001030001194e')
    sdk = PacketHandler(2.0)
    data = bytes(range(256)) * 2
    assert crc16(data) == sdk.updateCRC(0, list(data), len(data))


def test_p2_byte_stuffing_round_trip():
    params = bytes.fromhex('fffffd01ff')
    pkt = p2_packet(3, 0x55, params, error=0)
    assert b'\xff\xff\xfd\xfd' in pkt[8:]
    parsed, used = _parse_p2(bytearray(b'\x00\x13' + pkt))
    assert used == len(pkt) + 2 and parsed.checksum_ok
    assert parsed.params == b'\x00' + params   # error byte, then the unstuffed data


def _port(emu, margin_ms=50.0):  # generous: the emulator thread shares 2 busy cores
    port = FastPortHandler(emu.port_name, timeout_margin_ms=margin_ms)
    assert port.openPort()
    return port


def test_protocol1_ping_read_write_syncwrite():
    with ServoBusEmulator.of_model('ax18a', [1, 2, 3]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        assert ph.ping(port, 2)[:2] == (18, COMM_SUCCESS)
        assert ph.ping(port, 9)[1] == COMM_RX_TIMEOUT
        assert ph.read1ByteTxRx(port, 3, 3)[0] == 3                 # ID register
        assert ph.write1ByteTxRx(port, 1, 24, 1)[0] == COMM_SUCCESS
        assert emu.read_register(1, 'torque_enable') == 1
        # A write to a read-only register is refused with the range error bit.
        result, error = ph.write2ByteTxRx(port, 1, 36, 100)
        assert result == COMM_SUCCESS and error & 0x08
        sw = GroupSyncWrite(port, ph, 30, 2)
        for sid, tick in ((1, 600), (2, 400), (3, 700)):
            sw.addParam(sid, [tick & 0xFF, tick >> 8])
        assert sw.txPacket() == COMM_SUCCESS
        ph.ping(port, 1)   # the bus is served in order: once this answers, the write is in
        assert [emu.read_register(i, 'goal_position') for i in (1, 2, 3)] == [600, 400, 700]
        port.closePort()


def test_protocol2_sync_and_bulk_read():
    servos = [EmulatedServo(i, XL430, initial_position_rad=0.1 * i) for i in (1, 2, 3, 4)]
    with ServoBusEmulator(servos) as emu:
        port = _port(emu)
        ph = PacketHandler(2.0)
        assert ph.ping(port, 4)[:2] == (1060, COMM_SUCCESS)
        sr = GroupSyncRead(port, ph, 132, 4)
        for i in (1, 2, 3, 4):
            sr.addParam(i)
        assert sr.txRxPacket() == COMM_SUCCESS
        ticks = [sr.getData(i, 132, 4) for i in (1, 2, 3, 4)]
        assert_allclose([XL430.position_to_rad(t) for t in ticks], [0.1, 0.2, 0.3, 0.4],
                        atol=XL430.rad_per_tick)
        br = GroupBulkRead(port, ph)
        assert br.addParam(1, 132, 4) and br.addParam(3, 146, 1)
        assert br.txRxPacket() == COMM_SUCCESS
        assert br.getData(3, 146, 1) == 26
        assert XL430.position_to_rad(br.getData(1, 132, 4)) == pytest.approx(0.1, abs=2e-3)
        port.closePort()


@pytest.mark.parametrize('model,proto', [('ax18a', 1.0), ('xl430', 2.0)])
def test_faults_no_answer_bad_checksum_error_bits_late(model, proto):
    with ServoBusEmulator.of_model(model, [1, 2]) as emu:
        # the default 50 ms margin: at 20 ms a bad-checksum reply once came after it on a
        # quiet CI host (read as a timeout); the late reply below is 150 ms late either way
        port = _port(emu)
        ph = PacketHandler(proto)
        addr = 3 if proto == 1.0 else 7
        emu.inject(1, 'no_answer', count=1)
        assert ph.read1ByteTxRx(port, 1, addr)[1] == COMM_RX_TIMEOUT
        assert ph.read1ByteTxRx(port, 1, addr)[:2] == (1, COMM_SUCCESS)   # count exhausted
        emu.inject(2, 'bad_checksum', count=1)
        assert ph.read1ByteTxRx(port, 2, addr)[1] == COMM_RX_CORRUPT
        emu.inject(2, 'error_bits', error_bits=0x20, count=1)
        _, result, error = ph.read1ByteTxRx(port, 2, addr)
        assert result == COMM_SUCCESS
        assert error == (0x20 if proto == 1.0 else 0x80)      # 2.0: alert bit in the status
        emu.inject(1, 'late_reply', count=1, delay_s=0.15)
        assert ph.read1ByteTxRx(port, 1, addr)[1] == COMM_RX_TIMEOUT   # later than the 50 ms margin
        assert emu.servo(1).fault_hits == {'no_answer': 1, 'late_reply': 1}
        assert emu.servo(2).fault_hits == {'bad_checksum': 1, 'error_bits': 1}
        port.closePort()


def test_commanded_servo_moves_with_physics():
    with ServoBusEmulator.of_model('ax18a', [1]) as emu:
        port = _port(emu)
        ph = PacketHandler(1.0)
        ph.write1ByteTxRx(port, 1, 24, 1)
        ph.write2ByteTxRx(port, 1, 30, AX18A.rad_to_position(0.4))
        # Polling advances the emulator's clock-driven physics; 0.4 rad takes ~0.05 s at 97 rpm.
        for _ in range(2000):
            tick, result, _ = ph.read2ByteTxRx(port, 1, 36)
            if abs(AX18A.position_to_rad(tick) - 0.4) < 0.05:
                break
        assert abs(AX18A.position_to_rad(tick) - 0.4) < 0.05
        port.closePort()
