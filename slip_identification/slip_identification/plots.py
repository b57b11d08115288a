"""The per-stance SLIP fit against the data (``slip_fit_stances.png``/``.svg``).

Komsuoglu et al. judge a fit by Eq. 2, which compares the model's flow with the measured one
in all four sagittal states ``(bx, bx', bz, bz')`` along the stance, the model started from the
stance's first measured state. The figure shows exactly that, for the best, median and worst
stance by ``nerr`` of each gait (one row per gait): the COM path ``bz`` against ``bx`` (from the
touchdown), ``bx'`` and ``bz'`` against the time since touchdown, and the leg length
``||b - f||`` to the fitted foot with the fitted rest length. Measured: the spline-derived
1 kHz states the fit compared (solid) and the raw motion-capture samples (dots, on the path);
SLIP: the model re-simulated from the fitted parameters with :meth:`.model.SlipModel.
simulate_batch` (the integrator and step of :class:`.fit.SlipFitter`; dashed). Nothing is
refitted: a re-simulated trajectory reproduces the stance's ``nerr``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .fit import SlipFitResult, SlipFitter, Stance
from .model import SlipModel

__all__ = ['FIT_FIGURE', 'TRACE_CAP', 'pick_stances', 'plot_stance_fits', 'save_figure',
           'simulate_trace', 'stance_trace', 'trace_subset']

FloatArray = NDArray[np.float64]

#: file stem of the fit-against-data figure (PNG and SVG)
FIT_FIGURE = 'slip_fit_stances'

#: stances per gait and bag whose measured states are kept for the figure (ranks spread over
#: the bag's nerr, its lowest and highest included): a 30 min bag has thousands
TRACE_CAP = 101

#: the resolution of every SLIP figure, as the energy figures (hexapod_energy.plots._save)
DPI = 110

#: colours of the best, median and worst stance of a row
RANK_COLORS = {'best': '#1b9e77', 'median': '#7570b3', 'worst': '#d95f02'}


def save_figure(fig: Any, out_stem: str | Path, *, tight: bool = True) -> list[Path]:
    """Write ``fig`` as PNG and SVG at :data:`DPI` (the energy figures' resolution; with
    ``tight`` their margins too, cut to what is drawn), close it, return both paths. The
    SVG keeps its text as text (``svg.fonttype`` none: a quarter of the time of glyph
    paths)."""
    import matplotlib
    import matplotlib.pyplot as plt

    stem = Path(out_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix('.png'), stem.with_suffix('.svg')]
    kw: dict[str, Any] = {'bbox_inches': 'tight', 'pad_inches': 0.1} if tight else {}
    fig.savefig(paths[0], dpi=DPI, **kw)
    with matplotlib.rc_context({'svg.fonttype': 'none'}):
        fig.savefig(paths[1], dpi=DPI, **kw)
    plt.close(fig)
    return paths


def stance_trace(stance: Stance, fit: SlipFitResult, model: SlipModel) -> dict[str, Any]:
    """What the figure needs of one fitted stance: its measured states, raw samples, the
    fitted parameters (in ``model.param_names`` order) and the model that fitted them."""
    return {'t_s': np.asarray(stance.t_s, dtype=float),
            'state': np.asarray(stance.state, dtype=float),
            'raw_t_s': None if stance.raw_t_s is None else np.asarray(stance.raw_t_s, float),
            'raw_xz_m': None if stance.raw_xz_m is None else np.asarray(stance.raw_xz_m,
                                                                         float),
            'params': [float(fit.params[n]) for n in model.param_names],
            'model': model.name, 'mass_kg': float(model.mass_kg),
            'gravity_mps2': float(model.gravity_mps2),
            'gravity_x_mps2': float(model.gravity_x_mps2)}


def trace_subset(nerrs: Sequence[float], cap: int = TRACE_CAP) -> set[int]:
    """Indices of ``nerrs`` whose traces are kept: all up to ``cap``, else ``cap`` ranks
    spread evenly from the lowest to the highest (the finite ones), the middle one being the
    whole list's lower-middle rank, so that the kept stances' median (:func:`pick_stances`)
    is the median of them all."""
    vals = np.asarray(nerrs, dtype=float)
    ok = np.flatnonzero(np.isfinite(vals))
    if ok.size <= cap:
        return set(ok.tolist())
    order = ok[np.argsort(vals[ok], kind='stable')]
    ranks = np.round(np.linspace(0, order.size - 1, cap)).astype(int)
    # rounding half to even put the kept middle one rank above it for an even count
    ranks[(cap - 1) // 2] = (order.size - 1) // 2
    return set(order[np.unique(ranks)].tolist())


def simulate_trace(trace: dict[str, Any]) -> FloatArray:
    """The SLIP states (N, 4) of a :func:`stance_trace` from its fitted parameters, started
    from its first measured state, on its sample grid: :meth:`SlipModel.simulate_batch` with
    the step of :class:`.fit.SlipFitter` (what its ``nerr`` was computed on)."""
    model = SlipModel.from_name(str(trace['model']), mass_kg=float(trace['mass_kg']))
    if 'gravity_mps2' in trace:
        model = SlipModel(mass_kg=model.mass_kg, gravity_mps2=float(trace['gravity_mps2']),
                          extensions=model.extensions,
                          gravity_x_mps2=float(trace.get('gravity_x_mps2', 0.0)))
    t = np.asarray(trace['t_s'], dtype=float)
    xe = np.asarray(trace['state'], dtype=float)
    dt = float((t[-1] - t[0]) / (t.size - 1))
    p = np.asarray(trace['params'], dtype=float)
    return model.simulate_batch(xe[0][None, :], p[None, :], t.size, dt,
                                stride=SlipFitter().stride)[:, :, 0]


def pick_stances(stances: Sequence[dict[str, Any]], traces: Sequence[dict[str, Any] | None]
                 ) -> dict[str, list[tuple[str, int]]]:
    """Per gait (Table 3's order) the best, median and worst stance by ``nerr`` among those
    with a trace: ``{gait: [('best', i), ('median', j), ('worst', k)]}`` (indices into
    ``stances``; fewer with one or two stances). The median is the stance at the lower middle
    rank."""
    from .energetics import ordered_gaits

    by_gait: dict[str, list[int]] = {}
    for i, s in enumerate(stances):
        e = s.get('nerr')
        if i < len(traces) and traces[i] is not None and e is not None and \
                math.isfinite(float(e)):
            by_gait.setdefault(str(s.get('gait')), []).append(i)
    out: dict[str, list[tuple[str, int]]] = {}
    for g in ordered_gaits(by_gait):
        idx = sorted(by_gait[g], key=lambda i: (float(stances[i]['nerr']), i))
        picks = [('best', idx[0]), ('median', idx[(len(idx) - 1) // 2]), ('worst', idx[-1])]
        seen: set[int] = set()
        out[g] = [(name, i) for name, i in picks if not (i in seen or seen.add(i))]
    return out


def _label(stances: Sequence[dict[str, Any]], rank: str, i: int) -> str:
    s = stances[i]
    world = s.get('nerr_world')
    w = f', world {float(world):.3f}' if isinstance(world, (int, float)) and \
        math.isfinite(float(world)) else ''
    bag = Path(str(s.get('bag', ''))).name
    return (f"{rank}: stances[{i}] {bag} {s.get('tripod', '')}, td {float(s['touchdown']):.3f} s"
            f"\n  nerr {float(s['nerr']):.3f}{w}; k {float(s.get('stiffness') or math.nan):.0f}"
            f" N/m, l0 {1e3 * float(s.get('rest_length') or math.nan):.0f} mm")


def plot_stance_fits(stances: Sequence[dict[str, Any]],
                     traces: Sequence[dict[str, Any] | None], out_dir: str | Path, *,
                     source: str | None = None, mass_kg: float | None = None) -> list[Path]:
    """The SLIP fit against the data (module docstring): one row per gait, its best, median
    and worst stance by ``nerr``; ``stances`` are ``slip.json``'s, ``traces`` their
    :func:`stance_trace` (None where not kept). Returns the PNG and SVG paths, none when no
    stance has a trace."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from .energetics import gait_colors

    picks = pick_stances(stances, traces)
    if not picks:
        return []
    gaits = list(picks)
    gcol = gait_colors(gaits)
    # a fixed layout (no tight_layout, no tight bounding box: each costs a draw of 16 axes)
    height = 2.7 * len(gaits) + 1.1
    fig, axes = plt.subplots(len(gaits), 4, figsize=(16.0, height), squeeze=False,
                             gridspec_kw={'width_ratios': (1.25, 1, 1, 1)})
    fig.subplots_adjust(left=0.055, right=0.775, bottom=0.55 / height,
                        top=1.0 - 1.0 / height, wspace=0.32, hspace=0.42)
    for row, g in enumerate(gaits):
        ax_p, ax_vx, ax_vz, ax_r = axes[row]
        handles = []
        legs: list[float] = []
        rests: list[tuple[float, str]] = []
        for rank, i in picks[g]:
            tr = traces[i]
            assert tr is not None
            col = RANK_COLORS[rank]
            xe = np.asarray(tr['state'], dtype=float)
            xm = simulate_trace(tr)
            t_ms = 1e3 * (np.asarray(tr['t_s'], dtype=float) - float(tr['t_s'][0]))
            x0 = xe[0, 0]
            foot = float(tr['params'][2])
            l0 = float(tr['params'][1])
            ax_p.plot(1e3 * (xe[:, 0] - x0), 1e3 * xe[:, 2], '-', color=col, lw=1.6)
            ax_p.plot(1e3 * (xm[:, 0] - x0), 1e3 * xm[:, 2], '--', color=col, lw=1.3)
            raw = tr.get('raw_xz_m')
            if raw is not None and np.size(raw):
                raw = np.asarray(raw, dtype=float)
                ax_p.plot(1e3 * (raw[:, 0] - x0), 1e3 * raw[:, 1], 'o', ms=3.4, color=col,
                          mec='white', mew=0.4, zorder=3)
            for ax, k in ((ax_vx, 1), (ax_vz, 3)):
                ax.plot(t_ms, xe[:, k], '-', color=col, lw=1.6)
                ax.plot(t_ms, xm[:, k], '--', color=col, lw=1.3)
            for st, ls, lw in ((xe, '-', 1.6), (xm, '--', 1.3)):
                leg = np.hypot(st[:, 0] - foot, st[:, 2])
                ax_r.plot(t_ms, 1e3 * leg, ls, color=col, lw=lw)
                legs += [float(np.nanmin(leg)), float(np.nanmax(leg))]
            ax_r.axhline(1e3 * l0, color=col, lw=0.8, ls=':')
            rests.append((l0, col))
            handles.append(Line2D([], [], color=col, lw=2, label=_label(stances, rank, i)))
        if legs and all(math.isfinite(v) for v in legs):
            # the legs' range, with the rest lengths that lie near it (a walk's soft long
            # spring, l0 up to 290 mm for 100-125 mm legs, had squashed the curves flat)
            lo, hi = min(legs), max(legs)
            near = [l0 for l0, _ in rests if lo - 0.3 * (hi - lo) <= l0 <= hi + 0.3 * (hi - lo)]
            lo, hi = min([lo] + near), max([hi] + near)
            pad = 0.08 * (hi - lo) or 1e-3
            ax_r.set_ylim(1e3 * (lo - pad), 1e3 * (hi + pad))
            above = [l0 for l0, _ in rests if l0 > hi + pad]
            if above:
                ax_r.text(0.02, 0.97, 'l0 above the axis: ' + ', '.join(
                    f'{1e3 * v:.0f}' for v in above) + ' mm', transform=ax_r.transAxes,
                    fontsize=7, va='top')
        n = sum(1 for s in stances if str(s.get('gait')) == g)
        ax_p.set_ylabel(f'{g} (n = {n})\nCOM height bz [mm]', color=gcol[g], fontsize=9)
        ax_p.set_xlabel('bx - bx(touchdown) [mm]', fontsize=8)
        ax_vx.set_ylabel("forward speed bx' [m/s]", fontsize=8)
        ax_vz.set_ylabel("vertical speed bz' [m/s]", fontsize=8)
        ax_r.set_ylabel('leg length ||b - f|| [mm]', fontsize=8)
        for ax in (ax_vx, ax_vz, ax_r):
            ax.set_xlabel('time since touchdown [ms]', fontsize=8)
        for ax in axes[row]:
            ax.grid(alpha=0.3)
            ax.tick_params(labelsize=7)
        ax_r.legend(handles=handles, fontsize=7, loc='upper left', bbox_to_anchor=(1.03, 1.0),
                    borderaxespad=0.0, title=f'{g}: stances by nerr', title_fontsize=8)
    for ax, name in zip(axes[0], ('COM path', "fore/aft speed", 'vertical speed',
                                  'leg length to the fitted foot f = (fx, 0)')):
        ax.set_title(name, fontsize=9)
    style = [Line2D([], [], color='k', lw=1.6, label='measured (spline state the fit compares)'),
             Line2D([], [], color='k', lw=1.3, ls='--',
                    label='SLIP, re-simulated from the fitted k, l0, fx'),
             Line2D([], [], color='k', ls='', marker='o', ms=3, label='raw motion capture'),
             Line2D([], [], color='k', lw=0.8, ls=':', label='fitted rest length l0')]
    data = ', '.join(x for x in (source or '', f'm = {mass_kg:.3g} kg' if mass_kg else '')
                     if x)
    fig.suptitle('SLIP fit against the data: best, median and worst stance by nerr per gait '
                 '(Komsuoglu et al. Eq. 2 compares these four states along the stance; nerr '
                 'with bx from the stance start, "world": Eq. 2 literal)'
                 + (f'\n{data}' if data else ''), fontsize=9.5, y=1.0 - 0.08 / height,
                 va='top')
    fig.legend(handles=style, loc='upper center', ncol=4, fontsize=8, frameon=False,
               bbox_to_anchor=(0.45, 1.0 - 0.55 / height))
    return save_figure(fig, Path(out_dir) / FIT_FIGURE, tight=False)
