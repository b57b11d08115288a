"""Stance extraction from proprioception (Komsuoglu et al., Fig. 5 and Section 3).

For each tripod: the average measured hip speed ``w_a(t)`` of its three hips; the shift

    t_s = argmin_{tau >= 0} integral |w_a(t) - w_r(t - tau)| dt

of the target speed ``w_r`` (from the Buehler clock, or the logged target speeds) found on a
1 ms grid and refined to 0.05 ms; touchdown at the falling edges (fast -> slow) and lift-off at
the rising edges (slow -> fast) of the shifted target. A *single-tripod* stance is the part of
a tripod's stance during which the other tripod is not in stance (they overlap when
``dc > 0.5``); the longest such part is kept.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import SlipDataError

__all__ = [
    'StanceWindow',
    'SteadyClock',
    'best_shift',
    'edges_from_target',
    'longest_free_segment',
    'open_stance_windows',
    'refine_clock_edges',
    'single_tripod_stances',
    'steady_clock',
    'tripod_stance_windows',
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class StanceWindow:
    """One single-tripod stance: touchdown and lift-off [s], tripod, shift used [s]."""

    touchdown_s: float
    liftoff_s: float
    tripod: str
    shift_s: float


def best_shift(t_s: ArrayLike, measured_speed: ArrayLike,
               target_speed: Callable[[FloatArray], FloatArray], *,
               max_shift_s: float = 0.15, step_s: float = 1e-3) -> float:
    """Time shift ``tau in [0, max_shift_s]`` minimising mean |measured(t) - target(t - tau)|.

    Parameters
    ----------
    t_s : array_like, shape (n,)
    measured_speed : array_like, shape (n,)
        Tripod-average measured hip speed [rad/s].
    target_speed : callable
        ``target_speed(t) -> (n,)`` [rad/s], defined for ``t - tau``.
    """
    t = np.asarray(t_s, dtype=float)
    w = np.asarray(measured_speed, dtype=float)
    ok = np.isfinite(t) & np.isfinite(w)
    t, w = t[ok], w[ok]
    if t.size < 10:
        raise SlipDataError(f'best_shift needs >= 10 finite hip-speed samples, got {t.size}')

    def costs(taus: FloatArray) -> FloatArray:
        # all candidate shifts at once: (len(taus), n) target samples, in row blocks
        out = np.empty(taus.size)
        rows = max(1, 200_000 // max(t.size, 1))
        for a in range(0, taus.size, rows):
            tt = taus[a:a + rows]
            tgt = np.asarray(target_speed((t[None, :] - tt[:, None]).ravel()), dtype=float)
            out[a:a + rows] = np.mean(np.abs(w[None, :] - tgt.reshape(tt.size, t.size)), axis=1)
        return out

    taus = np.arange(0.0, max_shift_s + 0.5 * step_s, step_s)
    coarse = costs(taus)
    i = j = int(np.argmin(coarse))
    # the whole flat bottom around it: a measured speed that switches as sharply as its
    # target, sampled at 100 Hz, fits every shift over a 10 ms span exactly; refining only
    # around the first grid point of it put the shift near the span's start (8.9 ms from the
    # true lag: an outside review)
    while i > 0 and coarse[i - 1] <= coarse[j] + 1e-12:
        i -= 1
    while j < taus.size - 1 and coarse[j + 1] <= coarse[i] + 1e-12:
        j += 1
    lo, hi = taus[max(i - 1, 0)], taus[min(j + 1, taus.size - 1)]
    fine = np.arange(lo, hi + 1e-12, step_s / 20)
    fc = costs(fine)
    # the cost is piecewise linear and flat-bottomed between edges: take the middle of the
    # minimising set
    best = fine[fc <= fc.min() + 1e-12]
    return float(0.5 * (best.min() + best.max()))


def edges_from_target(t_s: ArrayLike, target_speed: ArrayLike, *,
                      threshold: float | None = None) -> tuple[FloatArray, FloatArray]:
    """Falling (touchdown) and rising (lift-off) edge times of a sampled two-speed target.

    Edges are located by linear interpolation of the crossing of ``threshold`` (default the
    middle of the slow and fast speeds).
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(target_speed, dtype=float)
    thr = threshold if threshold is not None else 0.5 * (np.nanmin(v) + np.nanmax(v))
    s = v - thr
    cross = np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))
    tc = t[cross] + (t[cross + 1] - t[cross]) * s[cross] / (s[cross] - s[cross + 1])
    falling = tc[s[cross] > 0]
    rising = tc[s[cross] < 0]
    return falling, rising


