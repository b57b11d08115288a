"""An outside review of the plots and the report (findings 1, 4-6, 8, 10-14, 16): the SLIP
figures in Komsuoglu et al.'s gait colours and Table 3 order, Fig. 9 as stances with median and
IQR, the residual plot one row per run, the demo writing into its --out on every run (an
earlier run moved to <out>.prev) and the report leaving nested runs out, min eta on the bench,
the two "bias" figures defined, the recommendation's rows named for what they are, captions,
and the per-gait table beside the paper's values."""

from __future__ import annotations

import json
import re
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import to_hex  # noqa: E402

from hexapod_common.report import write_report  # noqa: E402

_REAL_CLOSE = plt.close


# the ``kept`` fixture (figures kept open): test/unit/conftest.py


def _page(folder: Path) -> str:
    text = write_report(folder).read_text(encoding='utf-8')
    text = re.sub(r'data:image/png;base64,[^"]*', 'data:', text)
    return re.sub(r'<details>.*?</details>', '', text, flags=re.S)


# ------------------------------------------------------- 1, 6, 16: SLIP figures 7-9


def _slip_rows() -> list[dict[str, Any]]:
    """One run per gait, alphabetical order on purpose (the old colour assignment); pace has
    one stance far above the rest (the demo's 0.925)."""
    rows = []
    spec = (('jogging', 36.6, 0.633, 1.78, [0.03, 0.04, 0.05, 0.04]),
            ('pace', 27.9, 0.323, 2.66, [0.08, 0.12, 0.15, 0.2, 0.24, 0.1, 0.925]),
            ('running', 32.15, 0.878, 1.128, [0.03, 0.05, 0.07]),
            ('walk', 17.97, 0.181, 3.05, [0.2, 0.3, 0.4, 0.55]),
            ('bound', 25.0, 0.5, 1.5, [0.1, 0.12]))
    for gait, p, v, sr, nerrs in spec:
        rows += [{'gait': gait, 'nerr': e, 'power_w': p, 'speed_mps': v, 'sr': sr}
                 for e in nerrs]
    return rows


def _by_name(kept: list[Any]) -> dict[str, Any]:
    figs = [f for f in kept if f is not None]
    assert len(figs) == 3
    return dict(zip(('fig7', 'fig8', 'fig9'), figs))


def test_slip_figures_use_the_papers_colours_and_table3_order(kept: list[Any],
                                                               tmp_path: Path) -> None:
    from slip_identification.energetics import plot_figures

    plot_figures(_slip_rows(), tmp_path)
    paper = {'running': '#1f77b4', 'jogging': '#2ca02c', 'pace': '#9467bd',
             'walk': '#d62728'}                  # tab: blue, green, purple, red
    for fig in _by_name(kept).values():
        ax = fig.axes[0]
        legend = ax.get_legend()
        labels = [t.get_text() for t in legend.get_texts()]
        assert labels == ['running', 'jogging', 'pace', 'walk', 'bound']   # Table 3 order
        colours = {t.get_text(): to_hex(h.get_color())
                   for t, h in zip(legend.get_texts(), legend.legend_handles)}
        assert {g: colours[g] for g in paper} == paper
        # an unknown gait takes a colour of the cycle the paper's gaits do not use
        assert colours['bound'] not in paper.values()
        assert len([ln for ln in ax.get_lines() if ln.get_marker() == 'o']) == 5
    # the run markers themselves carry the gait's colour (Fig. 7: running at 0.878 m/s)
    marks = _by_name(kept)['fig7'].axes[0].get_lines()
    running = next(ln for ln in marks if ln.get_ydata()[0] == pytest.approx(0.878))
    assert to_hex(running.get_color()) == paper['running']


def test_gait_table_in_table3_order() -> None:
    from slip_identification.energetics import gait_table

    assert list(gait_table(_slip_rows())) == ['running', 'jogging', 'pace', 'walk', 'bound']


