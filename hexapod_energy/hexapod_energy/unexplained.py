"""What the residual loop could not explain: the final residual against the windows' noise.

The loop (:mod:`hexapod_energy.residuals`) only ever adds effects of its catalogue, so data
with an effect outside it (an accessory switched on mid-run, a payload picked up, a supply that
ripples, one run on another floor) is fitted by whichever candidates absorb most of it, and the
loop used to report them as "the model missed ..." with nothing said about the residual they
left. This module measures that leftover and says what shape it has.

* **Noise floor** ``noise_w``: the spread of the second differences of the final residual
  over windows two apart in the same run (the same half of the gait cycle), ``1.4826
  MAD(r[i+4] - 2 r[i+2] + r[i]) / sqrt(6)``: a trend cancels, a step touches two of them (the
  median ignores it) and a slow ripple little.
* **Isolated windows** (a window cut short at a run's end, a stumble) are set apart first: a
  window further than ``isolated_share`` of the mean power (and 8 noise floors) from the
  median of its two same-half neighbours on each side, on both sides with the same sign,
  while those neighbours agree among themselves to a third of that; they are counted and
  listed (``isolated``), not taken for structure.
* **Structured part** ``structured_w = sqrt(max(rms^2 - noise^2, 0))``; it is *significant*
  when it exceeds ``factor`` (2) times the noise floor and ``min_share`` (1 %) of the mean
  measured power, or, under that share, when it is a step within runs that explains
  :data:`STEP_SHARE` of it (``below_min_share``): clean simulated runs leave 0.25-0.35 W,
  10-14 noise floors but under 1 %, as offsets between runs or ripple; a fan's 2 W step
  beside a basal power left 0.59 W of 59 W, 2.6 noise floors, and was silent (an outside
  review).
* **Shape**: the residual is fitted by three patterns, each per run: an offset, an offset and a
  linear trend, an offset and one step (its place searched, at least ``min_side`` windows on
  each side); the one with the lowest BIC is reported with its numbers, or ``'other'`` when
  it leaves more than half of the structured variance (a ripple, a drift that is not linear).
  Offsets are preferred to a trend or step that explains less than :data:`OFFSETS_MARGIN`
  more of the structured variance (the BIC alone, over a low noise floor, told +2.5 W in one
  run as drifts of a fraction of a watt per minute).

Core module: numpy only. Arrays are per window, shapes ``(n,)``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hexapod_common.series import robust_sigma

__all__ = ['PATTERNS', 'isolated_windows', 'noise_floor_w', 'unexplained_residual',
           'unexplained_text']

#: a leftover under ``min_share`` of the mean power is still significant when it is a step
#: within runs that explains this share of its structured variance (and is above the noise)
STEP_SHARE = 0.8

#: shapes the leftover residual is described by
PATTERNS = ('run_offsets', 'trend', 'step', 'other')

#: a trend or step is told only when it explains this share of the structured variance more
#: than offsets between runs alone
OFFSETS_MARGIN = 0.1


def noise_floor_w(run: np.ndarray, t_s: np.ndarray, residual_w: np.ndarray) -> float:
    """White-noise level of the windows [W] from robust second differences of windows two
    apart in each run (nan with fewer than 3 of them)."""
    diffs = []
    for k in np.unique(run):
        r = residual_w[run == k][np.argsort(t_s[run == k], kind='stable')]
        if r.size >= 5:
            diffs.append(r[4:] - 2.0 * r[2:-2] + r[:-4])
    if not diffs:
        return math.nan
    d = np.concatenate(diffs)
    if d.size < 3:
        return math.nan
    return robust_sigma(d) / math.sqrt(6.0)


def isolated_windows(run: np.ndarray, t_s: np.ndarray, residual_w: np.ndarray,
                     threshold_w: float) -> np.ndarray:
    """Bool (n,): windows that stand apart from their same-half neighbours (module docs)."""
    out = np.zeros(residual_w.shape, dtype=bool)
    for k in np.unique(run):
        idx = np.flatnonzero(run == k)
        idx = idx[np.argsort(t_s[idx], kind='stable')]
        r = residual_w[idx]
        n = r.size
        for i in range(n):
            sides = []
            for nb in ([i - 4, i - 2], [i + 2, i + 4]):
                nb = [j for j in nb if 0 <= j < n]
                if len(nb) == 2:
                    sides.append(r[nb])
            if not sides:
                continue
            dev = [r[i] - float(np.median(v)) for v in sides]
            spread = max(float(np.ptp(v)) for v in sides)
            if (all(abs(d) > threshold_w for d in dev) and len({d > 0 for d in dev}) == 1
                    and spread < min(abs(d) for d in dev) / 3.0):
                out[idx[i]] = True
    return out


def _fit_run(t: np.ndarray, r: np.ndarray, pattern: str, min_side: int
             ) -> tuple[float, dict[str, float]]:
    """SSE and parameters of one run's residual under ``pattern`` (t sorted)."""
    if pattern == 'run_offsets':
        m = float(r.mean())
        return float(np.sum((r - m) ** 2)), {'mean_w': m}
    if pattern == 'trend':
        if r.size < 3 or np.ptp(t) <= 0:
            m = float(r.mean())
            return float(np.sum((r - m) ** 2)), {'mean_w': m, 'slope_w_per_s': 0.0}
        slope, icpt = np.polyfit(t - t[0], r, 1)
        fit = icpt + slope * (t - t[0])
        return float(np.sum((r - fit) ** 2)), {'mean_w': float(r.mean()),
                                                'slope_w_per_s': float(slope)}
    # step: the split that leaves the least squared error
    n = r.size
    if n < 2 * min_side:
        m = float(r.mean())
        return float(np.sum((r - m) ** 2)), {'mean_w': m, 'step_w': 0.0, 'at_s': float(t[0])}
    c1 = np.cumsum(r)
    c2 = np.cumsum(r * r)
    k = np.arange(min_side, n - min_side + 1)
    s_left = c2[k - 1] - c1[k - 1] ** 2 / k
    s_right = (c2[-1] - c2[k - 1]) - (c1[-1] - c1[k - 1]) ** 2 / (n - k)
    best = int(np.argmin(s_left + s_right))
    kk = int(k[best])
    before, after = float(r[:kk].mean()), float(r[kk:].mean())
    return float(s_left[best] + s_right[best]), {
        'mean_w': float(r.mean()), 'step_w': after - before,
        'at_s': float(0.5 * (t[kk - 1] + t[kk]))}


