"""Core modules of hexapod_energy import with rclpy blocked (DESIGN §3)."""

from __future__ import annotations

import subprocess
import sys

CORE = ('metrics', 'dynamics', 'single_leg', 'prediction', 'sweeps', 'plots', 'recommend',
        'bag_io', 'cli', 'errors')


def test_core_imports_without_rclpy() -> None:
    code = (
        "import sys; sys.modules['rclpy'] = None\n"
        + ''.join(f'import hexapod_energy.{m}\n' for m in CORE)
        + "assert not any(k.startswith('rclpy') and sys.modules[k] is not None "
          "for k in sys.modules)\n"
    )
    res = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
