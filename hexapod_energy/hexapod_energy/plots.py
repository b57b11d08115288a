"""Four-quadrant energy plots (Brodoline et al. 2024, Fig. 3) and the output power map (Fig. 7D).

Quadrant layout, all four sharing their axes two by two, as in the paper:

====================  ====================
II: P_out vs eta      I: P_out vs v
(eta grows leftward)
III: CoT/M vs eta     IV: CoT/M vs v
(both axes mirrored)  (CoT/M grows downward)
====================  ====================

Each curve is drawn at the nominal payload (solid; the first of its band unless the plot
names another, e.g. Fig. 3C's 140 g) with the payload band (e.g. 0-500 g) as a very light fill
in the curve's colour and its edges (the payloads other than the nominal one) as thin dashed
lines in that colour, so that overlapping bands stay apart; where Eq. 1 extrapolates the bench
(``outside_bench``) the curve is dotted and the band carries a grey hatch (the axes fit the
points the bench covers).  A P_out band thinner than the curve's line is said in the legend.
Optimal points are marked by shape, drawn so that coinciding ones stay visible: large hollow
circle maximum P_out, hollow square minimum CoT/M, small filled triangle maximum efficiency.  A
curve identical to an earlier one is drawn thin and dashed with hollow markers every few
points.  The subtitle gives the robot mass (the leg-count sweep: its body and leg mass, each
curve's mass in the legend), the parameters the curves share and the nominal payload and band.
Uses the
non-interactive Agg backend; writes PNG and SVG.
"""

from __future__ import annotations

from typing import Any

from collections.abc import Sequence
from pathlib import Path

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from hexapod_energy.sweeps import SweepCurve  # noqa: E402

__all__ = ['comparison_figure', 'comparison_plot', 'four_quadrant_figure', 'four_quadrant_plot',
           'measured_runs_plot', 'power_in_over_time_plot', 'power_map_plot',
           'prediction_figure', 'prediction_plot', 'watts_figure', 'watts_plot']

#: optimal-point markers: key -> (legend label, marker, size, filled); drawn largest first
#: so that coinciding optima (often all three at a curve's maximum speed) all stay visible
OPTIMUM_MARKERS = {
    'max_power_out': ('max P_out', 'o', 15.0, False),
    'min_cot_per_mass': ('min CoT/M', 's', 9.5, False),
    'max_efficiency': ('max efficiency', '^', 6.0, True),
}


#: the payload band: a very light fill in the curve's colour where the bench covers it (lighter
#: still where Eq. 1 extrapolates, ``outside_bench``), the band's edge payloads as thin dashed
#: lines in the curve's colour, and a grey hatch over the extrapolated part only: several
#: overlapping bands mixed their coloured hatches into one brown mass
BAND_ALPHA = 0.12
EXTRAPOLATED_BAND = {'alpha': 0.05, 'hatch': '////', 'edgecolor': '0.5', 'hatch_alpha': 0.55}
BAND_EDGE = {'ls': (0, (4, 2.5)), 'lw': 0.9}
#: the nominal curve's line width [pt]; a duplicate curve's
CURVE_LW, DUPLICATE_LW = 2.5, 1.2


def _band_split(outside: np.ndarray) -> np.ndarray:
    """Per speed interval ``i`` (speeds ``i`` and ``i + 1``) of a (k, m) ``outside_bench``
    mask, the last payload column up to which the band is on the bench: every column from
    the first to it is inside at both speeds; -1 when the first column is not (the whole
    band there is extrapolated), ``m - 1`` when the whole band is on the bench."""
    both = ~(outside[:-1] | outside[1:])                     # (k - 1, m)
    return np.cumprod(both, axis=1).sum(axis=1) - 1


def _band(ax: Any, x: np.ndarray, y: np.ndarray, color: str,
          outside: np.ndarray | None = None) -> tuple[bool, bool]:
    """Fill between the first and last payload columns of (k, m) arrays: a very light fill
    in ``color`` where the bench covers the payloads (every column from the first inside at
    both ends of a speed interval), a lighter one with a grey hatch above that column, i.e.
    where Eq. 1 extrapolates.

    Returns whether an in-bench part and an extrapolated part were drawn."""
    k, m = x.shape
    split = np.full(max(k - 1, 0), m - 1) if outside is None else _band_split(outside)
    drawn = [False, False]

    def fill(i0: int, i1: int, lo: int, hi: int, extrapolated: bool) -> None:
        # speeds i0..i1 (inclusive) between payload columns lo and hi
        xs = np.concatenate([x[i0:i1 + 1, lo], x[i0:i1 + 1, hi][::-1]])
        ys = np.concatenate([y[i0:i1 + 1, lo], y[i0:i1 + 1, hi][::-1]])
        ok = np.isfinite(xs) & np.isfinite(ys)
        if ok.sum() < 3:
            return
        drawn[int(extrapolated)] = True
        if extrapolated:
            ax.fill(xs[ok], ys[ok], facecolor=color, alpha=EXTRAPOLATED_BAND['alpha'],
                    linewidth=0)
            # a grey hatch, its own patch: overlapping bands' hatches coincide, colours
            # do not mix
            ax.fill(xs[ok], ys[ok], facecolor='none', linewidth=0,
                    edgecolor=EXTRAPOLATED_BAND['edgecolor'], hatch=EXTRAPOLATED_BAND['hatch'],
                    alpha=EXTRAPOLATED_BAND['hatch_alpha'], gid='band_extrapolated')
        else:
            ax.fill(xs[ok], ys[ok], color=color, alpha=BAND_ALPHA, linewidth=0)

    start = 0
    for i in range(1, split.size + 1):
        if i < split.size and split[i] == split[start]:
            continue
        j = int(split[start])                       # one run of speed intervals start..i-1
        if j > 0:
            fill(start, i, 0, j, False)
        if j < m - 1:
            fill(start, i, max(j, 0), m - 1, True)
        start = i
    return drawn[0], drawn[1]