def unexplained_residual(run: np.ndarray, t_s: np.ndarray, residual_w: np.ndarray, *,
                         run_names: Sequence[str] | None = None, mean_power_w: float,
                         run_t0_s: Sequence[float] | None = None, factor: float = 2.0,
                         min_share: float = 0.01,
                         isolated_share: float = 0.03, min_side: int = 4) -> dict[str, Any]:
    """The final residual's size against its noise, and its shape when it is significant.

    Parameters
    ----------
    run : (n,) int
        Run index of each window.
    t_s : (n,)
        Window centre [s].
    residual_w : (n,)
        Measured minus predicted input power after the added effects [W].
    run_names : sequence of str, optional
        Names of the runs (index order), for the per-run figures.
    run_t0_s : sequence of float, optional
        Start of each run [s] (index order), from which the reported times count (default:
        its first window).
    mean_power_w : float
        Mean measured input power [W] (the significance threshold's scale).

    Returns
    -------
    dict
        ``rmse_w``, ``noise_w``, ``structured_w``, ``significant`` (over the windows that
        are not isolated), ``isolated`` (run, ``at_s`` from the run's start, ``residual_w``
        of each isolated window); with ``significant``:
        ``pattern`` (one of :data:`PATTERNS`), ``explained_share`` (of the structured
        variance, by the pattern) and ``per_run`` (name, ``mean_w`` and the pattern's
        ``slope_w_per_s`` or ``step_w`` / ``at_s``, the step's time from the run's start).
    """
    run = np.asarray(run, dtype=int)
    t = np.asarray(t_s, dtype=float)
    r = np.asarray(residual_w, dtype=float)
    noise = noise_floor_w(run, t, r)
    names_all = [str(x) for x in run_names] if run_names is not None else []
    t0 = {int(k): (float(run_t0_s[k]) if run_t0_s is not None and k < len(run_t0_s)
                   else float(t[run == k].min())) for k in np.unique(run)}
    iso = isolated_windows(run, t, r, max(isolated_share * abs(mean_power_w),
                                          8.0 * (noise if math.isfinite(noise) else 0.0)))
    isolated = [{'run': names_all[k] if k < len(names_all) else f'run {k}',
                 'at_s': float(tt) - t0[int(k)], 'residual_w': float(rr)}
                for k, tt, rr in zip(run[iso], t[iso], r[iso])]
    run, t, r = run[~iso], t[~iso], r[~iso]
    rms = float(np.sqrt(np.mean(r ** 2))) if r.size else math.nan
    structured = math.sqrt(max(rms ** 2 - noise ** 2, 0.0)) if math.isfinite(noise) else \
        math.nan
    above_noise = bool(math.isfinite(structured) and structured > factor * noise)
    significant = above_noise and structured > min_share * abs(mean_power_w)
    out: dict[str, Any] = {'rmse_w': rms, 'noise_w': noise, 'structured_w': structured,
                           'significant': significant, 'factor': factor,
                           'min_share': min_share, 'isolated': isolated}
    if not above_noise:
        return out
    runs = list(np.unique(run))
    names = [str(run_names[k]) if run_names is not None and k < len(run_names) else
             f'run {k}' for k in runs]
    n = r.size
    total = float(np.sum(r ** 2))
    best: tuple[float, str, float, list[dict[str, Any]]] | None = None
    fits: dict[str, tuple[float, str, float, list[dict[str, Any]]]] = {}
    for pattern, per_run_k in (('run_offsets', 1), ('trend', 2), ('step', 3)):
        sse, rows = 0.0, []
        for k, name in zip(runs, names):
            m = run == k
            order = np.argsort(t[m], kind='stable')
            tk, rk = t[m][order], r[m][order]
            s, params = _fit_run(tk, rk, pattern, min_side)
            if 'at_s' in params:
                params['at_s'] = params['at_s'] - t0[int(k)]
            sse += s
            rows.append({'run': name, **params})
        bic = n * math.log(max(sse, 1e-300) / n) + per_run_k * len(runs) * math.log(n)
        fits[pattern] = (bic, pattern, sse, rows)
        if best is None or bic < best[0]:
            best = (bic, pattern, sse, rows)
    assert best is not None
    structured_ss = max(total - n * noise ** 2, 1e-300)

    def share_of(fit: tuple[float, str, float, list[dict[str, Any]]]) -> float:
        return float(np.clip((total - fit[2]) / structured_ss, 0.0, 1.0))

    # with a low noise floor the BIC takes a trend or step for a hair's breadth more; what is
    # left is said as offsets between runs when they explain nearly as much (+2.5 W in one
    # run, 99.7 % offsets, was told as drifts of +0.13 to +0.28 W/min)
    if best[1] != 'run_offsets' and \
            share_of(fits['run_offsets']) >= share_of(best) - OFFSETS_MARGIN:
        best = fits['run_offsets']
    _, pattern, sse, rows = best
    share = share_of(best)
    if not significant:
        # under min_share of the mean power: only a step within runs that the step pattern
        # explains (a fan switched on, 0.59 W of 59 W beside a basal power, 2.6 noise floors,
        # was silent: an outside review); clean runs leave offsets between runs or ripple
        if not (pattern == 'step' and share >= STEP_SHARE):
            return out
        out['significant'] = True
        out['below_min_share'] = True
    out['explained_share'] = share
    out['pattern'] = pattern if share >= 0.5 else 'other'
    out['per_run'] = rows
    return out