def test_fig9_stances_visible_median_and_iqr_from_zero(kept: list[Any], tmp_path: Path) -> None:
    from slip_identification.energetics import plot_figures

    plot_figures(_slip_rows(), tmp_path)
    ax = _by_name(kept)['fig9'].axes[0]
    assert ax.get_ylim()[0] == 0.0
    stances = [c for c in ax.collections if c.get_label() == '_stances']
    assert len(stances) == 5
    for c in stances:
        assert c.get_alpha() >= 0.5 and c.get_sizes()[0] >= 12
    pace = next(c for c in stances if to_hex(c.get_facecolor()[0]) == '#9467bd')
    xy = pace.get_offsets()
    assert len(xy) == 7 and np.ptp(xy[:, 0]) > 0          # jittered sideways
    assert np.max(xy[:, 1]) == pytest.approx(0.925)        # the outlier is drawn
    nerr = np.array([0.08, 0.12, 0.15, 0.2, 0.24, 0.1, 0.925])
    marker = next(ln for ln in ax.get_lines() if ln.get_marker() == 'o' and
                  ln.get_xdata()[0] == pytest.approx(2.66))
    assert marker.get_ydata()[0] == pytest.approx(np.median(nerr))      # not the mean
    q1, q3 = np.percentile(nerr, [25, 75])
    bars = [seg for coll in ax.collections if coll.get_label() != '_stances'
            for seg in getattr(coll, 'get_segments', lambda: [])()
            if np.allclose(np.asarray(seg)[:, 0], 2.66)]
    assert any(np.allclose(sorted(np.asarray(s)[:, 1]), [q1, q3]) for s in bars)
    # the outlier beyond Q3 + 1.5 IQR is labelled with its value
    assert '0.93' in {t.get_text() for t in ax.texts}
    assert 'median' in ax.get_ylabel() and 'IQR' in ax.get_ylabel()


def test_slip_axes_and_titles_name_units_mass_and_data(kept: list[Any],
                                                        tmp_path: Path) -> None:
    from slip_identification.energetics import plot_figures

    plot_figures(_slip_rows(), tmp_path, mass_kg=3.31, source='simulated EduBot')
    figs = _by_name(kept)
    assert figs['fig7'].axes[0].get_xlabel() == 'specific resistance SR [-]'
    assert figs['fig9'].axes[0].get_xlabel() == 'specific resistance SR [-]'
    for fig in figs.values():
        title = fig.axes[0].get_title()
        assert 'm = 3.31 kg' in title and 'simulated EduBot' in title
        assert '1 run per gait' in title


def test_slip_titles_found_from_the_slip_json_beside_them(kept: list[Any],
                                                           tmp_path: Path) -> None:
    """``hexapod-analyze slip`` writes slip.json before the figures: mass and source come
    from it (a bag the EduBot simulator wrote carries its truth in its metadata)."""
    from slip_identification.energetics import plot_figures

    bag = tmp_path / 'edubot_walk'
    bag.mkdir()
    (bag / 'metadata.yaml').write_text('custom_data:\n  hexapod_sim.edubot_truth: "{}"\n')
    (tmp_path / 'slip.json').write_text(json.dumps({'mass_kg': 3.5,
                                                    'runs': [{'bag': str(bag)}]}))
    plot_figures(_slip_rows(), tmp_path)
    title = _by_name(kept)['fig8'].axes[0].get_title()
    assert 'm = 3.5 kg' in title and 'simulated EduBot' in title


# ---------------------------------------------------------- 16, 10: report SLIP tables


def _slip_doc(with_run_values: bool = True) -> dict[str, Any]:
    def entry(n: float, nerr: float) -> dict[str, float]:
        return {'stances': n, 'nerr_mean': nerr, 'nerr_std': 0.01, 'power_w_mean': 30.0,
                'power_w_std': 0.0, 'speed_mps_mean': 0.5, 'speed_mps_std': 0.0,
                'sr_mean': 1.8, 'sr_std': 0.0}
    gaits = {g: entry(10.0, 0.1 * k) for k, g in
             enumerate(('jogging', 'pace', 'running', 'walk'))}     # alphabetical, as before
    run = {'bag': '/d/edubot_pace', 'gait': 'pace', 'offset_s': 0.025, 'ground_m': 0.01,
           'stances': 15, 'true_offset_s': 0.025, 'true_ground_m': 0.01}
    if with_run_values:
        run.update(skipped=1, power_w=27.92, speed_mps=0.3231, sr=2.661)
    return {'gaits': gaits, 'runs': [run]}