def _band_edges(ax: Any, x: np.ndarray, y: np.ndarray, color: str, nominal: int) -> None:
    """The band's edge payloads (first and last column, but the nominal one) as thin dashed
    lines in the curve's colour."""
    m = x.shape[1]
    for j in sorted({0, m - 1} - {nominal}):
        ax.plot(x[:, j], y[:, j], color=color, gid='band_edge', **BAND_EDGE)


def _nominal_column(payloads: np.ndarray, nominal_kg: float | None) -> int:
    """Index of the nominal payload (``None``: the first)."""
    if nominal_kg is None:
        return 0
    hit = np.flatnonzero(np.isclose(payloads, nominal_kg, rtol=0.0, atol=1e-9))
    if not hit.size:
        raise ValueError(f'nominal payload {nominal_kg:g} kg is not among the curve\'s '
                         f'payloads {[round(float(p), 4) for p in payloads]} (see '
                         'hexapod_energy.sweeps.with_payload)')
    return int(hit[0])


def _thin_band_share(ax: Any, xs: Sequence[np.ndarray], ys: Sequence[np.ndarray],
                     lw_pt: float) -> tuple[float, float]:
    """Share of the points (every curve and speed within the axis' x range) where the band,
    first to last payload column, is thinner on ``ax`` than a line of ``lw_pt`` points, and
    the largest relative change across the band there ((last - first) / first)."""
    y0, y1 = ax.get_ylim()
    h_pt = ax.get_position().height * ax.figure.get_figheight() * 72.0
    pt_per_unit = h_pt / abs(y1 - y0) if y1 != y0 else np.inf
    widths, rel = [], []
    for x, y in zip(xs, ys):
        w = np.abs(y[:, -1] - y[:, 0])
        ok = np.isfinite(w)
        widths.append(w[ok] * pt_per_unit)
        with np.errstate(divide='ignore', invalid='ignore'):
            r = w / np.abs(y[:, 0])
        rel.append(r[np.isfinite(r)])
    wid = np.concatenate(widths) if widths else np.zeros(0)
    rr = np.concatenate(rel) if rel else np.zeros(0)
    return (float(np.mean(wid < lw_pt)) if wid.size else 0.0,
            float(np.max(rr)) if rr.size else 0.0)


def _fixed_parameters(curves: Sequence[SweepCurve]) -> str:
    """What the curves of one sweep share: robot mass, gait, legs, duty factor, step."""
    specs = [c.spec for c in curves]
    parts = []
    masses = {round(c.robot_mass_kg, 9) for c in curves}
    if len(masses) == 1:
        parts.append(f'robot {masses.pop():.3g} kg')
    elif len({s.leg_count for s in specs}) > 1 and \
            all(s.mass_reference_legs is not None for s in specs):
        # the leg-count sweep: one body, each curve its own legs (masses in the legend)
        c0, c1 = min(curves, key=lambda c: c.spec.leg_count), \
            max(curves, key=lambda c: c.spec.leg_count)
        m_leg = (c1.robot_mass_kg - c0.robot_mass_kg) / (c1.spec.leg_count - c0.spec.leg_count)
        parts.append(f'body {c0.robot_mass_kg - c0.spec.leg_count * m_leg:.4g} kg + '
                     f'legs of {m_leg:.3g} kg')
    if len({s.gait for s in specs}) == 1:
        parts.append(specs[0].gait)
    if len({s.leg_count for s in specs}) == 1:
        parts.append(f'{specs[0].leg_count} legs')
    if len({s.duty_factor for s in specs}) == 1:
        parts.append(f'beta {specs[0].duty_factor:g}')
    if len({s.step_length_m for s in specs}) == 1:
        parts.append(f'step {1000 * specs[0].step_length_m:.0f} mm')
    if len({s.step_height_m for s in specs}) == 1:
        parts.append(f'lift {1000 * specs[0].step_height_m:.0f} mm')
    return ', '.join(parts)


def _inside_limits(values: Sequence[np.ndarray], margin: float = 0.06
                   ) -> tuple[float, float] | None:
    """Limits spanning the finite ``values`` with a margin; None when there are none."""
    v = np.concatenate([np.ravel(a) for a in values]) if values else np.zeros(0)
    v = v[np.isfinite(v)]
    if not v.size:
        return None
    lo, hi = float(v.min()), float(v.max())
    pad = margin * (hi - lo) if hi > lo else max(abs(hi), 1.0) * margin
    return lo - pad, hi + pad


