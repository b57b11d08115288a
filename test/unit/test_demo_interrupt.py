"""Ctrl-C during ``hexapod-demo``: one line, exit 130, demo.json 'incomplete' (an outside
review: a KeyboardInterrupt traceback through rclpy's executor or matplotlib, or exit 1 with
'RuntimeError: hexapod-sim robot failed with exit code 130')."""

from __future__ import annotations

import json

import pytest

from hexapod_common import demo


def _interrupted(*_a, **_k):
    raise KeyboardInterrupt


def test_ctrl_c_in_the_live_graph_is_one_line_and_exit_130(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(demo, 'run_live', _interrupted)
    rc = demo.main(['--out', str(tmp_path / 'd')])
    err = capsys.readouterr().err
    assert rc == 130 and 'interrupted' in err and 'Traceback' not in err
    assert json.loads((tmp_path / 'd' / 'demo.json').read_text())['status'] == 'incomplete'


def test_a_step_interrupted_is_an_interruption_not_a_failure():
    with pytest.raises(KeyboardInterrupt):
        demo._child_failed('hexapod-sim robot', 130)
    with pytest.raises(RuntimeError, match='exit code 1'):
        demo._child_failed('hexapod-sim robot', 1)


def test_sigterm_in_the_live_graph_is_one_line_and_exit_143(tmp_path, monkeypatch, capsys):
    """SIGTERM killed the demo without a word (Known gaps); now it stops as Ctrl-C does."""
    import os
    import signal

    def terminated(*_a, **_k):
        os.kill(os.getpid(), signal.SIGTERM)
        raise AssertionError('SIGTERM did not stop the demo')

    before = signal.getsignal(signal.SIGTERM)
    monkeypatch.setattr(demo, 'run_live', terminated)
    rc = demo.main(['--out', str(tmp_path / 'd')])
    err = capsys.readouterr().err
    assert rc == 143 and 'SIGTERM' in err and 'Traceback' not in err
    assert json.loads((tmp_path / 'd' / 'demo.json').read_text())['status'] == 'incomplete'
    assert signal.getsignal(signal.SIGTERM) == before
