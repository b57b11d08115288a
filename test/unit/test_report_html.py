"""report.html shows every result's headline figures readably: the SLIP per-gait table and
runs, the energy recommendation and each sweep's optimal points, the residual loop's fitted
parameters, numbers at four significant figures with units, each result's plots after its
section with a caption and an SVG link."""

from __future__ import annotations

import json
import re
from pathlib import Path

import matplotlib
import pytest

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402

from hexapod_common.report import fmt_number, unit_of, write_report  # noqa: E402

SLIP = {
    'schema': 'slip/1', 'model': 'slip', 'estimator': 'paper', 'mass_kg': 3.31,
    'stances': [{'bag': '/d/edubot_running', 'nerr': 0.07}] * 3,
    'runs': [{'bag': '/d/edubot_running', 'gait': 'running', 'offset_s': 0.025641204569364556,
              'offset_method': 'geometry', 'ground_m': 0.012805779420023923,
              'frame': {'tilt_deg': 3.0043348441555047}, 'power_w': 32.1504656862953,
              'speed_mps': 0.8781071570888861, 'sr': 1.1275680196311624, 'stances': 15,
              'skipped': 0}],
    'gaits': {'running': {'stances': 15.0, 'nerr_mean': 0.04265695107661902,
                          'nerr_std': 0.016863759332079266, 'power_w_mean': 32.150465686295306,
                          'power_w_std': 7.105427357601002e-15,
                          'speed_mps_mean': 0.878107157088886,
                          'speed_mps_std': 1.1102230246251565e-16,
                          'sr_mean': 1.1275680196311624, 'sr_std': 0.0}},
    'skipped': [], 'skipped_counts': {'too_short': 1}, 'failed_bags': []}


def _page(folder: Path) -> str:
    text = write_report(folder).read_text(encoding='utf-8')
    return re.sub(r'data:image/png;base64,[^"]*', 'data:', text)


def _headline(page: str) -> str:
    """The page without the folded full JSON."""
    return re.sub(r'<details>.*?</details>', '', page, flags=re.S)


def test_formatting_helpers() -> None:
    assert fmt_number(0.04265695107661902) == '0.04266'
    assert fmt_number(1.1102230246251565e-16) == '0'
    assert fmt_number(float('nan')) == '-'
    assert unit_of('power_w') == 'W' and unit_of('resistance_ohm') == 'ohm'
    assert unit_of('speed_mps') == 'm/s' and unit_of('offset_s') == 's'
    assert unit_of('saturated_conductance_s') == 'S' and unit_of('mass_kg') == 'kg'


def test_slip_only_folder_shows_the_per_gait_table_and_runs(tmp_path: Path) -> None:
    (tmp_path / 'slip.json').write_text(json.dumps(SLIP))
    page = _headline(_page(tmp_path))
    assert 'Table 3' in page
    row = ('<td>running</td><td>15</td><td>0.04266 \u00b1 0.017</td><td>32.15 \u00b1 0</td>'
           '<td>0.8781 \u00b1 0</td><td>1.128 \u00b1 0</td>')
    assert row in page
    # one row per run: clock offset 25.6 ms, ground 12.8 mm, tilt 3 deg
    assert '<td>edubot_running</td><td>running</td><td>15</td><td>0</td><td>25.6</td>' in page
    assert '<td>12.8</td><td>3</td>' in page
    assert 'too_short: 1' in page
    assert '0.016863759332079266' not in page and 'e-16' not in page


def _energy_doc() -> dict:
    curve = {'label': 'beta 0.5', 'min_efficiency': 0.0033487412926304473,
             'max_speed_mps': 0.6000000000000001,
             'optimal_points': {
                 'max_power_out': {'speed_mps': 0.6000000000000001,
                                   'value': 3.9469384984096445, 'outside_bench': False},
                 'min_cot_per_mass': {'speed_mps': 0.6000000000000001,
                                      'value': 47.37570213833706, 'outside_bench': True},
                 'max_efficiency': {'speed_mps': 0.6, 'value': 0.05980243085425773}}}
    rec = {'speed_mps': 0.3, 'payload_kg': 0.2, 'saving_fraction': -0.10630244227534758,
           'evaluated': 105, 'rejected': 219, 'outside_bench': 96, 'note': 'the default '
           'gait reads the bench surfaces outside their sessions',
           'best': {'gait': 'wave', 'leg_count': 6, 'duty_factor': 0.7, 'step_length_m': 0.14,
                    'period_s': 0.6666666666666667, 'power_in_w': 39.908028559572365,
                    'power_out_w': 1.6233748242342783, 'efficiency': 0.04067790073395882,
                    'specific_cost_of_transport': 53.55246011377548, 'outside_bench': []},
           'default': {'gait': 'alternating', 'leg_count': 6, 'duty_factor': 0.5,
                       'specific_cost_of_transport': 48.4067087510296}}
    return {'schema': 'hexapod_energy.energy/1', 'plots': ['prediction.png', 'prediction.svg'],
            'prediction_error': {'runs': 4, 'rmse_w': 7.461234567891234},
            'bench': {'bags': ['b'], 'fit': {'chosen': {'stance': 'poly3'},
                                             'fit_rmse_w': {'stance': 0.03201570563844442},
                                             'sessions': [{'session_id': 's0'}] * 9}},
            'sweeps': {'duty_factor': [curve]}, 'recommendation': rec}


def _png(path: Path) -> None:
    fig, ax = plt.subplots(figsize=(1, 1))
    ax.plot([0, 1])
    fig.savefig(path)
    fig.savefig(path.with_suffix('.svg'))
    plt.close(fig)


