"""The residual-loop core modules import with rclpy blocked (science without ROS)."""

from __future__ import annotations

import subprocess
import sys

CODE = '''
import sys
sys.modules["rclpy"] = None
import hexapod_energy.residuals, hexapod_energy.effects_catalogue
import hexapod_energy.residuals_cli, slip_identification.residuals
assert "rclpy" not in {m for m in sys.modules if sys.modules[m] is not None}
print("ok")
'''


def test_core_modules_import_without_rclpy():
    out = subprocess.run([sys.executable, '-c', CODE], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == 'ok'
