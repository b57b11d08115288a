"""Review fixes, power and force sensing (no ROS): SCPI late replies, overrange and unplug;
INA2xx chip reset, shunt range and overflow; force port reopen, malformed-line warning, HX711
saturation, MCU clock stamps."""

from __future__ import annotations

import os
import socket
import threading
import time
import tty

import pytest
from numpy.testing import assert_allclose

from hexapod_bench_drivers.force_backend import (
    ForceLineParser,
    ForceReading,
    MalformedWatch,
    McuClockMap,
    SerialForceSource,
)
from hexapod_bench_drivers.power_backends import (
    FailureLog,
    Ina2xxBackend,
    PowerBackendError,
    PowerPortLost,
    PowerSensorReset,
    ScpiSupplyBackend,
)


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


# --------------------------------------------------------------------------------------------
# INA2xx: a register file with the chips' clamps, flags and power-on reset.


class Ina:
    def __init__(self, chip='ina226', shunt_ohm=0.01, overflow='wrap'):
        self.chip, self.shunt_ohm, self.overflow = chip, shunt_ohm, overflow
        self.v_bus, self.i_true = 12.0, 2.5
        self.nack = False
        self.reset()

    def reset(self):
        self.regs = {0x00: 0x4127 if self.chip == 'ina226' else 0x399F, 0x05: 0}

    def _value(self, reg):
        if self.chip == 'ina226':
            shunt = max(-32768, min(32767, round(self.i_true * self.shunt_ohm / 2.5e-6)))
            cur = int(shunt * self.regs[0x05] / 2048)
        else:
            shunt = max(-32000, min(32000, round(self.i_true * self.shunt_ohm / 10e-6)))
            cur = int(shunt * (self.regs[0x05] & 0xFFFE) / 4096)
        ovf = not -32768 <= cur <= 32767
        if ovf:
            cur = (((cur + 32768) % 65536) - 32768 if self.overflow == 'wrap'
                   else max(-32768, min(32767, cur)))
        if reg == 0x01:
            return shunt & 0xFFFF
        if reg == 0x02:
            if self.chip == 'ina226':
                return round(self.v_bus / 1.25e-3)
            return (round(self.v_bus / 4e-3) << 3) | 0x2 | (0x1 if ovf else 0)
        if reg == 0x04:
            return cur & 0xFFFF
        if reg == 0x05 and self.chip == 'ina219':
            return self.regs[0x05] & 0xFFFE
        if reg == 0x06:
            return 0x8 | (0x4 if ovf else 0)
        if reg == 0xFE:
            return 0x5449
        return self.regs.get(reg, 0)

    def read_i2c_block_data(self, addr, reg, n):
        if self.nack:
            raise OSError(121, 'Remote I/O error')
        v = self._value(reg)
        return [(v >> 8) & 0xFF, v & 0xFF]

    def write_i2c_block_data(self, addr, reg, data):
        if self.nack:
            raise OSError(121, 'Remote I/O error')
        self.regs[reg] = (data[0] << 8) | data[1]


@pytest.mark.parametrize('chip', ['ina226', 'ina219'])
def test_ina_chip_reset_is_detected_and_calibration_rewritten(chip):
    chip_ = Ina(chip)
    clock = Clock()
    ina = Ina2xxBackend(chip_, chip=chip, shunt_ohm=0.01, max_current_a=8.0, clock=clock)
    assert_allclose(ina.read().current_a, 2.5, atol=1e-3)
    chip_.reset()                          # brown-out: calibration back to 0, current reads 0
    with pytest.raises(PowerSensorReset, match='calibration register reads 0x0000.*rewritten'):
        ina.read()
    assert ina.resets == 1
    with pytest.raises(PowerBackendError, match='waiting one conversion'):
        ina.read()
    clock.t += 0.05
    for _ in range(3):
        assert_allclose(ina.read().current_a, 2.5, atol=1e-3)


def test_ina_nack_then_power_cycle_reconfigures():
    chip_ = Ina('ina226')
    clock = Clock()
    ina = Ina2xxBackend(chip_, shunt_ohm=0.01, clock=clock, cal_check_every=1000)
    chip_.nack = True
    with pytest.raises(PowerBackendError, match='Remote I/O error'):
        ina.read()
    chip_.nack = False
    chip_.reset()
    chip_.i_true = 0.0                    # even with no current flowing: checked after the NACK
    with pytest.raises(PowerBackendError, match='chip was reset'):
        ina.read()
    clock.t += 0.05
    chip_.i_true = 1.0
    assert_allclose(ina.read().current_a, 1.0, atol=1e-3)


