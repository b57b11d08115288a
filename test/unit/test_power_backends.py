"""Power backends: INA226/INA219 against a register-level fake SMBus, SCPI against a pty peer."""

from __future__ import annotations

import os
import threading
import tty

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.power_backends import (
    Ina2xxBackend,
    PowerBackendError,
    PowerSample,
    ScpiSupplyBackend,
    SimPowerBackend,
    ZeroOffset,
    ros_battery_current,
)


class FakeIna:
    """INA226/INA219 register file behind an SMBus, with the chips' arithmetic.

    Registers are 16-bit, MSB first in I2C block transfers; ``read_word_data`` returns the
    SMBus little-endian word (byte-swapped), as a real bus does. The current register is 0 until
    the calibration register is written, as on the chips.
    """

    def __init__(self, chip, address, shunt_ohm, *, voltage_v, current_a):
        self.chip, self.address, self.shunt_ohm = chip, address, shunt_ohm
        self.voltage_v, self.current_a = voltage_v, current_a
        self.regs = {0x00: 0x4127 if chip == 'ina226' else 0x399F, 0x05: 0}
        self.writes = []

    def _value(self, reg):
        if reg == 0xFE and self.chip == 'ina226':
            return 0x5449
        shunt_lsb = 2.5e-6 if self.chip == 'ina226' else 10e-6
        shunt = int(round(self.current_a * self.shunt_ohm / shunt_lsb))
        if reg == 0x01:
            return shunt & 0xFFFF
        if reg == 0x02:
            if self.chip == 'ina226':
                return int(round(self.voltage_v / 1.25e-3))
            return (int(round(self.voltage_v / 4e-3)) << 3) | 0x2      # CNVR set
        if reg == 0x04:
            div = 2048 if self.chip == 'ina226' else 4096
            return int(shunt * self.regs[0x05] / div) & 0xFFFF
        return self.regs.get(reg, 0)

    def read_i2c_block_data(self, addr, reg, n):
        if addr != self.address:
            raise OSError(121, 'Remote I/O error')
        v = self._value(reg)
        return [(v >> 8) & 0xFF, v & 0xFF][:n]

    def read_word_data(self, addr, reg):
        msb, lsb = self.read_i2c_block_data(addr, reg, 2)
        return (lsb << 8) | msb

    def write_i2c_block_data(self, addr, reg, data):
        if addr != self.address:
            raise OSError(121, 'Remote I/O error')
        self.regs[reg] = (data[0] << 8) | data[1]
        self.writes.append((reg, self.regs[reg]))


@pytest.mark.parametrize('chip', ['ina226', 'ina219'])
@pytest.mark.parametrize('current_a', [2.345, -0.8])
def test_ina_register_level(chip, current_a):
    fake = FakeIna(chip, 0x41, 0.01, voltage_v=11.9, current_a=current_a)
    ina = Ina2xxBackend(fake, chip=chip, address=0x41, shunt_ohm=0.01, max_current_a=8.0)
    # Calibration from the datasheet formula, written MSB first.
    lsb = 8.0 / 2**15
    expected_cal = int((0.00512 if chip == 'ina226' else 0.04096) / (lsb * 0.01))
    assert (0x05, expected_cal) in fake.writes
    s = ina.read()
    assert_allclose(s.voltage_v, 11.9, atol=5e-3)
    assert_allclose(s.current_a, current_a, atol=2 * lsb)   # signed, through the calibration
    assert_allclose(s.power_w, 11.9 * current_a, rtol=2e-3)


def test_ina226_wrong_address_and_id():
    fake = FakeIna('ina226', 0x40, 0.01, voltage_v=12.0, current_a=1.0)
    with pytest.raises(PowerBackendError, match='0x45: read of register 0xfe failed'):
        Ina2xxBackend(fake, address=0x45)
    fake.chip = 'other'
    with pytest.raises(PowerBackendError, match='manufacturer ID 0x0000, expected 0x5449'):
        Ina2xxBackend(fake, address=0x40)


def test_ros_sign_sim_and_zero_offset():
    assert ros_battery_current(2.0) == -2.0     # discharging -> negative in BatteryState
    sim = SimPowerBackend(12.0, 0.05, noise_a=0.01, seed=3)
    zero = ZeroOffset().fit([sim.read().current_a for _ in range(200)])
    assert_allclose(zero.offset_a_, 0.05, atol=0.003)
    assert_allclose(zero.apply(PowerSample(12.0, 1.05)).current_a, 1.0, atol=0.003)
    with pytest.raises(ValueError, match='expected >= 10 finite samples, got 3'):
        ZeroOffset().fit([1.0, 2.0, 3.0])
    with pytest.raises(RuntimeError, match='not fitted'):
        ZeroOffset().apply(PowerSample(1.0, 1.0))


