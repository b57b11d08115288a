"""``bag_recorder``: record topics into a rosbag2 bag (mcap default) from raw subscriptions.

Usage: ``bag_recorder -o BAG [--topics T ...] [--storage mcap|sqlite3] [--flush-period S]``
(or the same as ROS parameters ``output``, ``topics``, ``storage``, ``flush_period``).
Storage files are closed every ``flush_period`` seconds, so a killed recorder loses at most
that much. An existing bag is never overwritten. An output that cannot be created (an existing
path, a folder that cannot be written) or a ``--flush-period`` that is not a finite number > 0
is refused before recording (exit 2, one line naming the option).
Ctrl-C, ``kill -INT`` or ``kill -TERM`` (also to a background job, which ignores SIGINT until
a program catches it) stop it: exit 0 with a valid bag (empty if nothing came) once the bag
folder exists, else 130 (SIGINT) or 143 (SIGTERM), one line and no folder (see :func:`main`).
"""

from __future__ import annotations

from hexapod_common import stop_signals

# First, before rclpy's second of imports: a `kill -INT` then, to a recorder started in the
# background by a script (SIGINT ignored), was lost and it recorded on (see stop_signals, main).
stop_signals.catch_if_program('bag_recorder')

import argparse  # noqa: E402
import math  # noqa: E402
import signal  # noqa: E402
import sys  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from pathlib import Path  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from typing import Any  # noqa: E402

from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import (  # noqa: E402
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
)

from hexapod_common.bags import BagWriter  # noqa: E402
from hexapod_common.cli_args import NumberArgumentParser  # noqa: E402
from hexapod_common.errors import HexapodError, UnknownTypeError  # noqa: E402
from hexapod_common.node_utils import (  # noqa: E402
    close_node,
    declare_params,
    param,
    stopping_errors,
)
from hexapod_common.ros_types import CONTRACT_TOPICS, ros_message_class  # noqa: E402

__all__ = ['BagRecorderNode', 'RecorderParams', 'check_args', 'main']


def _storage_ok(value: str) -> str | None:
    return None if value in ('mcap', 'sqlite3') else 'expected mcap or sqlite3'


def _positive(value: float) -> str | None:
    return None if value > 0 else 'must be > 0'


@dataclass(frozen=True)
class RecorderParams:
    output: str = param('', 'bag folder to create (refused if it exists)', read_only=True,
                        validate=lambda v: None if v else 'an output path is required')
    topics: list[str] = param(list(CONTRACT_TOPICS), 'topics to record', read_only=True)
    storage: str = param('mcap', 'storage plugin: mcap or sqlite3', validate=_storage_ok,
                         read_only=True)
    flush_period: float = param(1.0, 'seconds between storage file closes (crash loss bound)',
                                validate=_positive, read_only=True)
    discovery_period: float = param(0.5, 'seconds between looks for new publishers',
                                    validate=_positive, read_only=True)


class BagRecorderNode(Node):
    """Subscribes raw to each wanted topic once a publisher appears and writes to the bag."""

    def __init__(self, *, context: Any = None, parameter_overrides: Any = None,
                 namespace: str | None = None, node_name: str = 'bag_recorder') -> None:
        super().__init__(node_name, context=context, namespace=namespace or '',
                         parameter_overrides=parameter_overrides or [])
        self.params = declare_params(self, RecorderParams)
        self.writer = BagWriter(self.params.output, storage=self.params.storage,
                                split_every_s=self.params.flush_period)
        self.counts: dict[str, int] = {}
        self._subs: dict[str, Any] = {}
        self._warned: set[str] = set()
        try:
            # said at start and per topic as it is subscribed (it printed nothing until it
            # stopped)
            self.get_logger().info(
                f'recording into {self.params.output}: '
                f'{", ".join(self._resolve(t) for t in self.params.topics)} (each once a '
                'publisher appears)')
            self._discover()
            self.create_timer(self.params.discovery_period, self._discover)
            self.create_timer(self.params.flush_period, self.writer.flush)
        except BaseException:
            # the bag folder exists: close it as a valid (empty) bag. A SIGINT here shut the
            # context down under the first discovery and left a folder without metadata.yaml
            # that bag_replay could not read (an outside review)
            self.writer.close()
            raise

    def _resolve(self, topic: str) -> str:
        return self.resolve_topic_name(topic)

    def _discover(self) -> None:
        graph = dict(self.get_topic_names_and_types())
        for topic in self.params.topics:
            name = self._resolve(topic)
            if name in self._subs or name not in graph:
                continue
            infos = self.get_publishers_info_by_topic(name)
            if not infos:
                continue
            msgtype = graph[name][0]
            try:
                cls = ros_message_class(msgtype)
                self.writer.add_topic(name, msgtype)
            except UnknownTypeError as err:
                if name not in self._warned:
                    self._warned.add(name)
                    self.get_logger().warning(f'not recording {name}: {err}')
                continue
            reliable = all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE
                           for i in infos)
            latched = all(i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
                          for i in infos)
            qos = QoSProfile(
                history=HistoryPolicy.KEEP_ALL if reliable else HistoryPolicy.KEEP_LAST,
                depth=1000,
                reliability=ReliabilityPolicy.RELIABLE if reliable
                else ReliabilityPolicy.BEST_EFFORT,
                durability=DurabilityPolicy.TRANSIENT_LOCAL if latched
                else DurabilityPolicy.VOLATILE)
            self._subs[name] = self.create_subscription(
                cls, name, lambda data, _t=name, _m=msgtype: self._on_message(_t, _m, data),
                qos, raw=True)
            self.counts[name] = 0
            self.get_logger().info(
                f'recording {name} ({msgtype}, '
                f'{"reliable" if reliable else "best effort"}'
                f'{", transient local" if latched else ""})')

    def _on_message(self, topic: str, msgtype: str, data: bytes) -> None:
        self.writer.write(topic, msgtype, data, self.get_clock().now().nanoseconds)
        self.counts[topic] += 1

    def destroy_node(self) -> None:
        self.writer.close()
        super().destroy_node()


