"""``hexapod-analyze report DIR``: one self-contained HTML page from an analysis folder.

Collects every ``*.json`` result (``energy.json``, ``slip.json``, ``residuals.json``,
``demo.json``) and every PNG plot under DIR into ``DIR/report.html``. Each result gets a
section: its plain-words summary, its headline figures as tables (numbers at four significant
figures, units from the key suffixes), then its own plots inline (base64) with a caption and a
link to the SVG where one was written; the full JSON folded at the section's end. Plots no
result claims come last. The header names when the page was generated, the installed package
versions and, from a git checkout, the source commit (energy.json's ``options`` say what the
analysis ran with). A sub-folder holding its own ``report.html`` or ``demo.json`` is another run
(an older demo run under a newer one): it is left out and named, never interleaved.

Sections per result:

* ``energy.json``: the prediction error, one row per robot run, the recommendation, the
  optimal points of every sweep, the bench surface fit;
* ``slip.json``: the per-gait table (Komsuoglu et al. Table 3: stances, nerr, P, v, SR as mean
  +/- sd, in the paper's gait order, beside the paper's values) and one row per run (clock
  offset, ground, stances);
* ``residuals.json``: error before and after, the effects added with their fitted parameters
  +/- standard error, what is left unexplained;
* ``demo.json``: the live/replay check, the batch loop, the SLIP tables.
"""

from __future__ import annotations

import argparse
import base64
import html
import json
import math
import os
import time
from pathlib import Path
from typing import Any

__all__ = ['add_cli', 'fmt_number', 'unit_of', 'write_report']

#: headline keys rendered as tables, per result file (others are summarised as 'first keys')
HEADLINES: dict[str, tuple[str, ...] | None] = {
    'energy.json': ('prediction_error', 'robot_mass', 'failed_bags', 'options'),
    'residuals.json': ('model', 'unit', 'baseline', 'effects_added', 'final', 'heldout',
                       'stances', 'unexplained', 'supply_voltage'),
    'slip.json': ('model', 'estimator', 'mass_kg', 'skipped_counts', 'failed_bags'),
    'demo.json': ('live', 'batch'),
}

#: unit from the key's suffix (longest suffix first); '' = dimensionless
_SUFFIX_UNITS = (
    ('conductance_s', 'S'), ('_w_per_kg', 'W/kg'), ('_w_per_k', 'W/K'), ('_w_per_hz', 'W/Hz'),
    ('_w_per_s', 'W/s'), ('_j_per_m_kg', 'J/(m kg)'), ('_j_per_m', 'J/m'), ('_mps', 'm/s'),
    ('_ohm', 'ohm'), ('_deg', 'deg'), ('_rad', 'rad'), ('_kg', 'kg'), ('_hz', 'Hz'),
    ('_w', 'W'), ('_s', 's'), ('_m', 'm'), ('_a', 'A'), ('_v', 'V'), ('_k', 'K'),
    ('_c', 'degC'), ('_j', 'J'), ('_a2', 'A^2'),
)
#: whole keys with a unit their suffix does not give
_KEY_UNITS = {'rmse': '', 'speed': 'm/s', 'specific_cost_of_transport': 'J/(m kg)',
              'cost_of_transport': 'J/m', 'cv_rmse_w': 'W', 'fit_rmse_w': 'W'}

_MAX_TEXT = 600        # characters of one string value before it is cut (with an ellipsis)
_MAX_ITEMS = 12        # items of a list of numbers shown
_MAX_ROWS = 40         # rows of a list of records shown
_MAX_DEPTH = 6         # nesting of tables before the rest is shown as cut JSON

#: figure captions by file stem (prefix match, first wins)
CAPTIONS = (
    ('four_quadrant_', 'Four-quadrant plot (Brodoline et al. 2024, Fig. 3): P_out and CoT/M '
     'against speed and efficiency; solid line at the nominal payload its subtitle names, '
     'band over the payload range, dotted where Eq. 1 extrapolates the bench; markers at the '
     'optimal points.'),
    ('gait_type_comparison', 'Wave gait (beta 0.83) CoT/M divided by the tripod\'s, per '
     'payload, against speed: below 1 the wave gait is cheaper. Where either curve '
     'extrapolates the bench surfaces (dotted or shaded) the ratio is not measured: read a '
     'ratio below 1 there as a prediction only.'),
    ('power_map', 'Robot output power over speed and payload (Eq. 6, Fig. 7D), with contours.'),
    ('prediction', 'Measured against predicted (Eq. 1) input power per robot run; the 1:1 line '
                   'is a perfect prediction.'),
    ('power_in_over_time', 'Input power of each robot run against the time since its start: '
                           'every gait-cycle window (thin), the medians of its tenths '
                           '(markers) and the Eq. 1 prediction (dashed).'),
    ('measured_runs', 'Measured input power and specific cost of transport per robot run.'),
    ('bench_surfaces', 'Single-leg bench (Brodoline et al. Fig. 6): each walking session\'s '
                       'mean stance and swing power against 1 / T_phase (the surfaces\' f: '
                       'twice the step frequency at duty factor 0.5), one colour per load, '
                       'with the fitted surface; open squares at 0 are the standing '
                       'sessions\' mean power.'),
    ('where_the_watts_go', 'Where the watts go: the predicted input power split into holding, '
                           'stance and swing motion, against the measured input power.'),
    ('residual_time', 'Energy residual (measured minus predicted P_in, W) over time, one row '
                      'per run: per sample before the added effects (thin line), per '
                      'gait-phase window before (filled) and after (hollow) them, held-out '
                      'windows shaded grey; the bottom panel has every window of every run in '
                      'order (held-out windows ringed).'),
    ('residual_regressors', 'Residual against each added effect\'s fitted term: before the '
                            'effect the points follow the fitted line; after it they lose '
                            'that slope, and what scatter is left (per run, too) is the '
                            'windows\' noise and what no added effect explains.'),
    ('residual_unexplained', 'What the added effects left, per run, against the window noise.'),
    ('residual_slip_nerr', 'SLIP-measure nerr per stance (the stances and nerr of '
                           'hexapod-analyze slip, bx from each stance\'s start), one series '
                           'per bag: plain SLIP, and with the extension the loop added when '
                           'it added one.'),
    ('fig7', 'Komsuoglu et al. Fig. 7: speed against specific resistance, one marker per run, '
             'in the paper\'s gait colours (running blue, jogging green, pace purple, walk '
             'red).'),
    ('fig8', 'Komsuoglu et al. Fig. 8: input power against speed, one marker per run, in the '
             'paper\'s gait colours (running blue, jogging green, pace purple, walk red).'),
    ('fig9', 'Komsuoglu et al. Fig. 9: SLIP-measure against specific resistance: every '
             'stance (dots, jittered sideways), each run\'s median (ring) and interquartile '
             'range (bar); stances beyond Q3 + 1.5 IQR labelled with their value. Left: '
             'nerr_world, Eq. 2 read literally (bx in the run\'s world frame), the paper\'s '
             'measure; right: the same stances\' nerr (bx from each stance\'s start, '
             'independent of the frame\'s origin), the table\'s "nerr" column.'),
    ('slip_fit', 'SLIP fit against the data: for the best, median and worst stance by nerr '
                 'of each gait (one row per gait), the measured COM path, fore/aft and '
                 'vertical speed and leg length to the fitted foot (solid; raw motion-capture '
                 'samples as dots) against the SLIP re-simulated from the stance\'s fitted '
                 'k, l0, fx from its first measured state (dashed): the four states Eq. 2 '
                 'compares. The legend gives each stance\'s index in slip.json\'s stances, '
                 'touchdown, nerr and nerr_world.'),
)