class ScpiPeer:
    """A lab supply on the master side of a pty: answers MEAS:VOLT? / MEAS:CURR?."""

    def __init__(self, volts, amps, garbage_after=None):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self.volts, self.amps, self.garbage_after = volts, amps, garbage_after
        self.queries = []
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        buf = b''
        while True:
            try:
                chunk = os.read(self.master, 256)
            except OSError:
                return
            buf += chunk
            while b'\n' in buf:
                line, buf = buf.split(b'\n', 1)
                q = line.decode().strip()
                self.queries.append(q)
                if self.garbage_after is not None and len(self.queries) > self.garbage_after:
                    reply = 'ERR -113\n'
                else:
                    reply = {'MEAS:VOLT?': f'{self.volts:.3f}\n',
                             'MEAS:CURR?': f'{self.amps:.4f}\n'}.get(q, 'ERR\n')
                os.write(self.master, reply.encode())

    def close(self):
        os.close(self.master)
        os.close(self.slave)


@pytest.mark.timeout(30)
def test_scpi_supply_on_pty():
    peer = ScpiPeer(11.9, 1.2345, garbage_after=4)
    try:
        supply = ScpiSupplyBackend(peer.port, timeout_s=2.0)
        s = [supply.read() for _ in range(2)]
        assert_allclose([x.voltage_v for x in s], 11.9)
        assert_allclose([x.current_a for x in s], 1.2345)
        assert peer.queries == ['MEAS:VOLT?', 'MEAS:CURR?'] * 2
        with pytest.raises(PowerBackendError, match="MEAS:VOLT\\? answered 'ERR -113'"):
            supply.read()
        assert supply.query_failures == 1
        supply.close()
    finally:
        peer.close()


def test_power_sample_power():
    assert PowerSample(12.0, 0.5).power_w == 6.0
    assert np.isfinite(SimPowerBackend().read().power_w)


def test_ina226_driven_as_ina219_is_refused_and_an_ina219_kept():
    """An INA226 answers its manufacturer ID where an INA219 has no register, and holds bit 0
    of its calibration (an INA219's FS0 reads 0): chosen as ``ina219`` it was accepted and
    read with the INA219's scales (an outside review). A chip that NACKs the probe, answers
    anything else, or answers the ID but drops the bit (an emulator of an INA219 that answers
    every register) is an INA219 and is kept."""
    fake = FakeIna('ina226', 0x40, 0.01, voltage_v=12.0, current_a=1.0)
    with pytest.raises(PowerBackendError, match='it is an INA226 \\(backend ina226\\)'):
        Ina2xxBackend(fake, chip='ina219', address=0x40)
    ina219 = FakeIna('ina219', 0x40, 0.01, voltage_v=12.0, current_a=1.0)
    Ina2xxBackend(ina219, chip='ina219', address=0x40, max_current_a=8.0).read()

    class Ina219AnsweringTheId(FakeIna):
        def _value(self, reg):
            if reg == 0xFE:
                return 0x5449
            if reg == 0x05:
                return self.regs.get(0x05, 0) & 0xFFFE          # FS0 reads 0
            return super()._value(reg)

    both = Ina219AnsweringTheId('ina219', 0x40, 0.01, voltage_v=12.0, current_a=1.0)
    s = Ina2xxBackend(both, chip='ina219', address=0x40, max_current_a=8.0).read()
    assert_allclose(s.current_a, 1.0, atol=2e-3)

    class NackingIna219(FakeIna):
        def read_i2c_block_data(self, addr, reg, n):
            if reg == 0xFE:
                raise OSError(121, 'Remote I/O error')
            return super().read_i2c_block_data(addr, reg, n)

    nack = NackingIna219('ina219', 0x40, 0.01, voltage_v=12.0, current_a=1.5)
    s = Ina2xxBackend(nack, chip='ina219', address=0x40, max_current_a=8.0).read()
    assert_allclose(s.current_a, 1.5, atol=2e-3)


def test_a_regenerating_load_reads_charging():
    power_node = pytest.importorskip('hexapod_bench_drivers.power_node')
    from sensor_msgs.msg import BatteryState

    status = power_node.supply_status
    assert status(2.0) == BatteryState.POWER_SUPPLY_STATUS_DISCHARGING
    assert status(-0.5) == BatteryState.POWER_SUPPLY_STATUS_CHARGING      # energy back in
    assert status(0.0) == BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING
    assert status(-0.005) == BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING   # zero noise
    assert status(-0.05, noise_a=0.02) == BatteryState.POWER_SUPPLY_STATUS_NOT_CHARGING
