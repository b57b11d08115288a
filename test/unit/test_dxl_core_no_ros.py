"""The driver cores import without ROS (rclpy and message packages blocked)."""

from __future__ import annotations

import subprocess
import sys

CORE = ['control_tables', 'servo_bus_emulator', 'dynamixel_bus', 'power_backends',
        'force_backend', 'sequencer', 'sequencer_sim']


def test_cores_import_with_rclpy_blocked():
    code = ('import sys\n'
            'for m in ("rclpy", "sensor_msgs", "hexapod_interfaces", "std_srvs"):\n'
            '    sys.modules[m] = None\n'
            + ''.join(f'import hexapod_bench_drivers.{m}\n' for m in CORE))
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=60)
    assert result.returncode == 0, result.stderr