def fmt_number(value: float, digits: int = 4) -> str:
    """A float at ``digits`` significant figures; rounding noise (|x| < 1e-9) shown as 0.

    Parameters
    ----------
    value : float
        The number.
    digits : int
        Significant figures.

    Returns
    -------
    str
        ``'-'`` for NaN, ``'inf'``/``'-inf'``, else the number.
    """
    if isinstance(value, bool):
        return str(value).lower()
    if isinstance(value, int):
        return str(value)
    if math.isnan(value):
        return '-'
    if math.isinf(value):
        return 'inf' if value > 0 else '-inf'
    if abs(value) < 1e-9:
        return '0'
    return f'{value:.{digits}g}'


def unit_of(key: str) -> str:
    """The unit a result key's suffix names (``power_w`` -> ``W``), ``''`` when none."""
    k = key.lower()
    if k in _KEY_UNITS:
        return _KEY_UNITS[k]
    for suffix, unit in _SUFFIX_UNITS:
        if k.endswith(suffix):
            return unit
    return ''


def _esc(text: Any) -> str:
    return html.escape(str(text))


def _cut(text: str, limit: int = _MAX_TEXT) -> str:
    return text if len(text) <= limit else text[:limit].rstrip() + ' \u2026'


def _scalar(value: Any, unit: str = '') -> str:
    """One value as escaped HTML text with its unit."""
    if value is None:
        return '-'
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        text = fmt_number(value)
        return _esc(text + (f' {unit}' if unit and text not in ('-',) else ''))
    if isinstance(value, bool):
        return 'yes' if value else 'no'
    return _esc(_cut(str(value)))


def _is_scalar(value: Any) -> bool:
    return value is None or isinstance(value, (str, int, float, bool))


def render_value(value: Any, key: str = '', depth: int = 0, unit: str | None = None) -> str:
    """A JSON value as HTML: dicts as two-column tables, lists of records as tables, lists of
    numbers inline (cut with an ellipsis), strings cut with an ellipsis.

    Parameters
    ----------
    value : Any
        The JSON value.
    key : str
        Its key, whose suffix gives the unit (``power_w`` -> W).
    depth : int
        Nesting so far; deeper than ``_MAX_DEPTH`` is shown as cut JSON.
    unit : str, optional
        The unit, instead of the key's (a nested dict's keys inherit their parent's).

    Returns
    -------
    str
        HTML.
    """
    unit = unit_of(key) if unit is None else unit
    if _is_scalar(value):
        return _scalar(value, unit)
    if depth >= _MAX_DEPTH:
        return f'<code>{_esc(_cut(json.dumps(value, default=str), 300))}</code>'
    if isinstance(value, dict):
        if not value:
            return '-'
        return _kv_table(value, depth, unit, parent=key)
    if isinstance(value, (list, tuple)):
        if not value:
            return 'none'
        if all(_is_scalar(v) for v in value):
            shown = ', '.join(_scalar(v) for v in value[:_MAX_ITEMS])
            more = f', \u2026 ({len(value)} in all)' if len(value) > _MAX_ITEMS else ''
            return shown + more + (f' {_esc(unit)}' if unit else '')
        if all(isinstance(v, dict) for v in value):
            return _records_table(list(value), depth)
        return '<br>'.join(render_value(v, key, depth + 1) for v in value[:_MAX_ROWS])
    return _scalar(str(value))


#: (parent key, key) -> the row heading that says what a figure measures: the two
#: "bias" figures of a demo have opposite signs and different averaging
KEY_LABELS = {
    ('prediction_error', 'bias_w'): 'bias_w (predicted \u2212 measured P_in, per run)',
    ('prediction_error', 'rmse_w'): 'rmse_w (predicted \u2212 measured P_in, per run)',
    ('prediction_error', 'mae_w'): 'mae_w (per run)',
    ('baseline', 'bias'): 'bias (residual: measured \u2212 model, per window)',
    ('final', 'bias'): 'bias (residual: measured \u2212 model, per window)',
    ('baseline', 'rmse'): 'rmse (residual, per window)',
    ('final', 'rmse'): 'rmse (residual, per window)',
    ('baseline', 'mae'): 'mae (residual, per window)',
    ('final', 'mae'): 'mae (residual, per window)',
    ('heldout', 'rmse_before'): 'rmse_before (residual of the held-out windows)',
    ('heldout', 'rmse_after'): 'rmse_after (residual of the held-out windows)',
}

#: keys whose figures are in the unit of the document holding them (its ``unit`` key)
_IN_DOC_UNIT = ('baseline', 'final', 'heldout')


