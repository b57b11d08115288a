"""Topics stamped on another clock: found from the bag's receive times, re-stamped, noted.

A sensor whose driver stamps messages with its own clock -- a micro-ROS or rosserial board
without time synchronisation (seconds since boot), a motion-capture bridge passing the
capture system's time -- gives header stamps that do not overlap the other topics'. The
analysis matches streams by header stamp, so such a bag had no window at all ("no whole gait
cycle with battery samples around it") or was refused.

The recorder's receive times are on one clock for every topic. :class:`ClockCheck` takes, per
topic, the median of ``header stamp - receive time`` (the stamp clock's offset plus the
transport latency, milliseconds). Topics whose medians agree within ``ANOTHER_CLOCK_S`` share
a clock; the largest such group is the reference (on a tie, the group nearest the receive
clock: a bag re-recorded from a replay has every topic far from it, and then nothing is
changed). Every other topic is re-stamped ``t + (median_ref - median_topic)``: its own stamps'
spacing is kept and it is placed on the reference clock up to the difference of the two
latencies (milliseconds; the SLIP analysis estimates the motion capture's offset from the data
anyway). Offsets below ``ANOTHER_CLOCK_S`` (latency, NTP error) are left alone.

Core module: no rclpy.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np

__all__ = ['ANOTHER_CLOCK_S', 'FOREIGN_CLOCK_S', 'ClockCheck', 'LiveClockWatch', 'StreamClock',
           'StreamLoss', 'count_milestone', 'foreign_clock_note', 'shift_rows']

#: a live sample stamped this far [s] from every other stream's newest stamp is held back
#: (:class:`StreamClock`): a second publisher on another clock, or the whole graph's time moved
FOREIGN_CLOCK_S = 3600.0
#: far samples (and samples near the others in between) that tell the two cases apart
FOREIGN_EVIDENCE = 3

#: stamp-minus-receive medians further apart than this [s] are different clocks
ANOTHER_CLOCK_S = 1.0
#: samples per topic kept for the medians (evenly thinned beyond)
_MAX_SAMPLES = 4096


class ClockCheck:
    """Per-topic stamp clocks from a bag's receive times (module docs)."""

    def __init__(self, threshold_s: float = ANOTHER_CLOCK_S) -> None:
        self.threshold_s = float(threshold_s)
        self._d: dict[str, list[float]] = {}
        self._n: dict[str, int] = {}
        self._stride: dict[str, int] = {}

    def observe(self, topic: str, stamp_s: float, receive_s: float) -> None:
        """One message's header stamp and the bag's receive time [s]; zero stamps (replaced by
        the receive time) are not evidence and should not be passed.

        Every ``stride``-th message is kept; when ``2 * _MAX_SAMPLES`` are kept, every other
        one is dropped and the stride doubles, so the kept samples stay evenly spread over the
        whole bag. (A ring buffer kept only the last ~8k messages: a late last minute of a
        10-minute bag moved the whole stream by 3 s.)"""
        n = self._n.get(topic, 0)
        self._n[topic] = n + 1
        stride = self._stride.setdefault(topic, 1)
        if n % stride:
            return
        d = self._d.setdefault(topic, [])
        d.append(stamp_s - receive_s)
        if len(d) >= 2 * _MAX_SAMPLES:
            del d[1::2]
            self._stride[topic] = 2 * stride

    def medians(self) -> dict[str, float]:
        """Median ``stamp - receive`` per topic [s]."""
        return {t: float(np.median(d)) for t, d in self._d.items() if d}

    def shifts(self) -> tuple[dict[str, float], list[str]]:
        """``{topic: seconds to add to its stamps}`` for topics on another clock, and notes."""
        med = self.medians()
        if len(med) < 2:
            return {}, []
        groups: list[list[str]] = []
        for topic in sorted(med, key=med.get):  # type: ignore[arg-type]
            if groups and med[topic] - med[groups[-1][0]] <= self.threshold_s:
                groups[-1].append(topic)
            else:
                groups.append([topic])
        if len(groups) == 1:
            return {}, []
        ref = max(groups, key=lambda g: (len(g), -min(abs(med[t]) for t in g)))
        ref_med = float(np.median([med[t] for t in ref]))
        out: dict[str, float] = {}
        notes: list[str] = []
        for g in groups:
            if g is ref:
                continue
            for topic in g:
                out[topic] = ref_med - med[topic]
                notes.append(
                    f'{topic} stamped on another clock (header stamps {med[topic]:+.3f} s from '
                    f'the bag\'s receive times, against {ref_med:+.3f} s for '
                    f'{", ".join(sorted(ref))}): moved by {out[topic]:+.3f} s onto their clock '
                    '(its own stamp spacing kept)')
        return out, notes