def check_args(args: argparse.Namespace) -> str | None:
    """Why the command-line options cannot be recorded with, naming the option, else None
    (nothing is created)."""
    if args.flush_period is not None and not (math.isfinite(args.flush_period)
                                              and args.flush_period > 0):
        return f'--flush-period must be a finite number > 0 s, got {args.flush_period:g}'
    if not args.output:
        return None     # from the ROS parameter 'output', checked by the node
    out = Path(args.output)
    if out.is_symlink() or out.exists():
        what = 'a folder (an existing bag?)' if out.is_dir() else 'a file'
        return f'-o {out} exists and is {what}; refusing to overwrite it'
    from hexapod_common.outdir import creatable_problem

    return creatable_problem(out, '-o')


def main(argv: Sequence[str] | None = None) -> int:
    """Record until SIGINT or SIGTERM; exit 0 with a valid bag (empty if nothing came) once the
    bag folder was created, 130 (SIGINT) or 143 (SIGTERM) with one line and no folder when
    the signal came before, 2 for a refused option or output.

    The signals are noted by :mod:`hexapod_common.stop_signals` (the console script catches
    them at import, before rclpy's imports) and not by rclpy's handler, which ignored a
    signal that came before its context existed, and whose ``KeyboardInterrupt`` during the
    bag's close lost the last split. Once the stop has begun, more signals are only noted."""
    saved = {sig: signal.getsignal(sig) for sig in stop_signals.STOP_SIGNALS}
    stop_signals.catch()
    try:
        return _record(argv)
    finally:
        stop_signals.forget()                # consumed by this run
        for sig, handler in saved.items():   # called in-process (a test): its own handlers
            if handler is not None:
                signal.signal(sig, handler)


def _interrupted(sig: int) -> int:
    name = signal.Signals(sig).name
    print(f'bag_recorder: {name} before recording began: no bag written', file=sys.stderr)
    return stop_signals.EXIT_CODES[sig]


def _record(argv: Sequence[str] | None) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions
    from rclpy.utilities import remove_ros_args

    raw = list(sys.argv[1:] if argv is None else argv)
    parser = NumberArgumentParser(prog='bag_recorder', description=__doc__.split('\n')[0])
    parser.add_argument('-o', '--output', help='bag folder to create')
    parser.add_argument('--topics', nargs='*', help='topics (default: every contract topic)')
    parser.add_argument('--storage', choices=('mcap', 'sqlite3'))
    parser.add_argument('--flush-period', type=float,
                        help='seconds between storage file closes, > 0 (default 1)')
    args = parser.parse_args(remove_ros_args(['bag_recorder', *raw])[1:])
    if reason := check_args(args):
        print(f'bag_recorder: error: {reason}', file=sys.stderr)
        return 2
    overrides = []
    if args.output:
        overrides.append(Parameter('output', value=args.output))
    if args.topics:
        overrides.append(Parameter('topics', value=list(args.topics)))
    if args.storage:
        overrides.append(Parameter('storage', value=args.storage))
    if args.flush_period is not None:
        overrides.append(Parameter('flush_period', value=args.flush_period))
    if sig := stop_signals.received():
        return _interrupted(sig)
    rclpy.init(args=['bag_recorder', *raw], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        if sig := stop_signals.received():
            return _interrupted(sig)
        node = BagRecorderNode(parameter_overrides=overrides)
        executor = SingleThreadedExecutor(context=node.context)
        executor.add_node(node)
        # the noted signal is seen when spin_once returns: within 0.1 s
        while stop_signals.received() is None and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
    except ExternalShutdownException:
        pass
    except (HexapodError, ValueError) as err:
        print(f'bag_recorder: error: {err}', file=sys.stderr)
        return 2
    except OSError as err:
        # the output cannot be written after all (the checks above passed: a race)
        print(f'bag_recorder: error: {err.filename or "output"}: cannot write the bag '
              f'({err.strerror or err})', file=sys.stderr)
        return 2
    except stopping_errors() as err:
        # the context shut down under topic discovery or the wait set (by another handler
        # than ours, or rclpy.shutdown): a stop, unless still running
        if rclpy.ok():
            raise err
    finally:
        stop_signals.catch()     # a second signal no longer interrupts the close
        if node is not None:
            print(f'recorded: {dict(node.counts)}', file=sys.stderr)
        close_node(node)
    return 0
