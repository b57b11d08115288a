"""Samples that repeat their stream's previous header stamp with new values (numpy only).

A driver that stamps each message with the time of its last bus read, and publishes anyway
when a read is skipped, sends the previous stamp again with new values. The SLIP reader took
such samples as they were: full frames kept two different frames at one time (an outside
review's EduBot bag with every 20th stamp repeated: one stance's stiffness +87 %, the mean
+3.6 %, no note), and joint states split over several messages kept one of the two silently.

:class:`RepeatedStamps` watches each stream (a topic; for joint states each name set, for
batteries each source) in arrival order. A sample whose header stamp equals one of its
stream's last :data:`RECENT_STAMPS` stamps while its values differ from that sample's
(:func:`same_values`) is a repeat; exact repeats (the same message recorded twice) are left to
the duplicate handling that already exists, and samples received out of stamp order (a stamp
before the previous one but its own) are not touched: they are used in stamp order. (An
outside review: a stamp before the previous one had counted as a repeat, so a bag with 20 %
of its joint states received 15 ms late had 96 re-stamped from their receive times, a
spurious pitch zero and the median stiffness 3.4 % off.) After the bag is read,
:meth:`RepeatedStamps.resolve` re-stamps every repeat from its receive time shifted by the
stream's median ``stamp - receive`` offset when that offset is well defined -- at least
:data:`MIN_SAMPLES` samples whose spread (1.4826 times the median absolute deviation) is at
most :data:`MAX_SPREAD_STEPS` of the stream's median stamp step, and a new stamp strictly
between the stream's previous stamp and its next one -- and drops it otherwise; either way with
a note giving the count.

Core module: no rclpy.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from typing import Any

import numpy as np

from hexapod_common.series import robust_sigma

__all__ = ['LIVE_WINDOW', 'LiveRepeatedStamps', 'MAX_SPREAD_STEPS', 'MIN_SAMPLES', 'RECENT_STAMPS',
           'RepeatedStamps', 'StampMemory', 'repeat_note', 'same_values']

#: samples of a stream needed before its median stamp - receive offset re-stamps anything
MIN_SAMPLES = 10
#: the offsets' robust spread may be at most this share of the stream's median stamp step
MAX_SPREAD_STEPS = 0.25
#: offsets and steps kept per stream for the medians (evenly thinned beyond, as ClockCheck)
_MAX_KEPT = 4096
#: raw stamps per stream a repeat is looked for among (a stale stamp re-sent after newer ones)
RECENT_STAMPS = 16


def repeat_note(n: int, topic: str, how: str) -> str:
    """The note for ``n`` repeats of ``topic``; ``how`` what was done with them."""
    return f'{n} {topic} message(s) repeat the previous stamp with new values: {how}'


def _equal(x: Any, y: Any) -> bool:
    if isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        x, y = np.asarray(x), np.asarray(y)
        if x.shape != y.shape:
            return False
        if x.dtype.kind in 'fc' and y.dtype.kind in 'fc':
            return bool(np.array_equal(x, y, equal_nan=True))
        return bool(np.array_equal(x, y))
    if isinstance(x, float) and isinstance(y, float) and math.isnan(x) and math.isnan(y):
        return True
    return bool(x == y)


def same_values(a: Any, b: Any) -> bool:
    """Whether two samples (dataclasses of one type, or plain objects) carry the same values,
    their stamps ``t_s`` aside; samples with ``names`` compare joint by joint whatever the
    name order."""
    if type(a) is not type(b):
        return False
    names_a, names_b = getattr(a, 'names', None), getattr(b, 'names', None)
    idx = None
    if names_a is not None and tuple(names_a) != tuple(names_b):
        if len(names_a) != len(names_b) or set(names_a) != set(names_b):
            return False
        idx = [list(names_b).index(n) for n in names_a]
    fields = ([f.name for f in dataclasses.fields(a)] if dataclasses.is_dataclass(a)
              else list(vars(a)))
    for name in fields:
        if name in ('t_s', 'names'):
            continue
        x, y = getattr(a, name), getattr(b, name, None)
        if idx is not None and isinstance(y, np.ndarray) and y.ndim == 1 and \
                y.size == len(idx):
            y = y[idx]
        if not _equal(x, y):
            return False
    return True


class StampMemory:
    """A stream's latest stamp and its last :data:`RECENT_STAMPS` stamps with their samples
    (arrival order): what tells a repeat from a sample received out of stamp order."""

    __slots__ = ('last_t', 'last', 'recent')

    def __init__(self) -> None:
        self.last_t = -math.inf     # latest raw stamp seen
        self.last: Any = None       # the sample at it
        self.recent: dict[float, Any] = {}   # the last RECENT_STAMPS raw stamps: sample

    def is_repeat(self, t: float, sample: Any) -> bool:
        """Whether ``sample`` repeats one of the stream's recent stamps with new values."""
        if t > self.last_t:
            return False
        seen = self.recent.get(t)
        if seen is None:
            # not a recent stamp: received out of order (its own stamp), or older than the
            # recent ones, which a repeat of the last read's stamp never is
            return t == self.last_t and not same_values(sample, self.last)
        return not same_values(sample, seen)

    def remember(self, t: float, sample: Any) -> bool:
        """Keep a sample that is no repeat; True when it came out of stamp order."""
        self.recent[t] = sample
        if len(self.recent) > RECENT_STAMPS:
            del self.recent[next(iter(self.recent))]
        if t < self.last_t:
            return True
        self.last_t, self.last = t, sample
        return False

    def check(self, t: float, sample: Any) -> bool:
        """One sample in arrival order: True when it is a repeat (not remembered)."""
        if self.is_repeat(t, sample):
            return True
        self.remember(t, sample)
        return False