def _kv_table(data: dict[str, Any], depth: int = 0, unit: str = '', parent: str = '') -> str:
    """Two-column table of a dict; keys without a unit of their own take ``unit`` (the
    residual loop's ``baseline``, ``final``, ``heldout`` the dict's ``unit``); headings from
    :data:`KEY_LABELS` where the figure needs its definition."""
    own = data.get('unit') if isinstance(data.get('unit'), str) else None
    rows = ''
    for k, v in data.items():
        sub = unit_of(str(k)) or (own if own is not None and k in _IN_DOC_UNIT else unit)
        rows += (f'<tr><th>{_esc(KEY_LABELS.get((parent, str(k)), k))}</th><td>'
                 f'{render_value(v, str(k), depth + 1, sub)}</td></tr>')
    return f'<table class="kv">{rows}</table>'


def _records_table(records: list[dict[str, Any]], depth: int = 0) -> str:
    cols: list[str] = []
    for r in records[:_MAX_ROWS]:
        cols.extend(k for k in r if k not in cols)
    head = ''.join(f'<th>{_esc(c)}' + (f' [{_esc(unit_of(c))}]' if unit_of(c) else '') +
                   '</th>' for c in cols)
    body = ''
    for r in records[:_MAX_ROWS]:
        cells = ''.join(
            f'<td>{render_value(r[c], "", depth + 1) if c in r else ""}</td>' for c in cols)
        body += f'<tr>{cells}</tr>'
    more = (f'<p>\u2026 {len(records) - _MAX_ROWS} more rows in the full JSON</p>'
            if len(records) > _MAX_ROWS else '')
    return f'<table class="grid"><tr>{head}</tr>{body}</table>{more}'


def _table(head: list[str], rows: list[list[str]], caption: str = '') -> str:
    """A grid table of already-escaped cells."""
    cap = f'<caption>{_esc(caption)}</caption>' if caption else ''
    return ('<table class="grid">' + cap + '<tr>' +
            ''.join(f'<th>{_esc(h)}</th>' for h in head) + '</tr>' +
            ''.join('<tr>' + ''.join(f'<td>{c}</td>' for c in r) + '</tr>' for r in rows) +
            '</table>')


def _pm(mean: Any, sd: Any, sd_digits: int = 2) -> str:
    """``mean +/- sd`` at four significant figures, sd at ``sd_digits`` (omitted when
    unknown)."""
    if not isinstance(mean, (int, float)):
        return '-'
    text = fmt_number(float(mean))
    if isinstance(sd, (int, float)) and math.isfinite(float(sd)):
        text += ' \u00b1 ' + fmt_number(float(sd), sd_digits)
    return _esc(text)


def _num(value: Any, unit: str = '', digits: int = 4) -> str:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return '-' if value is None else _esc(str(value))
    text = fmt_number(float(value), digits)
    return _esc(text + (f' {unit}' if unit and text != '-' else ''))


# ---------------------------------------------------------------------------------- slip


#: Komsuoglu et al. Table 3's gait order
_GAIT_ORDER = ('running', 'jogging', 'pace', 'walk')


def _paper_table3(data: dict[str, Any]) -> dict[str, Any]:
    """Komsuoglu et al. Table 3 to compare with: the document's own ``paper_table3`` (the demo
    writes it), else the SLIP package's, else none."""
    own = data.get('paper_table3')
    if isinstance(own, dict) and own:
        return own
    try:
        from slip_identification.energetics import paper_table3_rows
    except ImportError:
        return {}
    return paper_table3_rows()


def _gait_order(gaits: Any) -> list[str]:
    names = [str(g) for g in gaits]
    return [g for g in _GAIT_ORDER if g in names] + sorted(set(names) - set(_GAIT_ORDER))


def _drop_empty_columns(head: list[str], rows: list[list[str]]) -> tuple[list[str], list[str]]:
    """The columns with a value in at least one row (and the headings dropped)."""
    keep = [k for k in range(len(head)) if any(r[k] not in ('', '-') for r in rows)]
    return [head[k] for k in keep], [h for k, h in enumerate(head) if k not in keep]


def _slip_sections(data: dict[str, Any]) -> list[str]:
    """Per-gait table (Table 3, in its gait order, beside the paper's values) and one row per
    run from a ``slip.json`` (or ``demo.json``'s ``slip``) document."""
    parts = []
    gaits = data.get('gaits')
    if isinstance(gaits, dict) and gaits:
        paper = _paper_table3(data)
        if not any(g in paper for g in gaits):      # another robot's gaits: nothing to compare
            paper = {}
        rows = []
        world = any(isinstance(e, dict) and 'nerr_world_mean' in e for e in gaits.values())
        for g in _gait_order(gaits):
            e = gaits[g]
            if not isinstance(e, dict):
                continue
            n = e.get('stances')
            ref = paper.get(g) if isinstance(paper.get(g), dict) else {}
            rows.append([_esc(g), _num(int(n) if isinstance(n, (int, float)) else n),
                         _pm(e.get('nerr_mean'), e.get('nerr_std'))] +
                        ([_pm(e.get('nerr_world_mean'), e.get('nerr_world_std'))]
                         if world else []) + [
                         _pm(e.get('power_w_mean'), e.get('power_w_std')),
                         _pm(e.get('speed_mps_mean'), e.get('speed_mps_std')),
                         _pm(e.get('sr_mean'), e.get('sr_std'))] +
                        ([_pm(ref.get('nerr_mean'), ref.get('nerr_std'), 3),
                          _pm(ref.get('power_w_mean'), ref.get('power_w_std'), 3),
                          _pm(ref.get('speed_mps_mean'), ref.get('speed_mps_std'), 3),
                          _num(ref.get('sr_mean'), digits=3)] if paper else []))
        head = ['gait', 'stances', 'nerr', 'P [W]', 'v [m/s]', 'SR [-]']
        cap = ('mean \u00b1 sd over the gait\'s stances (P, v and SR are per run, repeated on '
               'each of its stances)')
        if world:
            head[3:3] = ['nerr, world frame']
            cap += ('; nerr normalises by the states with bx from each stance\'s first sample '
                    '(independent of the frame\'s origin), "nerr, world frame" is Eq. 2 read '
                    'literally (bx in the run\'s world frame, the paper\'s measure); the '
                    'stances are the single-support windows from the leg geometry, not the '
                    'clock\'s edges the paper fitted (README, SLIP)')
        if paper:
            head += ['paper: nerr', 'paper: P [W]', 'paper: v [m/s]', 'paper: SR [-]']
            cap += ('; paper: Komsuoglu et al. Table 3 (EduBot, 3.31 kg; its SR = P / (m g v) '
                    'of the mean P and v)')
        parts.append('<h3>Per gait (Komsuoglu et al. Table 3)</h3>' + _table(head, rows, cap))
    runs = data.get('runs')
    if isinstance(runs, list) and runs:
        truth = any('true_offset_s' in r for r in runs if isinstance(r, dict))
        head = ['bag', 'gait', 'stances', 'skipped', 'clock offset [ms]', 'offset method',
                'ground [mm]', 'tilt [deg]', 'P [W]', 'v [m/s]', 'SR [-]']
        if truth:
            head[5:5] = ['hidden offset [ms]']
            head[8:8] = ['hidden ground [mm]']
        rows = []
        order = {g: k for k, g in enumerate(_GAIT_ORDER)}
        for r in sorted((r for r in runs if isinstance(r, dict)),
                        key=lambda r: order.get(str(r.get('gait')), len(order))):
            frame = r.get('frame') if isinstance(r.get('frame'), dict) else {}
            tilt = r.get('tilt_deg', frame.get('tilt_deg'))
            ms = (lambda x: x * 1e3 if isinstance(x, (int, float)) else x)  # noqa: E731
            row = [_esc(Path(str(r.get('bag', ''))).name), _esc(r.get('gait', '-')),
                   _num(r.get('stances')), _num(r.get('skipped')),
                   _num(ms(r.get('offset_s')), digits=3), _esc(r.get('offset_method', '-')),
                   _num(ms(r.get('ground_m')), digits=3), _num(tilt, digits=3),
                   _num(r.get('power_w')), _num(r.get('speed_mps')), _num(r.get('sr'))]
            if truth:
                row[5:5] = [_num(ms(r.get('true_offset_s')), digits=3)]
                row[8:8] = [_num(ms(r.get('true_ground_m')), digits=3)]
            rows.append(row)
        kept, dropped = _drop_empty_columns(head, rows)
        rows = [[c for c, h in zip(r, head) if h in kept] for r in rows]
        parts.append('<h3>Per run</h3>' + _table(kept, rows) + (
            f'<p>(not in this document: {_esc(", ".join(dropped))})</p>' if dropped else ''))
    counts = data.get('skipped_counts')
    if isinstance(counts, dict):
        parts.append('<p>Stances skipped: ' + (', '.join(
            f'{_esc(k)}: {_esc(v)}' for k, v in counts.items()) or 'none') + '</p>')
    stances = data.get('stances')
    if isinstance(stances, list):
        parts.append(f'<p>{len(stances)} stances fitted.</p>')
    return parts