def shift_rows(rows: Iterable[Any], dt: float) -> list[Any]:
    """Tuples whose first item is a time [s], moved by ``dt``."""
    return [(r[0] + dt, *r[1:]) for r in rows]


class LiveClockWatch:
    """A live node's check for a topic stamped on another clock than the others: the stamps
    against the node clock on arrival, judged after 200 and 2000 messages; returns the error
    messages to log, once. Live, such a topic cannot be re-stamped reliably (the node cannot
    know which messages came before the judgement), so it is reported instead."""

    def __init__(self) -> None:
        self._check: ClockCheck | None = ClockCheck()
        self._messages = 0

    def observe(self, topic: str, stamp_s: float, now_s: float) -> list[str]:
        """One message's header stamp and its arrival on the node clock [s] (zero stamps,
        which nodes replace by the arrival time, are skipped)."""
        if self._check is None or stamp_s == 0.0:
            return []
        self._check.observe(topic, stamp_s, now_s)
        self._messages += 1
        if self._messages not in (200, 2000):
            return []
        _, notes = self._check.shifts()
        if not notes:
            return []
        self._check = None
        return [note.split(': moved')[0].replace("the bag's receive times", 'the node clock') +
                ": its messages cannot be matched with the others' live; give the publisher a "
                "synchronised clock (offline, hexapod-analyze re-stamps it from the bag's "
                'receive times)' for note in notes]


def foreign_clock_note(stream: str, t: float) -> str:
    """The warning for ``stream`` found carrying two clocks (:class:`StreamClock`)."""
    return (f'{stream} carries two clocks: samples stamped {t:.3f} s, more than '
            f'{FOREIGN_CLOCK_S:g} s from the other topics\', between samples on theirs (a second '
            'publisher: a driver on the wall clock beside a replay or a simulation, or another '
            'node on this ROS domain?): its samples far from the other topics are dropped')


