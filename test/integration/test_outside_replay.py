"""``bag_replay`` as a command on another lab's bag: a Foxy-era sqlite3 bag (metadata
version 4, no message definitions, QoS as YAML strings) with a type nobody here knows."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from hexapod_common.testbags import downgrade_sqlite_bag, write_foreign_robot_bag

BIN = Path(sys.executable).parent
ENV = dict(os.environ, PYTHONUNBUFFERED='1')


def run(*args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / args[0]), *args[1:]], capture_output=True, text=True,
                          timeout=timeout, env=ENV)


@pytest.mark.timeout(60)
def test_replay_foxy_bag_with_unknown_type(tmp_path):
    bag = tmp_path / 'foxy'
    write_foreign_robot_bag(bag, msgdef=False, unknown_topic=True, duration_s=4.0)
    downgrade_sqlite_bag(bag, 4)
    proc = run('bag_replay', str(bag), '--no-clock')
    assert proc.returncode == 0, proc.stderr
    assert 'Traceback' not in proc.stderr
    # the unknown type is reported once and is not fatal; every known message is replayed
    unknown = [ln for ln in proc.stderr.splitlines() if '/lab/thing' in ln]
    assert len(unknown) == 1 and 'lab_msgs/msg/Thing' in unknown[0]
    assert 'replayed 440 messages' in proc.stdout
    assert '/battery_state 40' in proc.stdout and '/joint_states 200' in proc.stdout

