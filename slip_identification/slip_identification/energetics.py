"""Energetics per run (Komsuoglu et al., Section 5): specific resistance, Table 3, Figs. 7-9."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from hexapod_common.conversions import current_sign_factor

from .errors import SlipDataError
from .model import GRAVITY_MPS2

__all__ = ['battery_power_w', 'gait_table', 'plot_figures', 'specific_resistance']


def battery_power_w(voltage_v: ArrayLike, current_a: ArrayLike, *, sign: str = 'auto'
                    ) -> tuple[float, str]:
    """Mean input power [W] and the current sign convention used.

    ``sign``: ``'ros'`` (current negative when discharging, P = -V I), ``'positive_discharge'``
    (P = V I) or ``'auto'`` (the sign that makes the median V I a positive input power, as the
    energy analysis decides it: :func:`hexapod_common.conversions.current_sign_factor`).
    """
    v = np.asarray(voltage_v, dtype=float)
    i = np.asarray(current_a, dtype=float)
    ok = np.isfinite(v) & np.isfinite(i)
    if not ok.any():
        raise SlipDataError('battery power needs finite voltage and current samples')
    try:
        factor = current_sign_factor(v[ok], i[ok], sign)
    except ValueError as err:
        raise SlipDataError(str(err)) from None
    name = 'ros' if factor < 0 else 'positive_discharge'
    p = factor * float(np.mean(v[ok] * i[ok]))
    if p < 0:
        raise SlipDataError(f'input power is negative ({p:.2f} W) with sign={name!r}')
    return p, name


def specific_resistance(power_w: float, mass_kg: float, speed_mps: float,
                        gravity_mps2: float = GRAVITY_MPS2) -> float:
    """SR = P / (m g v) (Eq. 5); NaN when the speed is not positive."""
    return power_w / (mass_kg * gravity_mps2 * speed_mps) if speed_mps > 0 else math.nan


def gait_table(rows: Sequence[dict[str, float | str]]) -> dict[str, dict[str, float]]:
    """Table 3: per gait mean and std of ``nerr``, ``power_w``, ``speed_mps`` (and ``sr``).

    ``rows`` holds one dict per stance with keys ``gait``, ``nerr``, ``power_w``,
    ``speed_mps``, ``sr`` (run values repeated on each of the run's stances, as in the paper).
    """
    out: dict[str, dict[str, float]] = {}
    for gait in sorted({str(r['gait']) for r in rows}):
        sel = [r for r in rows if r['gait'] == gait]
        entry: dict[str, float] = {'stances': float(len(sel))}
        for key in ('nerr', 'power_w', 'speed_mps', 'sr'):
            vals = np.array([float(r[key]) for r in sel], dtype=float)
            vals = vals[np.isfinite(vals)]
            entry[f'{key}_mean'] = float(vals.mean()) if vals.size else math.nan
            entry[f'{key}_std'] = float(vals.std()) if vals.size else math.nan
        out[gait] = entry
    return out


def _runs_of(rows: Sequence[dict[str, float | str]]) -> list[list[dict[str, float | str]]]:
    """The stances grouped by run: by ``bag`` when the rows carry it, else by the run values
    every stance of a run repeats (gait, power, speed)."""
    groups: dict[tuple[str, ...], list[dict[str, float | str]]] = {}
    for r in rows:
        key = (str(r['gait']), str(r['bag'])) if 'bag' in r else \
            (str(r['gait']), repr(float(r['power_w'])), repr(float(r['speed_mps'])))
        groups.setdefault(key, []).append(r)
    return list(groups.values())


def plot_figures(rows: Sequence[dict[str, float | str]], out_dir: str | Path) -> list[Path]:
    """Figs. 7 (v vs SR), 8 (P vs v), 9 (nerr vs SR), colour per gait, one marker per run.

    Speed, power and SR are run values (repeated on each stance): one marker per run,
    annotated with its stance count ``n``; nerr is per stance: Fig. 9 shows each run's mean
    +/- sd over its stances, the stances faint behind it.

    Parameters
    ----------
    rows : sequence of dict
        One dict per stance (``gait``, ``nerr``, ``power_w``, ``speed_mps``, ``sr``,
        optionally ``bag``).
    out_dir : str or Path
        Output folder.

    Returns
    -------
    list of Path
        The three PNGs.
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    gaits = sorted({str(r['gait']) for r in rows})
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    color = {g: colors[i % len(colors)] for i, g in enumerate(gaits)}
    runs = _runs_of(rows)
    specs = [('fig7_speed_vs_sr.png', 'sr', 'speed_mps', 'specific resistance SR',
              'speed [m/s]', 'Fig. 7: speed against specific resistance'),
             ('fig8_power_vs_speed.png', 'speed_mps', 'power_w', 'speed [m/s]',
              'input power [W]', 'Fig. 8: input power against speed'),
             ('fig9_nerr_vs_sr.png', 'sr', 'nerr', 'specific resistance SR',
              'SLIP-measure nerr (mean \u00b1 sd per run)',
              'Fig. 9: SLIP-measure against specific resistance')]
    paths = []
    for name, kx, ky, lx, ly, title in specs:
        fig, ax = plt.subplots(figsize=(5.5, 4.3))
        labelled: set[str] = set()
        for run in runs:
            g = str(run[0]['gait'])
            xs = np.array([float(r[kx]) for r in run], dtype=float)
            ys = np.array([float(r[ky]) for r in run], dtype=float)
            x = float(np.nanmean(xs)) if np.isfinite(xs).any() else math.nan
            ok = np.isfinite(ys)
            y = float(ys[ok].mean()) if ok.any() else math.nan
            label = g if g not in labelled else None
            labelled.add(g)
            if ky == 'nerr':
                ax.scatter(np.full(ok.sum(), x), ys[ok], s=8, color=color[g], alpha=0.25,
                           linewidths=0, label='_stances')
                ax.errorbar([x], [y], yerr=[float(ys[ok].std()) if ok.any() else 0.0],
                            fmt='o', ms=7, color=color[g], capsize=4, label=label)
            else:
                ax.plot([x], [y], 'o', ms=8, color=color[g], label=label)
            if math.isfinite(x) and math.isfinite(y):
                ax.annotate(f'n={len(run)}', (x, y), textcoords='offset points',
                            xytext=(7, 4), fontsize=8)
        ax.set_xlabel(lx)
        ax.set_ylabel(ly)
        ax.set_title(f'{title}\n(Komsuoglu et al.; one marker per run, n stances)',
                     fontsize=9)
        ax.grid(alpha=0.3)
        ax.margins(0.15)
        ax.legend(title='gait', fontsize=8)
        fig.tight_layout()
        fig.savefig(out / name, dpi=100)
        plt.close(fig)
        paths.append(out / name)
    return paths
