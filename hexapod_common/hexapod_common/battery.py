"""Several batteries on one ``/battery_state`` topic: their input powers summed.

A robot with a servo pack and a logic pack, or a power board reporting each rail, may publish
every pack's ``sensor_msgs/BatteryState`` on the same topic, told apart by
``header.frame_id`` (else ``location``, else ``serial_number``:
:attr:`~hexapod_common.conversions.BatterySample.source`). Interleaved on one stream their
samples would be treated as one battery's, and any average over time gives the MEAN of the
packs' powers, not their sum: a robot drawing 30 W from its servo pack and 5 W from its logic
pack would read 17.5 W.

:class:`BatteryCombiner` turns such a stream back into one battery's: while one source has
been seen, samples pass unchanged (a one-battery robot is untouched, bit for bit). With two or
more, every sample gives one combined sample at its time, whose power ``V * I`` is the sum over
the sources of each one's latest ``V_k * I_k`` (voltage: the reference source's, the first
seen; current: the summed power over that voltage, in the messages' own sign convention, so
the current-sign detection downstream sees it as one pack's). A source silent for more than
``max(stale_s, 5 x its own sample interval)`` leaves the sum, noted; before its second report
its interval is unknown, and it stays in the sum for up to :data:`FIRST_REPORT_STALE_S` (a
monitor reporting every 3 s is not cut from 2 s to its second report). Offline readers pass every
source found in the bag (``expected``), so no sum is formed before each has reported once;
the live node learns them as they come (noted when one appears late).

Two sources that report the same voltage and power (within 0.5 % and 5 % over their first 50
samples) are more likely one pack published twice (a driver and a power board): noted, with
the way to keep one (``select``: only that source's samples pass; CLI ``--battery-source``,
node parameter ``battery_source``).

Core module: no rclpy.
"""

from __future__ import annotations

import dataclasses
import os
from collections.abc import Iterable, Sequence

import numpy as np

from .conversions import BatterySample

__all__ = ['AbsentBatteryFilter', 'BATTERY_SOURCE_ENV', 'MILLI_THRESHOLD', 'milli_factors',
           'BatteryCombiner', 'combine_battery_samples', 'FIRST_REPORT_STALE_S', 'STALE_S',
           'prepare_battery_samples', 'selected_source', 'unmeasured_power']

#: a source silent for longer than this (or 5 of its own sample intervals, if longer) [s]
#: leaves the sum
STALE_S = 2.0
#: a source seen once (its interval unknown) stays in the sum this long [s] waiting for its
#: second report: monitors reporting as slowly as every 10 s are summed without a hole
FIRST_REPORT_STALE_S = 10.0
#: environment variable naming the one battery to keep (``hexapod-analyze --battery-source``,
#: inherited by its ``--jobs`` workers)
BATTERY_SOURCE_ENV = 'HEXAPOD_BATTERY_SOURCE'
#: samples per source compared for the "same pack twice" note
SAME_PACK_SAMPLES = 50


def _label(source: str) -> str:
    return repr(source) if source else "'' (no frame_id)"


@dataclasses.dataclass
class _Source:
    t_s: float
    voltage_v: float
    current_a: float
    interval_s: float = 0.0
    stale: bool = False
    first: list[tuple[float, float]] = dataclasses.field(default_factory=list)