def four_quadrant_figure(curves: Sequence[SweepCurve], *, title: str = '',
                         subtitle: str | None = None,
                         nominal_payload_kg: float | None = None) -> Any:
    """The four-quadrant figure of ``curves`` (see the module docstring).

    Parameters
    ----------
    curves : sequence of SweepCurve
        One curve per configuration of the sweep (sharing their payloads).
    title : str
        Figure title.
    subtitle : str, optional
        Second title line; by default the robot mass and the parameters the curves share.
        The nominal payload and the band are added to it in either case.
    nominal_payload_kg : float, optional
        Payload of the solid curves and of the optimum markers; one of the curves' payloads
        (:func:`~hexapod_energy.sweeps.with_payload`). Default: the first.

    Returns
    -------
    matplotlib.figure.Figure
        The figure; the optimum markers are the lines whose ``gid`` is their key in
        :data:`OPTIMUM_MARKERS` (one legend entry each), the band edges those whose ``gid``
        is ``'band_edge'``.
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig, axes = plt.subplots(2, 2, figsize=(10, 9), sharex='col', sharey='row')
    (ax2, ax1), (ax3, ax4) = axes
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    inside_pout: list[np.ndarray] = []
    inside_cot: list[np.ndarray] = []
    pout_bands: list[tuple[np.ndarray, np.ndarray]] = []
    any_out = clipped = band_in = band_out = False
    masses = {round(c.robot_mass_kg, 9) for c in curves}   # several: each label says its own
    payloads = np.asarray(curves[0].payloads_kg, dtype=float) if curves else np.zeros(1)
    jn = _nominal_column(payloads, nominal_payload_kg)
    for c, curve in enumerate(curves):
        col = colors[c % len(colors)]
        m = len(curve.payloads_kg)
        j = _nominal_column(np.asarray(curve.payloads_kg, dtype=float),
                            float(payloads[jn]))
        v = np.repeat(curve.speeds_mps[:, None], m, axis=1)
        eta = curve.efficiency * 100.0
        p_out, cot = curve.power_out_w, curve.cot_per_mass
        out_all = curve.outside_bench if curve.outside_bench is not None else \
            np.zeros(p_out.shape, bool)
        out = out_all[:, j]
        any_out |= bool(out.any())
        # limits from the speeds where the nominal curve is on the bench (its whole payload
        # band there); a nominal curve the bench never covers (Fig. 3C's tripod at 140 g),
        # from the speeds where it covers another payload; a curve it never covers at all is
        # all there is of it: it all counts
        covered = ~out_all.all(axis=1)
        far = out if not out.all() else (~covered if covered.any() else np.zeros_like(out))
        keep = np.repeat(far[:, None], m, axis=1)
        inside_pout.append(np.where(keep, np.nan, p_out))
        inside_cot.append(np.where(keep, np.nan, cot))
        label = curve.spec.label + (f', {curve.robot_mass_kg:.4g} kg' if len(masses) > 1
                                    else '') + (' (all extrapolated)' if out.all() else '')
        # a curve equal to an earlier one (wave at beta 0.5 is the tripod: L(t) = 3 always)
        # is drawn thin and dashed over it with hollow markers every few points, and says so;
        # dashes alone merged with the earlier curve's line
        same = next((other.spec.label for other in curves[:c]
                     if other.speeds_mps.shape == curve.speeds_mps.shape
                     and np.allclose(other.speeds_mps, curve.speeds_mps)
                     and np.allclose(other.power_out_w, p_out, rtol=1e-9, equal_nan=True)
                     and np.allclose(other.cot_per_mass, cot, rtol=1e-9, equal_nan=True)),
                    None)
        marks = {'marker': 'o', 'ms': 5.5, 'mfc': 'white', 'mew': 1.3,
                 'markevery': max(1, len(curve.speeds_mps) // 8)} if same else {}
        style = {'ls': '--', 'lw': DUPLICATE_LW, **marks} if same else \
            {'ls': '-', 'lw': CURVE_LW}
        if same:
            label += f' (= {same})'
        else:
            pout_bands.append((v, p_out))
        for ax, x, y in ((ax1, v, p_out), (ax2, eta, p_out), (ax3, eta, cot), (ax4, v, cot)):
            if not same:   # a duplicate's band is the earlier curve's: drawn once
                drew_in, drew_out = _band(ax, x, y, col, out_all)
                band_in, band_out = band_in or drew_in, band_out or drew_out
                _band_edges(ax, x, y, col, j)
            # solid where the bench's sessions cover the point, dotted where Eq. 1 extrapolates
            inside = np.where(out, np.nan, y[:, j])
            ax.plot(x[:, j], inside, color=col, **style,
                    label=label if ax is ax1 and not out.all() else None)
            if out.any():
                edge = out | np.convolve(out, [1, 1, 1], 'same').astype(bool)
                # a duplicate's extrapolated part: its markers alone (dots over the earlier
                # curve's dots merged into one line)
                ax.plot(x[:, j], np.where(edge, y[:, j], np.nan), ls='none' if same else ':',
                        color=col, lw=1.0 if same else 2.0, **marks,
                        label=label if ax is ax1 and out.all() else None)
        pts = curve.optimal_points(payload_index=j)
        for key, (name, marker, size, filled) in OPTIMUM_MARKERS.items():
            i = int(np.argmin(np.abs(curve.speeds_mps - pts[key]['speed_mps'])))
            for ax, x, y in ((ax1, v, p_out), (ax2, eta, p_out), (ax3, eta, cot),
                             (ax4, v, cot)):
                ax.plot(x[i, j], y[i, j], marker, color='k', ms=size, mew=1.6,
                        mfc='k' if filled else 'none', zorder=5, gid=key)
    lo_g, hi_g = 1000 * float(payloads[0]), 1000 * float(payloads[-1])
    nom_g = 1000 * float(payloads[jn])
    band = f'band: payload {lo_g:.0f}-{hi_g:.0f} g'
    edges = [g for g in (lo_g, hi_g) if abs(g - nom_g) > 1e-6]
    extra = [Line2D([], [], color='0.3', lw=CURVE_LW, label=f'solid: {nom_g:.0f} g payload')]
    if band_in or not band_out:
        extra.append(Patch(color='0.3', alpha=BAND_ALPHA, label=band))
    if band_out:
        extra.append(Patch(facecolor='none', edgecolor=EXTRAPOLATED_BAND['edgecolor'],
                           linewidth=0, hatch=EXTRAPOLATED_BAND['hatch'],
                           label=('grey hatch: band ' if band_in else f'{band},\ngrey hatch: ')
                           + 'extrapolated beyond the bench'))
    if edges and payloads.size > 1:
        extra.append(Line2D([], [], color='0.3', **BAND_EDGE,
                            label='dashed: band edge' + ('s ' if len(edges) > 1 else ' ')
                            + ' and '.join(f'{g:.0f} g' for g in edges)))
    if any_out:
        extra.append(Line2D([], [], ls=':', color='0.3',
                            label='dotted: outside the bench (Eq. 1 extrapolated)'))
    # limits from the points the bench covers: an extrapolated tail must not set the scale
    lim_p = _inside_limits(inside_pout)
    lim_c = _inside_limits(inside_cot)
    if any_out and lim_c is not None:
        all_c = np.concatenate([np.ravel(c.cot_per_mass) for c in curves])
        clipped = bool(np.nanmax(all_c) > lim_c[1] or np.nanmin(all_c) < lim_c[0])
        ax3.set_ylim(lim_c[1], lim_c[0])            # CoT/M grows downward
    else:
        ax3.invert_yaxis()
    if any_out and lim_p is not None:
        ax1.set_ylim(*lim_p)
    ax2.invert_xaxis()
    ax1.set_ylabel('')
    ax2.set_ylabel('P_out [W]')
    ax3.set_ylabel('CoT/M [J/(m kg)]' + ('\n(axis fits the bench; extrapolated tail clipped)'
                                          if clipped else ''))
    ax3.set_xlabel('efficiency eta [%]')
    ax4.set_xlabel('speed v [m/s]')
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    sub = _fixed_parameters(curves) if subtitle is None else subtitle
    load = (f'nominal payload {nom_g:.0f} g (band {lo_g:.0f}-{hi_g:.0f} g)'
            if payloads.size > 1 else f'payload {nom_g:.0f} g')
    sub = f'{sub}; {load}' if sub else load
    fig.suptitle('\n'.join(t for t in (title, sub) if t), fontsize=11)
    # a first layout for the axes' size: is the P_out band thinner than the line?
    fig.tight_layout(rect=(0.0, 0.12, 1.0, 1.0))
    if payloads.size > 1 and pout_bands:
        thin, change = _thin_band_share(ax1, [x for x, _ in pout_bands],
                                        [y for _, y in pout_bands], CURVE_LW)
        if thin >= 0.5:
            extra.append(Patch(facecolor='none', edgecolor='none',
                               label=f'P_out band thinner than the line at '
                                     f'{100 * thin:.0f} % of points\n(payload changes '
                                     f'P_out <= {100 * change:.1f} %)'))
    extra += [Line2D([], [], ls='', marker=mk, color='k', ms=min(sz, 11), mew=1.6,
                     mfc='k' if filled else 'none', label=name)
              for name, mk, sz, filled in OPTIMUM_MARKERS.values()]
    handles, labels = ax1.get_legend_handles_labels()
    # below the quadrants: inside any of them it would cover curves or optimum markers
    legend = fig.legend(handles + extra, labels + [h.get_label() for h in extra], fontsize=8,
                        loc='lower center', ncol=4, frameon=False,
                        bbox_to_anchor=(0.5, 0.0))
    # the space the legend takes, no more (a fixed share per row left a wide empty band)
    renderer = fig.canvas.get_renderer()
    height = legend.get_window_extent(renderer).height / fig.bbox.height
    fig.tight_layout(rect=(0.0, height + 0.005, 1.0, 1.0))
    return fig


def four_quadrant_plot(
    curves: Sequence[SweepCurve], out_stem: str | Path, *, title: str = '',
    subtitle: str | None = None, nominal_payload_kg: float | None = None,
) -> list[Path]:
    """Draw the four-quadrant plot of ``curves``; returns the written PNG and SVG paths.

    Parameters
    ----------
    curves : sequence of SweepCurve
        One curve per configuration.
    out_stem : str or Path
        Output path without suffix.
    title : str
        Figure title.
    subtitle : str, optional
        Second title line (default: robot mass and the parameters the curves share; the
        nominal payload and band are added).
    nominal_payload_kg : float, optional
        Payload of the solid curves (one of the curves'); default the first.

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    return _save(four_quadrant_figure(curves, title=title, subtitle=subtitle,
                                      nominal_payload_kg=nominal_payload_kg), out_stem)


#: a contour level above this share of the colour map's range is drawn dark (light colours)
CONTOUR_DARK_ABOVE = 0.6


def _contour_colors(mesh: Any, levels: Any) -> list[str]:
    """Per contour level, black where the colour map is light (above
    :data:`CONTOUR_DARK_ABOVE` of its range), white where it is dark."""
    lo, hi = mesh.norm.vmin, mesh.norm.vmax
    span = hi - lo if hi > lo else 1.0
    return ['k' if (float(lv) - lo) / span > CONTOUR_DARK_ABOVE else 'w' for lv in levels]


def power_map_plot(
    speeds_mps: np.ndarray, payloads_kg: np.ndarray, power_w: np.ndarray, out_stem: str | Path,
    *, gait_label: str = '',
) -> list[Path]:
    """Fig. 7D: output power over speed x payload, (n_speed, n_payload) [W], with labelled
    contour lines; the title names the gait and how much P_out changes with the payload."""
    speeds = np.asarray(speeds_mps, dtype=float)
    grams = np.asarray(payloads_kg, dtype=float) * 1000.0
    pw = np.asarray(power_w, dtype=float)
    fig, ax = plt.subplots(figsize=(6.4, 4.8))
    mesh = ax.pcolormesh(speeds, grams, pw.T, shading='auto', cmap='viridis')
    fig.colorbar(mesh, ax=ax, label='P_out [W]')
    if pw.shape[0] > 1 and pw.shape[1] > 1 and np.ptp(pw[np.isfinite(pw)]) > 0:
        cs = ax.contour(speeds, grams, pw.T, levels=8, colors='w', linewidths=0.8)
        # dark lines and labels on the light (yellow) end of the colour map, white on the
        # dark end: a white label on yellow could not be read
        inks = _contour_colors(mesh, cs.levels)
        cs.set_edgecolor(inks)
        ax.clabel(cs, fmt='%.2g W', fontsize=7, colors=inks)
    ax.set_xlabel('speed v [m/s]')
    ax.set_ylabel('payload [g]')
    with np.errstate(divide='ignore', invalid='ignore'):
        change = (pw[:, -1] - pw[:, 0]) / pw[:, 0]
    change = change[np.isfinite(change)]
    line2 = (f'P_out changes at most {100 * float(np.max(np.abs(change))):.1f} % from '
             f'{grams[0]:.0f} to {grams[-1]:.0f} g' if change.size else '')
    head = 'Robot output power (Eq. 6)' + (f': {gait_label}' if gait_label else '')
    ax.set_title(head + (f'\n{line2}' if line2 else ''), fontsize=10)
    fig.tight_layout()
    return _save(fig, out_stem)


#: payload lines of the gait comparison closer than this (relative ratio spread) are drawn as
#: the band's two extreme payloads only, the spread said in the legend
COMPARISON_SPREAD_ALL = 0.02


def _speed_runs(v: np.ndarray, mask: np.ndarray) -> list[tuple[float, float]]:
    """(first, last) speed of each run of ``mask``, widened by half a step each side."""
    runs: list[tuple[float, float]] = []
    half = 0.5 * float(np.median(np.diff(v))) if v.size > 1 else 0.0
    i = 0
    while i < mask.size:
        if not mask[i]:
            i += 1
            continue
        k = i
        while k + 1 < mask.size and mask[k + 1]:
            k += 1
        runs.append((float(v[i]) - (half if i > 0 else 0.0),
                     float(v[k]) + (half if k + 1 < mask.size else 0.0)))
        i = k + 1
    return runs


def _span_text(ends: Sequence[float]) -> str:
    """'0.055 m/s', or a range over the payloads."""
    return (f'{min(ends):.3f} m/s' if max(ends) - min(ends) < 5e-4 else
            f'{min(ends):.3f}-{max(ends):.3f} m/s over the payloads')


def comparison_figure(cmp: dict[str, Any]) -> Any:
    """One curve's CoT/M over another's against speed
    (:func:`~hexapod_energy.sweeps.compare_curves`): below 1 the first named is cheaper.

    Solid where both curves are on the bench, dotted where either extrapolates it; the speeds
    extrapolated at every payload shaded grey.  The title says up to which speed the ratio
    stays below 1, and whether that holds on the bench or only where a curve extrapolates it
    (then with the ratio range the bench covers).  Payload lines that all but coincide
    (spread below :data:`COMPARISON_SPREAD_ALL`) are drawn for the band's two extreme payloads
    only, the spread said in the legend."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    v = np.asarray(cmp['speeds_mps'], dtype=float)
    ratio = np.asarray(cmp['ratio'], dtype=float)
    outside = np.asarray(cmp['outside_bench'], dtype=bool)
    grams = 1000.0 * np.asarray(cmp['payloads_kg'], dtype=float)
    fig, ax = plt.subplots(figsize=(7.0, 4.8))
    colors = plt.cm.viridis(np.linspace(0.0, 0.85, max(grams.size, 1)))
    with np.errstate(divide='ignore', invalid='ignore'):
        spread = np.nanmax((np.nanmax(ratio, axis=1) - np.nanmin(ratio, axis=1))
                           / np.nanmin(np.abs(ratio), axis=1)) if ratio.size else 0.0
    spread = float(spread) if np.isfinite(spread) else 0.0
    drawn = list(range(grams.size)) if spread >= COMPARISON_SPREAD_ALL or grams.size <= 2 \
        else [0, grams.size - 1]
    every_out = outside.all(axis=1) if outside.size else np.zeros(v.size, bool)
    for k, (a, b) in enumerate(_speed_runs(v, every_out)):
        ax.axvspan(a, b, color='0.5', alpha=0.16, lw=0, zorder=0, gid='extrapolated_speeds',
                   label='extrapolated at every payload' if k == 0 else None)
    for j in drawn:
        for mask, style in ((~outside[:, j], '-'), (outside[:, j], ':')):
            # each run extended by one point so that solid and dotted parts join
            y = np.where(np.convolve(mask, [1, 1, 1], 'same') > 0, ratio[:, j], np.nan)
            ax.plot(v, y, style, color=colors[j], lw=1.8,
                    label=f'{grams[j]:.0f} g' if style == '-' else None)
    ax.axhline(1.0, color='k', lw=0.8)
    ax.set_xlabel('speed v [m/s]')
    ax.set_ylabel(f"CoT/M {cmp['other']} / {cmp['base']}")
    other = cmp['other']
    ends = [u for u in cmp['below_one_until_mps'] if u is not None]
    bench_ends = [u for u in cmp.get('below_one_until_mps_on_bench', cmp['below_one_until_mps'])
                  if u is not None]
    on = ~outside
    if ends and bench_ends:
        line2 = f'{other} cheaper up to {_span_text(bench_ends)} on the bench'
        if max(ends) > max(bench_ends) + 5e-4:
            line2 += f' (up to {_span_text(ends)} extrapolated)'
    elif ends:
        line2 = (f'{other} cheaper up to {_span_text(ends)} only where a curve extrapolates '
                 'the bench')
    else:
        line2 = f'{other} never cheaper'
    if on.any() and not bench_ends:
        covered = [f'{g:.0f}' for g, col in zip(grams, on.T) if col.any()]
        rng = ratio[on]
        where = (f'{", ".join(covered)} g' if len(covered) < grams.size else 'every payload')
        line3 = (f'on the bench ({where}, v >= {float(v[on.any(axis=1)].min()):.3f} m/s): '
                 f'never cheaper, ratio {float(np.nanmin(rng)):.2f}-'
                 f'{float(np.nanmax(rng)):.2f}')
    elif not on.any():
        line3 = 'the bench covers none of these points: all extrapolated'
    else:
        line3 = ''
    ax.set_title('\n'.join(t for t in (f'{other} against {cmp["base"]}', line2, line3) if t),
                 fontsize=10)
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    extra = [Line2D([], [], color='0.3', lw=1.8, label='solid: both on the bench'),
             Line2D([], [], color='0.3', lw=1.8, ls=':', label='dotted: a curve extrapolated')]
    if len(drawn) < grams.size:
        extra.append(Patch(facecolor='none', edgecolor='none',
                           label=f'{grams[0]:.0f}-{grams[-1]:.0f} g change the ratio '
                                 f'< {max(100 * spread, 0.1):.1f} %'))
    ax.legend(handles + extra, labels + [h.get_label() for h in extra], title='payload',
              fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    return fig


def comparison_plot(cmp: dict[str, Any], out_stem: str | Path) -> list[Path]:
    """Draw :func:`comparison_figure`; returns the PNG and SVG paths."""
    return _save(comparison_figure(cmp), out_stem)


def prediction_figure(
    speeds_mps: Sequence[float], measured_w: Sequence[float], predicted_w: Sequence[float],
    *, labels: Sequence[str] | None = None, title: str = '',
    outside: Sequence[bool] | None = None,
) -> Any:
    """Predicted against measured robot input power, one labelled point per run, the 1:1
    line, the RMSE in the title; equal axes padded so that one run still reads.  Runs whose
    prediction extrapolates the bench (``outside``, true per run: energy.json
    ``prediction_outside_bench`` not empty) are ringed with a dotted circle, named in the
    legend."""
    meas = np.asarray(measured_w, dtype=float)
    pred = np.asarray(predicted_w, dtype=float)
    speeds = np.asarray(speeds_mps, dtype=float)
    names = list(labels) if labels is not None else [''] * meas.size
    fig, ax = plt.subplots(figsize=(6, 5.2))
    ok = np.isfinite(meas) & np.isfinite(pred)
    both = np.concatenate([meas[ok], pred[ok]])
    if both.size:
        lo, hi = float(both.min()), float(both.max())
        pad = max(0.12 * (hi - lo), 0.08 * hi, 1.0)
        lim = (max(0.0, lo - pad), hi + pad)
    else:
        lim = (0.0, 1.0)
    ax.plot(lim, lim, '-', color='0.5', lw=1, label='1:1 (perfect prediction)')
    ax.plot(lim, [1.1 * x for x in lim], ':', color='0.6', lw=1, label='\u00b110 %')
    ax.plot(lim, [0.9 * x for x in lim], ':', color='0.6', lw=1)
    sc = ax.scatter(meas, pred, c=speeds, cmap='viridis', s=40, zorder=3, edgecolor='k')
    far = np.zeros(meas.size, bool) if outside is None else np.asarray(outside, bool) & ok
    if far.any():
        ax.scatter(meas[far], pred[far], s=190, facecolors='none', edgecolors='crimson',
                   linestyles=':', linewidths=1.5, zorder=4,
                   label='Eq. 1 extrapolated beyond the bench')
    if np.unique(speeds[np.isfinite(speeds)]).size > 1:     # one speed: the labels say it
        fig.colorbar(sc, ax=ax, label='speed v [m/s]')
    for x, y, v, name in zip(meas, pred, speeds, names):
        if np.isfinite(x) and np.isfinite(y):
            text = f'{name} ' if name else ''
            ax.annotate(f'{text}{v:.2f} m/s' if np.isfinite(v) else text, (x, y),
                        textcoords='offset points', xytext=(6, -10), fontsize=7)
    ax.set_xlim(lim)
    ax.set_ylim(lim)
    ax.set_aspect('equal')
    ax.set_xlabel('measured P_in [W]')
    ax.set_ylabel('predicted P_in (Eq. 1) [W]')
    err = pred[ok] - meas[ok]
    line = (f'{ok.sum()} run{"s" if ok.sum() != 1 else ""}: RMSE {np.sqrt(np.mean(err ** 2)):.2f}'
            f' W, bias {np.mean(err):+.2f} W (predicted - measured)' if ok.any() else 'no runs')
    ax.set_title('\n'.join(t for t in (title or 'Eq. 1 prediction against measurement',
                                        line) if t), fontsize=10)
    ax.legend(fontsize=8, loc='upper left')
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def prediction_plot(
    speeds_mps: Sequence[float], measured_w: Sequence[float], predicted_w: Sequence[float],
    out_stem: str | Path, *, labels: Sequence[str] | None = None, title: str = '',
    outside: Sequence[bool] | None = None,
) -> list[Path]:
    """Measured against predicted robot input power per run (:func:`prediction_figure`);
    returns the PNG and SVG paths."""
    return _save(prediction_figure(speeds_mps, measured_w, predicted_w, labels=labels,
                                   title=title, outside=outside), out_stem)


def measured_runs_plot(labels: Sequence[str], power_in_w: Sequence[float],
                       cot_per_mass: Sequence[float], out_stem: str | Path, *,
                       title: str = '') -> list[Path]:
    """Measured input power and CoT/M per robot run (runs without a bench prediction).

    Parameters
    ----------
    labels : sequence of str
        One label per run (bag name, speed).
    power_in_w : sequence of float
        Measured mean input power [W].
    cot_per_mass : sequence of float
        Specific cost of transport [J/(m kg)] (NaN when unknown).
    out_stem : str or Path
        Output path without suffix.
    title : str
        Figure title.

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    x = np.arange(len(labels))
    fig, axes = plt.subplots(1, 2, figsize=(max(7.0, 1.6 * len(labels) + 3.0), 4.2))
    for ax, values, ylabel, color in (
            (axes[0], power_in_w, 'measured P_in [W]', '#1f77b4'),
            (axes[1], cot_per_mass, 'CoT/M [J/(m kg)]', '#ff7f0e')):
        vals = np.asarray(values, dtype=float)
        vals = np.where(np.isfinite(vals), vals, np.nan)   # a standing run's CoT is infinite
        bars = ax.bar(x, np.nan_to_num(vals, nan=0.0), 0.6, color=color)
        for b, v in zip(bars, vals):
            ax.annotate('n/a' if not np.isfinite(v) else f'{v:.3g}',
                        (b.get_x() + b.get_width() / 2, b.get_height()),
                        textcoords='offset points', xytext=(0, 2), ha='center', fontsize=8)
        ax.set_xticks(x)
        ax.set_xticklabels(labels, rotation=20, ha='right', fontsize=8)
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3, axis='y')
        top = np.nanmax(vals) if np.isfinite(vals).any() else 1.0
        ax.set_ylim(0.0, 1.15 * top if top > 0 else 1.0)
    fig.suptitle(title or 'Measured robot runs (no bench model: no prediction)', fontsize=10)
    fig.tight_layout()
    return _save(fig, out_stem)