# -------------------------------------------------------------------------------- energy


def _rec_labels(configs: list[tuple[str, dict[str, Any]]]) -> dict[str, str]:
    """Row names of the recommendation table: the best configuration the bench covers and
    the default gait, each saying when its figure is an extrapolation."""
    labels = {}
    for name, c in configs:
        outside = bool(c.get('outside_bench'))
        if name == 'best':
            labels[name] = ('best (extrapolated: no configuration the bench covers)'
                            if outside else 'best on the bench')
        else:
            labels[name] = 'default (extrapolated)' if outside else 'default'
    return labels


def _recommendation(rec: Any) -> list[str]:
    if not isinstance(rec, dict):
        return []
    parts = ['<h3>Recommendation</h3>']
    at = []
    if 'speed_mps' in rec:
        at.append(f'at {_num(rec["speed_mps"], "m/s")}')
    if 'payload_kg' in rec:
        at.append(f'payload {_num(rec["payload_kg"], "kg")}')
    configs = [(k, rec[k]) for k in ('best', 'default') if isinstance(rec.get(k), dict)]
    labels = _rec_labels(configs)
    if configs:
        keys = ('gait', 'leg_count', 'duty_factor', 'step_length_m', 'period_s', 'power_in_w',
                'power_out_w', 'efficiency', 'specific_cost_of_transport', 'outside_bench')
        head = ['', 'gait', 'legs', 'beta', 'step [m]', 'T [s]', 'P_in [W]', 'P_out [W]',
                'eta [%]', 'CoT/M [J/(m kg)]', 'outside the bench']
        rows = []
        for name, c in configs:
            row = [f'<b>{_esc(labels[name])}</b>' if name == 'best' else _esc(labels[name])]
            for k in keys:
                v = c.get(k)
                if k == 'efficiency' and isinstance(v, (int, float)):
                    v = 100.0 * v
                row.append(render_value(v, '', 1) if k == 'outside_bench' else
                           (_num(v, digits=4) if not isinstance(v, str) else _esc(v)))
            rows.append(row)
        parts.append(_table(head, rows, 'recommended gait ' + ', '.join(at)))
    saving = rec.get('saving_fraction')
    if isinstance(saving, (int, float)) and math.isfinite(saving):
        counts = (f' ({_esc(rec.get("evaluated"))} configurations evaluated, '
                  f'{_esc(rec.get("rejected"))} rejected, '
                  f'{_esc(rec.get("outside_bench"))} outside the bench)'
                  if 'evaluated' in rec else '')
        text = (f'<p>CoT/M saving against the default gait: '
                f'{_esc(fmt_number(100.0 * saving, 3))} %{counts}')
        if saving < 0:
            default = rec.get('default') if isinstance(rec.get('default'), dict) else {}
            text += (f'. <b>No saving: the recommended configuration costs '
                     f'{_esc(fmt_number(-100.0 * saving, 3))} % more CoT/M than the default '
                     'gait.</b>')
            if default.get('outside_bench'):
                text += (' No configuration the bench covers beats the default; the '
                         'default\'s figure is an extrapolation of the bench surfaces, not a '
                         'measured advantage.')
            elif 'outside_bench' in default:
                text += ' The default gait was not among the configurations searched.'
        parts.append(text + '</p>')
    if rec.get('note'):
        parts.append(f'<p><i>{_esc(rec["note"])}</i></p>')
    return parts


_OPT = (('max_power_out', 'max P_out [W]', 1.0), ('min_cot_per_mass', 'min CoT/M [J/(m kg)]',
                                                  1.0),
        ('max_efficiency', 'max eta [%]', 100.0))


