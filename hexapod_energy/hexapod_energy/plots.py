"""Four-quadrant energy plots (Brodoline et al. 2024, Fig. 3) and the output power map (Fig. 7D).

Quadrant layout, all four sharing their axes two by two, as in the paper:

====================  ====================
II: P_out vs eta      I: P_out vs v
(eta grows leftward)
III: CoT/M vs eta     IV: CoT/M vs v
(both axes mirrored)  (CoT/M grows downward)
====================  ====================

Each curve is drawn at the nominal payload (first of its band) with the payload band (e.g.
0-500 g) shaded; optimal points marked: red x maximum P_out, blue x minimum CoT/M, green x
maximum efficiency.  Uses the non-interactive Agg backend; writes PNG and SVG.
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

__all__ = ['four_quadrant_plot', 'power_map_plot', 'prediction_plot', 'watts_plot']

_MARKERS = {'max_power_out': 'red', 'min_cot_per_mass': 'blue', 'max_efficiency': 'green'}


def _band(ax, x: np.ndarray, y: np.ndarray, color: str) -> None:
    """Shade between the first and last payload columns of (k, m) arrays."""
    xs = np.concatenate([x[:, 0], x[::-1, -1]])
    ys = np.concatenate([y[:, 0], y[::-1, -1]])
    ok = np.isfinite(xs) & np.isfinite(ys)
    ax.fill(xs[ok], ys[ok], color=color, alpha=0.18, linewidth=0)


def four_quadrant_plot(
    curves: Sequence[SweepCurve], out_stem: str | Path, *, title: str = ''
) -> list[Path]:
    """Draw the four-quadrant plot of ``curves``; returns the written PNG and SVG paths."""
    fig, axes = plt.subplots(2, 2, figsize=(10, 8), sharex='col', sharey='row')
    (ax2, ax1), (ax3, ax4) = axes
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    for c, curve in enumerate(curves):
        col = colors[c % len(colors)]
        m = len(curve.payloads_kg)
        v = np.repeat(curve.speeds_mps[:, None], m, axis=1)
        eta = curve.efficiency * 100.0
        p_out, cot = curve.power_out_w, curve.cot_per_mass
        out = curve.outside_bench[:, 0] if curve.outside_bench is not None else \
            np.zeros(len(curve.speeds_mps), bool)
        for ax, x, y in ((ax1, v, p_out), (ax2, eta, p_out), (ax3, eta, cot), (ax4, v, cot)):
            _band(ax, x, y, col)
            # solid where the bench's sessions cover the point, dotted where Eq. 1 extrapolates
            inside = np.where(out, np.nan, y[:, 0])
            ax.plot(x[:, 0], inside, color=col, label=curve.spec.label if ax is ax1 else None)
            if out.any():
                edge = out | np.convolve(out, [1, 1, 1], 'same').astype(bool)
                ax.plot(x[:, 0], np.where(edge, y[:, 0], np.nan), ':', color=col)
        pts = curve.optimal_points()
        for key, color in _MARKERS.items():
            i = int(np.argmin(np.abs(curve.speeds_mps - pts[key]['speed_mps'])))
            for ax, x, y in ((ax1, v, p_out), (ax2, eta, p_out), (ax3, eta, cot),
                             (ax4, v, cot)):
                ax.plot(x[i, 0], y[i, 0], 'x', color=color, markersize=8, mew=2)
    if any(c.outside_bench is not None and c.outside_bench[:, 0].any() for c in curves):
        ax1.plot([], [], ':', color='0.3', label='outside the bench (extrapolated)')
    ax2.invert_xaxis()
    ax3.invert_yaxis()
    ax1.set_ylabel('')
    ax2.set_ylabel('P_out [W]')
    ax3.set_ylabel('CoT/M [J/(m kg)]')
    ax3.set_xlabel('efficiency eta [%]')
    ax4.set_xlabel('speed v [m/s]')
    ax1.legend(fontsize=8, loc='upper left')
    for ax in axes.ravel():
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    return _save(fig, out_stem)


def power_map_plot(
    speeds_mps: np.ndarray, payloads_kg: np.ndarray, power_w: np.ndarray, out_stem: str | Path
) -> list[Path]:
    """Fig. 7D: output power over speed x payload, (n_speed, n_payload) [W]."""
    fig, ax = plt.subplots(figsize=(6, 4.5))
    mesh = ax.pcolormesh(speeds_mps, np.asarray(payloads_kg) * 1000.0, np.asarray(power_w).T,
                         shading='auto', cmap='viridis')
    fig.colorbar(mesh, ax=ax, label='P_out [W]')
    ax.set_xlabel('speed v [m/s]')
    ax.set_ylabel('payload [g]')
    ax.set_title('Robot output power (Eq. 6)')
    fig.tight_layout()
    return _save(fig, out_stem)


def prediction_plot(
    speeds_mps: Sequence[float], measured_w: Sequence[float], predicted_w: Sequence[float],
    out_stem: str | Path,
) -> list[Path]:
    """Measured against predicted robot input power per run."""
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(speeds_mps, measured_w, 'o', label='measured P_in')
    ax.plot(speeds_mps, predicted_w, 's', mfc='none', label='predicted P_in (Eq. 1)')
    ax.set_xlabel('speed v [m/s]')
    ax.set_ylabel('P_in [W]')
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, out_stem)


def watts_plot(labels: Sequence[str], breakdowns: Sequence[dict[str, float]],
               measured_w: Sequence[float], power_out_w: Sequence[float],
               out_stem: str | Path) -> list[Path]:
    """Where the watts go, one stacked bar per robot run: holding (the legs' basal power at
    their loads), moving in stance, moving in swing (or the two phases when the bench has no
    0 Hz session), then what the bench model does not explain: measured power above the
    prediction hatched on top, a prediction above the measured power cross-hatched over the
    stack's top; the measured P_in and the mechanical output P_out marked."""
    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(labels) + 2.5), 4.8))
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
    ax.set_xticks(x)
    ax.set_xticklabels(labels, rotation=20, ha='right', fontsize=8)
    ax.set_ylabel('input power [W]')
    ax.set_title('Where the watts go')
    ax.legend(fontsize=7, loc='upper left')
    ax.grid(alpha=0.3, axis='y')
    fig.tight_layout()
    return _save(fig, out_stem)


def _save(fig: Any, out_stem: str | Path) -> list[Path]:
    """Write ``fig`` as PNG and SVG next to ``out_stem``, close it, return both paths."""
    stem = Path(out_stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    paths = [stem.with_suffix('.png'), stem.with_suffix('.svg')]
    for path in paths:
        fig.savefig(path, dpi=110)
    plt.close(fig)
    return paths
