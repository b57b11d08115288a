"""``run_node``'s spin for nodes with a ``finished`` future (gait_scheduler, dynamixel_driver,
bench_sequencer) must not grow with the callbacks it runs.

An outside review's 20-minute live run: ``gait_scheduler`` grew by 270 MB an hour, linearly.
``rclpy.spin_until_future_complete`` adds a done callback to the future on every
``spin_once`` (rclpy 7), and ``finished`` stays pending for the node's whole life: one
closure per callback run, never freed.
"""

from __future__ import annotations

import pytest
import rclpy
from rclpy.context import Context
from rclpy.task import Future

from hexapod_common.node_utils import spin_until_done


class CountingFuture(Future):
    """A future that counts the done callbacks added to it."""

    def __init__(self) -> None:
        super().__init__()
        self.added = 0

    def add_done_callback(self, callback):  # type: ignore[override]
        self.added += 1
        super().add_done_callback(callback)


@pytest.mark.timeout(60)
def test_spin_until_done_adds_one_callback_whatever_the_ticks() -> None:
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('spin_until_done_probe', context=ctx)
    finished = CountingFuture()
    ticks = []

    def tick() -> None:
        ticks.append(1)
        if len(ticks) == 500 and not finished.done():
            finished.set_result(0)
    node.create_timer(0.001, tick)
    try:
        spin_until_done(node, finished)
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    assert finished.done() and len(ticks) >= 500
    # rclpy.spin_until_future_complete added one per callback run: 500 here
    assert finished.added == 1


@pytest.mark.timeout(60)
def test_spin_until_done_returns_when_the_context_shuts_down() -> None:
    """Ctrl-C shuts the context down under the spin: it returns, the future still pending."""
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node('spin_until_done_stop', context=ctx)
    finished = CountingFuture()
    ticks = []

    def tick() -> None:
        ticks.append(1)
        if len(ticks) == 20:
            ctx.try_shutdown()
    node.create_timer(0.001, tick)
    try:
        spin_until_done(node, finished)
    except Exception as err:  # noqa: BLE001 - run_node treats these as a stop
        from hexapod_common.node_utils import stopping_errors
        assert isinstance(err, stopping_errors())
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
    assert not finished.done() and len(ticks) >= 20