def _min_efficiency(c: dict[str, Any]) -> tuple[Any, Any, bool, bool]:
    """A sweep curve's minimum efficiency for the report: ``(value, speed, starred,
    on_bench)``. ``min_efficiency_on_bench`` (the minimum over the points the bench covers,
    with its speed) when the document has it; else ``min_efficiency`` (over every speed and
    payload), starred unless ``min_efficiency_outside_bench`` says it is on the bench."""
    on = c.get('min_efficiency_on_bench')
    speed: Any = None
    if isinstance(on, dict):              # {'value': ..., 'speed_mps': ...}
        speed = on.get('speed_mps', on.get('speed'))
        on = on.get('value')
    if isinstance(on, (int, float)) and not isinstance(on, bool) and math.isfinite(on):
        if speed is None:
            speed = next((c[k] for k in ('min_efficiency_on_bench_speed_mps',
                                         'min_efficiency_on_bench_at_mps',
                                         'min_efficiency_on_bench_mps',
                                         'min_efficiency_on_bench_speed') if k in c), None)
        return on, speed, False, True
    me = c.get('min_efficiency')
    speed = next((c[k] for k in ('min_efficiency_speed_mps', 'min_efficiency_at_mps')
                  if k in c), None)
    return me, speed, c.get('min_efficiency_outside_bench') is not False, False


def _nominal_payload(curves: list[Any]) -> str:
    """' (nominal payload N g)' when every curve of a sweep has the same first payload (the
    one its optimal points are taken at), else ''."""
    first = {c['payloads_kg'][0] for c in curves if isinstance(c, dict) and
             isinstance(c.get('payloads_kg'), list) and c['payloads_kg'] and
             isinstance(c['payloads_kg'][0], (int, float))}
    return f' (nominal payload {1e3 * first.pop():.0f} g)' if len(first) == 1 else ''


def _plotted_points(settings: Any, name: str) -> tuple[dict[str, Any], str]:
    """A sweep's optimal points as its plot marks them, by curve label, and the table title's
    payload, when the plot's nominal payload is not the sweep's first (Fig. 3C at 140 g:
    energy.json ``sweep_settings.plot_optimal_points``); else ``({}, '')``."""
    plotted = (settings or {}).get('plot_optimal_points') if isinstance(settings, dict) else None
    rows = plotted.get(name) if isinstance(plotted, dict) else None
    if not isinstance(rows, list) or not rows:
        return {}, ''
    by_label = {r.get('label'): r.get('optimal_points') or {} for r in rows
                if isinstance(r, dict)}
    kg = rows[0].get('payload_kg') if isinstance(rows[0], dict) else None
    title = f' (nominal payload {1e3 * kg:.0f} g, as plotted)' \
        if isinstance(kg, (int, float)) else ''
    return by_label, title


def _optimal_points(sweeps: Any, settings: Any = None) -> list[str]:
    if not isinstance(sweeps, dict) or not sweeps:
        return []
    parts = ['<h3>Optimal points per sweep (at the nominal payload; 0 g unless named)</h3>']
    any_on, any_starred = False, False
    for name, curves in sweeps.items():
        if not isinstance(curves, list):
            continue
        plotted, plotted_title = _plotted_points(settings, name)
        head = ['curve']
        for _, label, _s in _OPT:
            head += [label, 'at v [m/s]']
        head += ['min eta [%]', 'at v [m/s]', 'max v [m/s]']
        rows = []
        for c in curves:
            if not isinstance(c, dict):
                continue
            pts = plotted.get(c.get('label')) or c.get('optimal_points') or {}
            row = [_esc(c.get('label', '-'))]
            if c.get('not_walkable'):     # priced as the paper draws it, not a walkable gait
                row[0] += f'<br><small>not walkable: {_esc(c["not_walkable"])}</small>'
            for key, _, scale in _OPT:
                p = pts.get(key) or {}
                v = p.get('value')
                star = '*' if p.get('outside_bench') else ''
                row += [_num(scale * v if isinstance(v, (int, float)) else v) + star,
                        _num(p.get('speed_mps'), digits=3)]
            me, at, starred, on = _min_efficiency(c)
            any_on |= on
            any_starred |= starred and isinstance(me, (int, float))
            cell = _num(100.0 * me if isinstance(me, (int, float)) else me, digits=3)
            if starred and isinstance(me, (int, float)):
                cell = f'<span style="color:#888">{cell}*</span>'
            row += [cell, _num(at, digits=3), _num(c.get('max_speed_mps'), digits=3)]
            rows.append(row)
        at_col = len(head) - 2        # min eta's speed: left out when no curve gives it
        if rows and all(r[at_col] == '-' for r in rows):
            head = head[:at_col] + head[at_col + 1:]
            rows = [r[:at_col] + r[at_col + 1:] for r in rows]
        parts.append(_table(head, rows, name.replace('_', ' ') +
                            (plotted_title or _nominal_payload(curves))))
    parts.append('<p>* the point extrapolates the bench surfaces (dotted in the plots)</p>')
    notes = []
    if any_on:
        notes.append('min eta is the smallest efficiency over the speeds and payloads the bench '
                     'covers (the extrapolated slow end of a curve reads lower)')
    if any_starred:
        notes.append('a grey starred min eta is the smallest over every speed and payload, '
                     'extrapolated ones included, or not known to be on the bench: not a '
                     'measured figure, and not comparable across sweeps that start at '
                     'different speeds')
    if notes:
        parts.append('<p>' + '; '.join(_esc(n) for n in notes) + '.</p>')
    return parts


def _bench_fit(bench: Any) -> list[str]:
    if not isinstance(bench, dict) or not isinstance(bench.get('fit'), dict):
        return []
    fit = dict(bench['fit'])
    sessions = fit.pop('sessions', None)
    summary = {k: v for k, v in fit.items() if not isinstance(v, list) or len(v) <= _MAX_ITEMS}
    parts = ['<h3>Bench surface fit</h3>', _kv_table(summary)]
    if isinstance(sessions, list):
        parts.append(f'<p>{len(sessions)} bench sessions from '
                     f'{len(bench.get("bags") or [])} bag(s) (listed in the full JSON).</p>')
    # how each bench bag was read, with its notes and warnings (a review: they were only in
    # the folded raw JSON, where a phase-label gap's note went unseen)
    rows = []
    for d in bench.get('diagnostics') or []:
        if not isinstance(d, dict):
            continue
        said = [*(f'warning: {w}' for w in d.get('warnings') or []), *(d.get('notes') or [])]
        rows.append([_esc(d.get('bag', '-')), _esc(d.get('sessions', '-')),
                     _esc(d.get('phase_split', '-')),
                     _num(d.get('force_offset_s'), digits=3),
                     '<br>'.join(_esc(x) for x in said) or '-'])
    if rows:
        parts.append(_table(['bench bag', 'sessions', 'phase split', 'force offset [s]',
                             'warnings and notes'], rows))
    return parts


