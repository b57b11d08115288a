"""Gait cycle boundaries from the joint positions alone (core, numpy only, no ROS).

Robots of other labs run their own gait code and publish no ``/gait/phase``; their joint
positions still repeat once per step period. This module estimates that period and lays whole
cycles from it, so the energy descriptors (means over whole cycles) work on such robots.

Continuous-rotation joints (RHex-class hips)
    A hip that turns one revolution per cycle is reported either unwrapped (an ever-growing
    angle: a ramp of 2 pi per cycle plus a periodic part) or wrapped into [-pi, pi) or
    [0, 2 pi) (a sawtooth that jumps by 2 pi once per cycle). The tracker unwraps each joint
    online (:func:`unwrap_near`: when a joint's new value differs from its last by more than
    pi, the 2 pi representative nearest the last value is taken; no joint of a legged robot
    moves by pi in one sample), so both reports become the same ramp; the period estimate
    removes a least-squares line per joint (:func:`detrend_linear`), not only the mean, so the
    ramp plus a periodic part is periodic. On simulated EduBot runs (Buehler clock, running,
    jogging, pace, walk; test ``test_outside_joints_energy.py``) the period is within 0.11 %
    of the clock's, unwrapped and wrapped alike (wrapped == unwrapped to rounding).

Period estimate (:func:`estimate_period`)
    The positions of every joint, resampled on a uniform grid of ``grid_dt_s``, are made
    free of their least-squares line (mean and slope) and divided by their standard deviation
    (joints that move less than ``min_amplitude_rad`` RMS about that line are left out; when
    every joint is that still, the robot is standing and no period is claimed). The
    normalised autocorrelation, summed over joints,

        r(k) = sum_j sum_t z_j(t) z_j(t + k) / ((n - k) * J),    r(0) = 1,

    is searched for local maxima at lags ``min_period_s .. min(max_period_s, span / 3)``; the
    first maximum whose height is at least 0.9 of the highest is the period (so 2T, 3T are not
    taken for T), refined by parabolic interpolation through its three samples and then by a
    least-squares line through the refined peaks near every multiple m T that fits in half the
    span (a lag measured m times longer is m times more precise). The periodicity is weak when
    the peak is below ``min_peak`` (0.5): no period. As the span's autocorrelation reacts to a
    stop only once the stop fills much of the span, the last period must also repeat the one
    before it (correlation >= ``min_peak``, RMS within a factor 2 of each other and at least
    0.32 of the span's), else no period.

Cycle boundaries (:class:`JointCycleTracker`)
    Streaming: positions arrive one JointState at a time and are interpolated onto the grid as
    they come (O(joints) per message); every ``hop_s`` of grid the period is re-estimated on
    the last ``span_periods`` periods (``max_span_s`` while no period is known). Averaging a
    periodic signal over a whole period does not depend on where the period starts, so whole
    cycles are laid from the first joint sample: b_0 = t_first, b_(k+1) = b_k + T, where a
    cycle [b_k, b_k + T] is laid, with the estimate T of the first evaluation at or after its
    end, once that evaluation's time reaches b_k + T. A change of step frequency is followed
    within about one span. When the periodicity is lost (the robot stops, changes gait, or
    moves irregularly), the chain of cycles ends (a NaN boundary marks the break) and a new
    chain starts from the time the periodicity was last found missing, estimated only on data
    after that time (so once 3 periods of it exist).

    Cost per message: O(joints) for the grid, plus one FFT of the span (``J`` joints x
    ``span / grid_dt_s`` samples) every ``hop_s``: amortised O(J log n) with n the span
    length, constant in the length of the run; no estimate ever looks at the whole history.

Accuracy (tests ``test_outside_nogait_cycles.py``): on simulated AntBot runs (tripod and wave,
4, 6 and 8 legs, 0.1 to 0.6 m/s) the period is within 1 % of the gait's (typically 0.1 %);
standing runs and white noise give no period. EduBot runs: see above.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = [
    'CycleSettings',
    'JointCycleTracker',
    'PeriodEstimate',
    'detrend_linear',
    'estimate_period',
    'resample_uniform',
    'unwrap_near',
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class CycleSettings:
    """Settings of the period estimate and of the cycle tracker.

    Attributes
    ----------
    grid_dt_s : float
        Resampling step [s].
    min_period_s, max_period_s : float
        Range of step periods searched [s].
    min_peak : float
        Least normalised autocorrelation at the period for a periodic gait.
    min_amplitude_rad : float
        RMS motion [rad] below which a joint is taken as still (standing robot).
    span_periods : float
        Periods of data in each re-estimate once a period is known.
    max_span_s : float
        Longest span of data used [s] (also the span while no period is known); must be at
        least ``3 * max_period_s`` so that any allowed period can be seen.
    hop_s : float
        Time between re-estimates [s].
    """

    grid_dt_s: float = 0.01
    min_period_s: float = 0.1
    max_period_s: float = 4.0
    min_peak: float = 0.5
    min_amplitude_rad: float = 0.01
    span_periods: float = 10.0
    max_span_s: float = 40.0
    hop_s: float = 0.5

    def __post_init__(self) -> None:
        if not (self.grid_dt_s > 0 and 0 < self.min_period_s < self.max_period_s):
            raise ValueError(
                f'cycle settings: need grid_dt_s > 0 and 0 < min_period_s < max_period_s, got '
                f'{self.grid_dt_s}, {self.min_period_s}, {self.max_period_s}')
        if self.min_period_s < 3 * self.grid_dt_s:
            raise ValueError(f'cycle settings: min_period_s {self.min_period_s} s must be at '
                             f'least 3 grid steps ({3 * self.grid_dt_s} s)')
        if self.max_span_s < 3 * self.max_period_s:
            raise ValueError(f'cycle settings: max_span_s {self.max_span_s} s must be at least '
                             f'3 max_period_s ({3 * self.max_period_s} s)')
        if self.span_periods < 3 or self.hop_s <= 0:
            raise ValueError(f'cycle settings: need span_periods >= 3 and hop_s > 0, got '
                             f'{self.span_periods}, {self.hop_s}')


@dataclass(frozen=True)
class PeriodEstimate:
    """Outcome of :func:`estimate_period`.

    ``period_s`` is NaN when no period is claimed; ``status`` says why: ``periodic``,
    ``standing`` (every joint still), ``weak`` (peak below ``min_peak`` with data enough to
    see every allowed period), ``changed`` (the last period does not repeat the one before it:
    correlation below ``min_peak``, RMS ratio outside 0.5-2 or RMS below 0.32 of the span's:
    the robot stopped or changed its gait) or ``short`` (no peak yet, too little data to decide).
    """

    period_s: float
    peak: float
    status: str
    active_joints: int

    @property
    def periodic(self) -> bool:
        return self.status == 'periodic'


def resample_uniform(t_s: FloatArray, positions: FloatArray, dt_s: float) -> FloatArray:
    """Linear interpolation of ``positions`` (n, J) at stamps ``t_s`` (n,) [s] on the grid
    ``t_s[0] + k dt_s``; returns (m, J)."""
    t = np.asarray(t_s, dtype=float)
    x = np.asarray(positions, dtype=float).reshape(t.shape[0], -1)
    grid = t[0] + dt_s * np.arange(int(math.floor((t[-1] - t[0]) / dt_s + 1e-9)) + 1)
    return np.column_stack([np.interp(grid, t, x[:, j]) for j in range(x.shape[1])])


def detrend_linear(x: FloatArray) -> FloatArray:
    """``x`` (n, J) minus each column's least-squares line in the sample index: a joint that
    turns continuously (a RHex-class hip, unwrapped: a ramp of 2 pi per cycle plus a periodic
    part) keeps only its periodic part; a periodic joint loses its mean (and the small slope
    a span of not quite whole periods fits)."""
    x = np.asarray(x, dtype=float)
    n = x.shape[0]
    tc = np.arange(n, dtype=float) - 0.5 * (n - 1)
    den = float(np.dot(tc, tc))
    slope = (tc @ x) / den if den > 0 else np.zeros(x.shape[1:])
    return x - x.mean(axis=0) - np.multiply.outer(tc, slope)


def unwrap_near(q_rad: float, last_rad: float) -> float:
    """The 2 pi representative of ``q_rad`` nearest ``last_rad`` when they differ by more
    than pi (a joint reported wrapped into [-pi, pi) or [0, 2 pi) that crossed the cut),
    else ``q_rad`` unchanged."""
    d = q_rad - last_rad
    if abs(d) <= math.pi:
        return q_rad
    return q_rad - 2.0 * math.pi * round(d / (2.0 * math.pi))


def _parabola(r: FloatArray, k: int) -> tuple[float, float]:
    """Vertex (lag, height) of the parabola through r[k-1], r[k], r[k+1]."""
    a, b, c = r[k - 1], r[k], r[k + 1]
    den = a - 2 * b + c
    if den >= 0:
        return float(k), float(b)
    d = 0.5 * (a - c) / den
    return k + d, float(b - 0.25 * (a - c) * d)


def estimate_period(grid: FloatArray, settings: CycleSettings | None = None) -> PeriodEstimate:
    """Step period of uniformly sampled joint positions.

    Parameters
    ----------
    grid : (n, J) array
        Joint positions [rad] on a uniform grid of ``settings.grid_dt_s``.
    settings : CycleSettings, optional

    Returns
    -------
    PeriodEstimate
    """
    s = settings or CycleSettings()
    x = np.asarray(grid, dtype=float)
    if x.ndim == 1:
        x = x[:, None]
    n = x.shape[0]
    dt = s.grid_dt_s
    if n < 8:
        return PeriodEstimate(math.nan, math.nan, 'short', 0)
    x = detrend_linear(x)
    std = x.std(axis=0)
    active = std > s.min_amplitude_rad
    if not active.any():
        return PeriodEstimate(math.nan, math.nan, 'standing', 0)
    z = x[:, active] / std[active]
    nfft = 1 << int(math.ceil(math.log2(2 * n)))
    spec = np.fft.rfft(z, nfft, axis=0)
    acf = np.fft.irfft(np.sum(spec.real**2 + spec.imag**2, axis=1), nfft)[:n]
    r = acf / ((n - np.arange(n)) * acf[0] / n)
    k_lo = max(2, int(math.floor(s.min_period_s / dt)))
    k_hi = min(int(math.ceil(s.max_period_s / dt)), n // 3)
    enough = n * dt >= 3 * s.max_period_s
    if k_hi <= k_lo + 1:
        return PeriodEstimate(math.nan, math.nan, 'short', int(active.sum()))
    seg = r[k_lo - 1:k_hi + 2]
    inner = seg[1:-1]
    is_max = (inner > seg[:-2]) & (inner >= seg[2:])
    lags = np.nonzero(is_max)[0] + k_lo
    if lags.size == 0:
        return PeriodEstimate(math.nan, math.nan, 'weak' if enough else 'short',
                              int(active.sum()))
    heights = r[lags]
    best = float(heights.max())
    if best < s.min_peak:
        return PeriodEstimate(math.nan, best, 'weak' if enough else 'short',
                              int(active.sum()))
    k = int(lags[np.nonzero(heights >= 0.9 * best)[0][0]])
    lag, peak = _parabola(r, k)
    # refine on the multiples of the period that fit in half the span
    ms, ls = [1.0], [lag]
    m = 2
    while m * lag + 3 < n // 2 and m <= 16:
        c = int(round(m * lag))
        window = r[c - 2:c + 3]
        j = c - 2 + int(np.argmax(window))
        if 1 <= j < n - 1 and r[j] >= r[j - 1] and r[j] >= r[j + 1]:
            ms.append(float(m))
            ls.append(_parabola(r, j)[0])
        m += 1
    m_arr, l_arr = np.array(ms), np.array(ls)
    period = float(np.sum(m_arr * l_arr) / np.sum(m_arr * m_arr)) * dt
    # the span's autocorrelation lags behind a stop: the last period must repeat the one
    # before it, in shape and in size
    k = int(round(period / dt))
    a = z[n - k:] - z[n - k:].mean(axis=0)
    b = z[n - 2 * k:n - k] - z[n - 2 * k:n - k].mean(axis=0)
    saa, sbb = float(np.sum(a * a)), float(np.sum(b * b))
    recent = float(np.sum(a * b)) / math.sqrt(saa * sbb) if saa > 0 and sbb > 0 else 0.0
    # mean squares of the unit-variance signals: a still stretch has ~0 (rounding only)
    ms_a, ms_b = saa / a.size, sbb / b.size
    if recent < s.min_peak or min(ms_a, ms_b) < 0.1 or not 0.25 <= ms_a / ms_b <= 4.0:
        return PeriodEstimate(math.nan, min(peak, recent), 'changed', int(active.sum()))
    return PeriodEstimate(period, peak, 'periodic', int(active.sum()))


@dataclass
class JointCycleTracker:
    """Streaming whole-cycle boundaries from JointState positions.

    Feed every joint sample with :meth:`add` (stamp order; a sample older than the newest is
    merged into the newest row); it returns the cycle boundaries [s] that became known, a NaN
    marking the end of a chain of cycles (no window may span it).

    Joints are matched by name; a joint first seen later is back-filled with its first value.
    Several JointState messages with the same stamp (one per servo bus) make one row. Each
    joint is unwrapped online (:func:`unwrap_near`), so wrapped continuous joints work.

    Attributes (fitted state)
    -------------------------
    period_s_ : float
        Latest period estimate (NaN before the first or after a lost periodicity).
    estimate_ : PeriodEstimate | None
        Latest estimate.
    evaluations_ : int
        Number of estimates made.
    """

    settings: CycleSettings = field(default_factory=CycleSettings)
    period_s_: float = field(default=math.nan, init=False)
    estimate_: PeriodEstimate | None = field(default=None, init=False)
    evaluations_: int = field(default=0, init=False)
    _names: dict[str, int] = field(default_factory=dict, init=False)
    _latest: list[float] = field(default_factory=list, init=False)
    _row_t: float | None = field(default=None, init=False)       # pending (open) row
    _row: FloatArray | None = field(default=None, init=False)
    _prev_t: float | None = field(default=None, init=False)      # last closed row
    _prev: FloatArray | None = field(default=None, init=False)
    _t_first: float | None = field(default=None, init=False)
    _buf: FloatArray = field(default_factory=lambda: np.zeros((0, 0)), init=False)
    _count: int = field(default=0, init=False)       # grid points in the buffer
    _k_total: int = field(default=0, init=False)     # grid points made since t_first
    _k_eval: int = field(default=0, init=False)
    _chain_last: float | None = field(default=None, init=False)
    _origin: float | None = field(default=None, init=False)
    _chain_start: float = field(default=math.nan, init=False)

    @property
    def origin_s(self) -> float | None:
        """Earliest time a future boundary can take (data before it is no longer needed)."""
        return self._chain_last if self._chain_last is not None else self._origin

    def add(self, t_s: float, names: Sequence[str], position_rad: Sequence[float]
            ) -> list[float]:
        """Add one JointState's positions; returns new boundaries [s] (NaN = chain break)."""
        pos = np.asarray(position_rad, dtype=float)
        if pos.size == 0 or pos.size != len(names):
            return []
        for name, q in zip(names, pos):
            if not math.isfinite(q):
                continue
            if name not in self._names:
                self._names[name] = len(self._latest)
                self._latest.append(float(q))
                self._add_column(float(q))
            else:
                j = self._names[name]
                self._latest[j] = unwrap_near(float(q), self._latest[j])
        if not self._latest:
            return []
        if self._row_t is None or t_s <= self._row_t:
            if self._row_t is None:
                self._row_t = float(t_s)
                self._t_first = float(t_s)
                self._origin = float(t_s)
            self._row = np.array(self._latest)
            return []
        out = self._close_row()
        self._row_t, self._row = float(t_s), np.array(self._latest)
        return out

    # -- grid ------------------------------------------------------------------------------
    def _add_column(self, q: float) -> None:
        buf = self._buf
        col = np.full((buf.shape[0], 1), q)
        self._buf = np.hstack([buf, col])
        if self._prev is not None:
            self._prev = np.append(self._prev, q)
        if self._row is not None:
            self._row = np.append(self._row, q)

    def _capacity(self) -> int:
        return int(math.ceil(self.settings.max_span_s / self.settings.grid_dt_s)) + 2

    def _append_grid(self, rows: FloatArray) -> None:
        cap = self._capacity()
        need = self._count + rows.shape[0]
        if need > self._buf.shape[0]:
            keep = min(self._count, cap)
            size = max(2 * cap, keep + rows.shape[0])
            new = np.empty((size, rows.shape[1]))
            new[:keep] = self._buf[self._count - keep:self._count]
            self._buf, self._count = new, keep
        self._buf[self._count:self._count + rows.shape[0]] = rows
        self._count += rows.shape[0]

    def _close_row(self) -> list[float]:
        """Interpolate the grid up to the pending row; evaluate every hop."""
        assert self._row_t is not None and self._row is not None and self._t_first is not None
        dt = self.settings.grid_dt_s
        t1, x1 = self._row_t, self._row
        if self._prev_t is None:
            self._prev_t, self._prev = t1, x1
            self._append_grid(x1[None, :])
            self._k_total = 1
            return []
        t0, x0 = self._prev_t, self._prev
        assert x0 is not None
        k_end = int(math.floor((t1 - self._t_first) / dt + 1e-9))
        out: list[float] = []
        hop = max(1, int(round(self.settings.hop_s / dt)))
        while self._k_total <= k_end:
            # at most up to the next evaluation at a time, so evaluations fall every hop
            next_eval = self._k_eval + hop
            k_stop = min(k_end, next_eval - 1)
            k = np.arange(self._k_total, k_stop + 1)
            g = self._t_first + dt * k
            w = ((g - t0) / (t1 - t0))[:, None]
            self._append_grid(x0[None, :] + w * (x1 - x0)[None, :])
            self._k_total = k_stop + 1
            if self._k_total == next_eval:
                self._k_eval = next_eval
                out.extend(self._evaluate(self._t_first + dt * (self._k_total - 1)))
        self._prev_t, self._prev = t1, x1
        return out

    # -- estimates and boundaries ------------------------------------------------------------
    def _evaluate(self, t_eval: float) -> list[float]:
        s = self.settings
        span_s = s.max_span_s
        if math.isfinite(self.period_s_):
            span_s = min(s.max_span_s, s.span_periods * self.period_s_)
        n = min(self._count, int(round(span_s / s.grid_dt_s)) + 1)
        # never across a stop: only data since the current chain (or attempt) began
        start = self._chain_start if self._chain_last is not None else self._origin
        assert start is not None
        n = min(n, int(math.floor((t_eval - start) / s.grid_dt_s + 1e-9)) + 1)
        est = estimate_period(self._buf[self._count - n:self._count], s)
        self.estimate_ = est
        self.evaluations_ += 1
        out: list[float] = []
        if not est.periodic:
            self.period_s_ = math.nan
            if est.status == 'short':
                return out
            if self._chain_last is not None:
                out.append(math.nan)
            self._chain_last = None
            self._origin = t_eval
            return out
        self.period_s_ = est.period_s
        if self._chain_last is None:
            assert self._origin is not None
            if self._origin + est.period_s > t_eval + 1e-9:
                return out
            self._chain_last = self._chain_start = self._origin
            out.append(self._origin)
        while self._chain_last + est.period_s <= t_eval + 1e-9:
            self._chain_last += est.period_s
            out.append(self._chain_last)
        return out