def _bracketed_edges(t: FloatArray, v: FloatArray, thr: float
                     ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """The sample pairs each threshold crossing lies between: (falling a, b, rising a, b)."""
    s = v - thr
    cross = np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))
    fall = s[cross] > 0
    return t[cross][fall], t[cross + 1][fall], t[cross][~fall], t[cross + 1][~fall]


#: a clock edge replaces the sampled one when the samples pin it within this fraction of
#: the sampled edge's own half-width (half a command spacing)
CLOCK_EDGE_GAIN = 0.5
#: cycles fitted together by :func:`refine_clock_edges` (the polygon's cost grows with the
#: cube of its edges; a slow drift of the clock stays within a block)
CLOCK_BLOCK_CYCLES = 16


@dataclass(frozen=True)
class SteadyClock:
    """A two-speed clock of constant period, as far as its command samples pin it down.

    Every clock consistent with the samples puts its ``j``-th touchdown at ``t_ref_s +
    phi + j T`` for some vertex-weighted ``(phi, T)`` of the polygon ``touchdown_vertices``
    (rows ``(phi, T)``; likewise lift-offs, ``j`` counted from the touchdown at ``t_ref_s``):
    an edge's possible times are the range of ``phi + j T`` over the vertices.
    """

    t_ref_s: float
    touchdown_vertices: FloatArray
    liftoff_vertices: FloatArray
    slow: float
    fast: float

    @property
    def period_s(self) -> float:
        return float(np.mean(np.concatenate([self.touchdown_vertices[:, 1],
                                             self.liftoff_vertices[:, 1]])))

    def nearest(self, t_s: ArrayLike, kind: str) -> tuple[FloatArray, FloatArray]:
        """The clock's touchdown (``kind='touchdown'``) or lift-off nearest each ``t_s`` [s]
        (the middle of what the samples allow) and half the range they allow [s]."""
        v = self.touchdown_vertices if kind == 'touchdown' else self.liftoff_vertices
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        phi0, period = float(np.mean(v[:, 0])), float(np.mean(v[:, 1]))
        j = np.round((t - self.t_ref_s - phi0) / period)
        times = v[None, :, 0] + j[:, None] * v[None, :, 1]       # (n, vertices)
        lo, hi = times.min(axis=1), times.max(axis=1)
        return self.t_ref_s + 0.5 * (lo + hi), 0.5 * (hi - lo)

    def target(self, t_s: ArrayLike) -> FloatArray:
        """The target speed at ``t_s`` (slow from a touchdown to the next lift-off)."""
        t = np.asarray(t_s, dtype=float)
        flat = np.atleast_1d(t).ravel()
        td, _ = self.nearest(flat, 'touchdown')
        period = self.period_s
        td = np.where(td > flat, td - period, td)                # the touchdown before t
        lo, _ = self.nearest(td + 0.5 * period, 'liftoff')
        lo = np.where(lo <= td, lo + period, lo)                  # the lift-off after it
        lo = np.where(lo - td > period, lo - period, lo)
        return np.where(flat < lo, self.slow, self.fast).reshape(t.shape)

    def snap(self, edges_s: ArrayLike, kind: str, half_width_s: float) -> FloatArray:
        """Edges found halfway between two command samples (``half_width_s``: half their
        spacing, the sampled edge's worst error) moved onto the middle of the clock's own
        range where that range is narrower (:data:`CLOCK_EDGE_GAIN`) and lies between the two
        samples; kept otherwise (a clock known too loosely there, or changed since it was
        fitted)."""
        e = np.asarray(edges_s, dtype=float)
        if e.size == 0:
            return e
        pred, unc = self.nearest(e, kind)
        ok = (np.abs(pred - e) <= half_width_s) & (unc <= CLOCK_EDGE_GAIN * half_width_s)
        return np.where(ok, pred, e)


def _feasible_polygon(j: FloatArray, a: FloatArray, b: FloatArray, t_lo: float, t_hi: float
                      ) -> FloatArray:
    """Vertices ``(phi, T)`` of ``{a_k <= phi + j_k T <= b_k, t_lo <= T <= t_hi}`` (empty
    (0, 2) when infeasible): every pairwise crossing of the boundary lines that satisfies all
    the constraints."""
    # boundary lines phi + j T = c, and T = t_lo / t_hi as phi + 0 T ... handled apart
    jj = np.concatenate([j, j])
    cc = np.concatenate([a, b])
    p, q = np.triu_indices(jj.size, 1)
    dj = jj[p] - jj[q]
    keep = dj != 0
    p, q, dj = p[keep], q[keep], dj[keep]
    period = (cc[p] - cc[q]) / dj
    phi = cc[p] - jj[p] * period
    # crossings with the period bounds
    for bound in (t_lo, t_hi):
        phi = np.concatenate([phi, cc - jj * bound])
        period = np.concatenate([period, np.full(cc.size, bound)])
    tol = 1e-12
    edge = phi[:, None] + period[:, None] * j[None, :]
    ok = np.all((edge >= a[None, :] - tol) & (edge <= b[None, :] + tol), axis=1) & \
        (period >= t_lo - tol) & (period <= t_hi + tol)
    return np.column_stack([phi[ok], period[ok]])


