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

:class:`FirstPublisherGate` goes one step further for the drivers' ``joint_commands``: it says,
for each message, whether it belongs to the publisher that was there first (the one the
driver already follows), so that a second publisher's commands can be dropped instead of
applied between the first's. Its series keep a stable identity across the episode: a number is
matched to the series whose own rate (from its numbers and send times) predicts it best, so
two publishers whose numbers cross (a 100 Hz newcomer overtaking a 10 Hz publisher's count) are
not swapped where :class:`PublisherSequences` (highest number below) would swap them.

Core module: no rclpy.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

__all__ = ['FOLLOWED_QUIET_MAX_S', 'FOLLOWED_QUIET_PERIODS', 'FOLLOWED_QUIET_S',
           'FOLLOWED_QUIET_UNKNOWN_S', 'MAX_NUMBER_EXCESS', 'START_MARGIN_S',
           'SEQUENCE_UNSUPPORTED',
           'FirstPublisherGate', 'GateSwitch', 'PublisherSequences', 'endpoint_names',
           'publication_sequence', 'source_time']

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


#: The followed publisher silent this long [s] (on the receiver's clock) while another one
#: speaks is gone (crashed, exited, killed): :class:`FirstPublisherGate` then follows the
#: remaining one. 0.5 s is 50 periods of the 100 Hz gait node (far above its jitter and a busy
#: executor's stalls, so a live first publisher is never taken for gone), it is the longest the
#: joints hold their last target when the followed gait node dies beside a second publisher, and
#: it is no longer than the gait node's ``startup_listen_s`` (0.5 s default): a respawned gait
#: node, whose first command comes at least that long after its process started, is followed
#: from its first command.
FOLLOWED_QUIET_S = 0.5
#: ... or this many of the followed publisher's own mean send periods, when that is longer (a
#: 1 Hz teleop followed first is not taken for gone between two of its messages)
FOLLOWED_QUIET_PERIODS = 5.0
#: ... for a publisher heard once (its rate unknown) [s]
FOLLOWED_QUIET_UNKNOWN_S = 2.0
#: ... and at most this, however slow its mean period reads [s]
FOLLOWED_QUIET_MAX_S = 5.0
#: Two publishers first heard within :data:`FOLLOWED_QUIET_S` of each other (both were there
#: before the receiver heard anything): the one whose series started more than this earlier
#: (:meth:`GateSeries.start`) is followed, else the one heard first (the gait node's
#: ``NEWCOMER_MARGIN_S``).
START_MARGIN_S = 0.02
#: A number more than this above what a series' own rate predicts (its last number, plus the
#: time since at its mean period; plus 1 before it has a rate) is another publisher's: a
#: publisher's numbers rise with its send times (a lossy link skips numbers and time alike;
#: a stalled sender sends fewer, not more), so only another, busier series jumps this far
MAX_NUMBER_EXCESS = 10.0


@dataclass
class GateSeries:
    """One publisher's series of numbers, as :class:`FirstPublisherGate` tracks it. Times:
    ``*_t`` the send times (the message info's ``source_timestamp``, or the arrival time when
    the middleware gives none), ``*_arrival`` the receiver's clock."""

    ident: int
    first_seq: int
    first_t: float
    last_seq: int
    last_t: float
    first_arrival: float
    last_arrival: float
    last_message: int
    messages: int = 1
    passed: int = 0
    dropped: int = 0
    #: the latest non-empty label its messages carried (a gait node's frame_id), for messages
    label: str = ''
    #: judged against the followed series by their starts (START_MARGIN_S)
    judged: bool = False

    def period(self) -> float | None:
        """Its mean send period [s] (None before two messages of rising number and time)."""
        if self.last_seq > self.first_seq and self.last_t > self.first_t:
            return (self.last_t - self.first_t) / (self.last_seq - self.first_seq)
        return None

    def start(self) -> float | None:
        """When it sent its number 1 [s], extrapolated at its mean period (as
        :meth:`PublisherSequences.series_starts`), or None."""
        p = self.period()
        return None if p is None else self.last_t - (self.last_seq - 1) * p


@dataclass(frozen=True)
class GateSwitch:
    """The gate follows another series from ``at_s``: ``reason`` 'quiet' (the followed one
    was silent ``silent_s``) or 'started earlier' (both first heard together, the new one's
    series started first); ``dropped``: the new one's messages dropped before."""

    old: int
    new: int
    reason: str
    silent_s: float
    dropped: int
    at_s: float


class FirstPublisherGate:
    """Which messages of a topic with several live publishers to apply: those of the publisher
    that was there first (module docs). :meth:`admit` says it for each message, from its
    publication sequence number, its send time and the receiver's clock (arguments: no clock
    is read here).

    - The followed series is the first one heard. A series first heard within ``quiet_s`` of
      it (both were there before the receiver heard anything) is followed instead if it
      started more than ``start_margin_s`` earlier (:meth:`GateSeries.start`), judged once
      both starts are known; meanwhile the first one heard is followed.
    - The other series' messages are dropped (``admit`` False).
    - When a message of another series comes and the followed one has been silent
      ``quiet_s`` (or ``quiet_periods`` of its own periods, if longer), it is gone: the
      remaining series heard first is followed (a respawned publisher, its numbers anew, is
      followed at once when the old one had been silent that long).
    - A message without a number (a middleware that gives none) passes: nothing can be told.

    A number is matched to the series, of those whose last number is below it and not more than
    ``max_excess`` above what its rate predicts (:data:`MAX_NUMBER_EXCESS`), whose own rate
    predicts it best (its numbers since its last message against the time since at its mean
    period; before a series has a rate, the gap in numbers), on a tie the one due longest; none:
    a new series. Two publishers whose counts cross keep their identity; two of the same rate,
    start and phase are not told apart (nothing tells them apart). Series not heard within the
    last ``window`` messages are forgotten, except the followed one."""

    def __init__(self, quiet_s: float = FOLLOWED_QUIET_S,
                 quiet_periods: float = FOLLOWED_QUIET_PERIODS,
                 start_margin_s: float = START_MARGIN_S,
                 max_excess: float = MAX_NUMBER_EXCESS, window: int = 1000,
                 max_series: int = 16) -> None:
        if not quiet_s > 0 or quiet_periods < 0 or start_margin_s < 0 or max_excess < 1 \
                or window < 2 or max_series < 2:
            raise ValueError('quiet_s > 0, quiet_periods >= 0, start_margin_s >= 0, '
                             'max_excess >= 1, window >= 2 and max_series >= 2')
        self.max_excess = float(max_excess)
        self.quiet_s = float(quiet_s)
        self.quiet_periods = float(quiet_periods)
        self.start_margin_s = float(start_margin_s)
        self.window = int(window)
        self.max_series = int(max_series)
        #: the followed series' ident (None before the first numbered message)
        self.followed: int | None = None
        #: numbered messages passed and dropped, and messages without a number (all passed)
        self.passed = 0
        self.dropped = 0
        self.unnumbered = 0
        self._series: list[GateSeries] = []
        self._next_ident = 1
        self._messages = 0
        self._switches: list[GateSwitch] = []

    # --- queries ---------------------------------------------------------------------------
    def series(self, ident: int | None = None) -> GateSeries | None:
        """The series ``ident`` (default: the followed one), None when unknown or forgotten."""
        ident = self.followed if ident is None else ident
        return next((s for s in self._series if s.ident == ident), None)

    def live_series(self) -> list[GateSeries]:
        """The series heard within the last ``window`` messages (and the followed one)."""
        return list(self._series)

    def take_switches(self) -> list[GateSwitch]:
        """The switches of the followed series since the last call (for the node's log)."""
        out, self._switches = self._switches, []
        return out

    # --- the decision ----------------------------------------------------------------------
    def admit(self, seq: int | None, t_s: float | None, now_s: float, label: str = '') -> bool:
        """One message: its sequence number (None: not numbered), its send time [s] (the
        message info's ``source_timestamp``, or None), the receiver's clock now [s] (a steady
        clock) and optionally a label for messages (its frame_id); True when it belongs to the
        followed series (apply it), False when another publisher sent it (drop it)."""
        if seq is None:
            self.unnumbered += 1
            return True
        now_s = float(now_s)
        t = float(t_s) if t_s is not None else now_s
        self._messages += 1
        s = self._match(seq, t)
        if s is None:
            s = GateSeries(self._next_ident, seq, t, seq, t, now_s, now_s, self._messages)
            self._next_ident += 1
            self._series.append(s)
        else:
            s.last_seq, s.last_t = seq, t
            s.last_arrival, s.last_message = now_s, self._messages
            s.messages += 1
        if label:
            s.label = label
        self._forget(s)
        self._choose(s, now_s)
        if s.ident == self.followed:
            s.passed += 1
            self.passed += 1
            return True
        s.dropped += 1
        self.dropped += 1
        return False

    def _match(self, seq: int, t: float) -> GateSeries | None:
        best: tuple[float, float, int] | None = None
        found = None
        for i, s in enumerate(self._series):
            if s.last_seq >= seq:
                continue
            period = s.period()
            gap = seq - s.last_seq
            expected = (t - s.last_t) / period if period is not None else 1.0
            if gap - expected > self.max_excess:
                continue                  # far more numbers than its rate sends: another's
            cost = abs(gap - expected)
            # on a tie the one due longest; between series heard once (no rate: every gap of
            # 1 ties) the one heard last: a 100 Hz newcomer's second number was matched to a
            # 1 Hz teleop heard once 0.6 s before, which then lost the joints (review J5)
            key = (cost, s.last_t if period is not None else -s.last_t, i)
            if best is None or key < best:
                best, found = key, s
        return found

    def _forget(self, current: GateSeries) -> None:
        keep = [s for s in self._series
                if s is current or s.ident == self.followed
                or self._messages - s.last_message <= self.window]
        while len(keep) > self.max_series:
            old = min((s for s in keep if s is not current and s.ident != self.followed),
                      key=lambda s: s.last_message)
            keep.remove(old)
        self._series = keep

    def _quiet_s(self, s: GateSeries) -> float:
        period = s.period()
        if period is None:
            # heard once: its rate unknown, a slow teleop is not gone after quiet_s (an
            # outside review: a 1 Hz publisher heard once lost the joints to a newcomer)
            return max(self.quiet_s, FOLLOWED_QUIET_UNKNOWN_S)
        # at most FOLLOWED_QUIET_MAX_S: a mean period inflated by a sender's clock step
        # (NTP at boot) made it 2,160 s (review J5)
        return max(self.quiet_s, min(self.quiet_periods * period, FOLLOWED_QUIET_MAX_S))

    def _choose(self, s: GateSeries, now_s: float) -> None:
        followed = self.series()
        if followed is None:              # the first numbered message (or nothing followed)
            self.followed = s.ident
            return
        if s is followed:
            return
        if not s.judged:
            if abs(s.first_arrival - followed.first_arrival) >= self.quiet_s:
                s.judged = True           # it came after: the followed one was there first
            else:
                mine, its = followed.start(), s.start()
                if mine is not None and its is not None:
                    s.judged = True
                    if its < mine - self.start_margin_s:
                        self._switch(followed, s, 'started earlier', 0.0, now_s)
                        return
        silent = now_s - followed.last_arrival
        if silent >= self._quiet_s(followed):
            # gone: the remaining series heard first (s itself was heard just now)
            live = [x for x in self._series if x is not followed
                    and now_s - x.last_arrival < self._quiet_s(x)]
            new = min(live, key=lambda x: (x.first_arrival, x.ident))
            self._switch(followed, new, 'quiet', silent, now_s)

    def _switch(self, old: GateSeries, new: GateSeries, reason: str, silent_s: float,
                now_s: float) -> None:
        self.followed = new.ident
        new.judged = True
        self._switches.append(GateSwitch(old.ident, new.ident, reason, silent_s, new.dropped,
                                         now_s))