def test_report_per_gait_table_in_table3_order_beside_the_paper(tmp_path: Path) -> None:
    (tmp_path / 'slip.json').write_text(json.dumps(_slip_doc()))
    page = _page(tmp_path)
    table = page[page.index('Per gait'):page.index('Per run')]
    order = [table.index(f'<td>{g}</td>') for g in ('running', 'jogging', 'pace', 'walk')]
    assert order == sorted(order)
    assert '<th>paper: nerr</th>' in table and '<th>paper: P [W]</th>' in table
    assert '<th>SR [-]</th>' in table
    # running: Table 3's 0.087 +/- 0.07, 31.63 +/- 2.99 W, 1.06 +/- 0.04 m/s
    assert '<td>0.087 \u00b1 0.07</td><td>31.63 \u00b1 2.99</td><td>1.06 \u00b1 0.04</td>' in table


def test_demo_json_carries_the_paper_table_and_run_values() -> None:
    from hexapod_common import demo

    run = {'bag': '/d/edubot_pace', 'gait': 'pace', 'offset_s': 0.025, 'stances': 15,
           'skipped': 1, 'power_w': 27.92, 'speed_mps': 0.3231, 'sr': 2.661,
           'frame': {'tilt_deg': 3.0}}
    row = demo.slip_run_summary(run, {'clock_offset_s': 0.025,
                                      'frame': {'ground_plane_z_m': 0.01}})
    assert {k: row[k] for k in ('power_w', 'speed_mps', 'sr', 'skipped')} == {
        'power_w': 27.92, 'speed_mps': 0.3231, 'sr': 2.661, 'skipped': 1}
    assert 'unit' in demo.RESIDUAL_KEYS
    table3 = demo._table3()
    assert list(table3) == ['running', 'jogging', 'pace', 'walk']
    assert table3['running'] == (0.087, 31.63, 1.06)


def test_report_per_run_table_filled_or_without_empty_columns(tmp_path: Path) -> None:
    (tmp_path / 'demo.json').write_text(json.dumps({'slip': _slip_doc()}))
    page = _page(tmp_path)
    assert '<td>27.92</td><td>0.3231</td><td>2.661</td>' in page
    # an older demo.json without the run values: no column of '-' only
    (tmp_path / 'demo.json').write_text(json.dumps({'slip': _slip_doc(False)}))
    page = _page(tmp_path)
    runs = page[page.index('<h3>Per run</h3>'):]
    runs = runs[:runs.index('</table>')]
    assert '<th>P [W]</th>' not in runs and '<th>skipped</th>' not in runs
    assert '<td>-</td>' not in runs


# ------------------------------------------------------------ 8, 14: residual plots


class _Offset:
    """A stand-in effect: a constant per window (one column)."""

    name, unit = 'basal_power', 'W'

    def columns(self, table: Any) -> np.ndarray:
        return np.ones((table.run.size, 1))


def _loop_inputs() -> tuple[Any, Any, np.ndarray, list[Any]]:
    rng = np.random.default_rng(1)
    runs, run_idx, resid, t_win = [], [], [], []
    for k, offset in enumerate((-1.0, -6.0, -12.0)):
        t = np.linspace(0.0, 10.0, 2000) + 100.0 * k
        predicted = np.full(t.size, 30.0)
        power = predicted + offset + 3.0 * np.sin(2 * np.pi * 1.5 * t)
        runs.append(SimpleNamespace(t_s=t, power_w=power, predicted_w=predicted,
                                    name=f'/d/robot_{k}'))
        run_idx += [k] * 20
        t_win += list(t[0] + 0.25 + 0.5 * np.arange(20))
        resid += list(offset + 0.2 * rng.standard_normal(20))
    r0 = np.array(resid)
    table = SimpleNamespace(residual_w=r0, run=np.array(run_idx), t_s=np.array(t_win),
                            duration_s=np.full(r0.size, 0.5))
    sel = SimpleNamespace(term_w_=r0 - 0.1, selected_=[_Offset()],
                          coef_=np.array([float(np.mean(r0))]))
    held = np.zeros(r0.size, bool)
    held[4:8] = True
    held[30:34] = True
    return table, sel, held, runs


