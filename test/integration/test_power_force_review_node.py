"""power_monitor / force_sensor review fixes at node level: a lost port is one error line and
the node carries on (reopened later), failed reads are throttled, malformed force lines and
saturated samples are reported, /diagnostics, force stamps from the microcontroller clock."""

from __future__ import annotations

import os
import tty

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from geometry_msgs.msg import WrenchStamped
from harness import Collector, ros_env
from rclpy.parameter import Parameter
from sensor_msgs.msg import BatteryState

from hexapod_bench_drivers.force_node import ForceSensorNode
from hexapod_bench_drivers.power_backends import (
    PowerBackendError,
    PowerPortLost,
    PowerSample,
    PowerSensorReset,
)
from hexapod_bench_drivers.power_node import PowerMonitorNode


class ScriptedBackend:
    """read() follows a script: 'ok', 'lost' (PowerPortLost), 'err' (PowerBackendError)."""

    def __init__(self, script):
        self.script = list(script)
        self.lost = None

    def read(self):
        what = self.script.pop(0) if self.script else 'ok'
        self.lost = 'unplugged' if what == 'lost' else None
        if what == 'lost':
            raise PowerPortLost("SCPI supply on '/dev/ttyUSB1': port failed (EIO)")
        if what == 'err':
            raise PowerBackendError('ina226 at 0x40: read of register 0x02 failed: NACK')
        if what == 'reset':
            raise PowerSensorReset('ina226 at 0x40: the chip was reset; rewritten')
        return PowerSample(12.0, 0.5)

    def close(self):
        pass


def capture(node, level):
    """The messages ``node`` logs at ``level`` from now on (kept, not printed)."""
    lines = []
    setattr(node.get_logger(), level, lambda msg, **kw: lines.append(msg))
    return lines


@pytest.mark.timeout(60)
def test_power_port_lost_one_error_then_recovers_and_failures_throttled():
    backend = ScriptedBackend(['ok'] * 3 + ['lost'] * 50 + ['ok'] * 3 + ['err'] * 100
                              + ['reset'] + ['ok'] * 3)
    with ros_env('power_review') as env:
        node = env.make(PowerMonitorNode, backend=backend, parameter_overrides=[
            Parameter('rate_hz', value=500.0), Parameter('diagnostics_period_s', value=0.05)])
        errors, warnings, infos = (capture(node, k) for k in ('error', 'warning', 'info'))
        msgs = Collector(env, BatteryState, 'battery_state')
        diags = Collector(env, DiagnosticArray, '/diagnostics')
        assert env.spin_until(lambda: not backend.script and len(msgs.messages) >= 8, 30.0)
        assert len(errors) == 1 and 'port failed' in errors[0]
        assert any('recovered after 50 failures' in x for x in infos)
        nack = [x for x in warnings if 'NACK' in x]
        assert 1 <= len(nack) <= 2, warnings        # 100 failures in 0.2 s: throttled
        assert node.read_errors == 151
        assert any('chip was reset' in x for x in warnings)     # never throttled away
        assert all(m.voltage == 12.0 and m.current == -0.5 for m in msgs.messages)
        assert env.spin_until(lambda: len(diags.messages) >= 2, 10.0)
        status = diags.messages[-1].status[0]
        assert status.level in (DiagnosticStatus.OK, DiagnosticStatus.WARN, DiagnosticStatus.ERROR)
        keys = {kv.key: kv.value for kv in status.values}
        assert keys['read_errors'] and keys['voltage_v'] == '12.0000'


@pytest.mark.timeout(60)
def test_force_malformed_warning_saturation_diagnostics_and_mcu_stamps():
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        with ros_env('force_review') as env:
            node = env.make(ForceSensorNode, parameter_overrides=[
                Parameter('serial_port', value=os.ttyname(slave)),
                Parameter('baud_rate', value=57600),
                Parameter('diagnostics_period_s', value=0.05),
                Parameter('calibration', value=[0.0, 0.001, 0.0, 0.0])])
            warnings = capture(node, 'warning')
            forces = Collector(env, WrenchStamped, 'bench/ground_force')
            diags = Collector(env, DiagnosticArray, '/diagnostics')
            os.write(master, b''.join(f'{k}\t{k}\n'.encode() for k in range(12)))
            assert env.spin_until(lambda: any('malformed' in w for w in warnings), 10.0)
            [w] = [w for w in warnings if 'malformed' in w]
            assert "12 malformed lines" in w or "malformed lines and no valid one" in w
            assert '57600 Bd' in w and '<t_ms>,<raw>' in w and "b'11\\t11'" in w
            assert env.spin_until(lambda: any(
                s.level >= DiagnosticStatus.WARN and 'malformed' in s.message
                for m in diags.messages for s in m.status), 10.0)
            # A burst of four samples 10 ms apart on the MCU clock, one saturated.
            os.write(master, b'1000,100\n1010,8388607\n1020,300\n1030,400\n')
            forces.wait_for(env, 3)
            assert [round(m.wrench.force.z, 6) for m in forces.messages] == [0.1, 0.3, 0.4]
            assert node.saturated_samples == 1
            assert any('HX711 limit' in x for x in warnings)
            t = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in forces.messages]
            # MCU spacing (20 ms, 10 ms), not the reception times (about 0 apart in a burst).
            assert abs((t[1] - t[0]) - 0.02) < 5e-3 and abs((t[2] - t[1]) - 0.01) < 5e-3
    finally:
        os.close(master)
        os.close(slave)
