"""``bag_replay``: publish a recorded bag's raw messages and ``/clock``, losing none.

A ROS 1 ``.bag`` is accepted too: its messages are converted to ROS 2 CDR on the fly
(``hexapod_common.ros1``); ROS 1 types with no ROS 2 counterpart are skipped with one warning.

Usage: ``bag_replay BAG [--rate R] [--topics T ...] [--remap FROM:=TO ...] [--start S]
[--end S] [--no-clock] [--wait-subscribers N] [--progress-every S]``. Rate 0 (default) is as
fast as possible. A negative rate or offset is refused, and so is a rate below
:data:`MIN_RATE` other than 0 (1e-6 would replay a 2 s bag in 23 days) and a ``--start`` past
the bag's end (exit 2). Every ``--progress-every`` seconds (default 5, 0 = never) a line on
stderr says how many messages were sent of how many and how far into the bag the replay is,
also while it waits for a message that is not due yet. Ctrl-C stops it with exit code 130,
SIGTERM with 143 (each with one line on stderr: the messages sent so far), also in the middle
of a long wait.
"""

from __future__ import annotations

import argparse
import os
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, TextIO

from rclpy.duration import Duration
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from hexapod_common.cli_args import NumberArgumentParser
from hexapod_common.errors import HexapodError
from hexapod_common.node_utils import LATCHED_QOS
from hexapod_common.replay import ReplayOptions, ReplaySource

__all__ = ['BagReplayNode', 'FASTDDS_PROFILE', 'MIN_RATE', 'check_args', 'main', 'parse_args',
           'use_replay_profile']

#: Slowest replay rate other than 0 (as fast as possible): 1 s of the bag per 1000 s.
MIN_RATE = 1e-3
#: Longest single sleep while waiting for a message that is not due yet [s].
_WAIT_SLICE_S = 0.5

#: Fast DDS writer profile with a 2 ms heartbeat period. Acknowledgements answer heartbeats, and
#: with the default 3 s period a replayer waiting for acks crawls (measured: 3000 messages to
#: another process took 58 s; with this profile 30,000 took 4 s, none lost).
FASTDDS_PROFILE = Path(__file__).with_name('fastdds_replay.xml')


def use_replay_profile() -> None:
    """Make this process's Fast DDS writers use :data:`FASTDDS_PROFILE`.

    Must run before the first ROS context of the process is initialised; a profile file the
    user set in ``FASTRTPS_DEFAULT_PROFILES_FILE`` is kept.
    """
    os.environ.setdefault('FASTRTPS_DEFAULT_PROFILES_FILE', str(FASTDDS_PROFILE))

#: Every sample kept until acknowledged: with ack waits this is the flow control.
REPLAY_QOS = QoSProfile(history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)
LATCHED_TOPICS = ('/bench/session',)
_ACK_POLL = Duration(nanoseconds=2_000_000)