def test_ina_calibration_checked_periodically():
    chip_ = Ina('ina226')
    ina = Ina2xxBackend(chip_, shunt_ohm=0.01, cal_check_every=5, clock=Clock())
    chip_.regs[0x05] = 1000               # corrupted, current still non-zero
    results = []
    for _ in range(5):
        try:
            ina.read()
            results.append('ok')
        except PowerBackendError:
            results.append('err')
    assert results == ['ok'] * 4 + ['err'] and chip_.regs[0x05] == ina.calibration


@pytest.mark.parametrize('chip, full_scale_a', [('ina226', 0.819), ('ina219', 3.2)])
def test_ina_shunt_range_refused_at_start(chip, full_scale_a):
    with pytest.raises(ValueError, match=f'measures at most {full_scale_a:.3f} A'):
        Ina2xxBackend(Ina(chip, 0.1), chip=chip, shunt_ohm=0.1, max_current_a=8.0)
    Ina2xxBackend(Ina(chip, 0.1), chip=chip, shunt_ohm=0.1, max_current_a=0.8)


@pytest.mark.parametrize('chip, max_a', [('ina226', 0.8), ('ina219', 3.2)])
def test_ina_shunt_adc_saturation_is_not_published(chip, max_a):
    chip_ = Ina(chip, 0.1)
    ina = Ina2xxBackend(chip_, chip=chip, shunt_ohm=0.1, max_current_a=max_a)
    chip_.i_true = 0.5
    assert_allclose(ina.read().current_a, 0.5, atol=1e-3)
    chip_.i_true = 5.0                     # beyond 0.82 A / 3.2 A: the ADC clamps
    with pytest.raises(PowerBackendError, match='shunt voltage at full scale'):
        ina.read()


@pytest.mark.parametrize('overflow', ['wrap', 'saturate'])
def test_ina226_math_overflow_is_not_published(overflow):
    chip_ = Ina('ina226', 0.01, overflow)
    ina = Ina2xxBackend(chip_, shunt_ohm=0.01, max_current_a=5.0)
    chip_.i_true = 6.5
    with pytest.raises(PowerBackendError, match='MathOvf'):
        ina.read()


def test_ina219_lsb_matches_the_calibration_it_holds():
    chip_ = Ina('ina219')
    chip_.i_true = 7.9
    ina = Ina2xxBackend(chip_, chip='ina219', shunt_ohm=0.01, max_current_a=8.0)
    assert_allclose(ina.read().current_a, 7.9, rtol=2e-5)


# --------------------------------------------------------------------------------------------
# SCPI supply on a pty: replies in order, some late.


class LateSupply:
    """Answers in order after ``delay_s``; ``delays`` overrides the delay of the n-th query."""

    def __init__(self, volts=12.0, amps=0.5, delay_s=0.0, delays=None, values=None):
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        self.port = os.ttyname(self.slave)
        self.volts, self.amps, self.delay_s = volts, amps, delay_s
        self.delays = delays or {}
        self.values = values or {}
        self.queries = []
        self.closed = False
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self):
        buf = b''
        while not self.closed:
            try:
                buf += os.read(self.master, 256)
            except OSError:
                return
            while b'\n' in buf:
                line, buf = buf.split(b'\n', 1)
                q = line.decode().strip()
                n = len(self.queries)
                self.queries.append(q)
                delay = self.delays.get(n, self.delay_s)
                if delay:
                    time.sleep(delay)       # in order: later replies queue behind this one
                reply = self.values.get(n) or {
                    'MEAS:VOLT?': f'{self.volts:.3f}', 'MEAS:CURR?': f'{self.amps:.4f}',
                    '*IDN?': 'EMU,PSU,0,1.0'}.get(q, 'ERR')
                try:
                    os.write(self.master, (reply + '\n').encode())
                except OSError:
                    return

    def close(self):
        self.closed = True
        os.close(self.master)
        os.close(self.slave)


@pytest.mark.timeout(60)
def test_scpi_late_reply_never_swaps_voltage_and_current():
    # The 4th query (MEAS:CURR? of the 2nd read) is answered after the 0.3 s deadline.
    supply = LateSupply(12.0, 0.5, delays={3: 0.45})
    try:
        scpi = ScpiSupplyBackend(supply.port, timeout_s=0.3)
        first = scpi.read()
        assert (first.voltage_v, first.current_a) == (12.0, 0.5)
        with pytest.raises(PowerBackendError, match=r"MEAS:CURR\? answered ''"):
            scpi.read()
        got = []
        for _ in range(8):
            try:
                got.append(scpi.read())
            except PowerBackendError:
                pass
        assert len(got) >= 7
        assert all((s.voltage_v, s.current_a) == (12.0, 0.5) for s in got), got
        assert scpi.resyncs == 1 and '*IDN?' in supply.queries
        scpi.close()
    finally:
        supply.close()