# ----------------------------------------------------------------------------- residuals


def _added_params(items: Any) -> list[str]:
    if not isinstance(items, list) or not items:
        return []
    rows = []
    for a in items:
        if not isinstance(a, dict):
            continue
        params, errs = a.get('params') or {}, a.get('stderr') or {}
        first = True
        for k, v in params.items():
            unit = unit_of(k)
            se = errs.get(k)
            value = (fmt_number(v) if isinstance(v, (int, float)) else str(v))
            if isinstance(se, (int, float)) and not isinstance(v, bool):
                value += ' \u00b1 ' + fmt_number(float(se), 2)
            rows.append([f'<b>{_esc(a.get("name", ""))}</b>' if first else '', _esc(k),
                         _esc(value + (f' {unit}' if unit else ''))])
            first = False
        alts = a.get('alternatives')
        if isinstance(alts, list) and alts:
            rows.append(['', 'alternatives (explain it nearly as well)',
                         _esc(', '.join(str(x.get('name')) for x in alts
                                        if isinstance(x, dict)))])
    return ['<h3>Effects added (fitted value \u00b1 standard error)</h3>',
            _table(['effect', 'parameter', 'value'], rows)]


# -------------------------------------------------------------------------------- plots


def png_description(png: Path) -> str:
    """The ``Description`` text a PNG carries (a ``tEXt`` or uncompressed ``iTXt`` chunk, as
    matplotlib writes ``savefig(..., metadata={'Description': ...})``), ``''`` without one."""
    import struct
    import zlib

    try:
        data = png.read_bytes()
    except OSError:
        return ''
    if not data.startswith(b'\x89PNG\r\n\x1a\n'):
        return ''
    at = 8
    while at + 8 <= len(data):
        length, kind = struct.unpack('>I4s', data[at:at + 8])
        body = data[at + 8:at + 8 + length]
        at += 12 + length
        if kind == b'IDAT' or kind == b'IEND':
            break
        if kind not in (b'tEXt', b'iTXt', b'zTXt'):
            continue
        key, _, rest = body.partition(b'\0')
        if key != b'Description':
            continue
        try:
            if kind == b'tEXt':
                return rest.decode('latin-1')
            if kind == b'zTXt':
                return zlib.decompress(rest[1:]).decode('latin-1')
            compressed, _method, rest = rest[0], rest[1], rest[2:]
            _lang, _, rest = rest.partition(b'\0')
            _tkey, _, text = rest.partition(b'\0')
            return (zlib.decompress(text) if compressed else text).decode('utf-8')
        except (ValueError, zlib.error, IndexError):
            return ''
    return ''


def _caption(path: Path) -> str:
    """The caption of a plot: by its file name (:data:`CAPTIONS`), then the description the
    PNG carries itself."""
    text = next((t for prefix, t in CAPTIONS if path.stem.startswith(prefix)), '')
    own = png_description(path) if path.suffix == '.png' else ''
    return ' '.join(x for x in (text, own) if x)


def _figure(png: Path, out: Path) -> str:
    """One inline PNG with its caption, its path and a link to its SVG when there is one."""
    b64 = base64.b64encode(png.read_bytes()).decode('ascii')
    rel = png.relative_to(out)
    svg = png.with_suffix('.svg')
    link = (f' (<a href="{_esc(svg.relative_to(out).as_posix())}">SVG</a>)'
            if svg.is_file() else '')
    cap = _caption(png)
    return (f'<figure><img alt="{_esc(png.name)}" src="data:image/png;base64,{b64}">'
            f'<figcaption><code>{_esc(rel.as_posix())}</code>{link}'
            f'{": " + _esc(cap) if cap else ""}</figcaption></figure>')


def _plots_of(path: Path, data: Any, pngs: list[Path], claimed: set[Path],
              results: list[Path]) -> list[Path]:
    """The PNGs that belong to the result ``path``: those its ``plots`` lists, then those of
    its folder whose names it owns (:data:`hexapod_common.outdir.OUTPUTS`, the files its
    command writes and removes)."""
    from hexapod_common.outdir import owned_by

    mine: list[Path] = []
    listed = data.get('plots') if isinstance(data, dict) else None
    if isinstance(listed, list):
        for name in listed:
            p = (path.parent / str(name)).resolve()
            if p.suffix == '.png' and p in pngs and p not in claimed:
                mine.append(p)
    for p in pngs:
        if p in claimed or p in mine or p.parent != path.parent.resolve():
            continue
        if owned_by(path.name, p.name):
            mine.append(p)
    return mine


# ------------------------------------------------------------------------------- report


def _section(path: Path, data: Any) -> list[str]:
    """Summary and headline tables of one result."""
    parts: list[str] = []
    if not isinstance(data, dict):
        parts.append(render_value(data))
        return parts
    if isinstance(data.get('summary_lines'), list):
        parts.extend(f'<p>{_esc(x)}</p>' for x in data['summary_lines'])
    for key in ('paragraph', 'summary'):
        if isinstance(data.get(key), str):
            parts.append(f'<p><b>{_esc(data[key])}</b></p>')
    if isinstance(data.get('warnings'), list) and data['warnings']:
        parts.append('<p>Warnings:</p><ul>' + ''.join(
            f'<li>{_esc(w)}</li>' for w in dict.fromkeys(map(str, data['warnings']))) +
            '</ul>')
    keys = HEADLINES.get(path.name)
    if keys is None:
        keys = tuple(k for k in list(data)[:8] if k not in ('summary', 'paragraph', 'plots',
                                                           'warnings'))
    head = {k: data[k] for k in keys if k in data and data[k] not in (None, [], {})}
    if head:
        # the residual loop's errors are in the document's unit (W or nerr)
        unit = str(data.get('unit', '')) if path.name == 'residuals.json' else ''
        parts.append('<table class="kv">' + ''.join(
            f'<tr><th>{_esc(k)}</th><td>'
            f'{render_value(v, k, 1, unit if k in ("baseline", "final", "heldout") else None)}'
            '</td></tr>' for k, v in head.items()) + '</table>')
    if path.name == 'energy.json':
        parts.extend(_energy_runs(data))
        parts.extend(_recommendation(data.get('recommendation')))
        parts.extend(_optimal_points(data.get('sweeps'), data.get('sweep_settings')))
        parts.extend(_bench_fit(data.get('bench')))
    elif path.name == 'residuals.json':
        parts.extend(_added_params(data.get('added_params')))
    elif path.name == 'slip.json':
        parts.extend(_slip_sections(data))
    elif path.name == 'demo.json' and isinstance(data.get('slip'), dict):
        parts.append('<h3>SLIP (EduBot runs)</h3>')
        parts.extend(_slip_sections(data['slip']))
    return parts


