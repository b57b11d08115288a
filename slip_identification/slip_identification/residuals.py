"""SLIP loop (DESIGN section 8): per-stance fits of the plain template against the template
with one extension (``leg_damping`` [N s/m], ``hip_torque`` [N m]), selected by BIC on training
stances and confirmed by the normalised state error (nerr) of held-out stances.

Core module: numpy and this package's fitters; no ROS.

Rule. Stances are split by index (every ``every``-th held out). An extension is a candidate
when, on the training stances, the summed BIC change against plain SLIP is below
``-min_delta_bic`` per stance on median; it is selected when, in addition, the mean nerr of the
held-out stances falls by more than ``min_improvement`` (fraction) and the fitted extension
parameter is non-zero by more than 2 standard errors on median. The parameter must also be one
property of the robot, not a per-stance fudge: its training median must be physical (leg
damping >= 0: :data:`PHYSICAL_SIGN`), at least ``min_same_sign`` of the training stances must
share its sign, and the median must stand out of the spread between stances (more than 2 of
its standard errors, ``1.2533 sd / sqrt(n)``). An outside review had a leg damping of
-31.2 N s/m named as missed, per-stance values from -105 to +4462 N s/m. Only the best
extension is added (forward selection stops after one: each extension is a per-stance
template).

Report (an outside review, H, on simulated EduBot runs). A parameter of one consistent value
of the unphysical sign (clean running: leg damping -61.5 N s/m on median, every stance
negative) is said to be what it is, energy added during stance that the template lacks (the
hip motors), not a per-stance fudge (``consistency``). Every candidate that lowered the
held-out error but was not added is named with every reason (clean pace: hip torque 0.343 ->
0.237 was left out of the summary because it failed the standard-error test). An extension
that passed every check and removed at least :data:`ALTERNATIVE_SHARE` of the held-out error
the added one removed is named beside it. The per-stance nerr left is checked for a step or
trend over each run and for stances standing apart (:func:`nerr_time_pattern`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from hexapod_common.series import robust_sigma

from .errors import SlipDataError
from .fit import SlipFitResult, SlipFitter, Stance
from .model import EXTENSIONS, SlipModel

__all__ = [
    'SLIP_CANDIDATES',
    'SlipExtensionSelection',
    'fit_slip_candidates',
    'nerr_time_pattern',
    'slip_loop_document',
]

#: sign an extension's parameter must have to be physical (+1: >= 0; 0: either)
PHYSICAL_SIGN: Mapping[str, int] = {'leg_damping': 1, 'hip_torque': 0}

#: what a consistent value of the unphysical sign means (an outside review: EduBot stances fit
#: a leg damping of -61.5 N s/m on median, every one of 28 stances negative, and the summary
#: called it "not one property of the robot")
UNPHYSICAL_MEANING: Mapping[str, str] = {
    'leg_damping': ('energy is added during stance (by the hip motors, for one), which the '
                    'template lacks; leg damping cannot be measured under it')}

#: an extension that passed every check is named beside the one added when it removed at least
#: this share of the held-out error the added one removed (the stances cannot tell them apart)
ALTERNATIVE_SHARE = 0.9

#: extension name -> SlipModel extensions tuple
SLIP_CANDIDATES: Mapping[str, tuple[str, ...]] = {
    'leg_damping': ('leg_damping',), 'hip_torque': ('hip_torque',)}


def fit_slip_candidates(stances: Sequence[Stance], *, mass_kg: float | None = None,
                        **fitter_kw: Any) -> dict[str, list[SlipFitResult]]:
    """Fit every stance with ``slip`` and each candidate extension; {'slip': [...], ...}."""
    kw = {} if mass_kg is None else {'mass_kg': mass_kg}
    out = {'slip': SlipFitter(SlipModel(**kw), **fitter_kw).fit(stances).results_}
    for name, ext in SLIP_CANDIDATES.items():
        out[name] = SlipFitter(SlipModel(extensions=ext, **kw), **fitter_kw).fit(stances).results_
    return out


def _metrics(nerr: np.ndarray) -> dict[str, float]:
    # the SLIP residual is the normalised state error itself (>= 0): rmse of the per-stance
    # nerr, mean absolute = mean nerr, bias = mean nerr
    return {'rmse': float(np.sqrt(np.mean(nerr ** 2))), 'mae': float(np.mean(np.abs(nerr))),
            'bias': float(np.mean(nerr))}


@dataclass
class SlipExtensionSelection:
    """Select a SLIP extension from paired per-stance fits.

    Parameters
    ----------
    every : int
        Every ``every``-th stance is held out.
    min_delta_bic : float
        Median per-stance BIC change must be below ``-min_delta_bic``.
    min_improvement : float
        Held-out mean nerr must fall by more than this fraction.

    Fitted attributes
    -----------------
    selected_ : list of str (zero or one name)
    candidates_ : list of dict (name, heldout_rmse, delta_bic, selected, params, stderr)
    held_ : bool (n,) held-out stances
    """

    every: int = 3
    min_delta_bic: float = 10.0
    min_improvement: float = 0.05
    min_same_sign: float = 0.75

    def fit(self, fits: Mapping[str, Sequence[SlipFitResult]]) -> SlipExtensionSelection:
        """``fits``: 'slip' and each extension name -> results in the same stance order."""
        base = list(fits['slip'])
        n = len(base)
        if n < 3 or n // self.every < 1:
            raise SlipDataError(f'too little data to split: {n} fitted stances, need >= 3 '
                                f'(every {self.every}th is held out)')
        held = (np.arange(n) % self.every) == self.every - 1
        train = ~held
        nerr0 = np.array([r.nerr for r in base])
        bic0 = np.array([r.bic() for r in base])
        self.held_ = held
        self.nerr_before_ = nerr0
        rmse0 = float(np.sqrt(np.mean(nerr0[held] ** 2)))
        cands, best = [], None
        for name, ext in SLIP_CANDIDATES.items():
            res = list(fits.get(name, ()))
            if len(res) != n:
                continue
            nerr = np.array([r.nerr for r in res])
            dbic = np.array([r.bic() for r in res]) - bic0
            pname = ext[0]
            vals = np.array([r.params[pname] for r in res])
            ses = np.array([r.stderr.get(pname, math.nan) for r in res])
            rmse = float(np.sqrt(np.mean(nerr[held] ** 2)))
            med_dbic = float(np.nanmedian(dbic[train]))
            signif = float(np.nanmedian(np.abs(vals[train]) / np.where(ses[train] > 0,
                                                                       ses[train], np.inf)))
            lowers = bool(rmse < rmse0 * (1 - self.min_improvement))
            ok = med_dbic < -self.min_delta_bic and lowers and signif > 2.0
            why, kind = self._inconsistent(name, vals[train])
            unit = EXTENSIONS[pname][0]
            # every reason it is not added (an outside review: a candidate that cut the
            # held-out error by 31 % but failed the standard-error test was not named at all)
            tests = []
            if not lowers:
                tests.append(f'held-out rms nerr {rmse:.3g} against {rmse0:.3g}: not lowered by '
                             f'more than {100 * self.min_improvement:.0f} %')
            if not med_dbic < -self.min_delta_bic:
                tests.append(f'median BIC change {med_dbic:.3g} per training stance (must be '
                             f'below {-self.min_delta_bic:g})')
            if not signif > 2.0:
                tests.append(f'per-stance value within {signif:.2g} of its own standard errors '
                             'on median (must be beyond 2)')
            fin = vals[np.isfinite(vals)]
            rec = {'name': name, 'heldout_rmse': rmse, 'delta_bic': float(np.nansum(dbic[train])),
                   'median_delta_bic': med_dbic, 'selected': False,
                   'rejected_because': tests + why, 'improves': bool(ok),
                   'lowers_heldout': lowers, 'consistency': kind,
                   'median_significance': signif,
                   'params': {pname: float(np.median(vals)), 'unit': unit,
                              'per_stance': vals.tolist(),
                              'per_stance_range': ([float(fin.min()), float(fin.max())]
                                                   if fin.size else [math.nan, math.nan])},
                   'stderr': {pname: float(np.std(vals) / math.sqrt(n)),
                              'per_stance_median': float(np.nanmedian(ses))},
                   '_nerr': nerr}
            cands.append(rec)
            if ok and not why and (best is None or rmse < best['heldout_rmse']):
                best = rec
        if best is not None:
            best['selected'] = True
            removed = rmse0 - best['heldout_rmse']
            for c in cands:
                if c is best or not c['improves'] or c['consistency'] != 'one_property':
                    continue
                # passed every check but lowered the held-out error less than the one added
                c['share'] = float((rmse0 - c['heldout_rmse']) / removed) if removed > 0 else 0.0
                c['near_tied'] = bool(c['share'] >= ALTERNATIVE_SHARE)
                c['rejected_because'].append(
                    f'{best["name"]} lowered the held-out error more ({best["heldout_rmse"]:.3g} '
                    f'against {c["heldout_rmse"]:.3g}); only one extension is added')
        self.selected_ = [best['name']] if best is not None else []
        self.nerr_after_ = best['_nerr'] if best is not None else nerr0
        for c in cands:
            c.pop('_nerr')
        self.candidates_ = cands
        self.rmse_heldout_before_ = rmse0
        self.rmse_heldout_after_ = float(np.sqrt(np.mean(self.nerr_after_[held] ** 2)))
        self.touchdown_s_ = np.array([float(getattr(r, 'touchdown_s', i))
                                      for i, r in enumerate(base)])
        self.run_ = [str(getattr(r, 'label', '')).rsplit('#', 1)[0] for r in base]
        return self

    def _inconsistent(self, name: str, vals: np.ndarray) -> tuple[list[str], str]:
        """Why the training stances' parameter values are not one property of the robot
        (empty: they are), and what they are: ``'one_property'``, ``'unphysical_sign'`` (one
        consistent value of the sign physics forbids: a missing effect of the other sign, not
        a fudge) or ``'inconsistent'``."""
        v = vals[np.isfinite(vals)]
        if v.size < 2:
            return ['too few finite values'], 'inconsistent'
        med = float(np.median(v))
        why = []
        same = float(np.mean(np.sign(v) == np.sign(med))) if med != 0.0 else 0.0
        se = 1.2533 * float(np.std(v, ddof=1)) / math.sqrt(v.size)
        consistent = same >= self.min_same_sign and abs(med) > 2.0 * se
        unphysical = PHYSICAL_SIGN.get(name, 0) > 0 and med <= 0.0
        if unphysical and consistent:
            why.append(f'the training stances\' median {med:.3g} is unphysical (must be > 0), '
                       f'yet {100 * same:.0f} % of them share its sign (standard error '
                       f'{se:.3g} across stances): '
                       + UNPHYSICAL_MEANING.get(name, 'an effect of the other sign that the '
                                                'template lacks'))
            return why, 'unphysical_sign'
        if unphysical:
            why.append(f'the training stances\' median {med:.3g} is unphysical (must be > 0)')
        if same < self.min_same_sign:
            why.append(f'sign varies between stances ({100 * same:.0f} % of the training '
                       f'stances share their median\'s, '
                       f'need {100 * self.min_same_sign:.0f} %)')
        if not abs(med) > 2.0 * se:
            why.append(f'the training stances\' median {med:.3g} within 2 standard errors '
                       f'({se:.3g}) of zero')
        return why, ('inconsistent' if why else 'one_property')


def nerr_time_pattern(run: Sequence[str], t_s: np.ndarray, nerr: np.ndarray, *,
                      min_side: int = 4, permutations: int = 999, alpha: float = 0.01,
                      min_ratio: float = 1.25, isolated_ratio: float = 2.0,
                      isolated_z: float = 3.5, seed: int = 0) -> dict[str, Any]:
    """Whether the per-stance nerr left by the loop changes over each run (a step or a
    trend), against the order of its stances shuffled within each run.

    ``log nerr`` (the error is a ratio: a step multiplies it) is centred per run; a step (its
    place searched, at least ``min_side`` stances each side) and a linear trend in touchdown
    time are fitted per run, and the share of the within-run variance the better pattern
    explains, pooled over runs, is the statistic. Its p-value comes from ``permutations``
    shuffles of each run's stances (the step's search is repeated on each, so the many places
    tried do not make a step look significant). ``significant``: ``p < alpha`` and some run's
    change is at least ``min_ratio`` (x1.25 or /1.25). A time-varying effect outside the
    catalogue (damping that sets in half-way, a knocked marker) shows so; a steady one does not.
    Stances whose nerr is at least ``isolated_ratio`` times their run's median and more than
    ``isolated_z`` robust deviations (1.4826 MAD of log nerr) above it stand apart (a knock, a
    slip, a stall, a cut in the data): they are listed in ``isolated`` (run, ``at_s``, nerr,
    ``ratio`` to the run's median) and left out of the pattern.

    Returns ``{"pattern": "step"|"trend", "p_value", "explained_share", "significant",
    "per_run": [{"run", "stances", "ratio", "at_s"? (step: touchdown time [s] of the first
    stance after it), "nerr_before", "nerr_after" (geometric means either side, or at the
    run's first and last stance for a trend)}]}``, or ``{"pattern": None, ...}`` with fewer
    than ``2 min_side`` stances in every run.
    """
    run = [str(x) for x in run]
    t = np.asarray(t_s, dtype=float)
    e = np.asarray(nerr, dtype=float)
    # a stance without a finite nerr (a failed fit) has no place in the pattern: a NaN read
    # as a trend at p 0.001 and an infinite one stood apart as 'xinf' (a review of the change)
    ok = np.isfinite(e) & np.isfinite(t)
    y_all = np.log(np.maximum(np.where(ok, e, 1.0), 1e-9))
    names = list(dict.fromkeys(run))
    rng = np.random.default_rng(seed)
    groups, isolated = [], []
    for name in names:
        idx = np.array([i for i, r in enumerate(run) if r == name and ok[i]], dtype=np.intp)
        if idx.size == 0:
            continue
        idx = idx[np.argsort(t[idx], kind='stable')]
        # a stance far above its run's (a knock, a slip, a stall): listed, left out here;
        # a run needs min_side stances for its median and spread to say what is usual (of 3,
        # the spread was 0 and any stance at twice the median stood apart)
        med = float(np.median(y_all[idx]))
        mad = robust_sigma(y_all[idx], med)
        apart = (y_all[idx] - med >= math.log(isolated_ratio)) & \
            (y_all[idx] - med > isolated_z * mad) & (idx.size >= min_side)
        isolated += [{'run': name, 'at_s': float(t[i]), 'nerr': float(math.exp(y_all[i])),
                      'ratio': float(math.exp(y_all[i] - med))} for i in idx[apart]]
        idx = idx[~apart]
        if idx.size >= 2 * min_side:
            groups.append((name, idx))
    out: dict[str, Any] = {'pattern': None, 'p_value': math.nan, 'explained_share': 0.0,
                           'significant': False, 'per_run': [], 'alpha': alpha,
                           'min_ratio': min_ratio, 'isolated': isolated}
    if not groups:
        return out

    def gains(y: np.ndarray, tc: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        # y (B, n) centred rows: variance a best step and a trend explain, per row
        n = y.shape[1]
        k = np.arange(min_side, n - min_side + 1)
        c = np.cumsum(y, axis=1)[:, k - 1]
        step = np.max(c ** 2 * n / (k * (n - k)), axis=1)
        trend = (y @ tc) ** 2 / float(tc @ tc) if float(tc @ tc) > 0 else np.zeros(len(y))
        return step, trend

    sse0 = 0.0
    obs_step = obs_trend = 0.0
    perm_step = np.zeros(permutations)
    perm_trend = np.zeros(permutations)
    for _, idx in groups:
        y = y_all[idx] - y_all[idx].mean()
        tc = t[idx] - t[idx].mean()
        sse0 += float(y @ y)
        s, tr = gains(y[None, :], tc)
        obs_step += float(s[0])
        obs_trend += float(tr[0])
        shuffled = rng.permuted(np.tile(y, (permutations, 1)), axis=1)
        s, tr = gains(shuffled, tc)
        perm_step += s
        perm_trend += tr
    if sse0 <= 0:
        return out
    obs = max(obs_step, obs_trend) / sse0
    perm = np.maximum(perm_step, perm_trend) / sse0
    pattern = 'step' if obs_step >= obs_trend else 'trend'
    rows = []
    for name, idx in groups:
        y, tt = y_all[idx], t[idx]
        n = y.size
        row: dict[str, Any] = {'run': name, 'stances': int(n)}
        if pattern == 'step':
            yc = y - y.mean()
            k = np.arange(min_side, n - min_side + 1)
            c = np.cumsum(yc)[k - 1]
            kk = int(k[int(np.argmax(c ** 2 * n / (k * (n - k))))])
            before, after = float(y[:kk].mean()), float(y[kk:].mean())
            row['at_s'] = float(tt[kk])
        else:
            slope, icpt = np.polyfit(tt - tt[0], y, 1)
            before, after = float(icpt), float(icpt + slope * (tt[-1] - tt[0]))
        row.update({'nerr_before': math.exp(before), 'nerr_after': math.exp(after),
                    'ratio': math.exp(after - before)})
        rows.append(row)
    p = float((1 + np.sum(perm >= obs - 1e-12)) / (permutations + 1))
    big = any(max(r['ratio'], 1.0 / r['ratio']) >= min_ratio for r in rows)
    out.update({'pattern': pattern, 'p_value': p, 'explained_share': float(obs),
                'significant': bool(p < alpha and big), 'per_run': rows})
    return out


def _value_text(c: Mapping[str, Any]) -> str:
    """'median 1.1 N m, per stance -1.68e+05 to 83'"""
    pname = c['name']
    p = c['params']
    lo, hi = p.get('per_stance_range', [math.nan, math.nan])
    return (f'median {pname} {p[pname]:.3g} {p["unit"]} over all stances, per stance '
            f'{lo:.3g} to {hi:.3g}')


def _rejected_text(c: Mapping[str, Any], rmse0: float) -> str:
    """One sentence on a candidate that lowered the held-out error and was not added."""
    lead = (f'{c["name"]} lowered the held-out error (rms nerr {rmse0:.3g} -> '
            f'{c["heldout_rmse"]:.3g}; {_value_text(c)})')
    why = '; '.join(c['rejected_because'])
    if c.get('consistency') == 'unphysical_sign':
        return f'{lead} with a consistent value of the unphysical sign: {why}.'
    if c.get('consistency') == 'inconsistent':
        return f'{lead} but is not one property of the robot: {why}.'
    return f'{lead} but was not added: {why}.'


def pattern_text(u: Mapping[str, Any]) -> str:
    """The summary's sentences on a significant time pattern of the nerr left and on
    isolated stances ('' if neither)."""
    rows = u.get('per_run') or []

    def name(r: Mapping[str, Any]) -> str:
        return str(r['run']).rstrip('/').rsplit('/', 1)[-1] or 'run'

    iso = u.get('isolated') or []
    iso_text = ''
    if iso:
        iso_text = (f'{len(iso)} stance{"s" if len(iso) > 1 else ""} stood apart from '
                    f'{"their" if len(iso) > 1 else "its"} run (' + ', '.join(
                        f'{name(x)} at {x["at_s"]:.1f} s nerr {x["nerr"]:.2g}, '
                        f'x{x["ratio"]:.1f} its median' for x in iso[:5])
                    + (', ...' if len(iso) > 5 else '') + '): a sudden event the template '
                    'lacks (a knock, a slip, a stall, a cut in the data); '
                    f'{"they were" if len(iso) > 1 else "it was"} left out of the time check.')
    if not u.get('significant'):
        return iso_text

    if u['pattern'] == 'step':
        shape = 'it steps within runs (' + ', '.join(
            f'{name(r)} x{r["ratio"]:.2f} at {r["at_s"]:.1f} s, nerr {r["nerr_before"]:.3g} -> '
            f'{r["nerr_after"]:.3g}' for r in rows) + ')'
    else:
        shape = 'it drifts within runs (' + ', '.join(
            f'{name(r)} x{r["ratio"]:.2f} from first to last stance, nerr '
            f'{r["nerr_before"]:.3g} -> {r["nerr_after"]:.3g}' for r in rows) + ')'
    return (f'The error left changes over time, which no extension of the catalogue follows: '
            f'{shape}, p = {u["p_value"]:.2g} against the stances shuffled within each run. '
            'Something changed during the run (a marker moved, a loss or load that set in); '
            'the fits above average over it.' + (' ' + iso_text if iso_text else ''))


def slip_loop_document(sel: SlipExtensionSelection) -> dict[str, Any]:
    """The ``residuals.json`` document of the SLIP loop (issue 8 schema, plus extras)."""
    t_s = getattr(sel, 'touchdown_s_', np.arange(sel.held_.size, dtype=float))
    runs = getattr(sel, 'run_', [''] * sel.held_.size)
    doc: dict[str, Any] = {
        'model': 'slip', 'unit': 'nerr',
        'baseline': _metrics(sel.nerr_before_),
        'candidates': sel.candidates_,
        'effects_added': list(sel.selected_),
        'final': _metrics(sel.nerr_after_),
        'heldout': {'rmse_before': sel.rmse_heldout_before_,
                    'rmse_after': sel.rmse_heldout_after_},
        'stances': {'count': int(sel.held_.size), 'heldout': int(sel.held_.sum())},
        'alternatives': [{'name': c['name'], 'heldout_rmse': c['heldout_rmse'],
                          'params': {k: v for k, v in c['params'].items() if k != 'per_stance'},
                          'share': c['share']}
                         for c in sel.candidates_ if c.get('near_tied')],
        'unexplained': nerr_time_pattern(runs, t_s, sel.nerr_after_),
    }
    b, h = doc['baseline'], doc['heldout']
    rmse0 = h['rmse_before']
    intro = (f'Plain SLIP left a mean normalised state error of {b["mae"]:.3g} over '
             f'{sel.held_.size} stances. ')
    rejected = [c for c in sel.candidates_ if c.get('lowers_heldout') and not c['selected']
                and not c.get('near_tied')]
    if sel.selected_:
        c = next(c for c in sel.candidates_ if c['selected'])
        pname = c['name']
        text = intro + (
            f'The template missed {c["name"]}; adding it per stance (median {pname} = '
            f'{c["params"][pname]:.3g} {c["params"]["unit"]}) reduced held-out error (rms nerr) '
            f'from {h["rmse_before"]:.3g} to {h["rmse_after"]:.3g}.')
        for a in doc['alternatives']:
            text += (f' {a["name"]} (median {a["params"][a["name"]]:.3g} {a["params"]["unit"]})'
                     f' passed every check too and lowered it nearly as well (to '
                     f'{a["heldout_rmse"]:.3g}): these stances cannot tell the two apart.')
        text += ''.join(' ' + _rejected_text(r, rmse0).replace(' lowered ', ' also lowered ', 1)
                        for r in rejected)
    elif rejected:
        text = intro + ' '.join(_rejected_text(r, rmse0) for r in rejected) + \
            ' Nothing is added: plain SLIP is kept.'
    else:
        text = intro + ('Neither leg damping nor hip torque lowered the held-out '
                        'error significantly, so plain SLIP is kept.')
    more = pattern_text(doc['unexplained'])
    doc['summary'] = text + (' ' + more if more else '')
    return doc