class _Stream(StampMemory):
    """One stream's bookkeeping (arrival order)."""

    __slots__ = ('kept_t', 'n', 'stride', 'offsets', 'steps', 'repeats', 'pending')

    def __init__(self) -> None:
        super().__init__()
        self.kept_t = -math.inf     # raw stamp of the previous sample that is no repeat
        self.n = 0                  # samples that are not repeats
        self.stride = 1
        self.offsets: list[float] = []   # stamp - receive [s], thinned
        self.steps: list[float] = []     # stamp - previous raw stamp [s], thinned
        # [row, receive_s, stamp of the previous sample that is no repeat, that of the next
        # one (inf until it comes)]
        self.repeats: list[list[float]] = []
        self.pending: list[list[float]] = []


class RepeatedStamps:
    """Repeated stamps of a bag reader's streams (module docs).

    Feed every stamped sample in arrival order with :meth:`observe` (samples whose zero stamp
    was replaced by the receive time are not evidence: leave them out), then call
    :meth:`resolve` once per topic with the sample store the rows index.
    """

    def __init__(self) -> None:
        self._streams: dict[Any, _Stream] = {}
        self._topics: dict[str, list[_Stream]] = {}

    def observe(self, topic: str, group: Any, row: int, sample: Any, receive_s: float) -> bool:
        """One sample of ``topic`` (``group`` tells streams of one topic apart: a joint name
        tuple, whatever its order, a battery source, or None) stored at ``row``; True when it
        repeats its stream's previous stamp with new values."""
        st = self._streams.get((topic, group))
        if st is None:   # one stream per name set, whatever the name order
            canon = (topic, frozenset(group) if isinstance(group, tuple) else group)
            st = self._streams.get(canon)
            if st is None:
                st = self._streams[canon] = _Stream()
                self._topics.setdefault(topic, []).append(st)
            self._streams[(topic, group)] = st
        t = sample.t_s
        if st.is_repeat(t, sample):
            entry = [float(row), float(receive_s), st.kept_t, math.inf]
            st.repeats.append(entry)
            st.pending.append(entry)
            st.last_t, st.last = max(t, st.last_t), sample
            return True
        late = t < st.last_t    # received out of stamp order: its own stamp, kept as it is
        if st.pending and not late:
            for entry in st.pending:
                entry[3] = t
            st.pending.clear()
        if st.n % st.stride == 0:
            st.offsets.append(t - receive_s)
            st.steps.append(math.nan if late else t - st.last_t)
            if len(st.offsets) >= 2 * _MAX_KEPT:
                del st.offsets[1::2], st.steps[1::2]
                st.stride *= 2
        st.n += 1
        st.remember(t, sample)
        if not late:
            st.kept_t = t
        return False

    def count(self, topic: str) -> int:
        """Repeats seen on ``topic``."""
        return sum(len(st.repeats) for st in self._topics.get(topic, ()))

    def resolve(self, topic: str, samples: Any,
                rebuild: Callable[[Any, set[int], dict[int, float]], Any]
                ) -> tuple[Any, list[str]]:
        """Re-stamp or drop ``topic``'s repeats in ``samples``; returns the samples and the
        notes. The stamps are written into ``samples.column('t_s')`` when that is a writable
        view of them (``SampleColumns``) and nothing is dropped; otherwise the samples are
        ``rebuild(samples, rows to drop, {row: new stamp})``."""
        streams = [st for st in self._topics.get(topic, ()) if st.repeats]
        if not streams:
            return samples, []
        restamp: dict[int, float] = {}
        offsets: list[float] = []
        drop: set[int] = set()
        why: set[str] = set()
        for st in streams:
            offset, reason = _offset(st)
            chain, prev = math.nan, -math.inf
            for row, receive_s, lo, nxt in st.repeats:
                k = int(row)
                if lo != chain:         # repeats in a row: each after the one before
                    chain, prev = lo, -math.inf
                if offset is not None:
                    new = receive_s + offset
                    if max(lo, prev) < new < nxt:
                        restamp[k] = prev = new
                        offsets.append(offset)
                        continue
                    why.add('a receive time outside the neighbouring stamps')
                else:
                    why.add(reason)
                drop.add(k)
        t = samples.column('t_s') if not drop else None
        if isinstance(t, np.ndarray) and t.flags.writeable:
            rows = np.fromiter(restamp, dtype=np.int64, count=len(restamp))
            t[rows] = np.fromiter(restamp.values(), dtype=float, count=len(restamp))
        else:
            samples = rebuild(samples, drop, restamp)
        del t   # release the view of the column
        notes = []
        if restamp:
            notes.append(repeat_note(
                len(restamp), topic,
                're-stamped from their receive times (shifted by the stream\'s median '
                f'stamp - receive offset, {1e3 * float(np.median(offsets)):+.2f} ms)'))
        if drop:
            notes.append(repeat_note(len(drop), topic, f'dropped ({"; ".join(sorted(why))})'))
        return samples, notes


