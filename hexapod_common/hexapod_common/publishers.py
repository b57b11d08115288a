"""Several live publishers on one topic, told from the messages' publication sequence numbers.

Every DDS writer numbers its messages 1, 2, 3, ... (``publication_sequence_number`` of the
message info rclpy passes to a two-argument subscription callback). One publisher's numbers
only rise (a best-effort link may skip some); two live publishers on one topic interleave
two rising series, so the numbers go back again and again. The ROS graph cannot tell this:
a publisher that crashed keeps its endpoint in ``count_publishers`` until its DDS lease
runs out (measured here: still 2 publishers 6 s after a ``kill -9`` and a respawn), and a
node that starts sees the graph only once discovery has run. The numbers can:

- a publisher that restarts (a respawned driver) starts a new series once, and the old one
  stops: one step back, then rising again: one publisher;
- two live publishers: each message of the one follows a message of the other, so a series
  that was already seen receives a message after another series did (a *switch back*).

:class:`PublisherSequences` assigns each number to the series whose last number is the
highest below it (a new series when none is below), and counts switch backs. Two or more
within the last ``window`` messages (1000) are two live publishers: a second publisher sending
less than one message for every 500 of the first (a 0.1 Hz teleop beside a 100 Hz gait
node) is not seen. A middleware that does not number its messages gives no numbers: nothing is
seen (the nodes say which checks fall back on the graph).

Core module: no rclpy.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ['SEQUENCE_UNSUPPORTED', 'PublisherSequences', 'endpoint_names', 'publication_sequence',
           'source_time']

#: ``RMW_MESSAGE_INFO_SEQUENCE_NUMBER_UNSUPPORTED`` (UINT64_MAX): a middleware that does not
#: number its messages
SEQUENCE_UNSUPPORTED = 2 ** 64 - 1


def source_time(info: Mapping[str, Any] | None) -> float | None:
    """The time [s] a message was sent, from rclpy's message info (``source_timestamp``),
    or None."""
    if not info:
        return None
    t = info.get('source_timestamp')
    return float(t) * 1e-9 if isinstance(t, int) and t > 0 else None


def publication_sequence(info: Mapping[str, Any] | None) -> int | None:
    """The publisher's sequence number of a message from rclpy's message info, or None when
    the middleware does not give one (missing, 0 or ``SEQUENCE_UNSUPPORTED``)."""
    if not info:
        return None
    seq = info.get('publication_sequence_number')
    if seq is None or seq <= 0 or seq >= SEQUENCE_UNSUPPORTED:
        return None
    return int(seq)


def endpoint_names(infos: Iterable[Any]) -> str:
    """``'/ns/node x2, a node not yet discovered'``: the nodes of a topic's graph endpoints
    (rclpy ``TopicEndpointInfo``; a node whose name discovery has not brought yet reads
    ``_NODE_NAME_UNKNOWN_``), for a message."""
    counts: dict[str, int] = {}
    for info in infos:
        name = str(getattr(info, 'node_name', ''))
        space = str(getattr(info, 'node_namespace', ''))
        if not name or 'UNKNOWN' in name:
            key = 'a node not yet discovered'
        else:
            key = space.rstrip('/') + '/' + name
        counts[key] = counts.get(key, 0) + 1
    if not counts:
        return 'none listed yet'
    return ', '.join(k + (f' x{n}' if n > 1 else '') for k, n in sorted(counts.items()))


class PublisherSequences:
    """Two or more live publishers on one topic, from its messages' sequence numbers (module
    docs). :meth:`add` returns True on the message that shows them (once per episode: an
    episode ends after ``window`` messages without a switch back)."""

    def __init__(self, window: int = 1000, min_switches: int = 2, max_series: int = 16) -> None:
        if window < 2 or min_switches < 1 or max_series < 2:
            raise ValueError('window >= 2, min_switches >= 1 and max_series >= 2')
        self.window = int(window)
        self.min_switches = int(min_switches)
        self.max_series = int(max_series)
        #: messages seen with a sequence number
        self.messages = 0
        #: messages without one (the middleware does not number them)
        self.unnumbered = 0
        #: episodes of several live publishers so far
        self.episodes = 0
        #: True while several publishers interleave (until ``window`` calm messages)
        self.interleaving = False
        self._last: list[int] = []          # each series' last number
        self._used: list[int] = []          # the message count at each series' last message
        # each series' first and last (number, time) seen, for its start (series_starts)
        self._first_at: list[tuple[int, float] | None] = []
        self._last_at: list[tuple[int, float] | None] = []
        self._current = -1                  # the series of the previous message
        self._switches: deque[int] = deque()

    @property
    def numbered(self) -> bool:
        """Whether the messages carry sequence numbers (False until one does)."""
        return self.messages > 0

    def add(self, seq: int | None, t_s: float | None = None) -> bool:
        """One message's sequence number (None: not numbered, ignored) and, optionally, the
        time it was sent [s] (the message info's ``source_timestamp``: :meth:`series_starts`)."""
        if seq is None:
            self.unnumbered += 1
            return False
        self.messages += 1
        n = self.messages
        best = -1
        for i, last in enumerate(self._last):
            # the series ending highest below ``seq``; on a tie the one just used
            if last < seq and (best < 0 or last > self._last[best]
                               or (last == self._last[best] and i == self._current)):
                best = i
        if best < 0:                        # a new series (a publisher, or one restarted)
            if len(self._last) >= self.max_series:
                oldest = min(range(len(self._used)), key=self._used.__getitem__)
                del self._last[oldest], self._used[oldest]
                del self._first_at[oldest], self._last_at[oldest]
                if self._current == oldest:
                    self._current = -1
                elif self._current > oldest:
                    self._current -= 1
            self._last.append(seq)
            self._used.append(n)
            at = (seq, float(t_s)) if t_s is not None else None
            self._first_at.append(at)
            self._last_at.append(at)
            best = len(self._last) - 1
        else:
            if best != self._current and self._current >= 0:
                self._switches.append(n)    # a series seen before speaks again
            self._last[best] = seq
            self._used[best] = n
            if t_s is not None:
                self._last_at[best] = (seq, float(t_s))
                if self._first_at[best] is None:
                    self._first_at[best] = (seq, float(t_s))
        self._current = best
        # series silent for a whole window are gone (a crashed publisher's last numbers)
        keep = [i for i, u in enumerate(self._used) if n - u <= self.window or i == best]
        if len(keep) < len(self._used):
            self._current = keep.index(best)
            self._last = [self._last[i] for i in keep]
            self._used = [self._used[i] for i in keep]
            self._first_at = [self._first_at[i] for i in keep]
            self._last_at = [self._last_at[i] for i in keep]
        while self._switches and n - self._switches[0] >= self.window:
            self._switches.popleft()
        if len(self._switches) >= self.min_switches:
            if not self.interleaving:
                self.interleaving = True
                self.episodes += 1
                return True
        elif self.interleaving and not self._switches:
            self.interleaving = False
        return False

    def series_last(self) -> list[int]:
        """Each live series' last number (about how many messages its publisher has sent,
        when the subscription matched from its start)."""
        return list(self._last)

    def series_starts(self) -> list[float | None]:
        """Each live series' start [s]: when its publisher sent its number 1, extrapolated at
        the rate its numbers rose between its first and last messages seen (None with fewer
        than two timed messages). Unlike the numbers themselves, these compare publishers of
        different rates (a 10 Hz node walking 4 s against a 100 Hz one walking 1 s)."""
        out: list[float | None] = []
        for first, last in zip(self._first_at, self._last_at):
            if first is None or last is None or last[0] <= first[0] or last[1] <= first[1]:
                out.append(None)
                continue
            period = (last[1] - first[1]) / (last[0] - first[0])
            out.append(last[1] - (last[0] - 1) * period)
        return out

    @property
    def live_series(self) -> int:
        """Series heard within the last ``window`` messages."""
        return len(self._last)
