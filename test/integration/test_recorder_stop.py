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


@pytest.mark.timeout(60)
def test_the_recorder_says_what_it_records(tmp_path: Any) -> None:
    """It printed nothing until it stopped (Known gaps): now its output and topics at start,
    and each topic as it is subscribed."""
    from harness import ros_env
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import BatteryState

    from hexapod_common.recorder_node import BagRecorderNode

    lines: list[str] = []
    with ros_env('recorder_says') as env:
        import rclpy

        feeder = env.add(rclpy.create_node('pack', context=env.context,
                                           namespace=env.namespace))
        feeder.create_publisher(BatteryState, 'battery_state', 10)
        original = BagRecorderNode.get_logger

        def logger(self: Any) -> Any:
            log = original(self)
            log.info = lambda msg, **kw: lines.append(msg)
            return log
        BagRecorderNode.get_logger = logger   # type: ignore[method-assign]
        try:
            node = env.make(BagRecorderNode, parameter_overrides=[
                Parameter('output', value=str(tmp_path / 'bag')),
                Parameter('topics', value=['battery_state'])])
            assert env.spin_until(lambda: node._subs, 20)
        finally:
            BagRecorderNode.get_logger = original   # type: ignore[method-assign]
    assert lines[0].startswith(f'recording into {tmp_path / "bag"}: ')
    assert 'battery_state' in lines[0]
    assert any(x.startswith('recording ') and 'sensor_msgs/msg/BatteryState' in x
               for x in lines[1:])
