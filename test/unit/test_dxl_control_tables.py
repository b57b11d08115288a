"""Control tables: addresses, unit conversions and error bits against the e-Manual."""

from __future__ import annotations

import math

import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.control_tables import (
    AX12A,
    AX18A,
    XL430,
    XM430,
    ControlTableError,
    decode_error_flags,
    table_for_model,
)


def test_model_numbers_and_detection():
    assert [t.model_number for t in (AX12A, AX18A, XL430, XM430)] == [12, 18, 1060, 1020]
    assert table_for_model(1, 18) is AX18A
    assert table_for_model(2, 1020) is XM430
    with pytest.raises(ControlTableError, match='unknown Dynamixel model number 999'):
        table_for_model(1, 999)


def test_addresses_from_emanual():
    assert AX18A.reg('goal_position').address == 30
    assert AX18A.reg('present_position').address == 36
    assert AX18A.reg('present_temperature').address == 43
    assert XL430.reg('torque_enable').address == 64
    assert XL430.reg('goal_position').address == 116
    assert XL430.reg('present_position').address == 132
    assert XL430.reg('present_input_voltage').address == 144
    assert XM430.reg('present_current').address == 126
    assert AX18A.read_block == (36, 8)
    assert XL430.read_block == XM430.read_block == (126, 21)
    assert AX18A.goal_block == (30, 4)
    assert XL430.goal_block == (112, 8)


def test_position_conversions():
    assert AX18A.position_to_rad(512) == 0.0
    assert_allclose(AX18A.position_to_rad(1023), math.radians(300) * 511 / 1023)
    assert_allclose(XL430.position_to_rad(3072), math.pi / 2)
    for t in (AX18A, XL430):
        for rad in (-1.0, -0.1, 0.0, 0.3, 2.0):
            assert abs(t.position_to_rad(t.rad_to_position(rad)) - rad) <= t.rad_per_tick / 2
    assert AX18A.rad_to_position(10.0) == 1023
    assert AX18A.rad_to_position(-10.0) == 0


def test_speed_and_load_sign_bit_protocol1():
    unit = 0.111 * 2 * math.pi / 60
    assert_allclose(AX18A.velocity_to_rad_s(100), 100 * unit)
    assert_allclose(AX18A.velocity_to_rad_s(1024 + 100), -100 * unit)
    assert_allclose(AX18A.load_to_fraction(1024 + 250), -0.25)
    assert_allclose(AX18A.load_to_fraction(500), 0.5)
    assert AX18A.fraction_to_load(-0.25) == 1024 + 250
    assert AX18A.rad_s_to_velocity(-100 * unit) == 1024 + 100
    assert AX18A.rad_s_to_speed_limit(0.0) == 0
    assert AX18A.rad_s_to_speed_limit(1e-6) == 1   # never 'unlimited' by rounding


def test_twos_complement_protocol2_and_current():
    data = bytearray(21)
    data[0:2] = (-300).to_bytes(2, 'little', signed=True)      # load -30 %
    data[2:6] = (-50).to_bytes(4, 'little', signed=True)       # velocity -50 units
    data[6:10] = (2048 + 1024).to_bytes(4, 'little', signed=True)
    data[18:20] = (118).to_bytes(2, 'little')
    data[20] = 41
    st = XL430.decode_present(data)
    assert_allclose(st.load_fraction, -0.3)
    assert_allclose(st.velocity_rad_s, -50 * 0.229 * 2 * math.pi / 60)
    assert_allclose(st.position_rad, math.pi / 2)
    assert_allclose(st.voltage_v, 11.8)
    assert st.temperature_c == 41.0
    data[0:2] = (855).to_bytes(2, 'little', signed=True)       # 855 * 2.69 mA = 2.3 A = stall
    assert_allclose(XM430.decode_present(data).load_fraction, 1.0, rtol=1e-3)


def test_encode_range_checked():
    assert AX18A.encode('goal_position', 512) == b'\x00\x02'
    with pytest.raises(ControlTableError, match='goal_position: value 70000'):
        AX18A.encode('goal_position', 70000)
    with pytest.raises(ControlTableError, match="no register 'present_current'"):
        AX18A.reg('present_current')


def test_error_bits():
    assert decode_error_flags(1, 0b0010_0101) == ('input_voltage', 'overheating', 'overload')
    assert decode_error_flags(2, 0b0001_0100) == ('overheating', 'electrical_shock')
    assert decode_error_flags(1, 0) == ()
