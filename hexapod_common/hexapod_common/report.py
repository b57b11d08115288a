"""``hexapod-analyze report DIR``: one self-contained HTML page from an analysis folder.

Collects every ``*.json`` result (``energy.json``, ``slip.json``, ``residuals.json``,
``demo.json``) and every PNG plot under DIR into ``DIR/report.html``. Each result gets a
section: its plain-words summary, its headline figures as tables (numbers at four significant
figures, units from the key suffixes), then its own plots inline (base64) with a caption and a
link to the SVG where one was written; the full JSON folded at the section's end. Plots no
result claims come last.

Sections per result:

* ``energy.json``: the prediction error, one row per robot run, the recommendation, the
  optimal points of every sweep, the bench surface fit;
* ``slip.json``: the per-gait table (Komsuoglu et al. Table 3: stances, nerr, P, v, SR as mean
  +/- sd) and one row per run (clock offset, ground, stances);
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
from pathlib import Path
from typing import Any

__all__ = ['add_cli', 'fmt_number', 'unit_of', 'write_report']

#: headline keys rendered as tables, per result file (others are summarised as 'first keys')
HEADLINES: dict[str, tuple[str, ...] | None] = {
    'energy.json': ('prediction_error', 'failed_bags'),
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
     'against speed and efficiency; solid line at 0 g payload, band 0-500 g, dotted where Eq. 1 '
     'extrapolates the bench; markers at the optimal points.'),
    ('power_map', 'Robot output power over speed and payload (Eq. 6, Fig. 7D), with contours.'),
    ('prediction', 'Measured against predicted (Eq. 1) input power per robot run; the 1:1 line '
                   'is a perfect prediction.'),
    ('power_in_over_time', 'Input power of each robot run against the time since its start: '
                           'every gait-cycle window (thin), the medians of its tenths '
                           '(markers) and the Eq. 1 prediction (dashed).'),
    ('measured_runs', 'Measured input power and specific cost of transport per robot run.'),
    ('where_the_watts_go', 'Where the watts go: the predicted input power split into holding, '
                           'stance and swing motion, against the measured input power.'),
    ('residual_time', 'Energy residual (measured minus predicted P_in) per run over time: per '
                      'sample (top), per half cycle before and after the added effects '
                      '(bottom).'),
    ('residual_regressors', 'Residual against each added effect\'s fitted term: before the '
                            'effect the points follow the fitted line, after it they are flat.'),
    ('residual_unexplained', 'What the added effects left, per run, against the window noise.'),
    ('residual_slip_nerr', 'SLIP-measure (nerr) per stance, one series per bag, plain SLIP '
                           '(before) and with the added extension (after).'),
    ('fig7', 'Komsuoglu et al. Fig. 7: speed against specific resistance, one marker per run.'),
    ('fig8', 'Komsuoglu et al. Fig. 8: input power against speed, one marker per run.'),
    ('fig9', 'Komsuoglu et al. Fig. 9: SLIP-measure (nerr, mean +/- sd over the run\'s stances) '
             'against specific resistance.'),
)

#: plots a result owns when its JSON does not list them (file-name prefixes)
_OWNED = {'slip.json': ('fig',), 'residuals.json': ('residual_',)}


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
        return _kv_table(value, depth, unit)
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


def _kv_table(data: dict[str, Any], depth: int = 0, unit: str = '') -> str:
    """Two-column table of a dict; keys without a unit of their own take ``unit``."""
    rows = ''.join(f'<tr><th>{_esc(k)}</th><td>'
                   f'{render_value(v, str(k), depth + 1, unit_of(str(k)) or unit)}</td></tr>'
                   for k, v in data.items())
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


def _pm(mean: Any, sd: Any) -> str:
    """``mean +/- sd`` at four significant figures (sd omitted when unknown)."""
    if not isinstance(mean, (int, float)):
        return '-'
    text = fmt_number(float(mean))
    if isinstance(sd, (int, float)) and math.isfinite(float(sd)):
        text += ' \u00b1 ' + fmt_number(float(sd), 2)
    return _esc(text)


def _num(value: Any, unit: str = '', digits: int = 4) -> str:
    if not isinstance(value, (int, float)) or isinstance(value, bool):
        return '-' if value is None else _esc(str(value))
    text = fmt_number(float(value), digits)
    return _esc(text + (f' {unit}' if unit and text != '-' else ''))


# ---------------------------------------------------------------------------------- slip


def _slip_sections(data: dict[str, Any]) -> list[str]:
    """Per-gait table (Table 3) and one row per run from a ``slip.json`` (or ``demo.json``'s
    ``slip``) document."""
    parts = []
    gaits = data.get('gaits')
    if isinstance(gaits, dict) and gaits:
        rows = []
        for g, e in gaits.items():
            if not isinstance(e, dict):
                continue
            n = e.get('stances')
            rows.append([_esc(g), _num(int(n) if isinstance(n, (int, float)) else n),
                         _pm(e.get('nerr_mean'), e.get('nerr_std')),
                         _pm(e.get('power_w_mean'), e.get('power_w_std')),
                         _pm(e.get('speed_mps_mean'), e.get('speed_mps_std')),
                         _pm(e.get('sr_mean'), e.get('sr_std'))])
        parts.append('<h3>Per gait (Komsuoglu et al. Table 3)</h3>' + _table(
            ['gait', 'stances', 'nerr', 'P [W]', 'v [m/s]', 'SR'], rows,
            'mean \u00b1 sd over the gait\'s stances (P, v and SR are per run, repeated on '
            'each of its stances)'))
    runs = data.get('runs')
    if isinstance(runs, list) and runs:
        truth = any('true_offset_s' in r for r in runs if isinstance(r, dict))
        head = ['bag', 'gait', 'stances', 'skipped', 'clock offset [ms]', 'offset method',
                'ground [mm]', 'tilt [deg]', 'P [W]', 'v [m/s]', 'SR']
        if truth:
            head[5:5] = ['hidden offset [ms]']
            head[8:8] = ['hidden ground [mm]']
        rows = []
        for r in runs:
            if not isinstance(r, dict):
                continue
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
        parts.append('<h3>Per run</h3>' + _table(head, rows))
    counts = data.get('skipped_counts')
    if isinstance(counts, dict):
        parts.append('<p>Stances skipped: ' + (', '.join(
            f'{_esc(k)}: {_esc(v)}' for k, v in counts.items()) or 'none') + '</p>')
    stances = data.get('stances')
    if isinstance(stances, list):
        parts.append(f'<p>{len(stances)} stances fitted.</p>')
    return parts


# -------------------------------------------------------------------------------- energy


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
    if configs:
        keys = ('gait', 'leg_count', 'duty_factor', 'step_length_m', 'period_s', 'power_in_w',
                'power_out_w', 'efficiency', 'specific_cost_of_transport', 'outside_bench')
        head = ['', 'gait', 'legs', 'beta', 'step [m]', 'T [s]', 'P_in [W]', 'P_out [W]',
                'eta [%]', 'CoT/M [J/(m kg)]', 'outside the bench']
        rows = []
        for name, c in configs:
            row = [f'<b>{_esc(name)}</b>']
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
        parts.append(f'<p>CoT/M saving against the default gait: '
                     f'{_esc(fmt_number(100.0 * saving, 3))} %'
                     + (f' ({_esc(rec.get("evaluated"))} configurations evaluated, '
                        f'{_esc(rec.get("rejected"))} rejected, '
                        f'{_esc(rec.get("outside_bench"))} outside the bench)'
                        if 'evaluated' in rec else '') + '</p>')
    if rec.get('note'):
        parts.append(f'<p><i>{_esc(rec["note"])}</i></p>')
    return parts


_OPT = (('max_power_out', 'max P_out [W]', 1.0), ('min_cot_per_mass', 'min CoT/M [J/(m kg)]',
                                                  1.0),
        ('max_efficiency', 'max eta [%]', 100.0))


def _optimal_points(sweeps: Any) -> list[str]:
    if not isinstance(sweeps, dict) or not sweeps:
        return []
    parts = ['<h3>Optimal points per sweep (0 g payload)</h3>']
    for name, curves in sweeps.items():
        if not isinstance(curves, list):
            continue
        head = ['curve']
        for _, label, _s in _OPT:
            head += [label, 'at v [m/s]']
        head += ['min eta [%]', 'max v [m/s]']
        rows = []
        for c in curves:
            if not isinstance(c, dict):
                continue
            pts = c.get('optimal_points') or {}
            row = [_esc(c.get('label', '-'))]
            for key, _, scale in _OPT:
                p = pts.get(key) or {}
                v = p.get('value')
                star = '*' if p.get('outside_bench') else ''
                row += [_num(scale * v if isinstance(v, (int, float)) else v) + star,
                        _num(p.get('speed_mps'), digits=3)]
            me = c.get('min_efficiency')
            row += [_num(100.0 * me if isinstance(me, (int, float)) else me, digits=3),
                    _num(c.get('max_speed_mps'), digits=3)]
            rows.append(row)
        parts.append(_table(head, rows, name.replace('_', ' ')))
    parts.append('<p>* the point extrapolates the bench surfaces (dotted in the plots)</p>')
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


def _caption(path: Path) -> str:
    for prefix, text in CAPTIONS:
        if path.stem.startswith(prefix):
            return text
    return ''


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
    its folder whose names it owns (``energy.json`` those no other result owns)."""
    mine: list[Path] = []
    listed = data.get('plots') if isinstance(data, dict) else None
    if isinstance(listed, list):
        for name in listed:
            p = (path.parent / str(name)).resolve()
            if p.suffix == '.png' and p in pngs and p not in claimed:
                mine.append(p)
    owned = _OWNED.get(path.name)
    others = tuple(pre for pres in _OWNED.values() for pre in pres)
    for p in pngs:
        if p in claimed or p in mine or p.parent != path.parent.resolve():
            continue
        if (p.name.startswith(owned) if owned else
                path.name == 'energy.json' and not p.name.startswith(others)):
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
        parts.extend(_optimal_points(data.get('sweeps')))
        parts.extend(_bench_fit(data.get('bench')))
    elif path.name == 'residuals.json':
        parts.extend(_added_params(data.get('added_params')))
    elif path.name == 'slip.json':
        parts.extend(_slip_sections(data))
    elif path.name == 'demo.json' and isinstance(data.get('slip'), dict):
        parts.append('<h3>SLIP (EduBot runs)</h3>')
        parts.extend(_slip_sections(data['slip']))
    return parts


