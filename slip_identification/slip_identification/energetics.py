"""Energetics per run (Komsuoglu et al., Section 5): specific resistance, Table 3, Figs. 7-9."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from hexapod_common.conversions import current_sign_factor
from hexapod_common.series import span_mean

from .errors import SlipDataError
from .fit import FORCE_SWING_MIN, TWO_MINIMA_NERR_RATIO
from .model import GRAVITY_MPS2

__all__ = ['GAIT_ORDER', 'PAPER_COLORS', 'PAPER_MASS_KG', 'PAPER_TABLE3', 'battery_power_w',
           'data_source', 'gait_colors', 'gait_table', 'ordered_gaits', 'paper_table3_rows',
           'plot_figures', 'specific_resistance']


def battery_power_w(voltage_v: ArrayLike, current_a: ArrayLike, *, sign: str = 'auto',
                    t_s: ArrayLike | None = None, span_s: tuple[float, float] | None = None
                    ) -> tuple[float, str]:
    """Mean input power [W] and the current sign convention used.

    ``sign``: ``'ros'`` (current negative when discharging, P = -V I), ``'positive_discharge'``
    (P = V I) or ``'auto'`` (the sign that makes the median V I a positive input power, as the
    energy analysis decides it: :func:`hexapod_common.conversions.current_sign_factor`).

    With the samples' stamps ``t_s`` (sorted) the mean is time-weighted: the trapezoidal
    integral of V I over ``span_s`` (default the samples' own span), interpolated at its
    bounds, over its length (:func:`hexapod_common.series.span_mean`, the mean `energy`
    takes). ``auto`` then decides the sign from the samples inside the span. Without stamps
    it is the plain mean of the samples, which weights clustered samples more (an outside
    review: up to 2.5 % on a run's power with irregular samples).
    """
    v = np.asarray(voltage_v, dtype=float)
    i = np.asarray(current_a, dtype=float)
    ok = np.isfinite(v) & np.isfinite(i)
    t = None
    if t_s is not None:
        t = np.asarray(t_s, dtype=float)
        if t.shape != v.shape:
            raise SlipDataError('battery stamps and samples differ in number')
        ok &= np.isfinite(t)
    if not ok.any():
        raise SlipDataError('battery power needs finite voltage and current samples')
    inside = ok
    if t is not None:
        a, b = span_s if span_s is not None else (float(t[ok][0]), float(t[ok][-1]))
        inside = ok & (t >= a) & (t <= b)
        if not inside.any():
            inside = ok
    try:
        factor = current_sign_factor(v[inside], i[inside], sign)
    except ValueError as err:
        raise SlipDataError(str(err)) from None
    name = 'ros' if factor < 0 else 'positive_discharge'
    if t is None or not b > a:
        p = factor * float(np.mean(v[ok] * i[ok]))
    else:
        p = factor * span_mean(t[ok], v[ok] * i[ok], a, b)
    if p < 0:
        raise SlipDataError(f'input power is negative ({p:.2f} W) with sign={name!r}')
    return p, name


def specific_resistance(power_w: float, mass_kg: float, speed_mps: float,
                        gravity_mps2: float = GRAVITY_MPS2) -> float:
    """SR = P / (m g v) (Eq. 5); NaN when the speed is not positive."""
    return power_w / (mass_kg * gravity_mps2 * speed_mps) if speed_mps > 0 else math.nan


#: Komsuoglu et al. Table 3's gait order, used for legends and tables.
GAIT_ORDER = ('running', 'jogging', 'pace', 'walk')

#: The paper's gait colours (captions of Figs. 7-9).
PAPER_COLORS = {'running': 'tab:blue', 'jogging': 'tab:green', 'pace': 'tab:purple',
                'walk': 'tab:red'}

#: Komsuoglu et al. Table 3 (EduBot, 3.31 kg): gait -> (mean, std) of nerr, P [W], v [m/s].
PAPER_TABLE3: dict[str, dict[str, tuple[float, float]]] = {
    'running': {'nerr': (0.087, 0.07), 'power_w': (31.63, 2.99), 'speed_mps': (1.06, 0.04)},
    'jogging': {'nerr': (0.26, 0.10), 'power_w': (42.92, 1.43), 'speed_mps': (0.64, 0.01)},
    'pace': {'nerr': (0.52, 0.11), 'power_w': (26.23, 0.51), 'speed_mps': (0.30, 0.004)},
    'walk': {'nerr': (0.54, 0.03), 'power_w': (20.93, 0.32), 'speed_mps': (0.16, 0.002)},
}

#: The robot mass of Table 3 [kg].
PAPER_MASS_KG = 3.31


def paper_table3_rows(mass_kg: float = PAPER_MASS_KG) -> dict[str, dict[str, float]]:
    """Table 3 as the per-gait entries :func:`gait_table` writes (``nerr_mean``,
    ``nerr_std``, ``power_w_mean``, ...), with ``sr_mean`` = P / (m g v) of the means (the
    paper gives no SR column)."""
    out: dict[str, dict[str, float]] = {}
    for gait, entry in PAPER_TABLE3.items():
        row: dict[str, float] = {}
        for key, (mean, std) in entry.items():
            row[f'{key}_mean'], row[f'{key}_std'] = mean, std
        row['sr_mean'] = specific_resistance(entry['power_w'][0], mass_kg,
                                             entry['speed_mps'][0])
        out[gait] = row
    return out


def ordered_gaits(gaits: Iterable[str]) -> list[str]:
    """The gaits in Table 3's order (running, jogging, pace, walk), any other after them,
    alphabetically."""
    names = {str(g) for g in gaits}
    return [g for g in GAIT_ORDER if g in names] + sorted(names - set(GAIT_ORDER))


def gait_colors(gaits: Iterable[str]) -> dict[str, str]:
    """Colour per gait: the paper's (Figs. 7-9: running blue, jogging green, pace purple,
    walk red); any other gait takes the next colour of matplotlib's cycle the paper's do not
    use."""
    import matplotlib.pyplot as plt
    from matplotlib.colors import to_hex

    cycle = [to_hex(c) for c in plt.rcParams['axes.prop_cycle'].by_key()['color']]
    taken = {to_hex(c) for c in PAPER_COLORS.values()}
    spare = [c for c in cycle if c not in taken] or cycle
    out: dict[str, str] = {}
    others = 0
    for g in ordered_gaits(gaits):
        if g in PAPER_COLORS:
            out[g] = PAPER_COLORS[g]
        else:
            out[g] = spare[others % len(spare)]
            others += 1
    return out


def gait_table(rows: Sequence[dict[str, float | str]]) -> dict[str, dict[str, float | int]]:
    """Table 3: per gait mean and std of ``nerr``, ``power_w``, ``speed_mps`` (and ``sr``),
    the gaits in Table 3's order (running, jogging, pace, walk, then any other); with
    ``stiffness`` and ``rest_length`` in the rows, their median and interquartile range.

    ``rows`` holds one dict per stance with keys ``gait``, ``nerr``, ``power_w``,
    ``speed_mps``, ``sr`` (run values repeated on each of the run's stances, as in the paper).
    With ``force_swing`` in the rows, ``constant_force_stances`` counts the stances fitted by
    a nearly constant leg force (:func:`.fit.spring_force_swing`); with ``other_nerr_ratio``
    (another minimum's nerr over the kept one's), ``two_minima_stances`` those within
    :data:`.fit.TWO_MINIMA_NERR_RATIO`; with ``nerr_noise_floor``, its median
    ``nerr_noise_floor_median``. The three counts (``stances`` and the two above) are ints,
    so that slip.json writes them as JSON integers.
    """
    out: dict[str, dict[str, float | int]] = {}
    for gait in ordered_gaits(str(r['gait']) for r in rows):
        sel = [r for r in rows if r['gait'] == gait]
        entry: dict[str, float | int] = {'stances': len(sel)}
        keys = ('nerr', 'power_w', 'speed_mps', 'sr') + \
            (('nerr_world',) if any('nerr_world' in r for r in sel) else ())
        for key in keys:
            vals = np.array([float(r.get(key, math.nan)) for r in sel], dtype=float)
            vals = vals[np.isfinite(vals)]
            entry[f'{key}_mean'] = float(vals.mean()) if vals.size else math.nan
            entry[f'{key}_std'] = float(vals.std()) if vals.size else math.nan
        for key in ('stiffness', 'rest_length'):
            # the fitted parameters: median and interquartile range (a soft long spring can
            # stand for a walk's nearly constant leg force, and would pull a mean)
            if not any(key in r for r in sel):
                continue
            vals = np.array([float(r.get(key, math.nan)) for r in sel], dtype=float)
            vals = vals[np.isfinite(vals)]
            q25, q50, q75 = (np.percentile(vals, (25, 50, 75)) if vals.size
                             else (math.nan,) * 3)
            entry[f'{key}_median'] = float(q50)
            entry[f'{key}_iqr'] = float(q75 - q25)
        if any('force_swing' in r for r in sel):
            swing = np.array([float(r.get('force_swing', math.nan)) for r in sel])
            # stances whose fit is a nearly constant leg force (k, l0 not identified apart)
            entry['constant_force_stances'] = int(np.sum(swing < FORCE_SWING_MIN))
        if any('nerr_noise_floor' in r for r in sel):
            # the part of the SLIP-measure that the motion capture's noise alone gives
            # (:func:`.fit.nerr_noise_floor`): gaits compare only at one rate and noise
            floor = np.array([float(r.get('nerr_noise_floor', math.nan)) for r in sel])
            floor = floor[np.isfinite(floor)]
            entry['nerr_noise_floor_median'] = float(np.median(floor)) if floor.size \
                else math.nan
        if any('other_nerr_ratio' in r for r in sel):
            ratio = np.array([float(r.get('other_nerr_ratio', math.inf)) for r in sel])
            # stances with another minimum the data hardly tell from the kept one
            entry['two_minima_stances'] = int(np.sum(ratio <= TWO_MINIMA_NERR_RATIO))
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


def _source_of(out: Path) -> tuple[float | None, str | None]:
    """Robot mass and data source from the ``slip.json`` the SLIP analysis wrote in ``out``
    (its ``mass_kg``; 'simulated EduBot' when every run's bag carries the EduBot simulator's
    truth, else 'recorded runs'), ``(None, None)`` without one."""
    import json

    try:
        doc = json.loads((out / 'slip.json').read_text(encoding='utf-8'))
    except (OSError, ValueError):
        return None, None
    if not isinstance(doc, dict):
        return None, None
    mass = doc.get('mass_kg')
    mass = float(mass) if isinstance(mass, (int, float)) and math.isfinite(mass) else None
    return mass, data_source(doc.get('runs') or [])


def data_source(runs: Sequence[Any]) -> str | None:
    """The data of ``slip.json`` runs, for figure titles: 'simulated EduBot' when every run's
    bag carries the EduBot simulator's truth, else 'recorded runs'; None without runs."""
    bags = [Path(str(r.get('bag', ''))) for r in runs if isinstance(r, dict)]

    def simulated(bag: Path) -> bool:
        try:
            return 'hexapod_sim.edubot_truth' in (bag / 'metadata.yaml').read_text(
                encoding='utf-8', errors='replace')
        except OSError:
            return False

    if not bags:
        return None
    return ('simulated EduBot (hexapod-sim)' if all(map(simulated, bags))
            else 'recorded runs')


#: Fig. 9's measures: key -> y-axis label (Eq. 2 literal first, the paper's Table 3 measure)
NERR_MEASURES = (
    ('nerr_world', "nerr_world: Eq. 2 literal, bx in the run's world frame\n"
                   "(the paper's SLIP-measure, Table 3)"),
    ('nerr', "nerr: Eq. 2 with bx from each stance's start\n"
             '(slip.json nerr; independent of the frame origin)'),
)


def _measures(rows: Sequence[dict[str, float | str]]) -> list[tuple[str, str]]:
    """Fig. 9's panels: each of :data:`NERR_MEASURES` with a finite value in ``rows``
    (``nerr`` alone when the rows carry no ``nerr_world``)."""
    out = [(k, label) for k, label in NERR_MEASURES
           if any(math.isfinite(float(r.get(k, math.nan))) for r in rows)]
    return out or [NERR_MEASURES[1]]


def _separate_labels(fig: Any, ax: Any, step_pt: float = 8.0, tries: int = 12) -> None:
    """Move ``ax``'s annotations (offset points) down, one after another, until none
    overlaps an earlier one (a run's 'n=15' sat on its outlier's '0.10': an outside
    review)."""
    renderer = fig.canvas.get_renderer()
    placed: list[Any] = []
    for text in ax.texts:
        if not hasattr(text, 'xyann'):
            continue
        for _ in range(tries):
            box = text.get_window_extent(renderer).expanded(1.05, 1.1)
            if not any(box.overlaps(b) for b in placed):
                break
            x, y = text.xyann
            text.xyann = (x, y - step_pt)
        placed.append(text.get_window_extent(renderer))


def plot_figures(rows: Sequence[dict[str, float | str]], out_dir: str | Path, *,
                 mass_kg: float | None = None, source: str | None = None) -> list[Path]:
    """Figs. 7 (v vs SR), 8 (P vs v), 9 (nerr vs SR) in the paper's gait colours (running
    blue, jogging green, pace purple, walk red; legend in Table 3's order), each as PNG and
    SVG at the energy figures' resolution (:func:`.plots.save_figure`).

    Speed, power and SR are run values (repeated on each stance): one marker per run,
    annotated with its stance count ``n``. nerr is per stance: Fig. 9 draws every stance
    (jittered sideways, over its run's marker) and each run's median (ring) with its
    interquartile range; stances beyond Q3 + 1.5 IQR are labelled with their value. With
    ``nerr_world`` in the rows Fig. 9 has two panels on one y scale: ``nerr_world`` (Eq. 2
    read literally, the paper's measure) and ``nerr`` (bx from each stance's start, what
    ``slip.json``'s ``nerr`` is); the y-axes name them.

    Parameters
    ----------
    rows : sequence of dict
        One dict per stance (``gait``, ``nerr``, ``power_w``, ``speed_mps``, ``sr``,
        optionally ``nerr_world`` and ``bag``).
    out_dir : str or Path
        Output folder.
    mass_kg : float, optional
        Robot mass named in the titles; default the ``mass_kg`` of ``out_dir/slip.json``.
    source : str, optional
        The data named in the titles (e.g. 'simulated EduBot'); default from
        ``out_dir/slip.json``'s runs.

    Returns
    -------
    list of Path
        The three PNGs (an SVG beside each).
    """
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D

    from .plots import save_figure

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    if mass_kg is None or source is None:
        found_mass, found_source = _source_of(out)
        mass_kg = found_mass if mass_kg is None else mass_kg
        source = found_source if source is None else source
    gaits = ordered_gaits(str(r['gait']) for r in rows)
    color = gait_colors(gaits)
    runs = sorted(_runs_of(rows), key=lambda run: gaits.index(str(run[0]['gait'])))
    per_gait = {g: sum(1 for run in runs if str(run[0]['gait']) == g) for g in gaits}
    counts = set(per_gait.values())
    data = [source or '']
    if mass_kg is not None:
        data.append(f'm = {mass_kg:.3g} kg')
    if len(counts) == 1:
        k = counts.pop()
        data.append(f'{k} run per gait' if k == 1 else f'{k} runs per gait')
    else:
        data.append(f'{len(runs)} runs')
    what = ', '.join(x for x in data if x)
    sr_label = 'specific resistance SR [-]'
    how = '\n(dots: stances; ring and bar: median and IQR per run)'
    specs = [('fig7_speed_vs_sr', 'sr', ['speed_mps'], sr_label, ['speed [m/s]'],
              'Fig. 7: speed against specific resistance'),
             ('fig8_power_vs_speed', 'speed_mps', ['power_w'], 'speed [m/s]',
              ['input power [W]'], 'Fig. 8: input power against speed'),
             ('fig9_nerr_vs_sr', 'sr', [k for k, _ in _measures(rows)], sr_label,
              [f'SLIP-measure {label} [-]{how}' for _, label in _measures(rows)],
              'Fig. 9: SLIP-measure against specific resistance')]
    paths = []
    for name, kx, kys, lx, lys, title in specs:
        rng = np.random.default_rng(0)       # the jitter: the same figure on every run
        fig, axs = plt.subplots(1, len(kys), figsize=(6.6 * len(kys), 4.9), squeeze=False,
                                sharey=True)
        xs_all = [float(np.nanmean([float(r[kx]) for r in run])) for run in runs
                  if np.isfinite([float(r[kx]) for r in run]).any()]
        span = (max(xs_all) - min(xs_all)) if len(xs_all) > 1 else 1.0
        for ax, ky, ly in zip(axs[0], kys, lys):
            nerr = ky.startswith('nerr')
            for run in runs:
                g = str(run[0]['gait'])
                xs = np.array([float(r[kx]) for r in run], dtype=float)
                ys = np.array([float(r.get(ky, math.nan)) for r in run], dtype=float)
                x = float(np.nanmean(xs)) if np.isfinite(xs).any() else math.nan
                ok = np.isfinite(ys)
                at = (x, math.nan)
                if nerr and ok.any():
                    y = float(np.median(ys[ok]))
                    q1, q3 = (float(q) for q in np.percentile(ys[ok], [25, 75]))
                    # dots spread wider than the run's ring and drawn over it: every stance
                    # shows (the filled median marker had hidden running's 0.044-0.101)
                    # (evenly spaced offsets in random order: a run of few stances spreads
                    # as wide as one of many)
                    m = int(ok.sum())
                    jitter = rng.permutation(np.linspace(-0.06, 0.06, m) if m > 1
                                             else np.zeros(1)) * (span or 1.0)
                    ax.errorbar([x], [y], yerr=[[y - q1], [q3 - y]], fmt='o', ms=11,
                                color=color[g], mfc='none', mec=color[g], mew=2.0,
                                ecolor='k', elinewidth=1.2, capsize=5, zorder=3,
                                label='_run')
                    ax.scatter(x + jitter, ys[ok], s=18, color=color[g], alpha=0.8,
                               edgecolors='k', linewidths=0.4, zorder=4, label='_stances')
                    far = q3 + 1.5 * (q3 - q1)
                    for v, jx in zip(ys[ok], x + jitter):
                        if v > far and q3 > q1:
                            ax.annotate(f'{v:.2f}', (jx, v), textcoords='offset points',
                                        xytext=(5, 0), va='center', fontsize=7,
                                        color=color[g])
                    at = (x, float(ys[ok].min()))     # the stance count below its dots
                else:
                    y = float(ys[ok].mean()) if ok.any() else math.nan
                    if math.isfinite(y):
                        ax.plot([x], [y], 'o', ms=8, color=color[g], label='_run')
                    at = (x, y)
                if math.isfinite(at[0]) and math.isfinite(at[1]):
                    if nerr:
                        ax.annotate(f'n={len(run)}', at, textcoords='offset points',
                                    xytext=(0, -9), ha='center', va='top', fontsize=8)
                    else:
                        ax.annotate(f'n={len(run)}', at, textcoords='offset points',
                                    xytext=(8, 4), fontsize=8)
            ax.set_xlabel(lx)
            ax.set_ylabel(ly, fontsize=9 if nerr else None)
            if ax is axs[0][0]:
                ax.set_title('\n'.join(x for x in (title, what, '(Komsuoglu et al.; one '
                                                    'marker per run, n = its stances)') if x),
                             fontsize=9)
            else:     # Fig. 9's second measure: the same stances
                ax.set_title(f'the same stances, {ky}\n(Eq. 2 with bx from each stance\'s '
                             'start: slip.json\'s and the report\'s "nerr")', fontsize=9)
            ax.grid(alpha=0.3)
            ax.margins(0.15)
            if nerr:
                ax.set_ylim(bottom=0.0)
                ax.yaxis.set_tick_params(labelleft=True)
            ax.legend(handles=[Line2D([], [], ls='', marker='o', ms=7, color=color[g],
                                      label=g) for g in gaits], title='gait', fontsize=8)
        fig.tight_layout()
        for ax in axs[0]:
            _separate_labels(fig, ax)
        paths.append(save_figure(fig, out / name)[0])
    return paths
