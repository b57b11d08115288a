"""Bag replay: a publishing node with flow control, and the in-process offline harness.

Two ways to push a bag through nodes:

- :class:`BagReplayNode` publishes the recorded raw CDR bytes over ROS, in bag-time order, with
  ``/clock``. Reliable publishers keep every sample (KEEP_ALL) and the replayer waits until
  every reliable subscriber has acknowledged each batch of 64 messages before it sends more,
  so a receiver with a reliable KEEP_ALL subscription (``bag_recorder`` is one) gets every
  message at any rate. Acknowledgements answer Fast DDS heartbeats, so the replay process uses
  a writer profile with a 2 ms heartbeat (``fastdds_replay.xml``); the waits poll and release
  the GIL, so a receiver spinning in another thread of the same process is not starved.
- :func:`run_offline` feeds the messages straight into the subscription callbacks of nodes in
  one process, deterministically, and captures what they publish: offline analysis runs the
  very nodes that run live, so their numbers are equal.

Both read rosbag2 bags (raw CDR, passed on untouched) and ROS 1 ``.bag`` files: a ROS 1 bag's
messages are converted to ROS 2 CDR on the fly (:class:`hexapod_common.ros1.Ros1ToCdr`: fields
copied by name, ``header.seq`` dropped); ROS 1 types with no ROS 2 counterpart are skipped with
one warning, like unknown types of rosbag2 bags.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

from hexapod_common.bags import BagMessage, iter_messages, open_reader
from hexapod_common.errors import UnknownTypeError
from hexapod_common.ros1 import Ros1ToCdr
from hexapod_common.ros_types import ros_message_class

__all__ = ['ReplayOptions', 'ReplaySource', 'run_offline']

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ReplayOptions:
    """What to replay and how fast.

    ``rate`` 0 means as fast as possible, 1 real time, N times real time. Offsets are seconds
    from the bag's start. ``remap`` maps recorded topic -> published topic.
    """

    rate: float = 0.0
    topics: tuple[str, ...] = ()
    remap: dict[str, str] = field(default_factory=dict)
    start_offset_s: float = 0.0
    end_offset_s: float = 0.0  # 0 = to the end
    publish_clock: bool = True


class ReplaySource:
    """Bag messages to replay, filtered, windowed and typed; unknown types skipped once each.

    Messages are yielded with ROS 2 CDR bytes: a rosbag2 bag's as recorded, a ROS 1 bag's
    converted (``ros1`` is then the :class:`Ros1ToCdr` in use; ``dropped`` counts per topic the
    ROS 1 messages that could not be converted, each topic warned once).
    """

    def __init__(self, bag: str | Sequence[str], options: ReplayOptions = ReplayOptions(),
                 warn: Callable[[str], None] | None = None) -> None:
        self.options = options
        self.warn = warn or log.warning
        self.reader = open_reader(bag)
        for note in getattr(self.reader, 'notes', ()):   # e.g. metadata.yaml vs storage
            self.warn(note)
        self.start_ns = self.reader.start_time
        self.end_ns = self.reader.end_time
        self.types: dict[str, Any] = {}
        self.skipped: dict[str, str] = {}
        self.ros1 = None if self.reader.is2 else Ros1ToCdr(self.reader)
        self.dropped: dict[str, int] = {}
        wanted = set(options.topics)
        for conn in self.reader.connections:
            if wanted and conn.topic not in wanted:
                continue
            if conn.topic in self.types or conn.topic in self.skipped:
                continue
            try:
                cls = ros_message_class(conn.msgtype)
                if self.ros1 is not None:
                    self.ros1.converter(conn.msgtype)
                self.types[conn.topic] = cls
            except UnknownTypeError as err:
                self.skipped[conn.topic] = str(err)
                self.warn(f'skipping topic {conn.topic}: {err}')
        if wanted - set(self.types) - set(self.skipped):
            missing = sorted(wanted - set(self.types) - set(self.skipped))
            self.warn(f'topics not in the bag: {", ".join(missing)}')
        self.msgtypes = {c.topic: c.msgtype for c in self.reader.connections
                         if c.topic in self.types}

    def out_topic(self, topic: str) -> str:
        return self.options.remap.get(topic, topic)

    def messages(self) -> Iterable[BagMessage]:
        start = self.start_ns + int(self.options.start_offset_s * 1e9)
        stop = self.start_ns + int(self.options.end_offset_s * 1e9) + 1 \
            if self.options.end_offset_s > 0 else None
        # replayed as recorded: a message stored twice is published twice
        raw = iter_messages(self.reader, topics=list(self.types), start_ns=start,
                            stop_ns=stop, dedupe=False)
        return raw if self.ros1 is None else self._from_ros1(raw)

    def _from_ros1(self, raw: Iterable[BagMessage]) -> Iterator[BagMessage]:
        """ROS 1 messages re-encoded as ROS 2 CDR; one that cannot be is dropped (counted)."""
        assert self.ros1 is not None
        convs: dict[str, Callable[[bytes], bytes]] = {}
        for item in raw:
            conv = convs.get(item.msgtype)
            if conv is None:
                conv = convs[item.msgtype] = self.ros1.converter(item.msgtype)
            try:
                data = conv(item.data)
            except Exception as err:  # rosbags raises several types for a bad message
                n = self.dropped.get(item.topic, 0)
                self.dropped[item.topic] = n + 1
                if n == 0:
                    self.warn(f'dropping {item.topic} message(s) that cannot be converted from '
                              f'ROS 1 ({item.msgtype}): {err}')
                continue
            yield BagMessage(item.topic, item.msgtype, item.stamp_ns, data)

    def close(self) -> None:
        self.reader.close()

    def __enter__(self) -> ReplaySource:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _set_sim_time(nodes: Sequence[Any], t_ns: int) -> None:
    from rclpy.time import Time

    now = Time(nanoseconds=t_ns)
    for node in nodes:
        clock = node.get_clock()
        if hasattr(clock, 'set_ros_time_override'):
            clock._set_ros_time_is_active(True)
            clock.set_ros_time_override(now)


def run_offline(nodes: Sequence[Any], bag: str | Sequence[str], *,
                options: ReplayOptions = ReplayOptions(), capture: Sequence[str] = (),
                progress: bool = False) -> dict[str, list[Any]]:
    """Feed a bag through ``nodes`` in one process and return what they published.

    Each bag message is deserialised once into the rclpy type and handed, in bag-time order,
    to every subscription callback of every node on that topic (raw subscriptions get the
    bytes; a two-argument callback also gets a message info with the bag time as its
    timestamps and no publication sequence number: a bag does not keep them). Before each
    message the nodes' ROS clocks are set to its bag time, as ``/clock``
    would. Publishers on ``capture`` topics (default: every publisher of the nodes) are
    wrapped so the published messages are returned per topic, in order. After the bag, a
    node's ``finish_offline()`` is called when it has one (``slip_fitter``: its
    self-calibration, which works on a thread, is waited for and its fits published).
    """
    from rclpy.serialization import deserialize_message

    captured: dict[str, list[Any]] = {}
    for node in nodes:
        for pub in node.publishers:
            topic = pub.topic_name
            if capture and topic not in capture:
                continue
            captured.setdefault(topic, [])
            original = pub.publish

            def _publish(msg: Any, _topic: str = topic, _orig: Callable = original) -> None:
                captured[_topic].append(msg)
                _orig(msg)
            pub.publish = _publish  # type: ignore[method-assign]
    routes: dict[str, list[Any]] = {}
    for node in nodes:
        for sub in node.subscriptions:
            routes.setdefault(sub.topic_name, []).append(sub)
    with ReplaySource(bag, options) as source:
        messages: Iterable[BagMessage] = source.messages()
        if progress:
            from tqdm import tqdm
            messages = tqdm(messages, total=source.reader.message_count, unit='msg',
                            desc='replay')
        for item in messages:
            subs = routes.get(source.out_topic(item.topic))
            if not subs:
                continue
            _set_sim_time(nodes, item.stamp_ns)
            msg = None
            for sub in subs:
                if sub.raw:
                    data = item.data
                else:
                    if msg is None:
                        msg = deserialize_message(item.data, source.types[item.topic])
                    data = msg
                if _wants_info(sub):
                    sub.callback(data, _bag_message_info(item.stamp_ns))
                else:
                    sub.callback(data)
    for node in nodes:
        finish = getattr(node, 'finish_offline', None)
        if callable(finish):
            finish()
    return captured


def _wants_info(sub: Any) -> bool:
    """Whether rclpy passes this subscription's callback the message info too."""
    from rclpy.subscription import Subscription

    return bool(getattr(sub, '_callback_type', None)
                == Subscription.CallbackType.WithMessageInfo)


def _bag_message_info(stamp_ns: int) -> dict[str, Any]:
    """rclpy's message info for a bag message: its bag time, no sequence numbers."""
    return {'source_timestamp': stamp_ns, 'received_timestamp': stamp_ns,
            'publication_sequence_number': None, 'reception_sequence_number': None}


def pace(rate: float, bag_t0_ns: int, wall_t0: float, stamp_ns: int) -> None:
    """Sleep until ``stamp_ns`` is due at ``rate`` times real time (no-op when rate is 0)."""
    if rate <= 0:
        return
    due = wall_t0 + (stamp_ns - bag_t0_ns) * 1e-9 / rate
    delay = due - time.monotonic()
    if delay > 0:
        time.sleep(delay)