class StreamClock:
    """Per-stream stamp bookkeeping of a live consumer that must survive time going backwards
    (a looped bag, a reset simulation clock): the energy monitor's accumulator and the online
    SLIP share it.

    :meth:`observe` records one sample's stamp. A stamp more than ``jump_s`` before the
    stream's last one is a backward jump: the clock starts again from it and calls
    ``on_jump(stream, previous stamp, new stamp)`` (the caller restarts its own state), and
    the other streams' samples still stamped on the old time are dropped (False, counted in
    ``stale_samples``) until their own stamps jump back or the new time catches up. Stamps a
    little out of order are kept.

    Two publishers of one topic on different clocks (a driver on the wall clock beside a
    replay or a simulation; another session's node on the same ROS domain): a sample more than
    :data:`FOREIGN_CLOCK_S` from every other stream's newest stamp is dropped and held as
    evidence. When the stream goes on with samples near the others between such samples
    (:data:`FOREIGN_EVIDENCE` of each), it carries two clocks: ``on_foreign(stream, t)`` is
    called once and from then on its samples far from the others are dropped (counted in
    ``foreign_samples``). When :data:`FOREIGN_EVIDENCE` far samples come with none near, the
    time itself moved (a simulation clock reset, a long loop): the jump is taken as above.
    Before, every alternation restarted the consumer: no window at all, and one warning per
    message (an outside review).
    """

    def __init__(self, jump_s: float,
                 on_jump: Callable[[str, float, float], None] | None = None,
                 on_foreign: Callable[[str, float], None] | None = None) -> None:
        self.jump_s = float(jump_s)
        self.on_jump = on_jump
        self.on_foreign = on_foreign
        #: streams found carrying two clocks, and their samples dropped as the foreign one's
        self.mixed: set[str] = set()
        self.foreign_samples = 0
        # per stream: [far samples, samples near the others since the first far one]
        self._far: dict[str, list[int]] = {}
        #: last (largest) stamp per stream since the last jump [s]
        self.last: dict[str, float] = {}
        #: newest and first stamp of any stream since the last jump [s]
        self.newest: float | None = None
        self.first: float | None = None
        #: samples dropped as stamped before a jump but arriving after it
        self.stale_samples = 0
        self._stale: dict[str, float] = {}

    def _foreign(self, stream: str, t: float) -> bool:
        """Whether to drop ``t`` as stamped on another clock than the other streams' (see the
        class doc)."""
        ref = max((v for k, v in self.last.items() if k != stream), default=None)
        if ref is None:
            return False
        far = abs(t - ref) > FOREIGN_CLOCK_S
        state = self._far.get(stream)
        if not far:
            if state is not None:
                state[1] += 1
            return False
        if stream in self.mixed:
            self.foreign_samples += 1
            return True
        if state is None:
            state = self._far[stream] = [0, 0]
        state[0] += 1
        if state[1] >= FOREIGN_EVIDENCE and state[0] >= FOREIGN_EVIDENCE:
            self.mixed.add(stream)
            if self.on_foreign is not None:
                self.on_foreign(stream, t)
        elif state[0] >= FOREIGN_EVIDENCE and state[1] == 0:
            del self._far[stream]     # the time moved: take it
            return False
        self.foreign_samples += 1
        return True

    def observe(self, stream: str, t: float) -> bool:
        """Record ``t`` on ``stream``; False: drop the sample (stamped before a jump, or on
        another clock than the other streams')."""
        if self._foreign(stream, t):
            return False
        last = self.last.get(stream)
        mark = self._stale.get(stream)
        if mark is not None:
            if self.newest is not None and self.newest >= mark:
                del self._stale[stream]   # the new time has caught up: nothing stale left
            elif t >= mark - self.jump_s:
                self.stale_samples += 1
                return False
            else:
                del self._stale[stream]   # this stream has jumped too
                last = None
        jumped = None
        if last is not None and t < last - self.jump_s:
            # streams whose last stamp lies ahead of the new time: their samples still in
            # flight from before the jump are dropped until their own stamps jump back
            self._stale = {k: v for k, v in self.last.items()
                           if k != stream and v > t + self.jump_s}
            self.last, self.newest, self.first = {}, None, None
            self._far = {}
            jumped, last = last, None
        self.last[stream] = t if last is None else max(last, t)
        if self.first is None:
            self.first = t
        if self.newest is None or t > self.newest:
            self.newest = t
        if jumped is not None and self.on_jump is not None:
            self.on_jump(stream, jumped, t)
        return True


#: a stamp gap this many periods long counts missing messages (jitter stays below it)
LOSS_GAP_PERIODS = 1.5
#: intervals the period is the median of
_LOSS_INTERVALS = 64
#: share of those intervals within 25 % of the period for a stream to count as periodic
_LOSS_REGULAR = 0.8
#: a gap longer than this [s] (and 50 periods) is a pause or a new run, not a loss
_LOSS_PAUSE_S = 2.0


