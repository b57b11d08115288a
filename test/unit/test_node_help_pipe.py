"""``NODE --help | head -1`` (the reader gone before the help is written): the node's help
still exits 0 without a traceback, as ``hexapod-analyze``, ``hexapod-sim`` and ``bag_replay``
do; it was a BrokenPipeError traceback and exit code 1."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

NODES = ['hexapod_energy.energy_node', 'hexapod_gait.gait_node']


@pytest.mark.parametrize('module', NODES)
def test_help_into_a_closed_pipe_exits_0_without_traceback(module):
    r, w = os.pipe()
    os.close(r)                       # the reader has gone: every write is EPIPE
    try:
        proc = subprocess.run(
            [sys.executable, '-c', f'import sys; from {module} import main; sys.exit(main())',
             '--help'], stdout=w, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(w)
    assert 'Traceback' not in proc.stderr, proc.stderr
    assert proc.returncode == 0, proc.stderr