def bench_surfaces_plot(model: Any, out_stem: str | Path, *, title: str = '') -> list[Path]:
    """The bench's phase powers against ``1 / T_phase`` per load, with the fitted surfaces
    (Brodoline et al. Fig. 6): the first figure to look at for a bench (an outside review: a
    bench-only analysis drew nothing).

    Parameters
    ----------
    model : hexapod_energy.single_leg.SingleLegModel
        Fitted; its walking sessions are the points, ``p_stance_w`` / ``p_swing_w`` the
        lines (over each load's measured range), the 0 Hz sessions' mean power the open
        squares at 0.
    out_stem : str or Path
        Output path without suffix.
    title : str
        Figure title.

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    samples = list(model.samples_)
    loads = sorted({float(x.load_kg) for x in samples})
    cmap = plt.get_cmap('viridis')
    colors = {m: cmap(0.85 * k / max(1, len(loads) - 1)) for k, m in enumerate(loads)}
    fig, axes = plt.subplots(1, 2, figsize=(10.0, 4.2), sharey=True)
    for ax, phase in zip(axes, ('stance', 'swing')):
        for m in loads:
            walk = [x for x in samples if x.load_kg == m and x.frequency_hz > 0]
            rate = np.array([1.0 / getattr(x, f't_{phase}_s') for x in walk])
            power = np.array([getattr(x, f'p_{phase}_w') for x in walk])
            c = colors[m]
            ax.plot(rate, power, 'o', color=c, ms=5, label=f'{1000 * m:.0f} g')
            if rate.size:
                grid = np.linspace(rate.min(), rate.max(), 60)
                fit = getattr(model, f'p_{phase}_w')(1.0 / grid, np.full_like(grid, m))
                ax.plot(grid, fit, '-', color=c, lw=1.4)
            basal = model.basal_power_w_.get(m)
            if basal is not None:
                ax.plot([0.0], [basal], 's', color=c, ms=6, mfc='none')
        ax.set_title(f'{phase}: {model.chosen_[phase]} surface, fit rmse '
                     f'{model.fit_rmse_w_[phase]:.3g} W', fontsize=9)
        ax.set_xlabel(f'1 / T_{phase} [1/s] (0: the standing sessions, squares)')
        ax.grid(alpha=0.3)
    axes[0].set_ylabel('mean phase power of the leg [W]')
    axes[1].legend(title='load', fontsize=8, title_fontsize=8, loc='best')
    fig.suptitle(title or 'Single-leg bench: phase powers and fitted surfaces', fontsize=10)
    fig.tight_layout()
    return _save(fig, out_stem)


def power_in_over_time_plot(series: Sequence[dict[str, Any]], out_stem: str | Path, *,
                            title: str = '') -> list[Path]:
    """Each robot run's input power against the time since its start: every gait-cycle window
    (thin), the medians of its tenths (markers, :func:`hexapod_energy.trend.power_in_trend`)
    and the Eq. 1 prediction (dashed) where there is one.

    Parameters
    ----------
    series : sequence of dict
        One per run: ``label``, ``time_s`` and ``power_in_w`` (the windows' centres from the
        run's start and their P_in), ``bin_time_s`` and ``bin_power_in_w``, ``predicted_w``
        (NaN: none), ``drift`` (bool, said in the legend).
    out_stem : str or Path
        Output path without suffix.
    title : str
        Figure title.

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    fig, ax = plt.subplots(figsize=(9.0, 4.6))
    span = max((float(np.max(s['time_s'])) for s in series if len(s['time_s'])), default=0.0)
    scale, unit = (60.0, 'min') if span >= 180.0 else (1.0, 's')
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    for k, s in enumerate(series):
        c = colors[k % len(colors)]
        ax.plot(np.asarray(s['time_s']) / scale, s['power_in_w'], '-', color=c, lw=0.6,
                alpha=0.45)
        ax.plot(np.asarray(s['bin_time_s']) / scale, s['bin_power_in_w'], 'o-', color=c,
                ms=4, lw=1.4, label=s['label'] + (' (drift)' if s.get('drift') else ''))
        pred = float(s.get('predicted_w', np.nan))
        if np.isfinite(pred):
            ax.axhline(pred, color=c, ls='--', lw=1.0)
    ax.plot([], [], 'k--', lw=1.0, label='Eq. 1 prediction')
    ax.set_xlabel(f'time since the run\'s start [{unit}]')
    ax.set_ylabel('input power P_in [W]')
    ax.set_title(title or 'Input power over time (windows; medians of each tenth)', fontsize=10)
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, out_stem)


