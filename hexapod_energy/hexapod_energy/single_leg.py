"""Single-leg method of Brodoline et al. 2024 (Methods, Fig. 6): phase split and surface fits.

Pipeline, each step a plain function on arrays:

1. :func:`align_offset_s` estimates the clock offset between the ground-force stream and the
   motion-capture stream by cross-correlating the normal force with the negated tip height (the
   tip is low exactly while the force is high); :func:`align_offset_sessions_s` combines the
   sessions so that no fast session's period aliases it, and :func:`power_label_lag_s`
   estimates the power monitor's clock offset against the stance/swing labels.
2. :func:`stance_mask` labels samples stance when the force is above a threshold *and* the tip is
   near the ground; everything else is swing.
3. :func:`phase_powers` averages the leg's input power over the stance and over the swing samples
   of one walking session.  A 0 Hz session gives the basal power (leg standing, loaded).
4. :class:`SingleLegModel` fits the surfaces ``P_stance(T_stance, load)`` and
   ``P_swing(T_swing, load)`` on ``x = (1 / T_phase, load)``; candidates are a 2-D local-linear
   LOWESS with tricube weights (:class:`Lowess2D`, spans 0.8 for stance and 0.9 for swing as in the
   paper) and a least-squares polynomial in phase frequency and load (:class:`PolySurface`);
   the one with the lower k-fold cross-validated RMSE is kept, per phase.

0 Hz sessions (leg standing, loaded) give the basal power per load (``basal_power_w_``).  By
default (``basal_in_stance=False``) they are left out of both surfaces: the stance power of the
slowest walking session (0.5 Hz) is already ~2.3 W above the standing power on the simulated
bench (the leg moves and its servos work against the load), so a smooth surface through the
``1 / T_stance = 0`` point bends across the whole walking range and misses the walking sessions
by ~0.5 W (-5 % whole-robot error at 0.1 m/s).  ``basal_in_stance=True`` puts them in the stance
surface at ``1 / T_stance = 0`` (the surface then tends to the loaded basal power at infinitely
slow stances); they never enter the swing surface, since a swinging leg carries no load.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from fractions import Fraction
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from hexapod_energy.errors import FitError, InvalidInputError, NotFittedError

__all__ = [
    'Lowess2D',
    'PhaseSample',
    'PhaseSamples',
    'PolySurface',
    'SingleLegModel',
    'SurfaceModel',
    'align_offset_s',
    'align_offset_sessions_s',
    'cross_validated_rmse',
    'phase_powers',
    'power_label_lag_s',
    'samples_from_mapping',
    'schedule_labels',
    'stance_mask',
]


#: a prediction is outside a surface's measured domain when its phase duration lies beyond
#: the sessions' shortest or longest by more than this fraction of it, or its load beyond
#: their range by more than this fraction of the range's width (a local-linear
#: surface carried that little further is still its own slope; AntBot's tripod with the paper's
#: load convention carries 0.562 kg per stance leg against the bench's largest 0.515 kg load,
#: 9 % of the range beyond it)
DOMAIN_TOLERANCE = 0.10

# ----------------------------------------------------------------------------- phase split


def align_offset_s(
    t_force_s: ArrayLike,
    force_z_n: ArrayLike,
    t_tip_s: ArrayLike,
    tip_z_m: ArrayLike,
    *,
    max_lag_s: float = 0.5,
    dt_s: float = 0.002,
    binarize: bool = True,
    height_margin_m: float = 0.01,
) -> float:
    """Offset to *add* to the force timestamps so that force and tip height line up [s].

    Both streams are interpolated on a common grid of step ``dt_s``, turned into contact
    indicators when ``binarize`` (force above half its 5-95 percentile range; tip within
    ``height_margin_m`` of its 5th percentile), else used raw (force against ``-tip_z``),
    standardised, and cross-correlated over lags ``|lag| <= max_lag_s`` (each lag's product
    averaged over its overlap); the lag is the weighted centre of the region around the peak
    above 80 % of its height.

    Parameters
    ----------
    t_force_s, force_z_n : array (n,)
        Force stamps [s] and normal force [N].
    t_tip_s, tip_z_m : array (m,)
        Tip stamps [s] and tip height [m].
    """
    lags, corr = offset_correlation(t_force_s, force_z_n, t_tip_s, tip_z_m, max_lag_s=max_lag_s,
                                    dt_s=dt_s, binarize=binarize,
                                    height_margin_m=height_margin_m)
    return float(-_peak_centre(lags, corr, int(np.argmax(corr))))


def offset_correlation(
    t_force_s: ArrayLike,
    force_z_n: ArrayLike,
    t_tip_s: ArrayLike,
    tip_z_m: ArrayLike,
    *,
    max_lag_s: float = 0.5,
    dt_s: float = 0.002,
    binarize: bool = True,
    height_margin_m: float = 0.01,
) -> tuple[np.ndarray, np.ndarray]:
    """Lags [s] (the force lags the tip by ``lag``) and the force-tip cross-correlation of
    :func:`align_offset_s` at each, on the grid ``k dt_s``, ``|k dt_s| <= max_lag_s``."""
    tf, fz = np.asarray(t_force_s, float), np.asarray(force_z_n, float)
    tt, tz = np.asarray(t_tip_s, float), np.asarray(tip_z_m, float)
    if len(tf) < 4 or len(tt) < 4:
        raise InvalidInputError(
            f'alignment needs at least 4 samples per stream, got {len(tf)} force, {len(tt)} tip'
        )
    t0, t1 = max(tf[0], tt[0]), min(tf[-1], tt[-1])
    if t1 - t0 < 4 * max_lag_s:
        raise InvalidInputError(
            f'force and tip streams overlap for {t1 - t0:.3f} s, need >= {4 * max_lag_s:.3f} s'
        )
    grid = np.arange(t0, t1, dt_s)
    a = np.interp(grid, tf, fz)
    b = -np.interp(grid, tt, tz)
    if binarize:
        # contact indicators from each stream: two rectangle waves whose correlation is a
        # triangle with a sharp peak (the raw tip height is flat near touchdown, which would
        # leave the peak ill-defined)
        lo, hi = np.percentile(a, [5, 95])
        a = (a > lo + 0.5 * (hi - lo)).astype(float)
        b = (-b < np.percentile(-b, 5) + height_margin_m).astype(float)
    if not (a.std() > 0 and b.std() > 0):
        # a flat stream (a tip whose z does not move: another axis up; a dead load cell) has
        # no correlation peak; the maximum lag came out and shifted the force by it
        raise InvalidInputError('force or tip height does not vary over the session: nothing '
                                'to align')
    a = (a - a.mean()) / a.std()
    b = (b - b.mean()) / b.std()
    n = len(grid)
    nfft = 1 << (2 * n - 1).bit_length()
    # corr[k] = sum_i a[i + k] b[i]: force lags tip by k samples
    corr_full = np.fft.irfft(np.fft.rfft(a, nfft) * np.conj(np.fft.rfft(b, nfft)), nfft)
    max_k = int(round(max_lag_s / dt_s))
    lags = np.arange(-max_k, max_k + 1)
    corr = corr_full[lags % nfft] / (n - np.abs(lags))  # mean over the overlap, unbiased
    return lags * dt_s, corr


def _peak_centre(lags: np.ndarray, corr: np.ndarray, i: int,
                 window: slice | None = None) -> float:
    """Centre [lag units] of the contiguous region around ``corr[i]`` above 80 % of the peak's
    height over ``window`` (default: all): the correlation of two contact indicators of
    unequal widths is a trapezoid whose flat top is centred on the true lag, where the bare
    argmax is not."""
    w = window or slice(0, len(corr))
    lo_w, hi_w = w.start, w.stop - 1
    level = corr[w].min() + 0.8 * (corr[i] - corr[w].min())
    lo_i, hi_i = i, i
    while lo_i > lo_w and corr[lo_i - 1] >= level:
        lo_i -= 1
    while hi_i < hi_w and corr[hi_i + 1] >= level:
        hi_i += 1
    sel = slice(lo_i, hi_i + 1)
    weights = corr[sel] - level
    return float(np.sum(lags[sel] * weights) / np.sum(weights)) if weights.sum() > 0 \
        else float(lags[i])


#: the force-to-tip offset search of :func:`align_offset_sessions_s` spans at most this [s]
#: (larger clock offsets are :class:`hexapod_common.clocks.ClockCheck`'s, from 1 s)
MAX_FORCE_OFFSET_S = 0.9


def _common_period_s(frequencies_hz: Sequence[float]) -> float:
    """Shortest time that is a whole number of periods of every frequency (inf: none up to
    60 s); a periodic correlation of them all repeats with it."""
    common = Fraction(0)
    for f in frequencies_hz:
        period = Fraction(1.0 / f).limit_denominator(1000)
        common = period if common == 0 else \
            Fraction(math.lcm(common.numerator * period.denominator,
                              period.numerator * common.denominator),
                     common.denominator * period.denominator)
        if common > 60:
            return math.inf
    return float(common)


def _rival_peaks(lags: np.ndarray, total: np.ndarray, i: int, period_s: float
                 ) -> list[int]:
    """Indices of the other local peaks of the combined correlation ``total`` within 10 % of
    its highest, ``total[i]``: the offset is ambiguous between them. Not ripples on the main
    peak's flat top (two, 0.068 s apart on a noisy 0.5 and 1 Hz bench, read as "ambiguous by
    a common period" of 2 s; outside review D, D8): a rival lies beyond the main peak's
    contiguous region above 80 % (past a dip, the region :func:`_peak_centre` takes), and a
    quarter of ``period_s`` (the shortest period walked) and 0.05 s away."""
    top, low = total[i], total.min()
    level = low + 0.8 * (top - low)
    lo_i, hi_i = i, i
    while lo_i > 0 and total[lo_i - 1] >= level:
        lo_i -= 1
    while hi_i < len(total) - 1 and total[hi_i + 1] >= level:
        hi_i += 1
    apart = max(0.05, 0.25 * period_s)
    return [j for j in range(1, len(total) - 1)
            if total[j] >= total[j - 1] and total[j] > total[j + 1]
            and total[j] >= top - 0.1 * (top - low) and not lo_i <= j <= hi_i
            and abs(lags[j] - lags[i]) > apart]


def align_offset_sessions_s(
    sessions: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float, float]],
    *,
    max_offset_s: float = MAX_FORCE_OFFSET_S,
    dt_s: float = 0.002,
    height_margin_m: float = 0.01,
) -> tuple[float, dict[str, Any]]:
    """Offset to *add* to the force stamps [s] from several walking sessions, and how it was
    found.

    ``sessions``: ``(t_force_s, force_z_n, t_tip_s, tip_z_m, frequency_hz, weight)`` each.
    Each session's own estimate (:func:`align_offset_s` over ``|lag| <= min(0.5, 0.45 / f)``,
    one peak of its periodic correlation) is ambiguous by whole periods: a 0.4 s offset read
    as 0.067 s at 3 Hz (outside review A, F2). The sessions' correlations are averaged on
    one lag grid, ``|lag| <= min(max_offset_s, 0.45 x`` the frequencies' common period,
    a quarter of the shortest session``)``, where only the true lag is a peak of every
    session; each session's estimate is then taken at its own peak nearest that lag (the
    same as before when they agree), and the result is their median weighted by
    ``weight``. ``info``: ``lag_s`` (the combined peak, force lagging the tip), ``search_s``,
    ``per_session`` (offsets), ``realiased`` (sessions whose own window about 0 would have
    read another peak, or clipped this one, by more than 0.1 period),
    ``disagree`` (sessions whose correlation at the result is below half their peak),
    ``edge`` (the combined peak at the search's edge), ``ambiguous`` (another combined peak
    within 10 % of the highest, past a dip below 80 % of it and a quarter of the shortest
    period away).
    """
    if not sessions:
        raise InvalidInputError('no session to align')
    freqs = [float(x[4]) for x in sessions]
    span = min(min(x[0][-1], x[2][-1]) - max(x[0][0], x[2][0]) if len(x[0]) and len(x[2])
               else 0.0 for x in sessions)
    search = max(min(max_offset_s, 0.45 * _common_period_s(freqs), span / 4),
                 max(min(0.5, 0.45 / f) for f in freqs))
    curves, kept = [], []
    for k, (tf, fz, tt, tz, f, _w) in enumerate(sessions):
        try:
            lags, corr = offset_correlation(tf, fz, tt, tz, max_lag_s=search, dt_s=dt_s,
                                            height_margin_m=height_margin_m)
        except InvalidInputError:
            continue
        curves.append(corr)
        kept.append(k)
    if not curves:
        raise InvalidInputError('no session to align')
    total = np.mean(curves, axis=0)
    i = int(np.argmax(total))
    peaks = _rival_peaks(lags, total, i, 1.0 / max(freqs))
    ambiguous = bool(peaks)
    if ambiguous:   # the one nearest zero, as a single session's window would
        i = min([i] + peaks, key=lambda j: abs(lags[j]))
    lag = _peak_centre(lags, total, i)
    edge = i <= 1 or i >= len(total) - 2
    per, weights, realiased, disagree = [], [], [], []
    c = int(np.argmin(np.abs(lags - lag)))
    for corr, k in zip(curves, kept):
        f, w = freqs[k], float(sessions[k][5])
        # the session's peak in a window of its own (+-0.45 periods, one peak) centred on
        # the common lag: at a common lag ~0 the window and the estimate are a single
        # session's (+-0.45 periods about 0)
        half = int(round(min(0.5, 0.45 / f) / dt_s))
        near = slice(max(0, c - half), min(len(corr), c + half + 1))
        j = near.start + int(np.argmax(corr[near]))
        est = _peak_centre(lags, corr, j, near)
        mid = len(corr) // 2
        own = slice(max(0, mid - half), min(len(corr), mid + half + 1))
        if abs(est - _peak_centre(lags, corr, own.start + int(np.argmax(corr[own])), own)) \
                > 0.1 / f:
            realiased.append(k)
        if corr[c] < 0.5 * corr.max():
            disagree.append(k)
        per.append(-est)
        weights.append(w)
    order = np.argsort(per)
    cum = np.cumsum(np.asarray(weights)[order])
    offset = float(np.asarray(per)[order][np.searchsorted(cum, 0.5 * cum[-1])])
    return offset, {'lag_s': float(lag), 'search_s': float(search), 'per_session': per,
                    'sessions': kept, 'realiased': realiased, 'disagree': disagree,
                    'edge': bool(edge), 'ambiguous': ambiguous}


#: the power-to-label lag search of :func:`power_label_lag_s` spans at most this [s]
MAX_POWER_LAG_S = 0.5


def _nearest_index(t_label_s: np.ndarray, t_s: np.ndarray) -> np.ndarray:
    """Index of the nearest label stamp to each of ``t_s`` (ties to the earlier)."""
    if len(t_label_s) < 2:
        return np.zeros(len(t_s), dtype=int)
    right = np.clip(np.searchsorted(t_label_s, t_s), 1, len(t_label_s) - 1)
    left = right - 1
    return np.where(np.abs(t_s - t_label_s[left]) <= np.abs(t_label_s[right] - t_s), left, right)


#: :func:`schedule_labels`: a sample this close to a phase boundary [s] is on it (nanosecond
#: stamps, float phases)
BOUNDARY_TOL_S = 1e-6
#: :func:`schedule_labels`: two schedule messages whose periods (relative) or duty factors
#: differ by more than this are of different schedules (no boundary placed between them)
SAME_SCHEDULE_TOL = 1e-6


def schedule_labels(t_s: ArrayLike, t_label_s: ArrayLike, stance: ArrayLike,
                    clock: ArrayLike | None = None) -> np.ndarray:
    """Stance (True) or swing of the schedule at each of ``t_s``, from its labels.

    ``t_label_s`` (sorted) and ``stance``: the schedule messages' stamps and the leg's
    ``in_stance``. ``clock`` (m, 3): each message's leg phase ``(cycle_phase - theta) mod 1``
    (0 at touchdown), period [s] and duty factor (NaN where the message has none); None: no
    clock. Without a clock each ``t`` takes the nearest label (ties to the earlier), as
    before. With one, between two consecutive labels that differ the phase boundary is placed
    where the schedule puts it: the touchdown (leg phase 0) or lift-off (``duty``) crossing
    interpolated from both messages' phases (their mean), when both are of one schedule
    (period and duty factor equal within :data:`SAME_SCHEDULE_TOL`) and the two estimates
    agree within the labels' spacing and fall between them (clipped there); else the midpoint
    (the nearest label). A ``t`` on a label takes that label, as the nearest label did: a
    boundary on a label sample is where it was. Labels at 100 Hz placed boundaries up to 5 ms
    off (a tie at the midpoint went to the earlier label): up to +-0.49 % per phase at 0.75 and
    1.5 Hz on a 200 Hz power stream (outside review, the bench of ``energy_bench_bags``).

    Each ``t`` is labelled by the phase it lies in (a point sample), not split between the
    phases by the time it stands for: the simulated bench's servo step ending at a sample is
    the phase at that sample, and a split by time fraction read P_stance -0.3 to -0.43 %,
    P_swing +0.2 % against its own labels there.
    """
    t = np.asarray(t_s, float)
    tl = np.asarray(t_label_s, float)
    st = np.asarray(stance, bool)
    if tl.size == 0:
        raise InvalidInputError('schedule_labels needs at least one label')
    if tl.size == 1:
        return np.full(t.shape, bool(st[0]))
    i = np.clip(np.searchsorted(tl, t, side='right') - 1, 0, tl.size - 2)
    lo, hi = tl[i], tl[i + 1]
    # nearest label (ties to the earlier); before the first and after the last, the end's
    b = 0.5 * (lo + hi)
    out = np.where(t <= b, st[i], st[i + 1])
    out = np.where(t < tl[0], st[0], np.where(t >= tl[-1], st[-1], out))
    if clock is None:
        return out
    ck = np.asarray(clock, float)
    if ck.shape != (tl.size, 3):
        raise InvalidInputError(f'schedule clock must have shape ({tl.size}, 3), got '
                                f'{ck.shape}')
    # pairs of consecutive labels that differ, of one schedule, with a clock each
    j = np.flatnonzero(st[:-1] != st[1:])
    if j.size == 0:
        return out
    ph, per, duty = ck[:, 0], ck[:, 1], ck[:, 2]
    with np.errstate(invalid='ignore'):
        ok = (np.isfinite(ph) & np.isfinite(per) & (per > 0) & np.isfinite(duty) & (duty > 0)
              & (duty < 1))
        same = ok[j] & ok[j + 1] & \
            (np.abs(per[j] - per[j + 1]) <= SAME_SCHEDULE_TOL * per[j]) & \
            (np.abs(duty[j] - duty[j + 1]) <= SAME_SCHEDULE_TOL)
    j = j[same]
    if j.size == 0:
        return out
    edge = np.where(st[j], duty[j], 0.0)   # lift-off after a stance label, else touchdown
    # signed phase to the edge in [-0.5, 0.5) cycle from each message
    d0 = (edge - ph[j] + 0.5) % 1.0 - 0.5
    d1 = (edge - ph[j + 1] + 0.5) % 1.0 - 0.5
    b0, b1 = tl[j] + d0 * per[j], tl[j + 1] + d1 * per[j + 1]
    gap = tl[j + 1] - tl[j]
    fine = (np.abs(b0 - b1) <= gap) & (b0 >= tl[j] - gap) & (b0 <= tl[j + 1] + gap)
    j, bj = j[fine], np.clip(0.5 * (b0 + b1), tl[j], tl[j + 1])[fine]
    if j.size == 0:
        return out
    edge_at = np.full(tl.size - 1, np.nan)
    edge_at[j] = bj
    e = edge_at[i]
    placed = np.isfinite(e) & (t >= tl[0]) & (t < tl[-1])
    # a t on label i is that label's whatever the clock says (a boundary computed at tl[i]);
    # a t on the boundary (within stamp rounding) is in the phase that starts there, as the
    # schedule's own labels are (stance is the leg phase in [0, duty))
    return np.where(placed, np.where((t < e - BOUNDARY_TOL_S) | (t == lo), st[i], st[i + 1]),
                    out)


def _explained_curve(tp: np.ndarray, p: np.ndarray, tl: np.ndarray, st: np.ndarray,
                     gap: float | None, lag_k: np.ndarray, dt_s: float,
                     clock: np.ndarray | None = None) -> np.ndarray | None:
    """Fraction of the power variance the stance/swing labels explain (the between-phase sum
    of squares over the total) when each power sample ``t`` takes the label of the labels'
    timeline at ``t - k dt_s``, for each ``k`` of ``lag_k``; None when too few samples stay
    inside the labels at every lag. The timeline: the nearest label, or with the schedule's
    ``clock`` each phase boundary where the schedule puts it (:func:`schedule_labels`)."""
    grid = tl[0] + dt_s * np.arange(int((tl[-1] - tl[0]) / dt_s) + 1)
    near = _nearest_index(tl, grid)
    lab_g = st[near] if clock is None else schedule_labels(grid, tl, st, clock)
    valid_g = np.abs(tl[near] - grid) <= gap if gap else np.ones(len(grid), bool)
    reach = dt_s * max(abs(int(lag_k[0])), abs(int(lag_k[-1])))
    keep = (tp >= tl[0] + reach) & (tp <= tl[-1] - reach)
    if keep.sum() < 10:
        return None
    x = p[keep] - p[keep].mean()
    total = float(np.sum(x * x))
    if not total > 0:
        return None
    base = np.rint((tp[keep] - tl[0]) / dt_s).astype(int)
    idx = np.clip(base[:, None] - lag_k[None, :], 0, len(grid) - 1)
    w = valid_g[idx]
    b = lab_g[idx] & w
    n, n1 = w.sum(0).astype(float), b.sum(0).astype(float)
    sx, s1 = (w * x[:, None]).sum(0), (b * x[:, None]).sum(0)
    n0 = n - n1
    with np.errstate(invalid='ignore', divide='ignore'):
        bw = n1 * n0 / n * (s1 / n1 - (sx - s1) / n0) ** 2
    return np.where((n1 > 0) & (n0 > 0), bw, 0.0) / total


def power_label_lag_s(
    sessions: Sequence[tuple[Any, ...]],
    *,
    max_lag_s: float = MAX_POWER_LAG_S,
    dt_s: float = 0.002,
    phase_step: float = 0.005,
) -> dict[str, Any]:
    """Clock offset of the power stream behind the stance/swing labels [s], from several
    walking sessions at two or more frequencies.

    ``sessions``: ``(t_power_s, power_w, t_label_s, stance, max_label_gap_s, frequency_hz)``
    each, the labels on their own clock, optionally with a seventh item, the schedule's clock
    at each label (:func:`schedule_labels`; None: none). Each session's power is best split in
    two by the labels shifted by some lag (each power sample ``t`` taking the label nearest
    ``t - lag``, or with a clock the phase the schedule puts ``t - lag`` in; the fraction of
    its variance the split explains). The nearest label moves every phase boundary between
    two labels to their midpoint, up to half their spacing, by an amount that depends on which
    labels were recorded: on the simulated bench (0.75 and 1.5 Hz, no clock offset) a
    ``/gait/phase`` thinned to 50 Hz read -0.257 or -0.037 s (-0.011 s at 100 Hz), applied;
    with the clock -0.034 s at either rate. That lag is a clock offset ``d``, the
    same at every frequency, plus the waveform's own delay, which is phase-locked (a servo's
    current follows the commanded cycle: on the simulated bench the best split trails the
    schedule by 0.11 of a cycle at 1, 2 and 3 Hz, 0.107, 0.057 and 0.037 s). The model
    ``lag = d + phi / f`` is fitted on a grid, ``|d| <=`` ``max_lag_s``, a quarter of the
    shortest session and half the frequencies' common half period (at a duty factor of 0.5
    a split explains as much half a period later, stance and swing swapped, so ``d`` is
    known modulo that period), ``|phi| <= 0.25`` cycle, by the mean over the sessions of
    the fraction explained. Only ``d`` is a clock's error; ``phi`` is the physics the
    phase split measures.

    Returns ``lag_s`` (``d``: take ``lag_s`` off the power stamps), ``phase_lag`` (``phi``,
    cycles), ``se_s`` (jackknife over the sessions; inf with one), ``explained`` and
    ``explained_at_zero`` (mean fractions at the fit and at the best ``phi`` with ``d = 0``),
    ``second`` (the highest other peak of the profile over ``d``, as a fraction of the main
    peak's height above its minimum), ``agree`` (sessions at 80 % of their own best or more
    at the fit), ``sessions``, ``frequencies`` (distinct), ``search_s``, ``alias_s`` (the
    common half period: ``lag_s`` minus or plus it fits as well at a duty factor of 0.5) and
    ``edge`` (the fit at the search's edge).
    """
    rows, freqs = [], []
    for tp, p, tl, st, gap, f, *more in sessions:
        tp, p, tl = np.asarray(tp, float), np.asarray(p, float), np.asarray(tl, float)
        clock = np.asarray(more[0], float) if more and more[0] is not None else None
        if clock is not None and clock.shape != (len(tl), 3):
            clock = None
        if len(tl) >= 4 and len(tp) >= 10 and f > 0:
            rows.append((tp, p, tl, np.asarray(st, bool), gap, float(f), clock))
            freqs.append(float(f))
    if not rows:
        raise InvalidInputError('no session with power and labels to align')
    span = min(min(tl[-1], tp[-1]) - max(tl[0], tp[0]) for tp, _p, tl, *_rest in rows)
    half_period = _common_period_s([2 * f for f in freqs])
    search = min(max_lag_s, span / 4, 0.5 * half_period)
    n_d = int(search / dt_s)
    d_k = np.arange(-n_d, n_d + 1)
    phis = np.arange(-0.25, 0.25, phase_step)
    curves, kept = [], []
    for tp, p, tl, st, gap, f, clock in rows:
        n_phi = int(math.ceil(0.25 / f / dt_s)) + 1
        lag_k = np.arange(-n_d - n_phi, n_d + n_phi + 1)
        c = _explained_curve(tp, p, tl, st, gap, lag_k, dt_s, clock)
        if c is None:
            continue
        # (phi, d) -> the session's explained fraction at lag d + phi / f
        at = d_k[None, :] + np.rint(phis[:, None] / f / dt_s).astype(int) + n_d + n_phi
        curves.append(c[at])
        kept.append(f)
    if not curves:
        raise InvalidInputError('no session long enough to align power and labels')
    cube = np.array(curves)                      # (sessions, phi, d)
    n_s = len(cube)
    surf = cube.mean(0)

    def fit(s2: np.ndarray) -> tuple[int, int]:
        a, b = np.unravel_index(int(np.argmax(s2)), s2.shape)
        return int(a), int(b)

    def refine(profile: np.ndarray, i: int) -> float:
        if 0 < i < len(profile) - 1:   # parabola through the top three
            den = profile[i - 1] - 2 * profile[i] + profile[i + 1]
            if den < 0:
                return float((d_k[i] + 0.5 * (profile[i - 1] - profile[i + 1]) / den) * dt_s)
        return float(d_k[i] * dt_s)

    profile = surf.max(0)
    a, i = fit(surf)
    lag = refine(profile, i)
    if n_s > 1:
        jack = []
        for k in range(n_s):
            s2 = (surf * n_s - cube[k]) / (n_s - 1)
            jack.append(refine(s2.max(0), fit(s2)[1]))
        jk = np.array(jack)
        # not below the grid's resolution (sessions that agree to the sample read 0)
        se = max(float(np.sqrt((n_s - 1) / n_s * np.sum((jk - jk.mean()) ** 2))), dt_s / 2)
    else:
        se = math.inf
    low, top = float(profile.min()), float(profile[i])
    lo_i, hi_i = i, i
    half = low + 0.5 * (top - low)
    while lo_i > 0 and profile[lo_i - 1] >= half:
        lo_i -= 1
    while hi_i < len(profile) - 1 and profile[hi_i + 1] >= half:
        hi_i += 1
    others = [j for j in range(1, len(profile) - 1) if not lo_i <= j <= hi_i
              and profile[j] >= profile[j - 1] and profile[j] >= profile[j + 1]]
    j2 = max(others, key=lambda j: profile[j]) if others else None
    second = (profile[j2] - low) / (top - low) if j2 is not None and top > low else 0.0
    second_lag = float(d_k[j2] * dt_s) if j2 is not None else math.nan
    agree = int(sum(c[a, i] >= 0.8 * c.max() for c in cube))
    distinct = len({round(f, 6) for f in kept})
    return {'lag_s': lag, 'phase_lag': float(phis[a]), 'se_s': se, 'explained': top,
            'explained_at_zero': float(profile[n_d]), 'second': float(second),
            'second_lag_s': second_lag,
            'agree': agree, 'sessions': n_s, 'frequencies': distinct,
            'search_s': float(search), 'alias_s': float(half_period),
            'edge': bool(i <= 1 or i >= len(profile) - 2)}


def stance_mask(
    force_z_n: ArrayLike,
    tip_z_m: ArrayLike,
    *,
    force_threshold_n: float | None = None,
    height_margin_m: float = 0.01,
) -> np.ndarray:
    """Stance labels (n,) bool: force above threshold and tip within ``height_margin_m`` of
    the ground height (5th percentile of the tip height).

    Parameters
    ----------
    force_z_n, tip_z_m : array (n,)
        Normal force [N] and tip height [m] on the same (aligned) time base.
    force_threshold_n : float, optional
        Default: halfway between the 5th and the 95th force percentiles.
    height_margin_m : float
        Tip height above ground still counted as contact [m].
    """
    fz = np.asarray(force_z_n, float)
    z = np.asarray(tip_z_m, float)
    if fz.shape != z.shape:
        raise InvalidInputError(
            f'force and tip must have the same shape, got {fz.shape}, {z.shape}')
    if force_threshold_n is None:
        lo, hi = np.percentile(fz, [5, 95])
        force_threshold_n = lo + 0.5 * (hi - lo)
    ground = np.percentile(z, 5)
    return (fz > force_threshold_n) & (z < ground + height_margin_m)


@dataclass(frozen=True)
class PhaseSample:
    """Average input power of each phase for one bench session.

    ``t_stance_s``/``t_swing_s`` are the commanded phase durations (``inf`` at 0 Hz).
    """

    session_id: str
    load_kg: float
    frequency_hz: float
    duty_factor: float
    t_stance_s: float
    t_swing_s: float
    p_stance_w: float
    p_swing_w: float
    p_mean_w: float
    stance_fraction: float
    samples: int
    #: the tip path the leg walked (nan: not recorded): the surfaces hold for this geometry,
    #: another step length or height is mapped onto it (:mod:`hexapod_energy.prediction`)
    step_length_m: float = math.nan
    step_height_m: float = math.nan


def phase_powers(
    t_power_s: ArrayLike,
    power_w: ArrayLike,
    t_label_s: ArrayLike,
    stance: ArrayLike,
    *,
    session_id: str,
    load_kg: float,
    frequency_hz: float,
    duty_factor: float,
    normalise: str = 'nominal',
    max_label_gap_s: float | None = None,
    gap_fill: bool = True,
    label_clock: ArrayLike | None = None,
) -> PhaseSample:
    """Average power of the stance and of the swing of one session.

    Each power sample takes the label of the nearest label sample (with ``label_clock``, of
    the phase the schedule puts it in: :func:`schedule_labels`).  At 0 Hz (or when one phase
    is absent) both phase powers are the session mean (basal power).

    ``normalise='nominal'`` (default) divides each phase's energy per cycle by its *nominal*
    duration, ``P_stance = mean(p * stance) / beta`` and ``P_swing = mean(p * swing) /
    (1 - beta)``, so that ``beta P_stance + (1 - beta) P_swing`` is exactly the session's mean
    power whatever the detected contact fraction.  Eq. 1 weights the phases by ``beta``; the
    contact the sensors see lasts longer than the commanded stance (on the simulated bench
    ~0.70 of the cycle at beta 0.5: the stage stays on the tip until the tip has lifted it off
    its stop, and the servos lag the command), and plain per-phase means recombined with
    ``beta`` would overstate the whole-cycle power by ~30 % (the high swing power weighted by
    0.5 instead of 0.3).  ``normalise='detected'`` gives the plain means over the labelled
    samples (equal to the nominal form when the contact fraction is ``beta``).

    Parameters
    ----------
    t_power_s, power_w : array (n,)
        Input power samples of the session [s], [W].
    t_label_s, stance : array (m,)
        Label stamps [s] (on the power clock) and stance labels.
    max_label_gap_s : float, optional
        Power samples farther than this from every label sample (a gap in the labels' stream:
        a force sensor or the tip tracking lost for a while) are left out rather than given
        the label of the gap's end.
    gap_fill : bool
        When samples were left out (and ``normalise='nominal'``), each phase's energy per
        cycle is the mean over bins of the cycle's phase (``(t - t0) f mod 1``) of
        ``p * stance``, a bin no sample fell in taken from its neighbours: the plain mean over
        the samples left assumes they still cover the cycle evenly, which gaps at a fixed point
        of the cycle (a marker hidden at the top of every swing) or a few random ones do not
        (outside review A, F4: +-12 % at 0.5 Hz, up to 8 % with 5 % random tip dropouts).
        ``False``: the plain mean (as without gaps).
    label_clock : array (m, 3), optional
        Each label's leg phase, period [s] and duty factor (a schedule's, from its
        ``/gait/phase`` messages): each phase boundary is placed where the schedule puts it
        between two labels, not at their midpoint (:func:`schedule_labels`).
    """
    tp, p = np.asarray(t_power_s, float), np.asarray(power_w, float)
    tl, st = np.asarray(t_label_s, float), np.asarray(stance, bool)
    if len(p) == 0:
        raise InvalidInputError(f'session {session_id!r} has no power samples')
    mean = float(p.mean())
    if frequency_hz <= 0 or len(tl) == 0:
        return PhaseSample(session_id, float(load_kg), 0.0, float(duty_factor), math.inf,
                           math.inf, mean, mean, mean, float('nan'), len(p))
    # nearest label sample (the latest one before would delay labels by half a label period)
    right = np.clip(np.searchsorted(tl, tp), 1, len(tl) - 1) if len(tl) > 1 else \
        np.zeros(len(tp), dtype=int)
    if len(tl) > 1:
        left = right - 1
        idx = np.where(np.abs(tp - tl[left]) <= np.abs(tl[right] - tp), left, right)
    else:
        idx = right
    lab = st[idx] if label_clock is None else schedule_labels(tp, tl, st, label_clock)
    folded = False
    if max_label_gap_s is not None and len(tl):
        near = np.abs(tl[idx] - tp) <= max_label_gap_s
        if near.any() and not near.all():
            folded = gap_fill and (tp[-1] - tp[0]) * frequency_hz >= 1.0
            n_all = len(p)
            p, lab, tp = p[near], lab[near], tp[near]
    if normalise == 'nominal' and 0.0 < duty_factor < 1.0 and lab.any() and (~lab).any():
        if folded:
            e_st, e_sw = _cycle_phase_means(tp, p, lab, frequency_hz, n_all)
        else:
            e_st, e_sw = float(np.mean(p * lab)), float(np.mean(p * ~lab))
        p_st = e_st / duty_factor
        p_sw = e_sw / (1.0 - duty_factor)
    elif normalise in ('nominal', 'detected'):
        p_st = float(p[lab].mean()) if lab.any() else mean
        p_sw = float(p[~lab].mean()) if (~lab).any() else mean
    else:
        raise InvalidInputError(f"normalise must be 'nominal' or 'detected', got {normalise!r}")
    period = 1.0 / frequency_hz
    return PhaseSample(session_id, float(load_kg), float(frequency_hz), float(duty_factor),
                       duty_factor * period, (1.0 - duty_factor) * period, p_st, p_sw, mean,
                       float(lab.mean()), len(p))


def _cycle_phase_means(t_s: np.ndarray, p: np.ndarray, stance: np.ndarray, frequency_hz: float,
                       n_all: int) -> tuple[float, float]:
    """Means over the gait cycle of ``p * stance`` and ``p * ~stance`` as the means over bins
    of the cycle's phase (about two of the session's samples per bin and cycle, 4 to 50 bins)
    of the samples in each; empty bins take the linear interpolation of their neighbours
    around the cycle."""
    cycles = max((t_s[-1] - t_s[0]) * frequency_hz, 1.0)
    bins = int(np.clip(round(n_all / cycles / 2), 4, 50))
    k = np.minimum((((t_s - t_s[0]) * frequency_hz) % 1.0 * bins).astype(int), bins - 1)
    count = np.bincount(k, minlength=bins).astype(float)
    have = count > 0
    centre = np.arange(bins) + 0.5
    out = []
    for x in (p * stance, p * ~stance):
        mean = np.bincount(k, weights=x, minlength=bins)[have] / count[have]
        out.append(float(np.mean(np.interp(centre, centre[have], mean, period=bins))))
    return out[0], out[1]


@dataclass(frozen=True)
class PhaseSamples:
    """Column view of many :class:`PhaseSample` (arrays of shape (n,))."""

    load_kg: np.ndarray
    stance_rate_hz: np.ndarray  # 1 / T_stance, 0 at 0 Hz
    swing_rate_hz: np.ndarray
    p_stance_w: np.ndarray
    p_swing_w: np.ndarray
    frequency_hz: np.ndarray

    @classmethod
    def from_samples(cls, samples: Sequence[PhaseSample]) -> PhaseSamples:
        def col(f: Callable[[PhaseSample], float]) -> np.ndarray:
            return np.array([f(s) for s in samples], dtype=float)

        return cls(
            load_kg=col(lambda s: s.load_kg),
            stance_rate_hz=col(lambda s: 1.0 / s.t_stance_s),
            swing_rate_hz=col(lambda s: 1.0 / s.t_swing_s),
            p_stance_w=col(lambda s: s.p_stance_w),
            p_swing_w=col(lambda s: s.p_swing_w),
            frequency_hz=col(lambda s: s.frequency_hz),
        )


# ----------------------------------------------------------------------------- surfaces


class SurfaceModel(Protocol):
    """A regression ``y = f(x)`` with ``x`` of shape (n, 2)."""

    def fit(self, x: ArrayLike, y: ArrayLike) -> Any: ...

    def predict(self, x: ArrayLike) -> np.ndarray: ...


def _check_xy(x: ArrayLike, y: ArrayLike | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    xa = np.asarray(x, float)
    if xa.ndim != 2 or xa.shape[1] != 2:
        raise InvalidInputError(f'x must have shape (n, 2), got {xa.shape}')
    if y is None:
        return xa, None
    ya = np.asarray(y, float)
    if ya.shape != (len(xa),):
        raise InvalidInputError(f'y must have shape ({len(xa)},), got {ya.shape}')
    return xa, ya


class Lowess2D:
    """2-D local-linear LOWESS with tricube weights.

    At each query point the ``ceil(span * n)`` nearest training points (Euclidean distance after
    scaling each coordinate by its training range) get tricube weights
    ``(1 - (d / h)^3)^3``, ``h`` = 1.0001 x the largest of those distances, and a weighted
    least-squares plane ``y = b0 + b1 x0 + b2 x1`` gives the prediction ``b0 + b . x``.

    Parameters
    ----------
    span : float in (0, 1]
        Fraction of training points in each local fit.
    """

    def __init__(self, span: float = 0.8) -> None:
        if not 0.0 < span <= 1.0:
            raise InvalidInputError(f'span must be in (0, 1], got {span}')
        self.span = span

    def fit(self, x: ArrayLike, y: ArrayLike) -> Lowess2D:
        xa, ya = _check_xy(x, y)
        assert ya is not None
        if len(xa) < 4:
            raise FitError(f'LOWESS needs at least 4 points, got {len(xa)}')
        self.scale_ = np.where(np.ptp(xa, axis=0) > 0, np.ptp(xa, axis=0), 1.0)
        self.x_ = xa / self.scale_
        self.y_ = ya
        self.k_ = max(4, int(math.ceil(self.span * len(xa))))
        return self

    def predict(self, x: ArrayLike) -> np.ndarray:
        if not hasattr(self, 'x_'):
            raise NotFittedError('Lowess2D.predict called before fit')
        xq, _ = _check_xy(x)
        xq = xq / self.scale_
        d = np.linalg.norm(xq[:, None, :] - self.x_[None, :, :], axis=2)  # (q, n)
        h = np.sort(d, axis=1)[:, self.k_ - 1] * 1.0001 + 1e-12
        w = np.clip(1.0 - (d / h[:, None]) ** 3, 0.0, None) ** 3  # (q, n)
        design = np.concatenate([np.ones((len(self.x_), 1)), self.x_], axis=1)  # (n, 3)
        a = np.einsum('qn,ni,nj->qij', w, design, design) + 1e-12 * np.eye(3)
        b = np.einsum('qn,ni,n->qi', w, design, self.y_)
        coef = np.linalg.solve(a, b[..., None])[..., 0]
        return coef[:, 0] + np.sum(coef[:, 1:] * xq, axis=1)

    def to_dict(self) -> dict[str, Any]:
        return {'kind': 'lowess', 'span': self.span}


class PolySurface:
    """Least-squares surface linear in its parameters, physically motivated:

    ``P = c0 + c1 f + c2 f^2 + c3 m + c4 m f``, ``f`` = phase rate ``1 / T_phase`` [Hz], ``m``
    the load [kg]: basal power rising with load, a speed-proportional (friction, electronics)
    term, a speed-squared (Joule heating of the accelerating current) term and load-times-speed.
    ``degree=3`` adds ``c5 f^3 + c6 m f^2`` (candidate ``'poly3'``).
    """

    def __init__(self, degree: int = 2) -> None:
        if degree not in (2, 3):
            raise InvalidInputError(f'PolySurface degree must be 2 or 3, got {degree}')
        self.degree = degree

    def fit(self, x: ArrayLike, y: ArrayLike) -> PolySurface:
        xa, ya = _check_xy(x, y)
        design = self._design(xa)
        if len(xa) < design.shape[1]:
            raise FitError(f'PolySurface needs >= {design.shape[1]} points, got {len(xa)}')
        self.coef_, *_ = np.linalg.lstsq(design, ya, rcond=None)
        return self

    def _design(self, x: np.ndarray) -> np.ndarray:
        f, m = x[:, 0], x[:, 1]
        cols = [np.ones_like(f), f, f * f, m, m * f]
        if self.degree == 3:
            cols += [f ** 3, m * f * f]
        return np.stack(cols, axis=1)

    def predict(self, x: ArrayLike) -> np.ndarray:
        if not hasattr(self, 'coef_'):
            raise NotFittedError('PolySurface.predict called before fit')
        xq, _ = _check_xy(x)
        return self._design(xq) @ self.coef_

    #: the regressors of ``coef``, in order (``f`` the phase rate 1 / T_phase [Hz], ``m`` the
    #: load [kg]; P in W)
    TERMS = ('1', 'f', 'f^2', 'm', 'm f', 'f^3', 'm f^2')

    def to_dict(self) -> dict[str, Any]:
        coef = [float(c) for c in getattr(self, 'coef_', [])]
        return {'kind': 'poly' if self.degree == 2 else 'poly3', 'coef': coef,
                'terms': list(self.TERMS[:len(coef)]),
                # the reader of energy.json / report.html is told what f is (a review: it
                # read as the step frequency)
                'variables': 'f = 1 / T_phase [1/s] (the phase rate: twice the step '
                             'frequency at duty factor 0.5), m = bench load [kg], P [W]'}


def cross_validated_rmse(
    make_model: Callable[[], SurfaceModel],
    x: ArrayLike,
    y: ArrayLike,
    *,
    folds: int = 5,
    seed: int = 0,
) -> float:
    """k-fold cross-validated RMSE of a surface model [units of y].

    Folds are a seeded random partition; every point is predicted once by a model that did not
    see it.
    """
    xa, ya = _check_xy(x, y)
    assert ya is not None
    n = len(xa)
    folds = min(folds, n)
    if folds < 2:
        raise FitError(f'cross-validation needs >= 2 points, got {n}')
    order = np.random.default_rng(seed).permutation(n)
    pred = np.empty(n)
    for k in range(folds):
        test = order[k::folds]
        train = np.setdiff1d(order, test)
        pred[test] = make_model().fit(xa[train], ya[train]).predict(xa[test])
    return float(np.sqrt(np.mean((pred - ya) ** 2)))


# ----------------------------------------------------------------------------- the model


@dataclass
class _PhaseFit:
    model: Any
    chosen: str
    cv_rmse_w: dict[str, float]
    fit_rmse_w: float


@dataclass
class SingleLegModel:
    """Surface fits ``P_stance(T_stance, load)``, ``P_swing(T_swing, load)`` from bench sessions.

    Parameters
    ----------
    spans : (float, float)
        LOWESS spans for stance and swing (paper: 0.8, 0.9).
    candidates : sequence of str
        Surface kinds compared by cross-validation: ``'lowess'``, ``'poly'``, ``'poly3'``.
    folds : int
        k of the k-fold cross-validation.
    seed : int
        Seed of the fold partition.
    basal_in_stance : bool
        Whether the 0 Hz sessions enter the stance surface (module docstring).

    Fitted attributes
    -----------------
    samples_ : list of PhaseSample
    stance_, swing_ : fitted surface per phase (chosen candidate)
    chosen_ : {'stance': kind, 'swing': kind}
    cv_rmse_w_ : {'stance': {kind: rmse}, 'swing': {...}}  [W]
    fit_rmse_w_ : {'stance': rmse, 'swing': rmse}  in-sample [W]
    basal_power_w_ : {load_kg: mean power of its 0 Hz session}  [W]
    bench_step_ : (step length, step height) [m] the walking sessions walked, or None when
        they did not record it (:func:`bench_step_geometry`)
    domain_ : {'stance'|'swing': {'rate_hz': (lo, hi), 'load_kg': (lo, hi)}}, the measured
        range of each surface's sessions (``rate = 1 / T_phase``); :meth:`outside_domain`
        says how far a prediction reaches beyond it
    """

    spans: tuple[float, float] = (0.8, 0.9)
    candidates: tuple[str, ...] = ('lowess', 'poly', 'poly3')
    folds: int = 5
    seed: int = 0
    basal_in_stance: bool = False
    _fits: dict[str, _PhaseFit] = field(default_factory=dict, repr=False)

    def _factory(self, kind: str, phase: str) -> Callable[[], SurfaceModel]:
        span = self.spans[0] if phase == 'stance' else self.spans[1]
        if kind == 'lowess':
            return lambda: Lowess2D(span)
        if kind == 'poly':
            return PolySurface
        if kind == 'poly3':
            return lambda: PolySurface(3)
        raise InvalidInputError(
            f"surface candidate must be 'lowess', 'poly' or 'poly3', got {kind!r}")

    def fit(self, samples: Sequence[PhaseSample]) -> SingleLegModel:
        """Fit both surfaces from per-session phase powers. Fewer walking sessions than
        :meth:`min_walking_sessions` are refused up front, the minimum named."""
        walking = sum(1 for s in samples if s.frequency_hz > 0)
        need = self.min_walking_sessions()
        if walking < need:
            raise FitError(
                f'single-leg fit needs >= {need} walking sessions (frequency > 0; the swing '
                f'surface has no others) with {self.folds}-fold cross-validation, got '
                f'{walking} walking of {len(samples)} sessions: the bench plan needs more '
                'loads x frequencies')
        cols = PhaseSamples.from_samples(samples)
        self.samples_ = list(samples)
        self._fits = {}
        self.domain_: dict[str, dict[str, tuple[float, float]]] = {}
        moving = cols.frequency_hz > 0
        if not np.any(moving):
            raise InvalidInputError(
                f'single-leg fit: none of the {len(samples)} bench sessions walks (all 0 Hz): '
                'the phase surfaces need walking sessions (a leg tip that never moves: is its '
                'height on z, REP-103?)')
        for phase, rate, y, keep in (
            ('stance', cols.stance_rate_hz, cols.p_stance_w,
             np.ones_like(moving) if self.basal_in_stance else moving),
            ('swing', cols.swing_rate_hz, cols.p_swing_w, moving),
        ):
            x = np.stack([rate, cols.load_kg], axis=1)[keep]
            y = y[keep]
            self.domain_[phase] = {'rate_hz': (float(x[:, 0].min()), float(x[:, 0].max())),
                                   'load_kg': (float(x[:, 1].min()), float(x[:, 1].max()))}
            # a candidate with more coefficients than a small bench's folds hold sessions
            # (poly3: 10) cannot compete: its CV error is infinite, the others decide
            cv, why = {}, []
            for kind in self.candidates:
                try:
                    cv[kind] = cross_validated_rmse(self._factory(kind, phase), x, y,
                                                    folds=self.folds, seed=self.seed)
                except FitError as err:
                    cv[kind] = math.inf
                    why.append(f'{kind}: {err}')
            if all(math.isinf(v) for v in cv.values()):
                raise FitError(f'{phase} surface: {len(y)} walking sessions are too few for '
                               f'every candidate ({"; ".join(why)}); the bench plan needs more '
                               'loads x frequencies')
            best = min(cv, key=cv.__getitem__)
            model = self._factory(best, phase)().fit(x, y)
            fit_rmse = float(np.sqrt(np.mean((model.predict(x) - y) ** 2)))
            self._fits[phase] = _PhaseFit(model, best, cv, fit_rmse)
        basal: dict[float, list[float]] = {}
        for s in samples:
            if s.frequency_hz <= 0:
                basal.setdefault(s.load_kg, []).append(s.p_mean_w)
        self.basal_power_w_ = {k: float(np.mean(v)) for k, v in sorted(basal.items())}
        self.bench_step_ = bench_step_geometry(samples)
        return self

    #: the fewest training points each candidate fits (LOWESS: a plane and a neighbour;
    #: PolySurface: its coefficients)
    MIN_POINTS = {'lowess': 4, 'poly': 5, 'poly3': 7}

    def min_walking_sessions(self) -> int:
        """The fewest walking sessions the surfaces can be fitted from: every fold of the
        k-fold cross-validation must leave at least one candidate its fewest training points
        (:attr:`MIN_POINTS`; default candidates and 5 folds: 5 walking sessions, 4 train each
        fold's LOWESS)."""
        least = min(self.MIN_POINTS.get(k, 4) for k in self.candidates)
        n = least + 1
        while n - math.ceil(n / max(2, min(self.folds, n))) < least:
            n += 1
        return n

    def _fit(self, phase: str) -> _PhaseFit:
        if phase not in self._fits:
            raise NotFittedError('SingleLegModel used before fit')
        return self._fits[phase]

    @property
    def chosen_(self) -> dict[str, str]:
        return {p: self._fit(p).chosen for p in ('stance', 'swing')}

    @property
    def cv_rmse_w_(self) -> dict[str, dict[str, float]]:
        return {p: dict(self._fit(p).cv_rmse_w) for p in ('stance', 'swing')}

    @property
    def fit_rmse_w_(self) -> dict[str, float]:
        return {p: self._fit(p).fit_rmse_w for p in ('stance', 'swing')}

    def _predict(self, phase: str, t_phase_s: ArrayLike, load_kg: ArrayLike) -> np.ndarray:
        t, m = np.broadcast_arrays(np.asarray(t_phase_s, float), np.asarray(load_kg, float))
        if np.any(t <= 0):
            raise InvalidInputError(f'{phase} durations must be > 0 s, got min {t.min()}')
        x = np.stack([1.0 / t.ravel(), m.ravel()], axis=1)
        return self._fit(phase).model.predict(x).reshape(t.shape)

    def p_stance_w(self, t_stance_s: ArrayLike, load_kg: ArrayLike) -> np.ndarray:
        """Average stance power [W] for stance durations [s] and loads [kg] (broadcast)."""
        return self._predict('stance', t_stance_s, load_kg)

    def p_swing_w(self, t_swing_s: ArrayLike, load_kg: ArrayLike) -> np.ndarray:
        """Average swing power [W] for swing durations [s] and loads [kg] (broadcast)."""
        return self._predict('swing', t_swing_s, load_kg)

    def outside_domain(self, phase: str, t_phase_s: float, load_kg: float) -> list[str]:
        """What of ``(T_phase, load)`` lies beyond the bench's measured range of ``phase``,
        in words (empty when inside; :data:`DOMAIN_TOLERANCE` says how far beyond counts).

        The surfaces are local fits in ``1 / T_phase`` and load: outside the sessions' range
        they extrapolate linearly (LOWESS) or by their polynomial, which the cross-validation
        never tested.
        """
        dom = self._domain(phase)
        out = []
        rate = 1.0 / t_phase_s if t_phase_s > 0 else math.inf
        lo, hi = dom['rate_hz']
        if rate < lo / (1.0 + DOMAIN_TOLERANCE) or rate > hi * (1.0 + DOMAIN_TOLERANCE):
            slow = 1.0 / lo if lo > 0 else math.inf
            out.append(f'{phase} {t_phase_s:.3g} s outside the bench\'s '
                       f'{1.0 / hi:.3g}-{slow:.3g} s')
        lo, hi = dom['load_kg']
        tol = DOMAIN_TOLERANCE * max(hi - lo, 1e-9)
        if load_kg < lo - tol or load_kg > hi + tol:
            out.append(f'{phase} load {load_kg:.3g} kg outside the bench\'s '
                       f'{lo:.3g}-{hi:.3g} kg')
        return out

    def _domain(self, phase: str) -> dict[str, tuple[float, float]]:
        self._fit(phase)
        return self.domain_[phase]

    def basal_power_at_w(self, load_kg: float) -> float:
        """Basal power interpolated over the 0 Hz sessions' loads [W] (nan without any);
        beyond them extrapolated along the line through the two nearest loads, as the phase
        surfaces (linear in the load) extrapolate Eq. 1 there: held at the heaviest load's
        value, the power breakdown's holding_w read 9.6 W for 13.2 beside an Eq. 1 that
        extrapolated (outside review B4). One load: that value."""
        if not self.basal_power_w_:
            return float('nan')
        order = sorted(self.basal_power_w_)
        loads = np.array(order, dtype=float)
        power = np.array([self.basal_power_w_[k] for k in order], dtype=float)
        m = float(load_kg)
        if loads.size >= 2 and (m > loads[-1] or m < loads[0]):
            i = (-2, -1) if m > loads[-1] else (0, 1)
            slope = (power[i[1]] - power[i[0]]) / (loads[i[1]] - loads[i[0]])
            end = i[1] if m > loads[-1] else i[0]
            return float(power[end] + slope * (m - loads[end]))
        return float(np.interp(m, loads, power))

    def summary(self) -> dict[str, Any]:
        """JSON-ready description of the fit."""
        return {
            'spans': list(self.spans),
            'chosen': self.chosen_,
            'cv_rmse_w': self.cv_rmse_w_,
            'fit_rmse_w': self.fit_rmse_w_,
            'basal_power_w': {f'{k:.3f}': v for k, v in self.basal_power_w_.items()},
            'domain': {p: {k: list(v) for k, v in d.items()} for p, d in self.domain_.items()},
            'sessions': [asdict(s) for s in self.samples_],
            # the chosen surfaces themselves (a polynomial's coefficients; LOWESS is
            # re-fitted from 'sessions' with its span), to re-evaluate Eq. 1 from the JSON
            'surfaces': {p: self._fit(p).model.to_dict() for p in ('stance', 'swing')},
            'step_geometry_m': (None if self.bench_step_ is None else
                                {'step_length': self.bench_step_[0],
                                 'step_height': self.bench_step_[1]}),
        }


def bench_step_geometry(samples: Sequence[PhaseSample]) -> tuple[float, float] | None:
    """The step length and height [m] the bench's walking sessions walked (their medians),
    None when a session did not record them. Sessions of different geometries would mix
    tip paths in one surface: :class:`InvalidInputError` (the bench plan must hold one)."""
    walk = [s for s in samples if s.frequency_hz > 0]
    if not walk or not all(math.isfinite(s.step_length_m) and math.isfinite(s.step_height_m)
                           and s.step_length_m > 0 for s in walk):
        return None
    lengths = np.array([s.step_length_m for s in walk])
    heights = np.array([s.step_height_m for s in walk])
    for name, x in (('step length', lengths), ('step height', heights)):
        if np.ptp(x) > 0.02 * max(float(np.max(np.abs(x))), 1e-9):
            raise InvalidInputError(
                f'bench sessions walked different {name}s ({np.min(x):.4g}-{np.max(x):.4g} '
                'm): the phase surfaces are fitted over durations and loads of one tip path; '
                'give the sessions of one geometry')
    return float(np.median(lengths)), float(np.median(heights))


def samples_from_mapping(rows: Sequence[Mapping[str, Any]]) -> list[PhaseSample]:
    """Rebuild :class:`PhaseSample` rows from their ``asdict`` form (e.g. read from JSON)."""
    return [PhaseSample(**dict(r)) for r in rows]