@pytest.mark.timeout(60)
def test_scpi_overrange_codes_are_refused():
    supply = LateSupply(12.0, 0.5, values={0: '+9.90000E+37', 2: '9.91E37', 4: 'nan'})
    try:
        scpi = ScpiSupplyBackend(supply.port, timeout_s=1.0)
        with pytest.raises(PowerBackendError, match='overrange'):
            scpi.read()
        with pytest.raises(PowerBackendError, match='overrange'):
            scpi.read()
        with pytest.raises(PowerBackendError, match='overrange'):
            scpi.read()
        assert scpi.read().voltage_v == 12.0
    finally:
        supply.close()


class FlakyPort:
    """A serial.Serial stand-in whose device can be unplugged and plugged back."""

    plugged = True
    opens = 0

    def __init__(self, port, **kw):
        if not FlakyPort.plugged:
            raise OSError(2, f'could not open port {port}: No such file or directory')
        FlakyPort.opens += 1
        self.queue = []

    def reset_input_buffer(self):
        pass

    def write(self, data):
        if not FlakyPort.plugged:
            raise OSError(5, 'Input/output error')
        q = data.decode().strip()
        self.queue.append({'MEAS:VOLT?': b'12.0\n', 'MEAS:CURR?': b'0.5\n'}.get(q, b'X,Y\n'))

    def readline(self):
        if not FlakyPort.plugged:
            import serial
            raise serial.SerialException('device reports readiness to read but returned no '
                                         'data (device disconnected or multiple access on port?)')
        return self.queue.pop(0)

    @property
    def in_waiting(self):
        if not FlakyPort.plugged:
            raise OSError(5, 'Input/output error')
        return sum(len(q) for q in self.queue)

    def read(self, n):
        out = b''.join(self.queue)
        self.queue = []
        return out

    def close(self):
        pass


def test_scpi_unplug_raises_port_lost_then_reopens_with_backoff():
    FlakyPort.plugged, FlakyPort.opens = True, 0
    clock = Clock()
    scpi = ScpiSupplyBackend('/dev/ttyUSB9', serial_factory=FlakyPort, clock=clock)
    assert scpi.read().current_a == 0.5
    FlakyPort.plugged = False
    with pytest.raises(PowerPortLost, match='port failed .*Input/output error'):
        scpi.read()
    assert scpi.lost
    with pytest.raises(PowerPortLost, match='port lost'):
        scpi.read()                        # within the backoff: no open attempt
    clock.t += 0.6
    with pytest.raises(PowerPortLost, match='cannot open.*next attempt in 1 s'):
        scpi.read()
    FlakyPort.plugged = True
    clock.t += 0.5
    with pytest.raises(PowerPortLost):
        scpi.read()                        # still inside the 1 s backoff
    clock.t += 0.6
    s = scpi.read()
    assert (s.voltage_v, s.current_a) == (12.0, 0.5)
    assert scpi.lost is None and scpi.reconnects == 1 and FlakyPort.opens == 2


@pytest.mark.timeout(30)
def test_scpi_socket_url_lan_supply():
    server = socket.create_server(('127.0.0.1', 0))
    port = server.getsockname()[1]

    def serve():
        conn, _ = server.accept()
        with conn:
            buf = b''
            while True:
                chunk = conn.recv(256)
                if not chunk:
                    return
                buf += chunk
                while b'\n' in buf:
                    line, buf = buf.split(b'\n', 1)
                    conn.sendall({b'MEAS:VOLT?': b'24.5\n', b'MEAS:CURR?': b'1.25\n'}.get(
                        line.strip(), b'ERR\n'))
    threading.Thread(target=serve, daemon=True).start()
    try:
        scpi = ScpiSupplyBackend(f'socket://127.0.0.1:{port}', timeout_s=2.0)
        s = scpi.read()
        assert (s.voltage_v, s.current_a) == (24.5, 1.25)
        scpi.close()
    finally:
        server.close()


def test_failure_log_first_then_throttled_then_recovered():
    log = FailureLog(5.0)
    lines = [log.failed(t * 0.01, 'NACK') for t in range(1000)]      # 10 s at 100 Hz
    shown = [x for x in lines if x is not None]
    assert shown[0] == 'NACK' and len(shown) == 2 and shown[1].startswith('500 more failures')
    assert log.succeeded(10.0) == 'recovered after 1000 failures'
    assert log.succeeded(10.01) is None


# --------------------------------------------------------------------------------------------
# Force sensor.


