"""A node started in the background by a script (SIGINT ignored, POSIX) and sent SIGINT or
SIGTERM during its imports: it ignored the SIGINT until rclpy.init and ran on until killed
again (an outside review; `bag_recorder` was fixed first, test_recorder_stop.py). The node's
console script now notes the signal from its module's first statement and `run_node` stops
before the node starts: exit 130 / 143, one line, no traceback."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

BIN = Path(sys.executable).parent


def _background(program: str) -> subprocess.Popen:
    """``program`` started as a script's ``program &`` starts it: SIGINT ignored."""
    return subprocess.Popen(
        [str(BIN / program)], env=dict(os.environ, PYTHONUNBUFFERED='1'),
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))


@pytest.mark.timeout(120)
@pytest.mark.parametrize('program,sig', [
    ('gait_scheduler', signal.SIGINT), ('energy_monitor', signal.SIGINT),
    ('sim_robot', signal.SIGINT), ('slip_fitter', signal.SIGTERM)])
def test_a_signal_during_the_imports_stops_the_node(program, sig):
    from harness import wait_until_loaded

    proc = _background(program)
    assert wait_until_loaded(proc, 'rclpy'), 'rclpy was never loaded'
    proc.send_signal(sig)
    try:
        out, _ = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:     # it ran on: the signal was lost
        proc.kill()
        out, _ = proc.communicate()
        pytest.fail(f'{program} ran on after {sig.name}:\n{out}')
    assert 'Traceback' not in out, out
    if proc.returncode != 0:   # 0 if the signal came after rclpy took it over: a clean stop
        assert proc.returncode == 128 + sig, out
        assert f'{program}: {sig.name} before the node started: stopped' in out, out
