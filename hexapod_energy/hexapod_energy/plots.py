"""Four-quadrant energy plots (Brodoline et al. 2024, Fig. 3) and the output power map (Fig. 7D).

Quadrant layout, all four sharing their axes two by two, as in the paper:

====================  ====================
II: P_out vs eta      I: P_out vs v
(eta grows leftward)
III: CoT/M vs eta     IV: CoT/M vs v
(both axes mirrored)  (CoT/M grows downward)
====================  ====================

Each curve is drawn at the nominal payload (first of its band, solid) with the payload band
(e.g. 0-500 g) shaded, the curve dotted and the band hatched (lighter) where Eq. 1 extrapolates
the bench (``outside_bench``; the axes fit the points the bench covers); optimal points marked
by shape, drawn so that coinciding ones stay visible: large hollow circle maximum P_out, hollow
square minimum CoT/M, small filled triangle maximum efficiency.  The subtitle gives the robot
mass (the leg-count sweep: its body and leg mass, each curve's mass in the legend) and the
parameters the curves share.  Uses the
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

__all__ = ['comparison_plot', 'four_quadrant_figure', 'four_quadrant_plot',
           'measured_runs_plot', 'power_in_over_time_plot', 'power_map_plot',
           'prediction_figure', 'prediction_plot', 'watts_figure', 'watts_plot']

#: optimal-point markers: key -> (legend label, marker, size, filled); drawn largest first
#: so that coinciding optima (often all three at a curve's maximum speed) all stay visible
OPTIMUM_MARKERS = {
    'max_power_out': ('max P_out', 'o', 15.0, False),
    'min_cot_per_mass': ('min CoT/M', 's', 9.5, False),
    'max_efficiency': ('max efficiency', '^', 6.0, True),
}


#: the payload band: solid shade where the bench covers it, hatched and lighter where Eq. 1
#: extrapolates (``outside_bench``)
BAND_ALPHA = 0.18
EXTRAPOLATED_BAND = {'alpha': 0.07, 'hatch': '////'}


def _band_split(outside: np.ndarray) -> np.ndarray:
    """Per speed interval ``i`` (speeds ``i`` and ``i + 1``) of a (k, m) ``outside_bench``
    mask, the last payload column up to which the band is on the bench: every column from
    the first to it is inside at both speeds; -1 when the first column is not (the whole
    band there is extrapolated), ``m - 1`` when the whole band is on the bench."""
    both = ~(outside[:-1] | outside[1:])                     # (k - 1, m)
    return np.cumprod(both, axis=1).sum(axis=1) - 1


def _band(ax: Any, x: np.ndarray, y: np.ndarray, color: str,
          outside: np.ndarray | None = None) -> tuple[bool, bool]:
    """Shade between the first and last payload columns of (k, m) arrays: solid where the
    bench covers the payloads (every column from the first inside at both ends of a speed
    interval), hatched and lighter above that column, i.e. where Eq. 1 extrapolates.

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
            # the hatch in the curve's colour, its own patch: alpha would fade it away
            ax.fill(xs[ok], ys[ok], facecolor='none', edgecolor=color, linewidth=0,
                    hatch=EXTRAPOLATED_BAND['hatch'], alpha=0.45)
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
                         subtitle: str | None = None) -> Any:
    """The four-quadrant figure of ``curves`` (see the module docstring).

    Parameters
    ----------
    curves : sequence of SweepCurve
        One curve per configuration of the sweep.
    title : str
        Figure title.
    subtitle : str, optional
        Second title line; by default the robot mass and the parameters the curves share.

    Returns
    -------
    matplotlib.figure.Figure
        The figure; the optimum markers are the lines whose ``gid`` is their key in
        :data:`OPTIMUM_MARKERS` (one legend entry each).
    """
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    fig, axes = plt.subplots(2, 2, figsize=(10, 9), sharex='col', sharey='row')
    (ax2, ax1), (ax3, ax4) = axes
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    inside_pout: list[np.ndarray] = []
    inside_cot: list[np.ndarray] = []
    any_out = clipped = band_in = band_out = False
    masses = {round(c.robot_mass_kg, 9) for c in curves}   # several: each label says its own
    for c, curve in enumerate(curves):
        col = colors[c % len(colors)]
        m = len(curve.payloads_kg)
        v = np.repeat(curve.speeds_mps[:, None], m, axis=1)
        eta = curve.efficiency * 100.0
        p_out, cot = curve.power_out_w, curve.cot_per_mass
        out_all = curve.outside_bench if curve.outside_bench is not None else \
            np.zeros(p_out.shape, bool)
        out = out_all[:, 0]
        any_out |= bool(out.any())
        # limits from the speeds where the nominal curve is on the bench (its whole payload
        # band there); a curve the bench never covers is all there is of it: it all counts
        keep = np.repeat(out[:, None], m, axis=1) & ~out.all()
        inside_pout.append(np.where(keep, np.nan, p_out))
        inside_cot.append(np.where(keep, np.nan, cot))
        label = curve.spec.label + (f', {curve.robot_mass_kg:.4g} kg' if len(masses) > 1
                                    else '') + (' (all extrapolated)' if out.all() else '')
        # a curve equal to an earlier one (wave at beta 0.5 is the tripod: L(t) = 3 always)
        # is drawn dashed over it and says so; it hid the earlier curve
        same = next((other.spec.label for other in curves[:c]
                     if other.speeds_mps.shape == curve.speeds_mps.shape
                     and np.allclose(other.speeds_mps, curve.speeds_mps)
                     and np.allclose(other.power_out_w, p_out, rtol=1e-9, equal_nan=True)
                     and np.allclose(other.cot_per_mass, cot, rtol=1e-9, equal_nan=True)),
                    None)
        style = '--' if same else '-'
        if same:
            label += f' (= {same})'
        for ax, x, y in ((ax1, v, p_out), (ax2, eta, p_out), (ax3, eta, cot), (ax4, v, cot)):
            drew_in, drew_out = _band(ax, x, y, col, out_all)
            band_in, band_out = band_in or drew_in, band_out or drew_out
            # solid where the bench's sessions cover the point, dotted where Eq. 1 extrapolates
            inside = np.where(out, np.nan, y[:, 0])
            ax.plot(x[:, 0], inside, style, color=col, lw=1.5 if same else 2.5,
                    label=label if ax is ax1 and not out.all() else None)
            if out.any():
                edge = out | np.convolve(out, [1, 1, 1], 'same').astype(bool)
                ax.plot(x[:, 0], np.where(edge, y[:, 0], np.nan), ':', color=col,
                        label=label if ax is ax1 and out.all() else None)
        pts = curve.optimal_points()
        for key, (name, marker, size, filled) in OPTIMUM_MARKERS.items():
            i = int(np.argmin(np.abs(curve.speeds_mps - pts[key]['speed_mps'])))
            for ax, x, y in ((ax1, v, p_out), (ax2, eta, p_out), (ax3, eta, cot),
                             (ax4, v, cot)):
                ax.plot(x[i, 0], y[i, 0], marker, color='k', ms=size, mew=1.6,
                        mfc='k' if filled else 'none', zorder=5, gid=key)
    payloads = curves[0].payloads_kg if curves else np.zeros(1)
    lo_g, hi_g = 1000 * float(payloads[0]), 1000 * float(payloads[-1])
    band = f'band: payload {lo_g:.0f}-{hi_g:.0f} g'
    extra = [Line2D([], [], color='0.3', label=f'solid: {lo_g:.0f} g payload')]
    if band_in or not band_out:
        extra.append(Patch(color='0.3', alpha=BAND_ALPHA, label=band))
    if band_out:
        extra.append(Patch(facecolor=(0.3, 0.3, 0.3, EXTRAPOLATED_BAND['alpha']),
                           edgecolor='0.45', linewidth=0, hatch=EXTRAPOLATED_BAND['hatch'],
                           label=('hatched: ' if band_in else f'{band}, hatched: ')
                           + 'extrapolated beyond the bench'))
    if any_out:
        extra.append(Line2D([], [], ls=':', color='0.3',
                            label='dotted: outside the bench (Eq. 1 extrapolated)'))
    extra += [Line2D([], [], ls='', marker=mk, color='k', ms=min(sz, 11), mew=1.6,
                     mfc='k' if filled else 'none', label=name)
              for name, mk, sz, filled in OPTIMUM_MARKERS.values()]
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
    handles, labels = ax1.get_legend_handles_labels()
    # below the quadrants: inside any of them it would cover curves or optimum markers
    fig.legend(handles + extra, labels + [h.get_label() for h in extra], fontsize=8,
               loc='lower center', ncol=4, frameon=False)
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    sub = _fixed_parameters(curves) if subtitle is None else subtitle
    if title or sub:
        fig.suptitle('\n'.join(t for t in (title, sub) if t), fontsize=11)
    rows = -(-(len(handles) + len(extra)) // 4)
    fig.tight_layout(rect=(0.0, 0.035 * rows + 0.01, 1.0, 1.0))
    return fig


def four_quadrant_plot(
    curves: Sequence[SweepCurve], out_stem: str | Path, *, title: str = '',
    subtitle: str | None = None,
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
        Second title line (default: robot mass and the parameters the curves share).

    Returns
    -------
    list of Path
        The PNG and the SVG.
    """
    return _save(four_quadrant_figure(curves, title=title, subtitle=subtitle), out_stem)


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
        ax.clabel(cs, fmt='%.2g W', fontsize=7)
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


def comparison_plot(cmp: dict[str, Any], out_stem: str | Path) -> list[Path]:
    """One curve's CoT/M over another's against speed, a line per payload
    (:func:`~hexapod_energy.sweeps.compare_curves`): below 1 the first named is cheaper;
    dotted where either extrapolates the bench."""
    v = np.asarray(cmp['speeds_mps'], dtype=float)
    ratio = np.asarray(cmp['ratio'], dtype=float)
    outside = np.asarray(cmp['outside_bench'], dtype=bool)
    grams = 1000.0 * np.asarray(cmp['payloads_kg'], dtype=float)
    fig, ax = plt.subplots(figsize=(6.4, 4.4))
    colors = plt.cm.viridis(np.linspace(0.0, 0.85, max(grams.size, 1)))
    for j, g in enumerate(grams):
        for mask, style in ((~outside[:, j], '-'), (outside[:, j], ':')):
            # each run extended by one point so that solid and dotted parts join
            y = np.where(np.convolve(mask, [1, 1, 1], 'same') > 0, ratio[:, j], np.nan)
            ax.plot(v, y, style, color=colors[j], lw=1.8,
                    label=f'{g:.0f} g' if style == '-' else None)
    ax.axhline(1.0, color='k', lw=0.8)
    ax.set_xlabel('speed v [m/s]')
    ax.set_ylabel(f"CoT/M {cmp['other']} / {cmp['base']}")
    ends = [u for u in cmp['below_one_until_mps'] if u is not None]
    span = (f'{min(ends):.3f} m/s' if ends and max(ends) - min(ends) < 5e-4 else
            f'{min(ends):.3f}-{max(ends):.3f} m/s over the payloads' if ends else '')
    line2 = f"{cmp['other']} cheaper up to {span}" if ends else f"{cmp['other']} never cheaper"
    ax.set_title(f"{cmp['other']} against {cmp['base']}\n{line2} (dotted: outside the bench)",
                 fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(title='payload', fontsize=8, ncol=2)
    fig.tight_layout()
    return _save(fig, out_stem)


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
                 title: str = '') -> Any:
    """Where the watts go, one stacked bar per robot run: holding (the legs' basal power at
    their loads), moving in stance, moving in swing (or the two phases when the bench has no
    0 Hz session), then what the bench model does not explain: measured power above the
    prediction hatched on top, a prediction above the measured power cross-hatched over the
    stack's top; the measured P_in and the mechanical output P_out marked. The legend sits
    beside the axes, never over a bar."""
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
        ax.bar(x, v, 0.6, bottom=bottom, label=label, color=color)
        bottom += v
    meas = np.array(measured_w, dtype=float)
    rest = meas - bottom
    if np.any(rest > 0):
        ax.bar(x, np.clip(rest, 0.0, None), 0.6, bottom=bottom, color='white', edgecolor='k',
               hatch='//', label='measured beyond the bench model (Eq. 1)')
    if np.any(rest < 0):
        ax.bar(x, np.clip(-rest, 0.0, None), 0.6, bottom=np.minimum(meas, bottom),
               color='white', edgecolor='0.4', hatch='xx', alpha=0.7,
               label='predicted by Eq. 1, not measured')
    ax.plot(x, measured_w, 'k_', ms=22, mew=2, label='measured P_in')
    ax.plot(x, power_out_w, 'v', color='green', label='of which mechanical output P_out')
    top = float(np.nanmax(np.concatenate([np.asarray(measured_w, dtype=float), bottom])))
    ax.set_ylim(0.0, 1.12 * top if np.isfinite(top) and top > 0 else None)
    if len(labels) == 1:
        ax.set_xlim(-1.0, 1.0)
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=20, ha='right', fontsize=8)
    ax.set_ylabel('input power [W]')
    ax.set_title('Where the watts go' + (f': {title}' if title else ''), fontsize=10)
    ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.grid(alpha=0.3, axis='y')
    fig.tight_layout()
    return fig


def watts_plot(labels: Sequence[str], breakdowns: Sequence[dict[str, float]],
               measured_w: Sequence[float], power_out_w: Sequence[float],
               out_stem: str | Path, *, title: str = '') -> list[Path]:
    """Where the watts go (:func:`watts_figure`); returns the PNG and SVG paths."""
    return _save(watts_figure(labels, breakdowns, measured_w, power_out_w, title=title),
                 out_stem)


def _save(fig: Any, out_stem: str | Path) -> list[Path]:
    """Write ``fig`` as PNG and SVG next to ``out_stem``, close it, return both paths."""
    stem = Path(out_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix('.png'), stem.with_suffix('.svg')]
    for path in paths:
        fig.savefig(path, dpi=110, bbox_inches='tight', pad_inches=0.1)
    plt.close(fig)
    return paths