class BatteryCombiner:
    """Sum of the input powers of the batteries on one topic (module docs).

    Parameters
    ----------
    expected : sequence of str, optional
        Every source the stream will carry (offline: found in the bag). With two or more, no
        sample is emitted before each has reported once.
    select : str, optional
        Keep only this source's samples (the others are dropped, counted in ``notes``; noted
        when it is not among the first 20). :func:`combine_battery_samples` keeps a stream
        of one source whatever its name.
    stale_s : float
        A source silent longer than ``max(stale_s, 5 x its interval)`` leaves the sum
        (``max(stale_s, FIRST_REPORT_STALE_S)`` before its second report).
    """

    def __init__(self, expected: Sequence[str] | None = None, select: str | None = None,
                 stale_s: float = STALE_S) -> None:
        if not stale_s > 0:
            raise ValueError(f'stale_s must be > 0, got {stale_s}')
        self.expected = tuple(dict.fromkeys(expected or ()))
        self.select = select
        self.stale_s = float(stale_s)
        self.notes: list[str] = []
        self._src: dict[str, _Source] = {}
        self._order: list[str] = []
        self._dropped = 0
        self._held = 0
        self._same_checked: set[tuple[str, str]] = set()
        self.selected_seen_ = False

    @property
    def sources_(self) -> tuple[str, ...]:
        """Sources seen so far, in order of appearance."""
        return tuple(self._order)

    @property
    def summing_(self) -> bool:
        """Whether samples are being summed over two or more sources."""
        return self.select is None and (len(self._order) > 1 or len(self.expected) > 1)

    def add(self, sample: BatterySample) -> BatterySample | None:
        """One sample in; the combined sample out (None while waiting for every expected
        source, or for a source other than ``select``)."""
        src = sample.source
        if self.select is not None:
            if src != self.select:
                self._dropped += 1
                if src not in self._order:
                    self._order.append(src)
                if self._dropped == 20 and not self.selected_seen_:
                    self.notes.append(
                        f'battery source {_label(self.select)} not seen in 20 samples; the '
                        f'topic carries {", ".join(map(_label, self._order))}')
                return None
            self.selected_seen_ = True
            return sample
        known = src in self._src
        if not known:
            if self._order and not self.expected:
                self.notes.append(
                    f'battery source {_label(src)} appeared at t = {sample.t_s:.3f} s beside '
                    f'{", ".join(map(_label, self._order))}: input power is the sum of the '
                    'sources from then on')
            elif self.expected and src not in self.expected:
                self.notes.append(f'battery source {_label(src)} not announced: summed from '
                                  f't = {sample.t_s:.3f} s')
            self._order.append(src)
            self._src[src] = _Source(sample.t_s, sample.voltage_v, sample.current_a)
        else:
            s = self._src[src]
            dt = sample.t_s - s.t_s
            if dt > 0:
                s.interval_s = dt if s.interval_s == 0 else 0.9 * s.interval_s + 0.1 * dt
            if s.stale:
                s.stale = False
                self.notes.append(f'battery source {_label(src)} back at t = '
                                  f'{sample.t_s:.3f} s: summed again')
            s.t_s, s.voltage_v, s.current_a = sample.t_s, sample.voltage_v, sample.current_a
        s = self._src[src]
        if len(s.first) < SAME_PACK_SAMPLES:
            s.first.append((sample.voltage_v, sample.voltage_v * sample.current_a))
            if len(s.first) == SAME_PACK_SAMPLES:
                self._check_same_pack(src)
        if not self.summing_:
            return sample
        if self.expected and any(e not in self._src for e in self.expected):
            self._held += 1
            return None
        return self._combined(sample)

    def _combined(self, sample: BatterySample) -> BatterySample:
        t = sample.t_s
        power = 0.0
        for name in self._order:
            s = self._src[name]
            limit = max(self.stale_s, 5.0 * s.interval_s if s.interval_s > 0
                        else FIRST_REPORT_STALE_S)
            if t - s.t_s > limit:
                if not s.stale:
                    s.stale = True
                    self.notes.append(
                        f'battery source {_label(name)} silent for more than {limit:.1f} s at '
                        f't = {t:.3f} s: left out of the summed input power until it reports')
                continue
            power += s.voltage_v * s.current_a
        ref = self._src[self._order[0]]
        volt = ref.voltage_v if abs(ref.voltage_v) > 1e-6 else 1.0
        return dataclasses.replace(sample, voltage_v=volt, current_a=power / volt,
                                   source='+'.join(self._order))

    def _check_same_pack(self, src: str) -> None:
        a = self._src[src].first
        for other in self._order:
            b = self._src[other].first
            pair = tuple(sorted((src, other)))
            if other == src or len(b) < SAME_PACK_SAMPLES or pair in self._same_checked:
                continue
            self._same_checked.add(pair)  # type: ignore[arg-type]
            va, pa = np.median(np.array(a), axis=0)
            vb, pb = np.median(np.array(b), axis=0)
            if (abs(va - vb) <= 0.005 * max(abs(va), abs(vb), 1e-9)
                    and abs(pa - pb) <= 0.05 * max(abs(pa), abs(pb), 1e-9)):
                self.notes.append(
                    f'battery sources {_label(other)} and {_label(src)} report the same '
                    f'voltage ({va:.2f} V) and power ({abs(pa):.2f} W): if they are one pack '
                    'published twice, their sum counts it twice; keep one with '
                    '--battery-source (node parameter battery_source)')

    def finish(self) -> list[str]:
        """Notes at the end of a stream (dropped, held samples; a ``select`` never seen)."""
        out = list(self.notes)
        if self.select is not None:
            if self._dropped:
                out.append(f'{self._dropped} /battery_state sample(s) of other sources than '
                           f'{_label(self.select)} ignored (--battery-source)')
        elif len(self._order) > 1:
            out.insert(0, f'{len(self._order)} batteries on /battery_state '
                          f'({", ".join(map(_label, self._order))}): input power is their sum')
            if self._held:
                out.append(f'{self._held} battery sample(s) before every source had reported '
                           'left out')
        return out