def write_report(out_dir: str | Path) -> Path:
    """Write ``out_dir/report.html`` and return its path.

    Parameters
    ----------
    out_dir : str or Path
        Analysis folder holding ``*.json`` results and ``*.png`` plots (any depth).

    Returns
    -------
    Path
        ``out_dir/report.html``.

    Raises
    ------
    FileNotFoundError
        When the folder is missing or holds neither results nor plots.
    """
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
             'figure{margin:12px 0}figcaption{font-size:90%;color:#333}</style>',
             f'<h1>Analysis report: {_esc(out)}</h1>']
    results = sorted(out.rglob('*.json'))
    pngs = sorted(p.resolve() for p in out.rglob('*.png'))
    if not results and not pngs:
        raise FileNotFoundError(f'{out} holds no *.json results and no plots')
    claimed: set[Path] = set()
    for path in results:
        try:
            data = json.loads(path.read_text(encoding='utf-8'))
        except (OSError, ValueError) as err:
            parts.append(f'<h2>{_esc(path.name)}</h2><p>unreadable: {_esc(err)}</p>')
            continue
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
    target = out / 'report.html'
    target.write_text('\n'.join(parts), encoding='utf-8')
    return target


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
    path = write_report(args.dir)
    print(f'wrote {path}')
    return 0


def add_cli(subparsers: Any) -> None:
    """Register ``report`` on ``hexapod-analyze``."""
    p = subparsers.add_parser('report', help='gather a folder of results into report.html',
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('dir', help='analysis output folder (holding *.json and *.png)')
    p.set_defaults(func=_handler)