def test_residual_time_one_row_per_run_legend_outside_held_out_marked(
        kept: list[Any], tmp_path: Path) -> None:
    from matplotlib.patches import Rectangle

    from hexapod_energy.residuals import plot_energy_loop

    table, sel, held, runs = _loop_inputs()
    plot_energy_loop(table, sel, held, runs, tmp_path)
    fig = next(f for f in kept if f is not None and len(f.axes) == 4)
    rows, bottom = fig.axes[:3], fig.axes[3]
    # one row per run, sharing the time axis, each naming its run
    assert all(ax.get_shared_x_axes().joined(rows[0], ax) for ax in rows)
    for k, ax in enumerate(rows):
        assert any(t.get_text().startswith(f'robot_{k}:') for t in ax.texts)
        # before and after per window in every row
        styles = {(ln.get_marker(), ln.get_markerfacecolor() == 'none')
                  for ln in ax.get_lines() if len(ln.get_xdata()) == 20}
        assert ('o', False) in styles and ('s', True) in styles
    # held-out windows shaded in the rows: 2 blocks in robot_0, 1 in robot_1
    spans = [[p for p in ax.patches if isinstance(p, Rectangle)] for ax in rows]
    assert [len(s) for s in spans] == [1, 1, 0]
    assert spans[0][0].get_x() == pytest.approx(4 * 0.5)            # window 4 starts at 2 s
    # legends outside the axes, with visible (lw 2) line proxies
    for ax in (rows[0], bottom):
        leg = ax.get_legend()
        assert leg is not None
        anchor = leg.get_bbox_to_anchor().transformed(ax.transAxes.inverted())
        assert anchor.x0 > 1.0
    line = next(h for h in rows[0].get_legend().legend_handles if h.get_linestyle() == '-')
    assert line.get_linewidth() >= 2
    # bottom: held-out windows ringed (hollow, larger), not small crosses
    rings = [ln for ln in bottom.get_lines() if ln.get_marker() == 'o' and
             ln.get_markerfacecolor() == 'none']
    assert rings and rings[0].get_markersize() >= 6 and len(rings[0].get_xdata()) == 8
    assert not any(ln.get_marker() == 'x' for ln in bottom.get_lines())


def test_residual_regressors_size_dpi_title_and_docstring(kept: list[Any],
                                                          tmp_path: Path) -> None:
    from PIL import Image

    from hexapod_energy.residuals import plot_energy_loop

    class _Documented(_Offset):
        """A constant power drawn whatever the gait does (electronics, sensors), in watts:
        P += c (c >= 0)."""

    table, sel, held, runs = _loop_inputs()
    sel.selected_ = [_Documented()]
    plot_energy_loop(table, sel, held, runs, tmp_path)
    fig = next(f for f in kept if f is not None and len(f.axes) == 1)
    w, h = fig.get_size_inches()
    assert w >= 6 and h >= 5
    assert fig.axes[0].get_title() == 'basal_power: fitted term vs residual'
    with Image.open(tmp_path / 'residual_regressors.png') as img:
        assert img.size == (round(w * 110), round(h * 110))
    # the docstring travels in the PNG and the report shows it in the caption
    from hexapod_common.report import png_description

    desc = png_description(tmp_path / 'residual_regressors.png')
    assert desc.startswith('basal_power: A constant power drawn') and 'P += c' in desc
    (tmp_path / 'residuals.json').write_text(json.dumps({'plots': ['residual_regressors.png',
                                                                   'residual_time.png']}))
    page = _page(tmp_path)
    cap = page[page.index('<code>residual_regressors.png</code>'):]
    cap = cap[:cap.index('</figcaption>')]
    assert 'A constant power drawn whatever the gait does' in cap