#: files marking a sub-folder as a run of its own (a demo run, an earlier report)
RUN_MARKERS = ('report.html', 'demo.json')


def _collect(out: Path) -> tuple[list[Path], list[Path]]:
    """The ``*.json`` and ``*.png`` files under ``out`` (any depth) and, apart, the sub-folders
    skipped because they hold a run of their own (:data:`RUN_MARKERS`: an older demo run
    under a newer one; merging them interleaved two runs' sections)."""
    files: list[Path] = []
    nested: list[Path] = []
    for root, dirs, names in os.walk(out):
        here = Path(root)
        if here != out and any(m in names for m in RUN_MARKERS):
            nested.append(here.relative_to(out))
            dirs[:] = []
            continue
        dirs.sort()
        files.extend(here / n for n in names if n.endswith(('.json', '.png')))
    return files, sorted(nested)


def _nested_note(out: Path, nested: list[Path]) -> str:
    """The paragraph naming the sub-folders left out, with links to their own reports."""
    items = []
    for d in nested:
        rep = out / d / 'report.html'
        link = (f' (<a href="{_esc((d / "report.html").as_posix())}">its report</a>)'
                if rep.is_file() else '')
        items.append(f'<li><code>{_esc(d.as_posix())}/</code>{link}</li>')
    return ('<p><b>Not included:</b> these sub-folders hold a run of their own (a '
            '<code>report.html</code> or <code>demo.json</code>); their results are left out '
            'here so that two runs are not mixed:</p><ul>' + ''.join(items) + '</ul>')


def _versions() -> str:
    """The installed versions of the project's packages (``name version``, comma-separated);
    ``'unknown'`` when none is installed as a distribution."""
    from importlib import metadata

    found = []
    for name in ('hexapod_common', 'hexapod_gait', 'hexapod_bench_drivers', 'hexapod_energy',
                 'slip_identification'):
        try:
            found.append(f'{name} {metadata.version(name)}')
        except metadata.PackageNotFoundError:
            continue
    return ', '.join(found) or 'unknown'