def test_energy_recommendation_optimal_points_and_bench_fit(tmp_path: Path) -> None:
    (tmp_path / 'energy.json').write_text(json.dumps(_energy_doc()))
    _png(tmp_path / 'prediction.png')
    page = _page(tmp_path)
    head = _headline(page)
    assert '<h3>Recommendation</h3>' in head
    assert ('<td><b>best on the bench</b></td><td>wave</td><td>6</td><td>0.7</td>'
            '<td>0.14</td>') in head
    assert '<td>53.55</td>' in head and '-10.6 %' in head
    assert 'outside their sessions' in head
    assert 'Optimal points per sweep' in head
    assert ('<td>beta 0.5</td><td>3.947</td><td>0.6</td><td>47.38*</td><td>0.6</td>'
            '<td>5.98</td>') in head
    assert 'Bench surface fit' in head and '0.03202 W' in head and '9 bench sessions' in head
    assert '7.461 W' in head and '7.461234567891234' not in head
    # the plot comes inside the energy section (before the folded JSON), captioned, with SVG
    fig_at, details_at = page.index('<figure>'), page.index('<details>')
    assert fig_at < details_at
    assert '<a href="prediction.svg">SVG</a>' in page and '1:1 line' in page
    assert '<h2>Other plots</h2>' not in page


def test_residuals_summary_once_added_params_with_stderr(tmp_path: Path) -> None:
    summary = 'The model missed supply_resistance.'
    doc = {'model': 'energy', 'unit': 'W', 'baseline': {'rmse': 8.575951191702162},
           'effects_added': ['supply_resistance'], 'final': {'rmse': 0.7416776312931804},
           'heldout': {'rmse_before': 8.55, 'rmse_after': 0.734}, 'summary': summary,
           'added_params': [{'name': 'supply_resistance',
                             'params': {'resistance_ohm': 0.3500419507986209,
                                        'electronics_current_a': 1.9026877048396102},
                             'stderr': {'resistance_ohm': 3.703246745782251e-05,
                                        'electronics_current_a': 0.09303671442148224}}],
           'unexplained': {'rmse_w': 0.74, 'note': 'x' * 5000},
           'plots': ['residual_time.png']}
    (tmp_path / 'residuals.json').write_text(json.dumps(doc))
    _png(tmp_path / 'residual_time.png')
    _png(tmp_path / 'stray.png')
    head = _headline(_page(tmp_path))
    assert head.count(summary) == 1
    assert '<td>resistance_ohm</td><td>0.35 \u00b1 3.7e-05 ohm</td>' in head
    assert '<td>electronics_current_a</td><td>1.903 \u00b1 0.093 A</td>' in head
    assert '8.576' in head and '8.575951191702162' not in head
    assert 'x' * 700 not in head and 'x' * 500 + ' \u2026' in head     # cut with an ellipsis
    assert head.index('residual_time.png') < head.index('<h2>Other plots</h2>') < \
        head.index('stray.png')


def test_demo_json_shows_its_slip_table(tmp_path: Path) -> None:
    runs = [dict(SLIP['runs'][0], true_offset_s=0.025, true_ground_m=0.0128)]
    (tmp_path / 'demo.json').write_text(json.dumps({
        'live': {'windows': 7}, 'slip': {'gaits': SLIP['gaits'], 'runs': runs}}))
    head = _headline(_page(tmp_path))
    assert 'Table 3' in head and '0.04266 \u00b1 0.017' in head
    assert '<th>hidden offset [ms]</th>' in head and '<td>25.6</td><td>25</td>' in head


def test_the_bench_diagnostics_and_their_warnings_are_in_the_report(tmp_path):
    """How each bench bag was read (phase split, force offset) and its notes and warnings
    were only in the folded raw JSON (an outside review: a phase-label gap's note went
    unseen)."""
    import json

    from hexapod_common.report import write_report

    doc = {'schema': 'hexapod_energy.energy/1', 'plots': [],
           'bench': {'bags': ['b1'], 'fit': {'chosen': {'stance': 'poly'}, 'sessions': []},
                     'diagnostics': [{'bag': 'b1', 'sessions': 25, 'phase_split': 'contact',
                                      'force_offset_s': 0.0123, 'warnings': ['W<1>'],
                                      'notes': ['a gap note']}]}}
    (tmp_path / 'energy.json').write_text(json.dumps(doc))
    html = write_report(tmp_path).read_text()
    row = html[html.index('bench bag'):]
    assert 'contact' in row and '0.0123' in row and 'a gap note' in row
    assert 'warning: W&lt;1&gt;' in row


@pytest.mark.parametrize('err', [OSError(30, 'Read-only file system'),
                                 PermissionError(13, 'Permission denied')])
def test_a_folder_report_cannot_write_to_is_said_in_words(tmp_path, monkeypatch, capsys, err):
    """A read-only folder gave a raw 'error: [Errno 30] ...' line (an outside review)."""
    from hexapod_common import report
    from hexapod_common.analyze_cli import main as analyze

    def refused(_d):
        raise err

    monkeypatch.setattr(report, '_write_report', refused)
    assert analyze(['report', str(tmp_path)]) == 2
    out = capsys.readouterr().err
    assert 'cannot write report.html in the folder' in out and 'Errno' not in out
    assert analyze(['report', str(tmp_path / 'missing')]) == 2
    assert 'is not a folder' in capsys.readouterr().err