class AbsentBatteryFilter:
    """Leaves out the samples of a battery that is not there.

    ``sensor_msgs/BatteryState.present`` False says no battery is connected (a BMS that lost
    its pack, a hot swap): its voltage and current (often 0) are no measurement, and counted
    they pulled the mean input power down (3 s of zeros in 30 s: -10 %). Many drivers never set
    ``present``, so a stream that is always False is kept; a False sample is left out when its
    source has published ``present`` True before, or when it reads 0 V and 0 A. Causal, so the
    live node and the offline readers leave out the same samples; the hole is a gap in the
    battery stream like a dropped NaN sample.
    """

    def __init__(self) -> None:
        self._present: set[str] = set()
        self.dropped = 0
        self.first_dropped_s: float | None = None

    def keep(self, sample: BatterySample) -> bool:
        if sample.present:
            self._present.add(sample.source)
            return True
        if sample.source in self._present or (sample.voltage_v == 0.0
                                              and sample.current_a == 0.0):
            self.dropped += 1
            if self.first_dropped_s is None:
                self.first_dropped_s = sample.t_s
            return False
        return True

    def note(self) -> str | None:
        """What was left out, or None."""
        if not self.dropped:
            return None
        return (f'{self.dropped} /battery_state sample(s) with present = false (no battery; '
                f'the first at t = {self.first_dropped_s:.3f} s) left out: not a measurement')


def selected_source() -> str | None:
    """The battery to keep, from ``BATTERY_SOURCE_ENV`` (None: sum them all)."""
    return os.environ.get(BATTERY_SOURCE_ENV) or None


def combine_battery_samples(samples: Iterable[BatterySample], select: str | None = None,
                            stale_s: float = STALE_S,
                            ) -> tuple[list[BatterySample], list[str]]:
    """Offline: the samples in time order through a :class:`BatteryCombiner` that expects
    every source they carry; returns the combined samples and the notes. ``select`` defaults
    to :func:`selected_source`. Raises ValueError when ``select`` names no source of the
    stream (listing those it has)."""
    if select is None:
        select = selected_source()
    ordered = sorted(samples, key=lambda s: s.t_s)
    sources = tuple(dict.fromkeys(s.source for s in ordered))
    if select is not None and len(sources) < 2:
        # a bag of one battery (a bench's supply beside robot bags of two packs): kept
        return ordered, ([] if select in sources or not sources else [
            f'--battery-source {select!r}: this bag has one battery ({_label(sources[0])}), '
            'kept'])
    if select is not None and select not in sources:
        raise ValueError(f'battery source {select!r} not on /battery_state; its sources: '
                         f'{", ".join(map(_label, sources)) or "none"}')
    comb = BatteryCombiner(expected=sources, select=select, stale_s=stale_s)
    out = [c for c in (comb.add(s) for s in ordered) if c is not None]
    return out, comb.finish()