def _source_commit() -> str:
    """The git commit of the installed code (``abc1234``, ``+ changes`` when the checkout
    has uncommitted changes), or '' when it is not a git checkout (a wheel) or git is
    missing: the package versions alone (0.1.0) did not tell two builds apart."""
    import subprocess

    here = Path(__file__).resolve()
    where = here.parent
    try:
        # this very file tracked by the repository: not a copy installed inside another
        # checkout (colcon's install/), whose HEAD is not the code that ran (review J5)
        tracked = subprocess.run(['git', '-C', str(where), 'ls-files', '--error-unmatch',
                                  here.name], capture_output=True, text=True, timeout=5)
        head = subprocess.run(['git', '-C', str(where), 'rev-parse', '--short', 'HEAD'],
                              capture_output=True, text=True, timeout=5)
        if tracked.returncode != 0 or head.returncode != 0 or not head.stdout.strip():
            return ''
        dirty = subprocess.run(['git', '-C', str(where), 'status', '--porcelain',
                                '--untracked-files=no'],
                               capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return ''
    return head.stdout.strip() + (' + changes' if dirty.stdout.strip() else '')


def _header_meta() -> str:
    """The line under the report's title: when it was generated and by which code."""
    stamp = time.strftime('%Y-%m-%d %H:%M:%S %Z', time.localtime())
    commit = _source_commit()
    source = f'; source commit {_esc(commit)}' if commit else ''
    return (f'<p class="meta">generated {_esc(stamp)} by <code>hexapod-analyze report</code>; '
            f'packages: {_esc(_versions())}{source}</p>')


def write_report(out_dir: str | Path) -> Path:
    """Write ``out_dir/report.html`` and return its path.

    Parameters
    ----------
    out_dir : str or Path
        Analysis folder holding ``*.json`` results and ``*.png`` plots (any depth; a
        sub-folder holding its own ``report.html`` or ``demo.json`` is another run and left
        out, named in the report).

    Returns
    -------
    Path
        ``out_dir/report.html``.

    Raises
    ------
    FileNotFoundError
        When the folder is missing or holds neither results nor plots.
    """
    return _write_report(out_dir)[0]


def _write_report(out_dir: str | Path) -> tuple[Path, list[str], int]:
    """:func:`write_report`; also returns the problems to say on the terminal (an
    unreadable result, an unfinished run) and how many results were read."""
    out = Path(out_dir)
    if out.is_file():
        raise FileNotFoundError(f'{out} is a file: give the analysis folder that holds it '
                                f'({out.parent})')
    if not out.is_dir():
        raise FileNotFoundError(f'no such analysis folder: {out}')
    parts = ['<!doctype html><meta charset="utf-8"><title>hexapod analysis report</title>',
             '<style>body{font-family:sans-serif;max-width:1100px;margin:auto}'
             'img{max-width:100%;border:1px solid #ccc}pre{background:#f6f6f6;padding:6px;'
             'overflow:auto}td,th{padding:2px 8px;text-align:left;vertical-align:top}'
             'table.grid{border-collapse:collapse;margin:6px 0}'
             'table.grid td,table.grid th{border:1px solid #ddd}'
             'table.kv th{color:#444;font-weight:normal;font-style:italic}'
             'caption{text-align:left;font-style:italic;color:#444}'
             'figure{margin:12px 0}figcaption{font-size:90%;color:#333}'
             '.meta{color:#555;font-size:90%}'
             '.banner{background:#fff3cd;border:1px solid #e0c36c;padding:6px}</style>',
             f'<h1>Analysis report: {_esc(out)}</h1>', _header_meta()]
    files, nested = _collect(out)
    results = sorted(p for p in files if p.suffix == '.json')
    pngs = sorted(p.resolve() for p in files if p.suffix == '.png')
    if not results and not pngs:
        raise FileNotFoundError(f'{out} holds no *.json results and no plots' +
                                (f' outside its sub-folders holding their own run '
                                 f'({", ".join(str(d) for d in nested)})' if nested else ''))
    top = len(parts)   # the banners go here, above everything else
    if nested:
        parts.append(_nested_note(out, nested))
    claimed: set[Path] = set()
    problems: list[str] = []
    read = 0
    for path in results:
        name = path.relative_to(out).as_posix()
        try:
            data = json.loads(path.read_text(encoding='utf-8'))
        except (OSError, ValueError) as err:
            parts.append(f'<h2>{_esc(path.name)}</h2><p>unreadable: {_esc(err)}</p>')
            problems.append(f'{name} unreadable ({err}): its results are not in the report')
            continue
        read += 1
        if isinstance(data, dict) and data.get('status') == 'incomplete':
            # an interrupted or failed demo run: only its folded JSON said so
            problems.append(f'{name} says "status": "incomplete": the run did not finish '
                            '(interrupted or failed); what it wrote before stopping is shown, '
                            'the rest is missing')
        parts.append(f'<h2>{_esc(path.relative_to(out).as_posix())}</h2>')
        parts.extend(_section(path, data))
        mine = _plots_of(path, data, pngs, claimed, results)
        claimed.update(mine)
        parts.extend(_figure(p, out.resolve()) for p in mine)
        parts.append(f'<details><summary>full {_esc(path.name)}</summary><pre>'
                     f'{_esc(json.dumps(data, indent=1, default=str))}</pre></details>')
    rest = [p for p in pngs if p not in claimed]
    if rest:
        parts.append('<h2>Other plots</h2>')
        parts.extend(_figure(p, out.resolve()) for p in rest)
    if problems:
        parts[top:top] = ['<div class="banner">' + ''.join(
            f'<p><b>Warning:</b> {_esc(x)}</p>' for x in problems) + '</div>']
    target = out / 'report.html'
    from hexapod_common.outdir import write_text_atomic

    write_text_atomic(target, '\n'.join(parts))   # a cut page is never left
    return target, problems, read


#: columns of the energy runs table: heading, key, format
_RUN_COLUMNS = (
    ('bag', 'bag', '{}'), ('gait', 'gait', '{}'), ('period [s]', 'period_s', '{:.3g}'),
    ('speed [m/s]', 'speed', '{:.3f}'), ('P_in [W]', 'measured_power_in_w', '{:.2f}'),
    ('predicted [W]', 'predicted_power_in_w', '{:.2f}'), ('P_out [W]', 'power_out_w', '{:.3f}'),
    ('eta [%]', 'efficiency', '{:.2%}'), ('CoT/M [J/(m kg)]', 'specific_cost_of_transport',
                                          '{:.1f}'),
    ('SR', 'specific_resistance', '{:.2f}'))


def _cell(value: Any, fmt: str) -> str:
    if value is None:
        return '-'
    try:
        text = fmt.format(value)
    except (ValueError, TypeError):
        text = str(value)
    return html.escape(text.replace('%', '') if fmt.endswith('%}') else text)


def _energy_runs(data: dict[str, Any]) -> list[str]:
    """One row per robot run (a bag, or one walking schedule of it), marking runs whose
    prediction extrapolates the bench."""
    runs = data.get('robot_runs')
    if not isinstance(runs, list) or not runs:
        return []
    head = ''.join(f'<th>{html.escape(h)}</th>' for h, _, _ in _RUN_COLUMNS)
    rows = []
    for r in runs:
        cells = []
        for _, key, fmt in _RUN_COLUMNS:
            value = r.get(key)
            if key == 'bag':
                seg = r.get('segment') or {}
                value = Path(str(value)).name + (f' [{seg["index"] + 1}/{seg["of"]}]'
                                                 if seg.get('of', 1) > 1 else '')
            if key == 'predicted_power_in_w' and r.get('prediction_outside_bench'):
                cells.append(f'<td title="{html.escape("; ".join(r["prediction_outside_bench"]))}"'
                             f'>{_cell(value, fmt)}*</td>')
                continue
            cells.append(f'<td>{_cell(value, fmt)}</td>')
        rows.append('<tr>' + ''.join(cells) + '</tr>')
    note = ('<p>* the prediction extrapolates the bench surfaces (see the run\'s '
            'prediction_outside_bench)</p>' if any(r.get('prediction_outside_bench')
                                                  for r in runs) else '')
    return ['<h3>Robot runs</h3><table class="grid"><tr>' + head + '</tr>' + ''.join(rows) +
            '</table>' + note]


def _handler(args: argparse.Namespace) -> int:
    import sys

    from pathlib import Path

    folder = Path(args.dir)
    if not folder.is_dir():
        print(f'hexapod-analyze report: error: {args.dir} is not a folder', file=sys.stderr)
        return 2
    try:
        path, problems, read = _write_report(args.dir)
    except OSError as err:
        import errno

        if not (isinstance(err, PermissionError) or err.errno == errno.EROFS):
            raise
        # the analysis commands' words, not a raw errno line (outside review C)
        print(f'hexapod-analyze report: error: {args.dir}: cannot write report.html in the '
              f'folder ({err.strerror})', file=sys.stderr)
        return 2
    for text in problems:
        print(f'hexapod-analyze report: warning: {text}', file=sys.stderr)
    if problems and not read:
        # the page says only that: success was claimed on nothing (outside review C)
        print(f'hexapod-analyze report: error: no result in {args.dir} could be read '
              f'({path} names the unreadable files)', file=sys.stderr)
        return 2
    print(f'wrote {path}')
    return 0


def add_cli(subparsers: Any) -> None:
    """Register ``report`` on ``hexapod-analyze``."""
    p = subparsers.add_parser('report', help='gather a folder of results into report.html',
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dir', help='analysis output folder (holding *.json and *.png)')
    p.set_defaults(func=_handler)