def steady_clock(t_s: ArrayLike, target_speed: ArrayLike) -> SteadyClock | None:
    """The edges of a steady two-speed clock sampled at the command rate, below the spacing.

    A sampled target only says that an edge lies between the last sample of one speed and the
    first of the other (10 ms at 100 Hz; the crossing of the middle speed puts it halfway, up
    to 5 ms off). A clock of constant period puts its edges at ``phi_f + j T`` (touchdowns)
    and ``phi_r + j T`` (lift-offs); every bracket constrains ``(phi, T)`` linearly, and the
    samples fall at other phases of each cycle, so together they pin the edges far below the
    sample spacing (a vernier). The polygon of every ``(phi, T)`` the brackets allow gives
    each edge's range; its middle is the estimate, used where the range is narrower than the
    sampled edge's (:class:`SteadyClock`; the Table 1 clocks over 12 s at 100 Hz: every edge
    within 0.5 ms, 3.3-4.2 ms on a slow gait's loosely pinned ones, 4.6-4.9 ms sampled). None
    when the brackets admit no single period (a
    clock that changes speed, a missed edge, fewer than three edges of each kind): the caller
    keeps the sampled target.
    """
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(target_speed, dtype=float)
    ok = np.isfinite(t) & np.isfinite(v)
    t, v = t[ok], v[ok]
    if t.size < 10 or np.ptp(v) <= 0:
        return None
    lo_v, hi_v = float(np.min(v)), float(np.max(v))
    fa, fb, ra, rb = _bracketed_edges(t, v, 0.5 * (lo_v + hi_v))
    if fa.size < 3 or ra.size < 3:
        return None
    mids, mids_r = 0.5 * (fa + fb), 0.5 * (ra + rb)
    period0 = float(np.median(np.diff(mids)))
    if not period0 > 0:
        return None
    for m in (mids, mids_r):
        gaps = np.diff(m) / period0
        if np.any(gaps < 0.5) or np.any(gaps > 1.5):
            return None           # a missed or extra edge: not one steady clock
    # cycles counted from the middle touchdown, lift-offs from the one nearest it
    t_ref = float(mids[mids.size // 2])
    jf = np.arange(mids.size) - float(mids.size // 2)
    jr = np.arange(mids_r.size) - float(np.argmin(np.abs(mids_r - t_ref)))
    vf = _feasible_polygon(jf, fa - t_ref, fb - t_ref, 0.5 * period0, 2.0 * period0)
    vr = _feasible_polygon(jr, ra - t_ref, rb - t_ref, 0.5 * period0, 2.0 * period0)
    if vf.shape[0] == 0 or vr.shape[0] == 0:
        return None               # no single period fits every bracket
    return SteadyClock(t_ref_s=t_ref, touchdown_vertices=vf, liftoff_vertices=vr,
                       slow=lo_v, fast=hi_v)


def refine_clock_edges(t_s: ArrayLike, target_speed: ArrayLike, touchdown_s: ArrayLike,
                       liftoff_s: ArrayLike) -> tuple[FloatArray, FloatArray]:
    """Sampled clock edges (halfway between two command samples, :func:`edges_from_target`
    on ``t_s``) moved onto the steady clock of their block of :data:`CLOCK_BLOCK_CYCLES`
    cycles where its samples pin them tighter (:func:`steady_clock`, :meth:`SteadyClock.snap`);
    kept elsewhere. Bounded cost on long runs; a clock that changes speed changes it between
    blocks or leaves its block unrefined."""
    t = np.asarray(t_s, dtype=float)
    v = np.asarray(target_speed, dtype=float)
    td = np.asarray(touchdown_s, dtype=float).copy()
    lo = np.asarray(liftoff_s, dtype=float).copy()
    if t.size < 10 or td.size < 3:
        return td, lo
    half = 0.5 * float(np.median(np.diff(t))) + 1e-6
    period = float(np.median(np.diff(td)))
    if not period > 0:
        return td, lo
    span = CLOCK_BLOCK_CYCLES * period
    n_blocks = max(1, int(np.ceil((t[-1] - t[0]) / span)))
    edges = np.linspace(t[0], t[-1] + 1e-9, n_blocks + 1)
    for a, b in zip(edges[:-1], edges[1:]):
        # the block's samples with half a cycle either side, so its edge brackets are whole
        sel = (t >= a - 0.5 * period) & (t <= b + 0.5 * period)
        clock = steady_clock(t[sel], v[sel])
        if clock is None:
            continue
        for arr, kind in ((td, 'touchdown'), (lo, 'liftoff')):
            inside = (arr >= a) & (arr < b)
            if np.any(inside):
                arr[inside] = clock.snap(arr[inside], kind, half)
    return td, lo


def tripod_stance_windows(touchdown_s: ArrayLike, liftoff_s: ArrayLike) -> FloatArray:
    """Pair each touchdown with the next lift-off: (m, 2) windows."""
    td = np.sort(np.asarray(touchdown_s, dtype=float))
    lo = np.sort(np.asarray(liftoff_s, dtype=float))
    out = []
    for a in td:
        j = np.searchsorted(lo, a, side='right')
        if j < lo.size:
            nxt = np.searchsorted(td, a, side='right')
            if nxt >= td.size or lo[j] <= td[nxt]:
                out.append((a, lo[j]))
    return np.array(out, dtype=float).reshape(-1, 2)


def open_stance_windows(touchdown_s: ArrayLike, liftoff_s: ArrayLike) -> FloatArray:
    """A tripod's stances cut by the ends of the data: ``(-inf, first lift-off)`` when the data
    start in a stance (a lift-off before any touchdown) and ``(last touchdown, inf)`` when they
    end in one (no lift-off after the last touchdown); (k, 2), k <= 2.

    :func:`tripod_stance_windows` keeps whole stances only, so without these the other
    tripod's single-support part ran over a stance still open at the end of the data: with a
    duty factor above 0.5 (the walk) the online fitter fitted each whole stance as soon as it
    ended, the other tripod being down but not yet up (and again, its single-support part,
    once the other lifted off), and the offline analysis its last stance likewise."""
    td = np.sort(np.asarray(touchdown_s, dtype=float))
    lo = np.sort(np.asarray(liftoff_s, dtype=float))
    out = []
    if lo.size and (td.size == 0 or lo[0] < td[0]):
        out.append((-np.inf, lo[0]))
    if td.size and (lo.size == 0 or lo[-1] < td[-1]):
        out.append((td[-1], np.inf))
    return np.array(out, dtype=float).reshape(-1, 2)


def longest_free_segment(a: float, b: float, others: ArrayLike
                         ) -> tuple[float, float] | None:
    """Longest part of the interval ``[a, b]`` not covered by any of ``others`` (shape (k, 2)),
    or None when it is covered entirely (single support: this tripod down, the other not)."""
    segs = [(float(a), float(b))]
    for c, d in np.asarray(others, dtype=float).reshape(-1, 2):
        nxt = []
        for s0, s1 in segs:
            if d <= s0 or c >= s1:
                nxt.append((s0, s1))
                continue
            if c > s0:
                nxt.append((s0, c))
            if d < s1:
                nxt.append((d, s1))
        segs = nxt
    return max(segs, key=lambda x: x[1] - x[0]) if segs else None



def single_tripod_stances(windows: dict[str, FloatArray], shifts: dict[str, float] | None = None,
                          *, min_duration_s: float = 0.0,
                          open_windows: dict[str, FloatArray] | None = None
                          ) -> list[StanceWindow]:
    """Single-tripod parts of each tripod's stance windows (the other tripod off the ground).

    Parameters
    ----------
    windows : dict
        ``{'left': (m, 2), 'right': (k, 2)}`` stance windows [s].
    shifts : dict, optional
        Shift used per tripod (carried to the result).
    open_windows : dict, optional
        ``{tripod: (k, 2)}`` stances cut by the ends of the data
        (:func:`open_stance_windows`): never fitted, but they end the other tripod's single
        support like whole ones.
    """
    shifts = shifts or {}
    opened = open_windows or {}
    out: list[StanceWindow] = []
    for tripod, w in windows.items():
        others = np.concatenate([v for k, v in windows.items() if k != tripod]
                                + [v for k, v in opened.items() if k != tripod]
                                + [np.zeros((0, 2))])
        for a, b in np.asarray(w).reshape(-1, 2):
            longest = longest_free_segment(a, b, others)
            if longest is None:
                continue
            s0, s1 = longest
            if s1 - s0 > min_duration_s:
                out.append(StanceWindow(float(s0), float(s1), tripod, shifts.get(tripod, 0.0)))
    out.sort(key=lambda s: s.touchdown_s)
    return out