def unmeasured_power(voltage_v: Sequence[float], current_a: Sequence[float]) -> str | None:
    """Why a battery stream does not measure power, or None: a monitor without a current
    sensor (or a voltage input) often fills the field with 0 instead of NaN, and an input
    power of 0 W is then not a measurement. Returns a message when every one of 3 or more
    samples has ``V * I == 0``."""
    v = np.asarray(voltage_v, dtype=float)
    i = np.asarray(current_a, dtype=float)
    if v.size < 3 or np.any(v * i != 0):
        return None
    which = 'current' if np.all(i == 0) else 'voltage' if np.all(v == 0) else 'voltage or current'
    return (f'every /battery_state sample ({v.size}) has {which} 0: the monitor does not '
            f'measure it (a driver filling 0 for "unknown"), so there is no input power')


#: a median |voltage| or |current| above this is taken as milli-units (mV, mA)
MILLI_THRESHOLD = 1000.0
#: input power a legged robot on a battery draws [W] (a servo leg idling to a large quadruped):
#: decides whether a current beside millivolts is in mA or A
PLAUSIBLE_POWER_W = (0.5, 5000.0)


def milli_factors(voltage: float, current: float) -> tuple[float, float]:
    """Factors (1 or 1e-3) taking a battery reading's |voltage| and |current| to V and A.

    Above :data:`MILLI_THRESHOLD` a value is in milli-units. A current under it beside a
    voltage in millivolts is either a robot drawing under 1 A in mA (the driver's unit for
    both) or amps: the power decides, the reading that gives a plausible legged robot's draw
    (:data:`PLAUSIBLE_POWER_W`), and the driver's own unit (mA) when both would.
    """
    v, i = abs(float(voltage)), abs(float(current))
    fv = 1e-3 if v > MILLI_THRESHOLD else 1.0
    fi = 1e-3 if i > MILLI_THRESHOLD else 1.0
    if fv != 1.0 and fi == 1.0 and i > 0:
        p_milli, p_unit = 1e-6 * v * i, 1e-3 * v * i

        def plausible(p: float) -> bool:
            return PLAUSIBLE_POWER_W[0] <= p <= PLAUSIBLE_POWER_W[1]
        if plausible(p_milli) or not plausible(p_unit):
            fi = 1e-3
    return fv, fi


def _milli_scaled(samples: list[BatterySample], notes: list[str]) -> list[BatterySample]:
    """Voltages or currents published in millivolts or milliamps (some BMS and INA2xx drivers)
    scaled to V and A, per source: a median magnitude above 1000 (no legged robot's pack
    reaches 1000 V or draws 1000 A), noted."""
    out = list(samples)
    for src in dict.fromkeys(s.source for s in samples):
        idx = [k for k, s in enumerate(samples) if s.source == src]
        v = float(np.median([abs(samples[k].voltage_v) for k in idx]))
        i = float(np.median([abs(samples[k].current_a) for k in idx]))
        fv, fi = milli_factors(v, i)
        if fv == fi == 1.0:
            continue
        for k in idx:
            out[k] = dataclasses.replace(out[k], voltage_v=out[k].voltage_v * fv,
                                         current_a=out[k].current_a * fi)
        what = ' and '.join(x for x, f in (('voltage', fv), ('current', fi)) if f != 1.0)
        med = ' and '.join(f'{x:.0f}' for x, f in ((v, fv), (i, fi)) if f != 1.0)
        notes.append(f'/battery_state {_label(src) + " " if src else ""}{what} in milli-units '
                     f'(median {med}): divided by 1000')
    return out


def prepare_battery_samples(samples: Sequence[BatterySample]
                            ) -> tuple[list[BatterySample], list[str]]:
    """Offline readers' battery stream: milli-units scaled, several sources summed or the one
    of ``--battery-source`` kept (:func:`combine_battery_samples`); returns the samples (the
    input list unchanged for one battery in V and A) and notes. Raises ValueError when the
    stream measures no power (:func:`unmeasured_power`) or the chosen source is missing."""
    notes: list[str] = []
    absent = AbsentBatteryFilter()
    kept = [b for b in samples if absent.keep(b)]
    if absent.dropped:
        notes.append(absent.note() or '')
    else:
        kept = list(samples)
    out = _milli_scaled(kept, notes) if kept else kept
    if len({b.source for b in out}) > 1 or selected_source() is not None:
        out, more = combine_battery_samples(out)
        notes.extend(more)
    why = unmeasured_power([b.voltage_v for b in out], [b.current_a for b in out])
    if why:
        raise ValueError(why)
    return out, notes
