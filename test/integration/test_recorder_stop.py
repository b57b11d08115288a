"""bag_recorder stopped by SIGINT while it discovers topics: rclpy's handler shuts the context
down under the call, which raised RCLError; a script's `kill -INT` at start-up gave a
traceback and exit 1 (a README review). It is a stop: exit 0."""

from __future__ import annotations

from typing import Any

import pytest


@pytest.mark.timeout(60)
def test_a_stop_under_discovery_is_exit_0(tmp_path: Any, monkeypatch: Any, capsys) -> None:
    import rclpy
    from rclpy.impl.implementation_singleton import rclpy_implementation

    from hexapod_common import recorder_node

    def interrupted(**_: Any) -> Any:
        rclpy.shutdown()     # what rclpy's SIGINT handler does
        raise rclpy_implementation.RCLError("rcl node's context is invalid")

    monkeypatch.setattr(recorder_node, 'BagRecorderNode', interrupted)
    assert recorder_node.main(['-o', str(tmp_path / 'bag')]) == 0

    def broken(**_: Any) -> Any:   # the same error while rclpy still runs is a real one
        raise rclpy_implementation.RCLError('something else')

    monkeypatch.setattr(recorder_node, 'BagRecorderNode', broken)
    with pytest.raises(rclpy_implementation.RCLError):
        recorder_node.main(['-o', str(tmp_path / 'bag2')])