def _offset(st: _Stream) -> tuple[float | None, str]:
    """The stream's median stamp - receive offset [s] when well defined, else why not."""
    if len(st.offsets) < MIN_SAMPLES:
        return None, f'fewer than {MIN_SAMPLES} samples to place them by receive time'
    off = np.asarray(st.offsets)
    med = float(np.median(off))
    steps = np.asarray(st.steps)
    steps = steps[np.isfinite(steps) & (steps > 0)]
    if not steps.size:
        return None, 'no stamp step to judge the receive times by'
    step = float(np.median(steps))
    spread = robust_sigma(off, med)
    if spread > MAX_SPREAD_STEPS * step:
        return None, (f'receive times too irregular to place them: stamp - receive spread '
                      f'{1e3 * spread:.2f} ms against a {1e3 * step:.2f} ms stamp step')
    return med, ''



#: samples per stream the live re-stamping keeps for its medians
LIVE_WINDOW = 400


class LiveRepeatedStamps:
    """:class:`RepeatedStamps` for a live node: each sample is judged as it arrives.

    :meth:`stamp` returns the stamp to use: the sample's own, or for a repeat its arrival time
    (node clock) shifted by the stream's median ``stamp - arrival`` offset over the last
    :data:`LIVE_WINDOW` samples when that offset is well defined (as offline, and the new
    stamp after the stream's previous one), else None (drop it). ``counts`` holds per topic
    how many were re-stamped and dropped.
    """

    def __init__(self) -> None:
        self._streams: dict[Any, _Stream] = {}
        self.counts: dict[str, list[int]] = {}

    def stamp(self, topic: str, group: Any, sample: Any, arrival_s: float) -> float | None:
        key = (topic, frozenset(group) if isinstance(group, tuple) else group)
        st = self._streams.get(key)
        if st is None:
            st = self._streams[key] = _Stream()
        t = sample.t_s
        if st.is_repeat(t, sample):
            st.last = sample
            offset, _ = _offset(st)
            n = self.counts.setdefault(topic, [0, 0])
            new = arrival_s + offset if offset is not None else math.nan
            if offset is not None and new > st.kept_t:
                st.kept_t = new
                n[0] += 1
                return new
            n[1] += 1
            return None
        late = t < st.last_t    # received out of stamp order: its own stamp
        st.offsets.append(t - arrival_s)
        st.steps.append(math.nan if late else t - st.last_t)
        if len(st.offsets) > LIVE_WINDOW:
            del st.offsets[0], st.steps[0]
        st.remember(t, sample)
        if not late:
            st.kept_t = t
        return t