class StreamLoss:
    """Messages missing from periodic live streams, counted from their stamp gaps.

    A subscriber that falls behind its input loses the oldest queued messages without a word
    (the DDS history is overwritten: a review drove ``energy_monitor`` at 2 kHz and lost 6 % of
    the joint states, unannounced); so does a lossy link. Per stream (a topic, or one name
    group of a joint-state topic split over several messages): the period is the median of the
    last 64 positive stamp intervals (gaps included, so a rate that changes is learnt again).
    An interval longer than :data:`LOSS_GAP_PERIODS` periods holds ``round(interval /
    period) - 1`` missing messages, counted when the next interval is a period again (a loss
    within a steady rate) and dropped otherwise (the rate changed). Nothing is counted on a
    stream whose intervals are not periodic (fewer than 80 % within 25 % of the period, or a
    mean interval over 1.5 periods: a driver stamping bursts of samples read together, a
    stream losing a third of its messages), before 16 intervals are known, across
    a pause of over 2 s and 50 periods (a new run, a paused bag: the stream starts again), or
    on repeated, out-of-order or backward-jumping stamps. Stamps alone cannot tell a message
    lost from one never sent: a driver or simulator whose timer runs late on a loaded machine
    and publishes one sample for two periods counts too (the demo's simulated robot on two
    busy cores: 3-5 % of its periods). Losses right next to each other can be missed (the
    first gap is then dropped as a rate change); a gap is counted one message late.
    """

    def __init__(self, gap_periods: float = LOSS_GAP_PERIODS) -> None:
        self.gap_periods = float(gap_periods)
        #: messages counted missing, per stream
        self.missing: dict[Any, int] = {}
        #: messages seen, per stream
        self.seen: dict[Any, int] = {}
        self._last: dict[Any, float] = {}
        self._dt: dict[Any, list[float]] = {}
        self._period: dict[Any, float] = {}
        self._regular: dict[Any, bool] = {}
        self._fresh: dict[Any, int] = {}
        self._pending: dict[Any, int] = {}
        self._logged: dict[str, int] = {}

    def _restart(self, stream: Any, t_s: float) -> None:
        self._last[stream] = t_s
        self._dt[stream] = []
        self._period.pop(stream, None)
        self._regular[stream] = False
        self._fresh[stream] = 0
        self._pending[stream] = 0

    def observe(self, stream: Any, t_s: float) -> int:
        """One message of ``stream`` stamped ``t_s`` [s]; returns the messages newly counted
        missing (0 mostly)."""
        self.seen[stream] = self.seen.get(stream, 0) + 1
        last = self._last.get(stream)
        if last is None or t_s < last - 1.0:       # first, or time went back: start again
            self._restart(stream, t_s)
            return 0
        dt = t_s - last
        if dt <= 0.0:
            return 0
        period = self._period.get(stream, 0.0)
        if period > 0 and dt > _LOSS_PAUSE_S and dt > 50.0 * period:
            self._restart(stream, t_s)             # a pause or a new run
            return 0
        self._last[stream] = t_s
        lost = 0
        pending = self._pending.get(stream, 0)
        if period > 0 and self._regular.get(stream, False):
            ratio = dt / period
            if pending and 0.5 < ratio < self.gap_periods:
                lost = pending                     # the rate held: those were lost
                self.missing[stream] = self.missing.get(stream, 0) + lost
            self._pending[stream] = int(round(ratio)) - 1 if ratio > self.gap_periods else 0
        hist = self._dt[stream]
        hist.append(dt)
        if len(hist) > _LOSS_INTERVALS:
            del hist[0]
        n = self._fresh[stream] = self._fresh.get(stream, 0) + 1
        if n >= 16:                                 # the period refreshed every 16 intervals
            self._fresh[stream] = 0
            h = np.asarray(hist)
            med = float(np.median(h))
            if period > 0 and abs(med / period - 1.0) > 0.25:
                self._pending[stream] = 0          # the rate changed: judge no gap across it
            self._period[stream] = med
            # periodic: most intervals near the median, and no bursts (bursts of samples read
            # together put the median far below the mean interval)
            self._regular[stream] = bool(
                med > 0 and np.mean(np.abs(h / med - 1.0) <= 0.25) >= _LOSS_REGULAR
                and float(np.mean(h)) <= 1.5 * med)
        return lost

    def total(self, topic: str | None = None) -> int:
        """Messages missing in all, or of the streams ``(topic, ...)`` / ``topic``."""
        return sum(n for k, n in self.missing.items() if topic is None or _topic(k) == topic)

    def observe_topic(self, topic: str, stream: Any, t_s: float) -> str | None:
        """:meth:`observe` for stream ``(topic, stream)``; returns a line to log when the
        topic's missing messages reach 1, 10, 100, 1000, then every 10,000 (else None)."""
        if not self.observe((topic, stream), t_s):
            return None
        missing = self.total(topic)
        before = self._logged.get(topic, 0)
        self._logged[topic] = missing
        if _log_level(missing) <= _log_level(before):
            return None
        seen = sum(n for k, n in self.seen.items() if _topic(k) == topic)
        share = 100.0 * missing / max(missing + seen, 1)
        period = self._period.get((topic, stream), math.nan)
        return (f'{topic}: {missing} messages missing so far ({share:.1f} % of its '
                f'{1e3 * period:.3g} ms periods, from gaps in the stamps): not sent (a driver '
                'or simulator late on its timer), lost on the way, or dropped by this node '
                'falling behind its input; values over the gaps are interpolated')


def _topic(key: Any) -> Any:
    return key[0] if isinstance(key, tuple) else key


def count_milestone(n: int) -> bool:
    """Whether the ``n``-th occurrence of something is logged: the 1st, 10th, 100th and
    1000th, then every 10,000th (as :class:`StreamLoss` logs missing messages)."""
    return n > 0 and _log_level(n) != _log_level(n - 1)


def _log_level(n: int) -> int:
    """0 for none; one more at 1, 10, 100 and 1000 missing, then every 10,000."""
    if n <= 0:
        return 0
    return len(str(n)) if n < 10000 else 4 + n // 10000
