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
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import SlipDataError
from .fit import SlipFitResult, SlipFitter, Stance
from .model import EXTENSIONS, SlipModel

__all__ = [
    'SLIP_CANDIDATES',
    'SlipExtensionSelection',
    'fit_slip_candidates',
    'slip_loop_document',
]

#: sign an extension's parameter must have to be physical (+1: >= 0; 0: either)
PHYSICAL_SIGN: Mapping[str, int] = {'leg_damping': 1, 'hip_torque': 0}

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
            ok = (med_dbic < -self.min_delta_bic and rmse < rmse0 * (1 - self.min_improvement)
                  and signif > 2.0)
            why = self._inconsistent(name, vals[train])
            unit = EXTENSIONS[pname][0]
            rec = {'name': name, 'heldout_rmse': rmse, 'delta_bic': float(np.nansum(dbic[train])),
                   'median_delta_bic': med_dbic, 'selected': False, 'rejected_because': why,
                   'improves': bool(ok),
                   'params': {pname: float(np.median(vals)), 'unit': unit,
                              'per_stance': vals.tolist()},
                   'stderr': {pname: float(np.std(vals) / math.sqrt(n)),
                              'per_stance_median': float(np.nanmedian(ses))},
                   '_nerr': nerr}
            cands.append(rec)
            if ok and not why and (best is None or rmse < best['heldout_rmse']):
                best = rec
        if best is not None:
            best['selected'] = True
        self.selected_ = [best['name']] if best is not None else []
        self.nerr_after_ = best['_nerr'] if best is not None else nerr0
        for c in cands:
            c.pop('_nerr')
        self.candidates_ = cands
        self.rmse_heldout_before_ = rmse0
        self.rmse_heldout_after_ = float(np.sqrt(np.mean(self.nerr_after_[held] ** 2)))
        return self

    def _inconsistent(self, name: str, vals: np.ndarray) -> list[str]:
        """Why the training stances' parameter values are not one property of the robot
        (empty: they are)."""
        v = vals[np.isfinite(vals)]
        if v.size < 2:
            return ['too few finite values']
        med = float(np.median(v))
        why = []
        if PHYSICAL_SIGN.get(name, 0) > 0 and med <= 0.0:
            why.append(f'unphysical median {med:.3g} (must be > 0)')
        same = float(np.mean(np.sign(v) == np.sign(med))) if med != 0.0 else 0.0
        if same < self.min_same_sign:
            why.append(f'sign varies between stances ({100 * same:.0f} % share the median\'s, '
                       f'need {100 * self.min_same_sign:.0f} %)')
        se = 1.2533 * float(np.std(v, ddof=1)) / math.sqrt(v.size)
        if not abs(med) > 2.0 * se:
            why.append(f'median {med:.3g} within 2 standard errors ({se:.3g}) of zero across '
                       'stances')
        return why


def slip_loop_document(sel: SlipExtensionSelection) -> dict[str, Any]:
    """The ``residuals.json`` document of the SLIP loop (issue 8 schema, plus extras)."""
    doc: dict[str, Any] = {
        'model': 'slip', 'unit': 'nerr',
        'baseline': _metrics(sel.nerr_before_),
        'candidates': sel.candidates_,
        'effects_added': list(sel.selected_),
        'final': _metrics(sel.nerr_after_),
        'heldout': {'rmse_before': sel.rmse_heldout_before_,
                    'rmse_after': sel.rmse_heldout_after_},
        'stances': {'count': int(sel.held_.size), 'heldout': int(sel.held_.sum())},
    }
    b, h = doc['baseline'], doc['heldout']
    intro = (f'Plain SLIP left a mean normalised state error of {b["mae"]:.3g} over '
             f'{sel.held_.size} stances. ')
    if sel.selected_:
        c = next(c for c in sel.candidates_ if c['selected'])
        pname = next(k for k in c['params'] if k not in ('unit', 'per_stance'))
        doc['summary'] = intro + (
            f'The template missed {c["name"]}; adding it per stance (median {pname} = '
            f'{c["params"][pname]:.3g} {c["params"]["unit"]}) reduced held-out error (rms nerr) '
            f'from {h["rmse_before"]:.3g} to {h["rmse_after"]:.3g}.')
    else:
        fudge = [c for c in sel.candidates_ if c.get('improves') and c.get('rejected_because')]
        if fudge:
            doc['summary'] = intro + ' '.join(
                f'{c["name"]} lowered the held-out error (rms nerr {h["rmse_before"]:.3g} -> '
                f'{c["heldout_rmse"]:.3g}) but is not one property of the robot: '
                f'{"; ".join(c["rejected_because"])}.' for c in fudge) + ' Plain SLIP is kept.'
        else:
            doc['summary'] = intro + ('Neither leg damping nor hip torque lowered the held-out '
                                      'error significantly, so plain SLIP is kept.')
    return doc