def test_force_source_reopens_after_unplug_with_backoff():
    FlakyPort.plugged, FlakyPort.opens = True, 0
    clock = Clock()
    src = SerialForceSource('/dev/ttyACM9', serial_factory=FlakyPort, clock=clock)
    src.ser.queue.append(b'10,5\n')
    assert src.poll() == [ForceReading(0.01, 5)]
    FlakyPort.plugged = False
    assert src.poll() == [] and src.lost and 'Input/output error' in src.lost
    for _ in range(100):
        assert src.poll() == []            # no open attempt within the backoff, no raise
    assert src.failed_opens == 0
    clock.t += 0.6
    assert src.poll() == [] and src.failed_opens == 1
    FlakyPort.plugged = True
    clock.t += 1.1
    assert src.poll() == [] and src.lost is None and src.reconnects == 1
    src.ser.queue.append(b'20,7\n')
    assert src.poll() == [ForceReading(0.02, 7)]


def test_malformed_watch_warns_once_then_throttled():
    p = ForceLineParser()
    watch = MalformedWatch(threshold=10, period_s=10.0)
    warnings = []
    for k in range(300):                   # tab-separated lines at 100 Hz for 3 s
        p.feed(f'{k}\t{k * 3}\n'.encode())
        w = watch.check(k * 0.01, p)
        if w:
            warnings.append(w)
    assert len(warnings) == 1
    assert "10 malformed lines and no valid one" in warnings[0]
    assert "last seen: b'9\\t27'" in warnings[0] and '<t_ms>,<raw>' in warnings[0]
    p.feed(b'1,2\n')
    assert watch.check(3.0, p) is None
    for k in range(10):
        p.feed(b'12\n')
    assert watch.check(3.1, p) is not None      # a new run after a valid line warns again


def test_hx711_saturation_flag():
    p = ForceLineParser()
    out = p.feed(b'1,8388607\n2,-8388608\n3,8388606\n')
    assert [r.saturated for r in out] == [True, True, False]


def test_mcu_clock_map_keeps_spacing_in_bursts_and_survives_reset():
    m = McuClockMap()
    stamps = []
    # 1 kHz samples arriving in bursts of 16 every 16 ms, with 1-3 ms of jitter.
    for b in range(20):
        t_recv = 1000.0 + (b + 1) * 16e-3 + 1e-3 * (b % 3)
        stamps += m.stamp_batch([5.0 + (16 * b + k) * 1e-3 for k in range(16)], t_recv)
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert_allclose(gaps, 1e-3, atol=1e-9)
    assert all(s <= 1000.0 + (k // 16 + 1) * 16e-3 for k, s in enumerate(stamps))
    # MCU reset: t_ms starts again at 0; stamped at reception until the map restarts.
    after = [m.stamp(k * 1e-3, 1000.4 + k * 1e-3) for k in range(5)]
    assert after[:2] == [1000.4, 1000.401] and m.restarts == 1
    assert_allclose(after[3] - after[2], 1e-3, atol=1e-9)


def test_mcu_clock_map_first_burst_keeps_spacing():
    m = McuClockMap()
    stamps = m.stamp_batch([1.0, 1.01, 1.02, 1.03], 500.0)
    assert_allclose(stamps, [499.97, 499.98, 499.99, 500.0], atol=1e-9)


def test_mcu_clock_map_never_steps_back_when_the_delay_drops():
    m = McuClockMap()
    stamps = []
    for k in range(2000):                  # 500 Hz; the first 0.1 s read 30 ms late (start-up)
        t_mcu = k * 2e-3
        stamps += m.stamp_batch([t_mcu], 50.0 + t_mcu + (0.03 if k < 50 else 0.0005))
    gaps = [b - a for a, b in zip(stamps, stamps[1:])]
    assert min(gaps) > 1.7e-3                          # compressed by at most 10 %, never back
    assert_allclose(stamps[-1], 50.0 + 3.998, atol=1e-3)   # converged to the least delay


def test_mcu_clock_map_reset_inside_one_read_keeps_the_stamps_true():
    """A reset or a 16-bit millis wrap inside one read of 16 lines: the lines before it were
    stamped with the new offset, the whole uptime late, and every later stamp was held there
    (80 % of stamps up to 65 s off over 5 min, a second review). Now each line keeps its own
    clock's offset."""
    import numpy as np

    from hexapod_bench_drivers.force_backend import McuClockMap

    rng = np.random.default_rng(1)
    m = McuClockMap()
    hz, n = 1000, 200_000                       # 200 s: three 16-bit wraps
    t_true = np.arange(n) / hz
    ms = np.floor((5.0 + t_true) * 1000).astype(np.int64) % 65536
    recv = 1.7e9 + t_true + 0.001 + rng.exponential(0.002, n)
    err = []
    for j in range(0, n, 16):
        st = m.stamp_batch(list(ms[j:j + 16] / 1000.0), float(recv[j:j + 16].max()))
        err += list(np.array(st) - (1.7e9 + t_true[j:j + 16]))
    err = np.abs(np.array(err))
    assert m.restarts >= 3
    assert np.percentile(err, 99) < 0.005 and err.max() < 0.05
