"""Fixes from the outside hardware review of the Dynamixel driver against an independent
emulator (/tmp/rev_dxl/REPORT.md, findings 1-5), at bus level on the project's emulator: a stop
during the torque-on pass, the Protocol 1.0 Alarm Shutdown (Torque Limit 0), goals beyond the
angle limits, torque off at shutdown, -0.0 at rest."""

from __future__ import annotations

import math

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
