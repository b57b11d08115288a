"""dynamixel_driver's exit code after SIGTERM: 3 when torque off at shutdown was not confirmed.

An outside hardware review cut the power of all 18 servos and sent SIGTERM: the driver logged
"torque off at shutdown not confirmed by J1 ... J18" and exited 0, which a supervisor cannot
tell from a clean stop. The console script runs in a child process against the emulator in
this one; it is stopped once its read loop has reached the last servo a number of times.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
from pathlib import Path

import pytest

from hexapod_bench_drivers.dynamixel_node import EXIT_TORQUE_OFF_UNCONFIRMED
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

N = 3
READS = 30     # READs of the last servo before the stop: the node is spinning (open: ~5)


@pytest.mark.timeout(120)
@pytest.mark.parametrize('silent', [False, True])
def test_exit_code_says_whether_torque_off_was_confirmed(tmp_path, silent):
    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n' + ''.join(f'  j{i}: {{id: {i}}}\n' for i in range(1, N + 1)))
    script = Path(sys.executable).parent / 'dynamixel_driver'
    with ServoBusEmulator.of_model('ax18a', range(1, N + 1)) as emu:
        reads = []
        running = threading.Event()

        def count(servo):
            reads.append(1)
            if len(reads) >= READS:
                running.set()
        emu.servo(N).read_hook = count
        proc = subprocess.Popen(
            [str(script), '--ros-args', '-p', f'port:={emu.port_name}', '-p', 'protocol:=1',
             '-p', f'joints_file:={joints}', '-p', 'timeout_margin_ms:=20.0',
             '-p', 'retries:=0'],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
            env=dict(os.environ, PYTHONUNBUFFERED='1'))
        try:
            assert running.wait(60.0), 'the driver did not reach its read loop'
            assert all(emu.read_register(i, 'torque_enable') for i in range(1, N + 1))
            if silent:                 # no reply from any servo (power cut, cable)
                for i in range(1, N + 1):
                    emu.inject(i, 'no_answer')
            proc.send_signal(signal.SIGTERM)
            out, _ = proc.communicate(timeout=60.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        final = [emu.read_register(i, 'torque_enable') for i in range(1, N + 1)]
    if silent:
        assert proc.returncode == EXIT_TORQUE_OFF_UNCONFIRMED == 3, out
        assert 'torque off at shutdown not confirmed by j1, j2, j3' in out
        # (the emulator's silent servos still carry out writes: it is the reply that is gone)
    else:
        assert proc.returncode == 0, out
        assert f'torque off on {N} servo(s)' in out
        assert final == [0, 0, 0]
    # the node's /rosout publisher is invalid after the stop: its lines go to
    # 'dynamixel_driver.shutdown' (each was followed by "Failed to publish log message to
    # rosout: publisher's context is invalid")
    assert 'Failed to publish' not in out, out
    assert '[dynamixel_driver.shutdown]: ' in out, out