# -------------------------------------------------------------- 4: demo output folder


def test_demo_moves_an_earlier_run_aside_and_writes_in_place(tmp_path: Path,
                                                             monkeypatch: pytest.MonkeyPatch,
                                                             capsys: Any) -> None:
    from hexapod_common import demo

    out = tmp_path / 'demo_out'
    out.mkdir()
    (out / 'demo.json').write_text('{"run": "first"}')
    (out / 'report.html').write_text('first')
    older = tmp_path / 'demo_out.prev'
    older.mkdir()
    (older / 'demo.json').write_text('{"run": "zeroth"}')

    class Stop(Exception):
        pass

    def live(where: Path, *a: Any, **k: Any) -> None:
        assert where == out
        raise Stop

    monkeypatch.setattr(demo, 'run_live', live)
    with pytest.raises(Stop):
        demo.main(['--out', str(out), '--quick'])
    assert json.loads((older / 'demo.json').read_text()) == {'run': 'first'}   # replaced
    assert (older / 'report.html').read_text() == 'first'
    assert [p.name for p in out.iterdir()] == ['demo.json']                    # in place
    assert json.loads((out / 'demo.json').read_text())['status'] == 'incomplete'
    assert 'moved to' in capsys.readouterr().out
    # the stopped run is still a demo run: the next one moves it aside in turn
    assert demo._check_out(out) is None