def unexplained_text(u: dict[str, Any], unit: str = 'W', *, effects_added: bool = True) -> str:
    """One or two sentences for the loop's summary ('' when nothing significant is left);
    ``effects_added``: whether the loop added any effect (the caution about them)."""
    iso = u.get('isolated') or []
    iso_text = ''
    if iso:
        iso_text = (f"{len(iso)} window{'s' if len(iso) > 1 else ''} stood apart from "
                    f"{'their' if len(iso) > 1 else 'its'} neighbours (" + ', '.join(
                        f"{Path(x['run']).name} at {x['at_s']:.1f} s {x['residual_w']:+.2f} "
                        f"{unit}" for x in iso[:5]) + (', ...' if len(iso) > 5 else '')
                    + f") and {'were' if len(iso) > 1 else 'was'} left out of this check.")
    if not u.get('significant'):
        return iso_text
    head = (f"A residual of {u['structured_w']:.3g} {unit} RMS remains beyond the windows' "
            f"noise ({u['noise_w']:.2g} {unit}) that no effect of the catalogue explains")
    rows = [dict(x, run=Path(str(x['run'])).name or str(x['run']))
            for x in u.get('per_run', [])]
    pattern = u.get('pattern')
    means = [x['mean_w'] for x in rows]
    if pattern == 'run_offsets' and (all(m > 0 for m in means) or all(m < 0 for m in means)):
        side = 'under' if means[0] > 0 else 'over'
        shape = (f"the model {side}-predicts every run, by {min(map(abs, means)):.2f} to "
                 f"{max(map(abs, means)):.2f} {unit} (" + ', '.join(
                     f"{x['run']} {x['mean_w']:+.2f} {unit}" for x in rows) + ')')
    elif pattern == 'run_offsets':
        shape = 'it differs between runs (mean ' + ', '.join(
            f"{x['run']} {x['mean_w']:+.2f} {unit}" for x in rows) + ')'
    elif pattern == 'trend':
        shape = 'it drifts within runs (' + ', '.join(
            f"{x['run']} {60 * x['slope_w_per_s']:+.2f} {unit}/min about {x['mean_w']:+.2f} "
            f'{unit}' for x in rows) + ')'
    elif pattern == 'step':
        shape = 'it steps within runs (' + ', '.join(
            f"{x['run']} {x['step_w']:+.2f} {unit} at {x['at_s']:.1f} s" for x in rows) + ')'
    else:
        shape = ('it varies within runs without one step or trend (a ripple, a changing '
                 'load: see the residual plot)')
    care = (' The effects added above may have absorbed part of it; read their values with '
            'care.') if effects_added else ''
    return f'{head}: {shape}.{care}' + (' ' + iso_text if iso_text else '')
