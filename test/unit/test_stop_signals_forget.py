"""Review J5: a signal noted by one in-process ``bag_recorder`` run stopped the next at once
("SIGINT before recording began", exit 130, nothing recorded); the run now forgets it."""

from __future__ import annotations

import signal

from hexapod_common import recorder_node, stop_signals


def test_a_run_forgets_the_signal_it_consumed(monkeypatch) -> None:
    def record(argv):
        stop_signals._note(signal.SIGINT, None)      # Ctrl-C during this run
        return 0

    monkeypatch.setattr(recorder_node, '_record', record)
    assert recorder_node.main([]) == 0
    assert stop_signals.received() is None
    stop_signals._note(signal.SIGTERM, None)
    stop_signals.forget()
    assert stop_signals.received() is None