def test_demo_refuses_a_folder_that_is_not_a_demo_run(tmp_path: Path, capsys: Any,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    from hexapod_common import demo

    out = tmp_path / 'results'
    out.mkdir()
    (out / 'notes.txt').write_text('mine')
    monkeypatch.setattr(demo, 'run_live', lambda *a, **k: pytest.fail('graph started'))
    assert demo.main(['--out', str(out), '--quick']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'not an earlier demo run' in err[0] and str(out) in err[0]
    assert [p.name for p in out.iterdir()] == ['notes.txt']
    assert not (tmp_path / 'results.prev').exists()
    # an empty folder and a new one are fine
    assert demo._check_out(tmp_path / 'new') is None
    (tmp_path / 'empty').mkdir()
    assert demo._check_out(tmp_path / 'empty') is None


def test_report_leaves_nested_runs_out_and_names_time_and_version(tmp_path: Path) -> None:
    from importlib.metadata import version

    (tmp_path / 'demo.json').write_text(json.dumps({'live': {'windows': 7}}))
    old = tmp_path / '20261126-230022'
    (old / 'energy').mkdir(parents=True)
    (old / 'demo.json').write_text(json.dumps({'live': {'windows': 5}}))
    (old / 'report.html').write_text('old')
    (old / 'energy' / 'energy.json').write_text(json.dumps({'prediction_error': {}}))
    fig, ax = plt.subplots(figsize=(1, 1))
    fig.savefig(old / 'energy' / 'prediction.png')
    _REAL_CLOSE(fig)
    page = _page(tmp_path)
    assert re.findall(r'<h2>(.*?)</h2>', page) == ['demo.json']
    assert 'prediction.png' not in page
    assert '<code>20261126-230022/</code>' in page and 'Not included' in page
    assert '<a href="20261126-230022/report.html">' in page
    head = page[page.index('<h1>'):page.index('Not included')]
    assert re.search(r'generated \d{4}-\d{2}-\d{2} \d{2}:\d{2}:\d{2}', head)
    assert f'hexapod_common {version("hexapod_common")}' in head


# ------------------------------------------------------------ 5, 11, 12, 13: report


def _curve(**extra: Any) -> dict[str, Any]:
    return {'label': 'beta 0.5', 'min_efficiency': 0.00353, 'max_speed_mps': 0.6,
            'payloads_kg': [0.0, 0.5],
            'optimal_points': {'max_power_out': {'speed_mps': 0.6, 'value': 4.0}}, **extra}


def _min_eta_cell(page: str, label: str) -> str:
    row = page[page.index(f'<td>{label}</td>'):]
    cells = re.findall(r'<td>(.*?)</td>', row[:row.index('</tr>')])
    return cells[7]


def test_min_eta_on_the_bench_when_known_else_starred(tmp_path: Path) -> None:
    curves = [
        _curve(label='new keys', min_efficiency_outside_bench=True,
               min_efficiency_on_bench=0.0065, min_efficiency_on_bench_speed_mps=0.092),
        _curve(label='none on bench', min_efficiency_outside_bench=True,
               min_efficiency_on_bench=None, min_efficiency_on_bench_speed_mps=None),
        _curve(label='old document'),
        _curve(label='known on bench', min_efficiency_outside_bench=False)]
    (tmp_path / 'energy.json').write_text(json.dumps({'sweeps': {'duty_factor': curves}}))
    page = _page(tmp_path)
    assert _min_eta_cell(page, 'new keys') == '0.65'
    row = page[page.index('<td>new keys</td>'):]
    assert re.findall(r'<td>(.*?)</td>', row[:row.index('</tr>')])[8] == '0.092'
    assert _min_eta_cell(page, 'none on bench').endswith('0.353*</span>')
    assert _min_eta_cell(page, 'old document').endswith('0.353*</span>')
    assert _min_eta_cell(page, 'known on bench') == '0.353'
    assert 'the bench covers' in page and 'nominal payload 0 g' in page


def test_the_two_bias_figures_say_their_sign_and_unit(tmp_path: Path) -> None:
    (tmp_path / 'demo.json').write_text(json.dumps({'batch': {
        'prediction_error': {'rmse_w': 6.875, 'bias_w': 4.888},
        'residuals': {'unit': 'W', 'baseline': {'rmse': 8.547, 'bias': -6.956},
                      'final': {'rmse': 0.885, 'bias': 0.0027}}}}))
    page = _page(tmp_path)
    assert '<th>bias_w (predicted \u2212 measured P_in, per run)</th><td>4.888 W</td>' in page
    assert ('<th>bias (residual: measured \u2212 model, per window)</th><td>-6.956 W</td>'
            in page)


def test_gait_type_comparison_has_a_caption(tmp_path: Path) -> None:
    fig, ax = plt.subplots(figsize=(1, 1))
    fig.savefig(tmp_path / 'gait_type_comparison.png')
    _REAL_CLOSE(fig)
    (tmp_path / 'energy.json').write_text(json.dumps({'prediction_error': {'rmse_w': 1.0}}))
    page = _page(tmp_path)
    cap = page[page.index('<code>gait_type_comparison.png</code>'):]
    cap = cap[:cap.index('</figcaption>')]
    assert 'below 1 the wave gait is cheaper' in cap and 'extrapolates' in cap


def test_recommendation_rows_named_and_a_negative_saving_said_plainly(tmp_path: Path) -> None:
    rec = {'speed_mps': 0.3, 'payload_kg': 0.2, 'saving_fraction': -0.2127,
           'best': {'gait': 'ripple', 'specific_cost_of_transport': 58.66,
                    'outside_bench': []},
           'default': {'gait': 'tripod', 'specific_cost_of_transport': 48.37,
                       'outside_bench': ["stance load 0.628 kg outside the bench's 0-0.515"]}}
    (tmp_path / 'energy.json').write_text(json.dumps({'recommendation': rec}))
    page = _page(tmp_path)
    assert '<td><b>best on the bench</b></td><td>ripple</td>' in page
    assert '<td>default (extrapolated)</td><td>tripod</td>' in page
    assert '<b>best</b>' not in page
    assert 'No saving: the recommended configuration costs 21.3 % more CoT/M' in page
    assert "No configuration the bench covers beats the default" in page
