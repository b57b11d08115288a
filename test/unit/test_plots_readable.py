"""The energy plots read on their own: distinct optimum markers with legend entries, the
payload line and band and the extrapolated tail named, axes fitted to the bench, the power
map with contours and its gait, the prediction as measured against predicted with a 1:1 line,
the where-the-watts-go legend beside the bars; the residual and SLIP plots: runs told apart,
before and after labelled, a single spike not setting the scale."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from hexapod_energy import plots  # noqa: E402
from hexapod_energy.sweeps import SweepCurve, SweepSpec  # noqa: E402

_REAL_CLOSE = plt.close


def _curve(label: str, scale: float, out_until: int = 0, legs: int = 6) -> SweepCurve:
    """A synthetic curve: P_out and efficiency grow with speed, CoT/M falls; the first
    ``out_until`` speeds outside the bench (a steep extrapolated CoT/M tail)."""
    v = np.linspace(0.05, 0.6, 12)
    pay = np.array([0.0, 0.25, 0.5])
    mass = 2.183 + pay
    p_out = scale * 4.0 * (v / 0.6) ** 2.5
    p_out = np.repeat(p_out[:, None], 3, axis=1) * np.array([1.0, 1.02, 1.05])
    p_in = 12.0 + 40.0 * v[:, None] + 0.0 * pay
    cot = p_in / (mass * v[:, None])
    out = np.zeros((v.size, 3), bool)
    out[:out_until] = True
    return SweepCurve(SweepSpec(label, 'alternating', legs, 0.5), v, pay, mass, p_in, p_out,
                      p_out / p_in, cot, cot / 9.81, out)


@pytest.fixture
def figures(monkeypatch: pytest.MonkeyPatch) -> list[Any]:
    """Figures the plot functions would save (kept open, closed after the test)."""
    got: list[Any] = []
    monkeypatch.setattr(plots, '_save', lambda fig, stem: got.append(fig) or [])
    yield got
    for fig in got:
        plt.close(fig)


def test_optimum_markers_are_distinct_and_in_the_legend() -> None:
    fig = plots.four_quadrant_figure([_curve('6 legs', 1.0), _curve('8 legs', 1.3)],
                                     title='Fig. 3D leg count')
    ax1 = fig.axes[1]
    marks = {k: [ln for ln in ax1.get_lines() if ln.get_gid() == k]
             for k in plots.OPTIMUM_MARKERS}
    assert all(len(v) == 2 for v in marks.values())                   # one per curve
    shapes = {k: (v[0].get_marker(), v[0].get_markersize()) for k, v in marks.items()}
    assert len({s for s, _ in shapes.values()}) == 3                  # three shapes
    # all three coincide at the curve's maximum speed here: sizes decrease so each shows
    sizes = [shapes[k][1] for k in ('max_power_out', 'min_cot_per_mass', 'max_efficiency')]
    assert sizes == sorted(sizes, reverse=True) and len(set(sizes)) == 3
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    for text in ('max P_out', 'min CoT/M', 'max efficiency', 'solid: 0 g payload',
                 'band: payload 0-500 g', '6 legs', '8 legs'):
        assert text in labels
    assert 'robot 2.18 kg' in fig._suptitle.get_text()
    assert 'alternating' in fig._suptitle.get_text()
    plt.close(fig)


def test_extrapolated_tail_is_dotted_named_and_does_not_set_the_scale() -> None:
    four = _curve('4 legs', 0.7, out_until=12, legs=4)           # never on the bench
    six = _curve('6 legs', 1.0, out_until=3)
    fig = plots.four_quadrant_figure([four, six])
    legend = fig.legends[0]
    entries = dict(zip([t.get_text() for t in legend.get_texts()], legend.legend_handles))
    assert entries['4 legs (all extrapolated)'].get_linestyle() == ':'
    assert entries['6 legs'].get_linestyle() == '-'
    assert 'dotted: outside the bench (Eq. 1 extrapolated)' in entries
    plt.close(fig)
    # a curve partly on the bench: its extrapolated slow tail is clipped
    fig = plots.four_quadrant_figure([six, _curve('8 legs', 1.3, out_until=3, legs=8)])
    ax3 = fig.axes[2]
    bottom, top = ax3.get_ylim()                       # inverted: CoT/M grows downward
    assert bottom > top
    tail = float(six.cot_per_mass[0, -1])              # 0.05 m/s, 500 g: extrapolated
    inside = float(np.max(six.cot_per_mass[3:]))
    assert bottom < tail and bottom >= inside
    assert 'clipped' in ax3.get_ylabel()
    plt.close(fig)


def test_power_map_has_labelled_contours_and_names_its_gait(figures: list[Any]) -> None:
    v, pay = np.linspace(0.1, 0.6, 10), np.linspace(0.0, 0.5, 6)
    pw = 4.0 * (v[:, None] / 0.6) ** 2.5 * (1.0 + 0.1 * pay[None, :])
    plots.power_map_plot(v, pay, pw, 'unused', gait_label='tripod beta 0.5, step 100 mm')
    ax = figures[0].axes[0]
    assert ax.texts, 'contour labels'
    assert 'tripod beta 0.5, step 100 mm' in ax.get_title()
    assert 'P_out changes at most 5.0 %' in ax.get_title()


def test_prediction_is_measured_against_predicted_with_one_to_one_line() -> None:
    fig = plots.prediction_figure([0.3], [32.41], [35.12], labels=['robot_1'],
                                  title='AntBot')
    ax = fig.axes[0]
    lo, hi = ax.get_xlim()
    assert hi - lo > 5.0                           # one run: not a meaningless tiny axis
    assert ax.get_xlim() == ax.get_ylim()
    one = [ln for ln in ax.get_lines() if ln.get_label().startswith('1:1')]
    assert one and list(one[0].get_xdata()) == list(one[0].get_ydata())
    assert 'RMSE 2.71 W' in ax.get_title() and 'AntBot' in ax.get_title()
    assert any('robot_1' in t.get_text() for t in ax.texts)
    plt.close(fig)


def test_watts_legend_beside_the_bars_and_title_names_the_robot() -> None:
    b = {'holding_w': 14.0, 'stance_motion_w': 3.0, 'swing_motion_w': 7.0}
    fig = plots.watts_figure(['robot_0\n0.15 m/s'], [b], [23.6], [0.24],
                             title='AntBot robot, 2.183 kg')
    ax = fig.axes[0]
    fig.canvas.draw()
    legend_box = ax.get_legend().get_window_extent()
    assert legend_box.x0 >= ax.get_window_extent().x1           # outside the axes
    assert 'AntBot robot, 2.183 kg' in ax.get_title()
    plt.close(fig)


def test_measured_runs_plot_without_a_bench(tmp_path: Path) -> None:
    paths = plots.measured_runs_plot(['robot_1\n0.30 m/s', 'robot_3\n0.60 m/s'],
                                     [32.4, 53.0], [48.4, float('nan')], tmp_path / 'runs')
    assert [p.suffix for p in paths] == ['.png', '.svg']
    assert all(p.stat().st_size > 5000 for p in paths)


# ------------------------------------------------------------------- SLIP figures 7-9


def test_slip_figures_one_marker_per_run_with_titles(monkeypatch: pytest.MonkeyPatch,
                                                     tmp_path: Path) -> None:
    from slip_identification.energetics import plot_figures

    kept: list[Any] = []
    monkeypatch.setattr(plt, 'close', lambda fig=None: kept.append(fig))
    rows = []
    for gait, p, v, sr, n in (('running', 32.15, 0.878, 1.128, 15),
                              ('walk', 17.97, 0.181, 3.05, 8)):
        rows += [{'gait': gait, 'nerr': 0.05 + 0.01 * k, 'power_w': p, 'speed_mps': v,
                  'sr': sr} for k in range(n)]
    paths = plot_figures(rows, tmp_path)
    assert [p.name for p in paths] == ['fig7_speed_vs_sr.png', 'fig8_power_vs_speed.png',
                                       'fig9_nerr_vs_sr.png']
    try:
        for fig in kept:
            ax = fig.axes[0]
            assert ax.get_title()
            # one marker per run, annotated with its stance count
            runs = sum(len(ln.get_xdata()) for ln in ax.get_lines() if ln.get_marker() == 'o')
            assert runs == 2
            assert {t.get_text() for t in ax.get_legend().get_texts()} == {'running', 'walk'}
            assert {'n=15', 'n=8'} <= {t.get_text().split()[0] for t in ax.texts}
    finally:
        _REAL_CLOSE('all')


# ------------------------------------------------------------------------ residuals


def test_residual_slip_nerr_one_series_per_bag(monkeypatch: pytest.MonkeyPatch,
                                               tmp_path: Path) -> None:
    from hexapod_energy.residuals_cli import _plot_slip

    kept: list[Any] = []
    monkeypatch.setattr(plt, 'close', lambda fig=None: kept.append(fig))

    def fit(t: float, nerr: float, bag: str) -> SimpleNamespace:
        return SimpleNamespace(touchdown_s=t, nerr=nerr, label=f'{bag}#{int(t * 10)}')

    slip = [fit(t, 0.1, '/d/run_a') for t in (1.6, 2.0, 2.4)] + \
        [fit(t, 0.4, '/d/run_b') for t in (1.7, 2.1)]
    damped = [SimpleNamespace(touchdown_s=f.touchdown_s, nerr=f.nerr / 2, label=f.label)
              for f in slip]
    doc = {'effects_added': ['leg_damping'], 'bags': ['/d/run_a', '/d/run_b']}
    assert _plot_slip({'slip': slip, 'leg_damping': damped}, doc, tmp_path) == [
        'residual_slip_nerr.png']
    try:
        fig = next(f for f in kept if f is not None)
        ax = fig.axes[0]
        assert ax.get_title()
        series = [ln for ln in ax.get_lines() if ln.get_label() and
                  not ln.get_label().startswith('_')]
        names = [ln.get_label() for ln in series]
        assert any('run_a' in n and 'before' in n for n in names)
        assert any('run_b' in n and 'after' in n for n in names)
        for ln in series:                      # never back in time inside one series
            assert np.all(np.diff(np.asarray(ln.get_xdata(), float)) > 0)
        assert len(series) == 4                # 2 bags x (before, after)
    finally:
        _REAL_CLOSE('all')


class _Offset:
    """A stand-in effect: a constant per window (one column)."""

    name, unit = 'basal_power', 'W'

    def columns(self, table: Any) -> np.ndarray:
        return np.ones((table.run.size, 1))


def test_residual_time_runs_told_apart_and_a_spike_clipped(monkeypatch: pytest.MonkeyPatch,
                                                          tmp_path: Path) -> None:
    from hexapod_energy.residuals import plot_energy_loop

    kept: list[Any] = []
    monkeypatch.setattr(plt, 'close', lambda fig=None: kept.append(fig))
    rng = np.random.default_rng(1)
    runs, run_idx, resid = [], [], []
    for k, offset in enumerate((-1.0, -6.0, -12.0)):
        t = np.linspace(0.0, 10.0, 2000)
        predicted = np.full(t.size, 30.0)
        power = predicted + offset + 3.0 * np.sin(2 * np.pi * 1.5 * t)
        if k == 0:
            power[0] += 130.0                       # one start-up spike
        runs.append(SimpleNamespace(t_s=t + 100.0 * k, power_w=power, predicted_w=predicted,
                                    name=f'/d/robot_{k}'))
        run_idx += [k] * 20
        resid += list(offset + 0.2 * rng.standard_normal(20))
    r0 = np.array(resid)
    table = SimpleNamespace(residual_w=r0, run=np.array(run_idx), t_s=np.arange(r0.size))
    sel = SimpleNamespace(term_w_=r0 - 0.1, selected_=[_Offset()],
                          coef_=np.array([float(np.mean(r0))]))
    held = np.zeros(r0.size, bool)
    held[::5] = True
    assert plot_energy_loop(table, sel, held, runs, tmp_path) == [
        'residual_time.png', 'residual_regressors.png']
    try:
        # one row per run (the per-sample ripples overlaid were unreadable), then every window
        fig = next(f for f in kept if f is not None and len(f.axes) == 4)
        top, bottom = fig.axes[0], fig.axes[3]
        assert top.get_ylim()[1] < 100.0                          # the spike does not set it
        assert top.get_ylim()[1] > 3.0 - 1.0                      # the ripple stays in
        assert any('clipped' in t.get_text() for t in top.texts)
        assert [t.get_text().split(':')[0] for ax in fig.axes[:3] for t in ax.texts
                if t.get_text().startswith('robot_')] == ['robot_0', 'robot_1', 'robot_2']
        # before and after both drawn, each run in its own colour; boundaries named
        styles = {(ln.get_marker(), ln.get_markerfacecolor() == 'none')
                  for ln in bottom.get_lines() if len(ln.get_xdata()) == 20}
        assert ('o', False) in styles and ('s', True) in styles
        assert {t.get_text() for t in bottom.texts} == {'robot_0', 'robot_1', 'robot_2'}
        assert sum(1 for ln in bottom.get_lines() if ln.get_linestyle() == '--') == 2
        reg = next(f for f in kept if f is not None and f is not fig)
        assert 'fitted basal_power term [W]' == reg.axes[0].get_xlabel()
        assert any('fitted term' in ln.get_label() for ln in reg.axes[0].get_lines())
    finally:
        _REAL_CLOSE('all')


def test_a_curve_equal_to_an_earlier_one_is_dashed_and_says_so() -> None:
    """Wave at beta 0.5 is the tripod (L(t) = 3 at every instant; the paper says so): drawn
    solid over it, it hid the tripod curve. It is now dashed and labelled '(= tripod ...)'."""
    fig = plots.four_quadrant_figure([_curve('tripod beta 0.5', 1.0),
                                      _curve('wave beta 0.5', 1.0)], title='Fig. 3C')
    lines = [ln for ln in fig.axes[1].get_lines() if not ln.get_label().startswith('_')]
    twin = [ln for ln in lines if ln.get_label().startswith('wave beta 0.5')]
    assert twin and twin[0].get_label() == 'wave beta 0.5 (= tripod beta 0.5)'
    assert twin[0].get_linestyle() == '--'
    plt.close(fig)
