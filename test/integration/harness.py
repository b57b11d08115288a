"""Launch-free integration harness: fresh Context per test, futures with deadlines, no sleeps."""

from __future__ import annotations

import itertools
import os
import signal
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import rclpy
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future

__all__ = ['Collector', 'RosEnv', 'ctrl_c', 'ros_env', 'unique_namespace', 'wait_until_loaded']

_counter = itertools.count()

KEEP_ALL_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL,
                          reliability=ReliabilityPolicy.RELIABLE)


def unique_namespace(prefix: str = 't') -> str:
    """A namespace no other test (in this or another process) uses."""
    return f'/{prefix}_{os.getpid()}_{next(_counter)}'


class RosEnv:
    """A context and executor; nodes added with :meth:`add` are destroyed at the end."""

    def __init__(self, context: Any, executor: SingleThreadedExecutor, namespace: str) -> None:
        self.context = context
        self.executor = executor
        self.namespace = namespace
        self.nodes: list[Any] = []

    def add(self, node: Any) -> Any:
        self.nodes.append(node)
        self.executor.add_node(node)
        return node

    def make(self, factory: Callable[..., Any], **kwargs: Any) -> Any:
        """Build a node with this env's context and namespace and add it to the executor."""
        return self.add(factory(context=self.context, namespace=self.namespace, **kwargs))

    def spin_until(self, predicate: Callable[[], bool], timeout_s: float = 30.0) -> bool:
        """Spin until ``predicate()`` is true or the deadline passes; returns the predicate."""
        fut = Future()

        def check() -> None:
            if predicate() and not fut.done():
                fut.set_result(True)
        helper = rclpy.create_node('spin_until_helper', context=self.context,
                                   namespace=self.namespace)
        timer = helper.create_timer(0.005, check)
        self.executor.add_node(helper)
        try:
            check()
            if not fut.done():
                self.executor.spin_until_future_complete(fut, timeout_sec=timeout_s)
        finally:
            helper.destroy_timer(timer)
            self.executor.remove_node(helper)
            helper.destroy_node()
        return predicate()


class Collector:
    """Subscribes to a topic (reliable, keep all) and keeps every message."""

    def __init__(self, env: RosEnv, msg_type: Any, topic: str, qos: Any = KEEP_ALL_QOS) -> None:
        self.messages: list[Any] = []
        self.node = env.add(rclpy.create_node(f'collector_{next(_counter)}',
                                              context=env.context, namespace=env.namespace))
        self.node.create_subscription(msg_type, topic, self.messages.append, qos)

    def wait_for(self, env: RosEnv, n: int, timeout_s: float = 30.0) -> list[Any]:
        assert env.spin_until(lambda: len(self.messages) >= n, timeout_s), \
            f'got {len(self.messages)} of {n} messages before the deadline'
        return self.messages


@contextmanager
def ros_env(prefix: str = 't') -> Iterator[RosEnv]:
    """A fresh Context with its own executor; everything is shut down afterwards."""
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    env = RosEnv(context, executor, unique_namespace(prefix))
    try:
        yield env
    finally:
        for node in env.nodes:
            executor.remove_node(node)
            node.destroy_node()
        executor.shutdown()
        context.try_shutdown()


def capture_errors(node: Any) -> list[str]:
    """The messages ``node`` logs at error level from now on (still logged as well)."""
    errors: list[str] = []
    logger = node.get_logger()
    original = logger.error
    logger.error = lambda msg, **kw: errors.append(msg) or original(msg, **kw)
    return errors


def ctrl_c(install: Callable[[Any], None], node: Any, times: int = 1) -> None:
    """Install a node's signal handlers (``install(node)``, e.g. ``stand_on_signals``), run
    what Ctrl-C runs ``times`` times, and put the process's own handlers back."""
    saved = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        install(node)
        for _ in range(times):
            signal.getsignal(signal.SIGINT)(signal.SIGINT, None)
    finally:
        for s, h in saved.items():
            signal.signal(s, h)


def wait_until_loaded(proc: Any, library: str, timeout_s: float = 60.0) -> bool:
    """Poll a child's memory mappings (no sleep, to catch its imports in progress) until
    ``library`` is loaded, the child ends or ``timeout_s`` passes; True if loaded."""
    import time
    from pathlib import Path

    def maps() -> str:
        try:
            return Path(f'/proc/{proc.pid}/maps').read_text()
        except OSError:
            return ''

    deadline = time.monotonic() + timeout_s
    while library not in maps() and proc.poll() is None and time.monotonic() < deadline:
        pass
    return library in maps()
