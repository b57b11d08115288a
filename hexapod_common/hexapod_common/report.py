"""``hexapod-analyze report DIR``: one self-contained HTML page from an analysis folder.

Collects every ``*.json`` result (``energy.json``, ``slip.json``, ``residuals.json``,
``demo.json``) and every PNG plot under DIR into ``DIR/report.html``: the headline figures of
each result first, the plots inline (base64), the full JSON folded at the end.
"""

from __future__ import annotations

import argparse
import base64
import html
import json
from pathlib import Path
from typing import Any

__all__ = ['add_cli', 'write_report']

HEADLINES = {
    'energy.json': ('prediction_error', 'failed_bags'),
    'residuals.json': ('model', 'unit', 'baseline', 'effects_added', 'final', 'heldout',
                       'unexplained', 'summary'),
    'slip.json': ('gait_table', 'table', 'counts', 'skipped'),
    'demo.json': None,
}


def _fmt(value: Any) -> str:
    return html.escape(json.dumps(value, indent=1, default=str)[:4000])


def write_report(out_dir: str | Path) -> Path:
    """Write ``out_dir/report.html`` and return its path."""
    out = Path(out_dir)
    if not out.is_dir():
        raise FileNotFoundError(f'no such analysis folder: {out}')
    parts = ['<!doctype html><meta charset="utf-8"><title>hexapod analysis report</title>',
             '<style>body{font-family:sans-serif;max-width:1100px;margin:auto}'
             'img{max-width:100%;border:1px solid #ccc}pre{background:#f6f6f6;padding:6px;'
             'overflow:auto}td,th{padding:2px 8px;text-align:left}</style>',
             f'<h1>Analysis report: {html.escape(str(out))}</h1>']
    results = sorted(out.rglob('*.json'))
    if not results and not list(out.rglob('*.png')):
        raise FileNotFoundError(f'{out} holds no *.json results and no plots')
    for path in results:
        try:
            data = json.loads(path.read_text(encoding='utf-8'))
        except (OSError, ValueError) as err:
            parts.append(f'<h2>{html.escape(path.name)}</h2><p>unreadable: '
                         f'{html.escape(str(err))}</p>')
            continue
        parts.append(f'<h2>{html.escape(str(path.relative_to(out)))}</h2>')
        if isinstance(data, dict):
            for key in data.get('summary_lines', []) if isinstance(
                    data.get('summary_lines'), list) else []:
                parts.append(f'<p>{html.escape(str(key))}</p>')
            for key in ('paragraph', 'summary'):
                if isinstance(data.get(key), str):
                    parts.append(f'<p><b>{html.escape(data[key])}</b></p>')
            if path.name == 'energy.json':
                parts.extend(_energy_runs(data))
            if isinstance(data.get('warnings'), list) and data['warnings']:
                parts.append('<p>Warnings:</p><ul>' + ''.join(
                    f'<li>{html.escape(str(w))}</li>' for w in data['warnings']) + '</ul>')
            keys = HEADLINES.get(path.name) or list(data)[:8]
            rows = [f'<tr><th>{html.escape(k)}</th><td><pre>{_fmt(data[k])}</pre></td></tr>'
                    for k in keys if k in data]
            if rows:
                parts.append('<table>' + ''.join(rows) + '</table>')
        parts.append(f'<details><summary>full {html.escape(path.name)}</summary><pre>'
                     f'{html.escape(json.dumps(data, indent=1, default=str))}</pre></details>')
    pngs = sorted(out.rglob('*.png'))
    if pngs:
        parts.append('<h2>Plots</h2>')
    for png in pngs:
        b64 = base64.b64encode(png.read_bytes()).decode('ascii')
        parts.append(f'<h3>{html.escape(str(png.relative_to(out)))}</h3>'
                     f'<img alt="{html.escape(png.name)}" src="data:image/png;base64,{b64}">')
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
    return ['<table><tr>' + head + '</tr>' + ''.join(rows) + '</table>' + note]


def _handler(args: argparse.Namespace) -> int:
    path = write_report(args.dir)
    print(f'wrote {path}')
    return 0


def add_cli(subparsers: Any) -> None:
    """Register ``report`` on ``hexapod-analyze``."""
    p = subparsers.add_parser('report', help='gather a folder of results into report.html',
                              description=__doc__)
    p.add_argument('dir', help='analysis output folder (holding *.json and *.png)')
    p.set_defaults(func=_handler)