class BagReplayNode(Node):
    """Publishes a bag; call :meth:`run` (blocking) after the graph is up.

    ``progress_every_s``: every so many seconds of wall time (checked once per batch of
    ``ack_every`` messages, so it costs nothing measurable) :meth:`run` writes a progress line
    to ``progress_file`` (stderr by default); None or 0 writes none.
    """

    def __init__(self, bag: str | Sequence[str], options: ReplayOptions = ReplayOptions(), *,
                 ack_every: int = 64, ack_timeout_s: float = 10.0, context: Any = None,
                 parameter_overrides: Any = None, namespace: str | None = None,
                 node_name: str = 'bag_replay', progress_every_s: float | None = None,
                 progress_file: TextIO | None = None) -> None:
        super().__init__(node_name, context=context, namespace=namespace or '',
                         parameter_overrides=parameter_overrides or [])
        self.options = options
        self.progress_every_s = progress_every_s or 0.0
        self.progress_file = progress_file
        self.ack_every = max(1, ack_every)
        self.ack_timeout = Duration(seconds=ack_timeout_s)
        self.source = ReplaySource(bag, options, warn=self.get_logger().warning)
        self.pubs: dict[str, Any] = {}
        for topic, cls in self.source.types.items():
            out = self.source.out_topic(topic)
            qos = LATCHED_QOS if out.lstrip('/') in (t.lstrip('/') for t in LATCHED_TOPICS) \
                else REPLAY_QOS
            self.pubs[topic] = self.create_publisher(cls, out.lstrip('/') if namespace else out,
                                                     qos)
        self.clock_pub = None
        if options.publish_clock:
            from rosgraph_msgs.msg import Clock
            self.clock_pub = self.create_publisher(Clock, '/clock', REPLAY_QOS)
        self.published: dict[str, int] = {t: 0 for t in self.pubs}
        self.ack_timeouts = 0

    def wait_for_subscribers(self, count: int, timeout_s: float = 10.0) -> bool:
        """Wait until every data publisher has at least ``count`` subscribers."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(p.get_subscription_count() >= count for p in self.pubs.values()):
                return True
            time.sleep(0.01)
        return False

    def run(self) -> dict[str, int]:
        """Publish every selected message in bag-time order; returns counts per topic."""
        from rosgraph_msgs.msg import Clock

        wall_t0 = time.monotonic()
        bag_t0 = self.source.start_ns + int(self.options.start_offset_s * 1e9)
        dirty: set[str] = set()
        n = 0
        every = self.progress_every_s
        next_report = wall_t0 + every if every > 0 else float('inf')
        last_ns = bag_t0
        for item in self.source.messages():
            if self.options.rate > 0:
                next_report = self._wait_due(item.stamp_ns, bag_t0, wall_t0, n, last_ns,
                                             next_report)
            last_ns = item.stamp_ns
            if self.clock_pub is not None:
                clock = Clock()
                clock.clock.sec, clock.clock.nanosec = divmod(item.stamp_ns, 1_000_000_000)
                self.clock_pub.publish(clock)
            self.pubs[item.topic].publish(item.data)
            self.published[item.topic] += 1
            dirty.add(item.topic)
            n += 1
            if n % self.ack_every == 0:
                self._wait_acked(dirty)
                dirty.clear()
                if time.monotonic() >= next_report:
                    self._report(n, item.stamp_ns, wall_t0)
                    next_report = time.monotonic() + every
        self._wait_acked(dirty)
        return dict(self.published)

    def _wait_due(self, stamp_ns: int, bag_t0: int, wall_t0: float, sent: int, last_ns: int,
                  next_report: float) -> float:
        """Sleep until ``stamp_ns`` is due at the rate (``replay.pace``) in slices of at most
        :data:`_WAIT_SLICE_S`: a progress line when one is due while waiting (a slow rate
        waits long between two messages), and a stop when the context is shut down. Returns
        the time of the next progress line."""
        from rclpy.executors import ExternalShutdownException

        due = wall_t0 + (stamp_ns - bag_t0) * 1e-9 / self.options.rate
        while (now := time.monotonic()) < due:
            if not self.context.ok():
                raise ExternalShutdownException()
            if now >= next_report:
                self._report(sent, last_ns, wall_t0, wait_s=due - now)
                next_report = now + self.progress_every_s
            time.sleep(max(0.0, min(due - now, next_report - now, _WAIT_SLICE_S)))
        return next_report

    def total_messages(self) -> int:
        """Messages of the replayed topics in the whole bag (0 when the bag does not say)."""
        return sum(c.msgcount for c in self.source.reader.connections
                   if c.topic in self.source.types)

    def _report(self, sent: int, stamp_ns: int, wall_t0: float,
                wait_s: float | None = None) -> None:
        """One progress line: messages sent of the total, bag time reached, rate (and, while
        waiting, when the next message is due)."""
        span_s = max(0, self.source.end_ns - self.source.start_ns) * 1e-9
        bag_s = max(0, stamp_ns - self.source.start_ns) * 1e-9
        wall_s = max(time.monotonic() - wall_t0, 1e-9)
        out = self.progress_file or sys.stderr
        a, b = self.options.start_offset_s, self.options.end_offset_s
        waiting = '' if wait_s is None else \
            f'; the next message is due in {wait_s:,.1f} s (--rate {self.options.rate:g})'
        if a > 0 or b > 0:
            # a --start/--end window: progress through it, not through the whole bag (it said
            # '832 / 12,300 (7 %)' of a window of 1,645 messages: new-user review)
            hi = b if b > 0 else span_s
            frac = (bag_s - a) / (hi - a) if hi > a else 1.0
            print(f'bag_replay: {sent:,} messages sent, bag time {bag_s:.1f} s of the window '
                  f'{a:.1f}-{hi:.1f} s ({100.0 * min(max(frac, 0.0), 1.0):.0f} %), '
                  f'{sent / wall_s:,.0f} msg/s{waiting}', file=out, flush=True)
            return
        total = self.total_messages()
        of = f' / {total:,} ({100.0 * sent / total:.0f} %)' if total else ''
        print(f'bag_replay: {sent:,}{of} messages sent, bag time {bag_s:.1f} / {span_s:.1f} s, '
              f'{sent / wall_s:,.0f} msg/s{waiting}', file=out, flush=True)

    def _wait_acked(self, topics: set[str]) -> None:
        pubs = [self.pubs[t] for t in topics]
        if self.clock_pub is not None:
            pubs.append(self.clock_pub)
        for pub in pubs:
            # Short polls with a GIL release in between: rclpy holds the GIL inside
            # wait_for_all_acked, which would starve a receiver spinning in another thread of
            # this process until its KEEP_ALL history filled and acks stopped (a deadlock).
            deadline = time.monotonic() + self.ack_timeout.nanoseconds * 1e-9
            while not pub.wait_for_all_acked(_ACK_POLL):
                if time.monotonic() > deadline:
                    self.ack_timeouts += 1
                    self.get_logger().warning(
                        f'{pub.topic_name}: a reliable subscriber did not acknowledge within '
                        f'{self.ack_timeout.nanoseconds * 1e-9:.1f} s; going on')
                    break
                time.sleep(0.0002)

    def destroy_node(self) -> None:
        self.source.close()
        super().destroy_node()


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    parser = NumberArgumentParser(prog='bag_replay', description=__doc__.split('\n')[0])
    parser.add_argument('bag', nargs='?', default=None,
                        help='rosbag2 bag folder (mcap or sqlite3) or ROS 1 .bag file')
    parser.add_argument('--rate', type=float, default=0.0,
                        help='1 = real time, N = N times real time, 0 = as fast as possible '
                        '(default 0)')
    parser.add_argument('--topics', nargs='*', default=[], help='only these topics')
    parser.add_argument('--remap', nargs='*', default=[], metavar='FROM:=TO',
                        help='publish a recorded topic under another name')
    parser.add_argument('--start', type=float, default=0.0, help='start offset [s]')
    parser.add_argument('--end', type=float, default=0.0, help='end offset [s] (0 = end)')
    parser.add_argument('--no-clock', action='store_true', help='do not publish /clock')
    parser.add_argument('--wait-subscribers', type=int, default=0, metavar='N',
                        help='wait (up to 10 s) for N subscribers on every topic first')
    parser.add_argument('--progress-every', type=float, default=5.0, metavar='S',
                        help='a progress line on stderr every S seconds (0 = none)')
    args = parser.parse_args(argv)
    if args.bag is None:
        # --topics / --remap take every word after them: the bag given last had read 'the
        # following arguments are required: bag' (a review)
        taken = [opt for opt, vals in (('--topics', args.topics), ('--remap', args.remap))
                 if vals and os.path.exists(vals[-1])]
        parser.error(f'the bag goes before {taken[0]} (it takes every word after it): '
                     f'bag_replay BAG {taken[0]} ...' if taken else
                     'the following arguments are required: bag')
    remap = {}
    for item in args.remap:
        if ':=' not in item:
            parser.error(f'--remap takes FROM:=TO, got {item!r}')
        src, dst = item.split(':=', 1)
        remap[src] = dst
    args.options = ReplayOptions(rate=args.rate, topics=tuple(args.topics), remap=remap,
                                 start_offset_s=args.start, end_offset_s=args.end,
                                 publish_clock=not args.no_clock)
    return args


def check_args(args: argparse.Namespace) -> str | None:
    """Why the numbers of :func:`parse_args` are refused, else None."""
    import math

    for name in ('rate', 'start', 'end', 'progress_every'):
        value = getattr(args, name)
        if not math.isfinite(value) or value < 0:
            extra = ' (1 = real time, 0 = as fast as possible)' if name == 'rate' else ''
            return f'--{name.replace("_", "-")} must be a finite number >= 0{extra}, ' \
                f'got {value:g}'
    if 0 < args.rate < MIN_RATE:
        return (f'--rate must be 0 (as fast as possible) or >= {MIN_RATE:g} (1 s of the bag per '
                f'{1 / MIN_RATE:g} s), got {args.rate:g}')
    if args.end and args.end <= args.start:
        return f'--end {args.end:g} s must be after --start {args.start:g} s (0 = to the end)'
    if args.wait_subscribers < 0:
        return f'--wait-subscribers must be >= 0, got {args.wait_subscribers}'
    return None


def _check_window(args: argparse.Namespace, source: ReplaySource) -> str | None:
    """Why ``--start`` selects nothing of the bag (it starts past the bag's end), else None."""
    span_s = max(0, source.end_ns - source.start_ns) * 1e-9
    if args.start > span_s:
        return (f'--start {args.start:g} s is past the end: the bag spans {span_s:.3f} s, '
                'nothing to replay')
    return None


class _Terminated(Exception):
    """SIGTERM arrived (raised by :func:`_on_signal` in the main thread)."""


class _Stop:
    """The first SIGINT or SIGTERM raises (:class:`KeyboardInterrupt`, :class:`_Terminated`)
    in the main thread; any later one, or one after :attr:`done`, is ignored, so that a second
    signal cannot interrupt the exit (a traceback)."""

    def __init__(self) -> None:
        self.raised = False
        self.done = False

    def __call__(self, signum: int, frame: Any) -> None:
        if self.raised or self.done:
            return
        self.raised = True
        raise KeyboardInterrupt() if signum == signal.SIGINT else _Terminated()


def _catch_signals(stop: _Stop) -> dict[int, Any]:
    """Make SIGINT and SIGTERM raise in the main thread (see :class:`_Stop`); returns the
    handlers to put back (none outside the main thread, where handlers cannot be set).

    rclpy's own handlers only shut the context down: a replay sleeping until its next message
    never saw SIGTERM (review: SIGKILL needed), and a SIGINT to a replay started in the
    background of a script (Python's KeyboardInterrupt handler is not installed there, SIGINT
    being ignored) made the next publish fail with a traceback, "publisher's context is
    invalid", exit 1 (an outside review, 4 of 4 tries). rclpy is started without them."""
    if threading.current_thread() is not threading.main_thread():
        return {}
    previous = {}
    for signum in (signal.SIGINT, signal.SIGTERM):
        old = signal.signal(signum, stop)
        # None: a handler set outside Python; the default is the closest to put back
        previous[signum] = signal.SIG_DFL if old is None else old
    return previous


def main(argv: Sequence[str] | None = None) -> int:
    """``bag_replay``; exit 0, 2 (refused input), 130 (SIGINT), 143 (SIGTERM)."""
    stop = _Stop()
    previous = _catch_signals(stop)
    node: list[BagReplayNode] = []
    try:
        return _main(argv, node)
    except (KeyboardInterrupt, _Terminated) as stopped:
        # Ctrl-C, kill -INT or kill -TERM: how far the replay got, in one line
        sent = sum(node[0].published.values()) if node else 0
        name = 'SIGINT' if isinstance(stopped, KeyboardInterrupt) else 'SIGTERM'
        print(f'bag_replay: stopped ({name}) after {sent} messages', file=sys.stderr)
        return 130 if name == 'SIGINT' else 143
    finally:
        stop.done = True
        for signum, handler in previous.items():
            signal.signal(signum, handler)


def _main(argv: Sequence[str] | None, made: list[BagReplayNode]) -> int:
    """:func:`main` with the signals caught; the node goes into ``made`` once created."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.signals import SignalHandlerOptions

    raw = list(sys.argv[1:] if argv is None else argv)
    # only the --ros-args part goes to rcl: a plain '--remap /a:=/b' of ours was read by rcl as
    # its deprecated remapping syntax too (a warning printed twice, new-user review)
    ros_part: list[str] = []
    own: list[str] = []
    inside = False
    for a in raw:
        if a == '--ros-args':
            inside = True
        elif a == '--' and inside:
            inside = False
            continue
        (ros_part if inside else own).append(a)
    args = parse_args(own)
    if reason := check_args(args):
        print(f'bag_replay: error: {reason}', file=sys.stderr)
        return 2
    use_replay_profile()
    # rclpy's signal handlers would replace ours (see _catch_signals)
    rclpy.init(args=['bag_replay', *ros_part], signal_handler_options=SignalHandlerOptions.NO)
    node = None
    try:
        node = BagReplayNode(args.bag, args.options, progress_every_s=args.progress_every)
        made.append(node)
        if not node.source.types:
            unknown = '; '.join(f'{t}: {why}' for t, why in node.source.skipped.items())
            raise HexapodError('nothing to replay' + (f' (unknown types: {unknown})'
                                                      if unknown else ' (no matching topics)'))
        if reason := _check_window(args, node.source):
            print(f'bag_replay: error: {reason}', file=sys.stderr)
            return 2
        if args.wait_subscribers and not node.wait_for_subscribers(args.wait_subscribers):
            short = {t: p.get_subscription_count() for t, p in node.pubs.items()
                     if p.get_subscription_count() < args.wait_subscribers}
            # it waited 10 s without a word and replayed (new-user review)
            print('bag_replay: warning: after 10 s, fewer than '
                  f'{args.wait_subscribers} subscriber(s) on ' + ', '.join(
                      f'{t} ({c})' for t, c in sorted(short.items()))
                  + '; replaying anyway (--topics selects the topics a node reads)',
                  file=sys.stderr)
        counts = node.run()
        total = sum(counts.values())
        print(f'replayed {total} messages: ' +
              ', '.join(f'{t} {c}' for t, c in sorted(counts.items())))
        if total == 0:
            span_s = max(0, node.source.end_ns - node.source.start_ns) * 1e-9
            print(f'bag_replay: error: no message in the selected window '
                  f'(--start {args.start:g} s, --end {args.end:g} s); the bag spans '
                  f'{span_s:.3f} s', file=sys.stderr)
            return 2
        return 0
    except HexapodError as err:
        print(f'bag_replay: error: {err}', file=sys.stderr)
        return 2
    except ExternalShutdownException:
        return 130      # the context was shut down (in a process that set rclpy's handlers)
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