def watts_figure(labels: Sequence[str], breakdowns: Sequence[dict[str, float]],
                 measured_w: Sequence[float], power_out_w: Sequence[float], *,
                 title: str = '', efficiency: Sequence[float] | None = None) -> Any:
    """Where the watts go, one stacked bar per robot run: the Eq. 1 model's split of its
    predicted input power into holding (the legs' basal power at their loads), moving in
    stance, moving in swing (or the two phases when the bench has no 0 Hz session), against
    the measured P_in (black bar). Measured power above the prediction is hatched on top of
    the stack; a prediction above the measured power is outlined (dashed, no fill) over the
    stack's top, which stays visible. The mechanical output P_out and the efficiency (P_out
    over the measured P_in, or ``efficiency`` per run when given) are written above each bar.
    The legend sits beside the axes, never over a bar; ``title`` (robot and run set) is the
    second title line."""
    from matplotlib.lines import Line2D

    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(labels) + 2.5) + 3.0, 4.8))
    x = np.arange(len(labels))
    with_basal = all(np.isfinite(b.get('holding_w', np.nan)) for b in breakdowns)
    parts = ((('holding_w', 'holding (basal at load)', '#8c8c8c'),
              ('stance_motion_w', 'moving, stance', '#1f77b4'),
              ('swing_motion_w', 'moving, swing', '#ff7f0e')) if with_basal else
             (('stance_w', 'stance legs', '#1f77b4'), ('swing_w', 'swing legs', '#ff7f0e')))
    bottom = np.zeros(len(labels))
    for key, label, color in parts:
        v = np.array([b[key] for b in breakdowns], dtype=float)
        ax.bar(x, v, 0.6, bottom=bottom, label=f'Eq. 1 model: {label}', color=color)
        bottom += v
    meas = np.array(measured_w, dtype=float)
    rest = meas - bottom
    if np.any(rest > 0):
        ax.bar(x, np.clip(rest, 0.0, None), 0.6, bottom=bottom, color='white', edgecolor='k',
               hatch='//', label='measured beyond the Eq. 1 model')
    if np.any(rest < 0):
        # an outline only: a filled overlay hid the top of the model's swing segment
        ax.bar(x, np.clip(-rest, 0.0, None), 0.6, bottom=np.minimum(meas, bottom),
               facecolor='none', edgecolor='k', linestyle='--', linewidth=1.2,
               label='Eq. 1 model above the measured P_in', gid='over_prediction')
    ax.plot(x, measured_w, 'k_', ms=22, mew=2.5, label='measured P_in')
    p_out = np.asarray(power_out_w, dtype=float)
    with np.errstate(divide='ignore', invalid='ignore'):
        eta = np.asarray(efficiency, dtype=float) if efficiency is not None else p_out / meas
    top_of = np.fmax(meas, bottom)
    for xi, t, po, e in zip(x, top_of, p_out, eta):
        if not np.isfinite(t):
            continue
        text = (f'P_out {po:.2f} W\neta {100 * e:.1f} %' if np.isfinite(po) and np.isfinite(e)
                else 'P_out unknown')
        ax.annotate(text, (xi, t), textcoords='offset points', xytext=(0, 3), ha='center',
                    va='bottom', fontsize=7.5, color='darkgreen', gid='power_out')
    top = float(np.nanmax(np.concatenate([meas, bottom])))
    ax.set_ylim(0.0, 1.2 * top if np.isfinite(top) and top > 0 else None)
    if len(labels) == 1:
        ax.set_xlim(-1.0, 1.0)
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=20, ha='right', fontsize=8)
    ax.set_ylabel('input power [W]')
    import textwrap

    wrap = max(60, int(11 * fig.get_figwidth() * ax.get_position().width))
    ax.set_title('Where the watts go: the Eq. 1 model\'s split against the measured P_in'
                 + (f'\n{textwrap.fill(title, wrap)}' if title else ''), fontsize=10)
    handles, names = ax.get_legend_handles_labels()
    note = Line2D([], [], ls='', marker='$P$', color='darkgreen',
                  label='above each bar: mechanical output P_out,\n'
                        'efficiency eta = P_out / measured P_in')
    extra = [note]
    if not with_basal:
        # the holding split is missing: say why, not only leave its bars out
        extra.append(Line2D([], [], ls='', marker='x', color='dimgray', gid='no_basal',
                            label='no holding (basal) split: the bench has\n'
                                  'no 0 Hz (standing) session'))
    ax.legend(handles + extra, names + [h.get_label() for h in extra], fontsize=7,
              loc='upper left',
              bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.grid(alpha=0.3, axis='y')
    fig.tight_layout()
    return fig


def watts_plot(labels: Sequence[str], breakdowns: Sequence[dict[str, float]],
               measured_w: Sequence[float], power_out_w: Sequence[float],
               out_stem: str | Path, *, title: str = '',
               efficiency: Sequence[float] | None = None) -> list[Path]:
    """Where the watts go (:func:`watts_figure`); returns the PNG and SVG paths."""
    return _save(watts_figure(labels, breakdowns, measured_w, power_out_w, title=title,
                              efficiency=efficiency), out_stem)


def _save(fig: Any, out_stem: str | Path) -> list[Path]:
    """Write ``fig`` as PNG and SVG next to ``out_stem``, close it, return both paths."""
    stem = Path(out_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix('.png'), stem.with_suffix('.svg')]
    for path in paths:
        fig.savefig(path, dpi=110, bbox_inches='tight', pad_inches=0.1)
    plt.close(fig)
    return paths
