"""Outside plot review (FINDINGS.md), the energy plots and energy.json:

- #2 the gait-type comparison's saving computed on the bench too, its title honest about an
  extrapolated saving, the extrapolated speeds shaded, no identical payload lines in the legend;
- #3 Fig. 3C's solid curves at the paper's 140 g, every four-quadrant subtitle naming its
  nominal payload and band;
- #5 ``min_efficiency_on_bench`` (and where the minima lie) beside ``min_efficiency``;
- #7 where the watts go: the stack labelled as the Eq. 1 model's, the over-prediction an
  outline, P_out and eta written per bar, the run set in the title;
- #9 overlapping payload bands told apart (dashed edges in the curve's colour, grey hatch for
  the extrapolated part), a P_out band thinner than the line said in the legend;
- #15 power-map contour labels dark on the light end of the colour map;
- #16 the duplicate curve's markers, the model note's real reason for refusing efforts, no
  empty band between the quadrants and the legend.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use('Agg')
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.colors import to_rgba  # noqa: E402
from numpy.testing import assert_allclose  # noqa: E402

from hexapod_energy import plots  # noqa: E402
from hexapod_energy.prediction import OutputPowerModel  # noqa: E402
from hexapod_energy.sweeps import SweepCurve, SweepSpec, compare_curves, sweep_curve  # noqa
from test_energy_sweeps import Phase, StubTrajectory  # noqa: E402  (analytic phase model)

PAY = np.array([0.0, 0.1, 0.2, 0.3, 0.4, 0.5])


def _curve(label: str, cot: np.ndarray, *, out: np.ndarray | None = None,
           v: np.ndarray | None = None, pay: np.ndarray = PAY,
           pout_per_kg: float = 0.01, eff: np.ndarray | None = None) -> SweepCurve:
    """A synthetic curve of the given CoT/M (k, m); P_out grows with speed, by
    ``pout_per_kg`` per kg of payload."""
    k, m = cot.shape
    v = np.linspace(0.02, 0.13, k) if v is None else v
    mass = 2.183 + pay
    p_out = 4.0 * (v[:, None] / 0.6) ** 2.5 * (1.0 + pout_per_kg * pay[None, :])
    p_in = cot * mass[None, :] * v[:, None] + p_out
    e = p_out / p_in if eff is None else eff
    return SweepCurve(SweepSpec(label, 'tripod', 6, 0.5), v, pay, mass, p_in, p_out, e, cot,
                      p_in / (mass * 9.81 * v[:, None]),
                      np.zeros((k, m), bool) if out is None else out)


def _wave_against_tripod() -> tuple[SweepCurve, SweepCurve]:
    """Wave cheaper below 0.055 m/s, where every payload is outside the bench (the demo's
    gait-type sweep: stance 2 s beyond the bench's 1 s), 25-39 % dearer on the bench."""
    v = np.linspace(0.02, 0.13, 45)
    ratio = np.interp(v, [0.02, 0.055, 0.09, 0.13], [0.85, 1.0, 1.22, 1.39])
    base = np.repeat((40.0 + 2.0 / v)[:, None], PAY.size, axis=1)
    other = base * ratio[:, None] * (1.0 + 0.001 * PAY[None, :])
    out = np.zeros((v.size, PAY.size), bool)
    out[v < 0.09] = True
    out[:, 1:] = True                    # payloads above 0 g: the stance load beyond the bench
    return (_curve('tripod beta 0.5', base, out=out, v=v),
            _curve('wave beta 0.83', other, out=out, v=v))


# ------------------------------------------------------------------------ #2 comparison


def test_comparison_keys_on_the_bench() -> None:
    """``below_one_until_mps`` said 0.055 m/s: every such point was extrapolated. The same
    figures on the points the bench covers are new keys; the old ones are unchanged."""
    tri, wave = _wave_against_tripod()
    cmp = compare_curves(tri, wave)
    assert all(u == pytest.approx(0.055, abs=0.003) for u in cmp['below_one_until_mps'])
    assert all(r < 0.86 for r in cmp['best_ratio'])
    assert cmp['below_one_until_mps_on_bench'] == [None] * PAY.size
    # only 0 g is on the bench (from 0.09 m/s): its best ratio there is > 1
    assert cmp['best_ratio_on_bench'][0] == pytest.approx(1.22, abs=0.01)
    assert cmp['best_speed_mps_on_bench'][0] >= 0.09
    assert cmp['best_ratio_on_bench'][1:] == [None] * (PAY.size - 1)
    assert cmp['best_speed_mps_on_bench'][1:] == [None] * (PAY.size - 1)
    # a saving on the bench is found there too
    inside = dataclasses.replace(wave, outside_bench=np.zeros_like(wave.outside_bench))
    both = compare_curves(dataclasses.replace(tri, outside_bench=inside.outside_bench), inside)
    assert both['below_one_until_mps_on_bench'] == both['below_one_until_mps']


def test_comparison_title_shading_and_legend() -> None:
    tri, wave = _wave_against_tripod()
    cmp = compare_curves(tri, wave)
    fig = plots.comparison_figure(cmp)
    ax = fig.axes[0]
    title = ax.get_title()
    assert 'cheaper up to 0.05' in title
    assert 'only where a curve extrapolates the bench' in title
    assert 'on the bench (0 g' in title and 'never cheaper, ratio 1.2' in title
    # the speeds extrapolated at every payload are shaded
    spans = [p for p in ax.patches if p.get_gid() == 'extrapolated_speeds']
    assert len(spans) == 1
    lo, hi = spans[0].get_x(), spans[0].get_x() + spans[0].get_width()
    assert lo == pytest.approx(0.02) and 0.085 < hi < 0.095
    # six all-but-identical payload lines: the extremes only, the spread said
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert '0 g' in texts and '500 g' in texts
    assert not any(t in texts for t in ('100 g', '200 g', '300 g', '400 g'))
    assert any(t.startswith('0-500 g change the ratio < ') for t in texts)
    assert 'extrapolated at every payload' in texts
    plt.close(fig)
    # payloads that matter: every line drawn
    far = dict(cmp, ratio=np.asarray(cmp['ratio']) * (1.0 + 0.2 * PAY[None, :]))
    fig = plots.comparison_figure(far)
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert all(f'{g:.0f} g' in texts for g in 1000 * PAY)
    plt.close(fig)


# ------------------------------------------------------------------- #3 Fig. 3C at 140 g


@pytest.fixture(scope='module')
def opm() -> OutputPowerModel:
    return OutputPowerModel(trajectory_factory=StubTrajectory, n_samples=64)


def test_with_payload_adds_one_exact_column(opm) -> None:
    from hexapod_energy.sweeps import PAPER_GAIT_TYPE_PAYLOAD_KG, with_payload

    spec = SweepSpec('wave beta 0.83', 'wave', 6, 0.83, min_speed_mps=0.02)
    curve = sweep_curve(spec, Phase(), opm, n_speeds=6)
    more = with_payload(curve, PAPER_GAIT_TYPE_PAYLOAD_KG, Phase(), opm)
    assert_allclose(more.payloads_kg, [0.0, 0.1, 0.14, 0.2, 0.3, 0.4, 0.5])
    keep = [0, 1, 3, 4, 5, 6]
    for name in ('power_in_w', 'power_out_w', 'efficiency', 'cot_per_mass'):
        assert_allclose(getattr(more, name)[:, keep], getattr(curve, name), rtol=1e-12)
    alone = sweep_curve(spec, Phase(), opm, n_speeds=6, payloads_kg=(0.14,))
    assert_allclose(more.cot_per_mass[:, 2], alone.cot_per_mass[:, 0], rtol=1e-12)
    assert more.outside_bench.shape == (6, 7)
    assert with_payload(curve, 0.1, Phase(), opm) is curve     # already there


def test_four_quadrant_nominal_payload_and_subtitles() -> None:
    pay = np.array([0.0, 0.1, 0.14, 0.2, 0.3, 0.4, 0.5])
    v = np.linspace(0.05, 0.6, 12)
    cot = (40.0 + 3.0 / v)[:, None] * (1.0 + 0.1 * pay[None, :])
    curve = _curve('tripod beta 0.5', cot, v=v, pay=pay)
    fig = plots.four_quadrant_figure([curve], title='Fig. 3C gait type',
                                     nominal_payload_kg=0.14)
    sub = fig._suptitle.get_text()
    assert 'nominal payload 140 g (band 0-500 g)' in sub
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert 'solid: 140 g payload' in texts
    assert 'dashed: band edges 0 g and 500 g' in texts
    ax4 = fig.axes[3]                                    # CoT/M vs speed
    solid = [ln for ln in ax4.get_lines() if ln.get_linestyle() == '-'
             and ln.get_gid() is None]
    assert_allclose(solid[0].get_ydata(), cot[:, 2])
    marks = [ln for ln in ax4.get_lines() if ln.get_gid() == 'min_cot_per_mass']
    assert float(marks[0].get_ydata()[0]) == pytest.approx(float(cot[:, 2].min()))
    plt.close(fig)
    # every four-quadrant plot says its nominal payload and band
    fig = plots.four_quadrant_figure([_curve('beta 0.5', cot[:, [0, 1, 3, 4, 5, 6]], v=v)])
    assert 'nominal payload 0 g (band 0-500 g)' in fig._suptitle.get_text()
    plt.close(fig)
    fig = plots.four_quadrant_figure([_curve('beta 0.5', cot[:, [0, 1, 3, 4, 5, 6]], v=v)],
                                     subtitle='given')
    assert fig._suptitle.get_text().endswith('given; nominal payload 0 g (band 0-500 g)')
    plt.close(fig)
    with pytest.raises(ValueError, match='not among'):
        plots.four_quadrant_figure([_curve('beta 0.5', cot[:, :6], v=v)],
                                   nominal_payload_kg=0.14)


def test_sweep_draws_fig_3c_at_140_g(opm, tmp_path, monkeypatch) -> None:
    """``--sweep``: the gait-type plot gets 140 g curves and that nominal payload; the other
    plots their first payload; energy.json keeps the sweep's own payloads."""
    from hexapod_energy import cli

    seen: dict[str, tuple[Any, Any]] = {}

    def spy(curves, stem, **kw):
        seen[Path(stem).name] = (curves, kw)
        return []
    monkeypatch.setattr(plots, 'four_quadrant_plot', spy)
    monkeypatch.setattr(plots, 'comparison_plot', lambda cmp, stem: [])
    monkeypatch.setattr(plots, 'power_map_plot', lambda *a, **kw: [])
    monkeypatch.setattr(type(opm), 'power_map_w',
                        lambda self, gait, v, p: np.ones((len(v), len(p))))
    doc: dict[str, Any] = {'plots': []}
    cli._sweep(doc, Phase(), opm, tmp_path, None)
    curves, kw = seen['four_quadrant_gait_type']
    assert kw['nominal_payload_kg'] == pytest.approx(0.14)
    assert all(np.any(np.isclose(c.payloads_kg, 0.14)) for c in curves)
    assert seen['four_quadrant_duty_factor'][1]['nominal_payload_kg'] is None
    assert doc['sweeps']['gait_type'][0]['payloads_kg'] == [0.0, 0.1, 0.2, 0.3, 0.4, 0.5]
    assert doc['sweep_settings']['plot_nominal_payload_kg'] == {
        'duty_factor': 0.0, 'step_length': 0.0, 'gait_type': 0.14, 'leg_count': 0.0}
    cmp = doc['gait_type_comparison']
    for key in ('below_one_until_mps_on_bench', 'best_ratio_on_bench',
                'best_speed_mps_on_bench'):
        assert len(cmp[key]) == len(cmp['payloads_kg'])
    for c in doc['sweeps']['duty_factor']:
        assert 'min_efficiency_on_bench' in c and 'min_efficiency_outside_bench' in c


def test_report_table_gives_fig_3c_points_as_plotted_and_the_bar_ends(opm, tmp_path,
                                                                      monkeypatch) -> None:
    """A review: the report's table headed Fig. 3C "nominal payload 0 g" with the 0 g optimal
    points beside a plot drawn at 140 g; energy.json now keeps the plot's points and the
    table gives them. ``--sweep``'s progress steps (16 counted, 14 ticked, none while the
    plots were drawn) now match its ticks."""
    from hexapod_common.report import _optimal_points
    from hexapod_energy import cli

    monkeypatch.setattr(plots, 'four_quadrant_plot', lambda curves, stem, **kw: [])
    monkeypatch.setattr(plots, 'comparison_plot', lambda cmp, stem: [])
    monkeypatch.setattr(plots, 'power_map_plot', lambda *a, **kw: [])
    monkeypatch.setattr(type(opm), 'power_map_w',
                        lambda self, gait, v, p: np.ones((len(v), len(p))))

    class Bar:
        n = 0

        def update(self, k: int = 1) -> None:
            self.n += k

    bar = Bar()
    doc: dict[str, Any] = {'plots': []}
    cli._sweep(doc, Phase(), opm, tmp_path, bar)
    assert bar.n == cli._sweep_steps()
    plotted = doc['sweep_settings']['plot_optimal_points']
    assert list(plotted) == ['gait_type']
    first = doc['sweeps']['gait_type'][0]
    mark = plotted['gait_type'][0]
    assert mark['label'] == first['label'] and mark['payload_kg'] == pytest.approx(0.14)
    at_0 = first['optimal_points']['min_cot_per_mass']['value']
    at_140 = mark['optimal_points']['min_cot_per_mass']['value']
    assert at_140 != pytest.approx(at_0)
    html = '\n'.join(_optimal_points(doc['sweeps'], doc['sweep_settings']))
    assert 'gait type (nominal payload 140 g, as plotted)' in html
    assert 'duty factor (nominal payload 0 g)' in html
    # the gait-type table's first row gives the plotted (140 g) min CoT/M, not the 0 g one
    row = html.split('gait type (nominal payload 140 g')[1].split('</tr>')[1]
    assert f'{at_140:.4g}' in row and f'{at_0:.4g}' not in row


# ------------------------------------------------------------------- #5 min eta on bench


def test_min_efficiency_on_bench_beside_the_overall_one() -> None:
    v = np.linspace(0.05, 0.6, 8)
    eff = np.repeat(np.linspace(0.003, 0.06, 8)[:, None], PAY.size, axis=1) \
        * (1.0 - 0.01 * PAY[None, :])
    out = np.zeros((8, PAY.size), bool)
    out[:2] = True                                   # the two slowest speeds extrapolated
    out[:, 3:] = True                                # and the heavy payloads
    c = _curve('beta 0.5', np.full((8, PAY.size), 50.0), v=v, out=out, eff=eff)
    d = c.to_dict()
    assert d['min_efficiency'] == pytest.approx(eff.min())            # unchanged
    assert d['min_efficiency_speed_mps'] == pytest.approx(0.05)
    assert d['min_efficiency_payload_kg'] == pytest.approx(0.5)
    assert d['min_efficiency_outside_bench'] is True
    assert d['min_efficiency_on_bench'] == pytest.approx(eff[2, 2])
    assert d['min_efficiency_on_bench_speed_mps'] == pytest.approx(v[2])
    assert d['min_efficiency_on_bench_payload_kg'] == pytest.approx(0.2)
    json.dumps(d)                                                     # plain JSON types
    # nothing on the bench: null, not the extrapolated value
    d = dataclasses.replace(c, outside_bench=np.ones_like(out)).to_dict()
    assert d['min_efficiency_on_bench'] is None
    assert d['min_efficiency_on_bench_speed_mps'] is None
    # all on the bench: the same point
    d = dataclasses.replace(c, outside_bench=np.zeros_like(out)).to_dict()
    assert d['min_efficiency_on_bench'] == d['min_efficiency']
    assert d['min_efficiency_outside_bench'] is False


# ------------------------------------------------------------ #7 where the watts go


def _watts() -> Any:
    b = [{'holding_w': 14.38, 'stance_motion_w': 3.0, 'swing_motion_w': 7.5},
         {'holding_w': 14.38, 'stance_motion_w': 8.87, 'swing_motion_w': 42.75}]
    return plots.watts_figure(['robot_0\n0.15 m/s', 'robot_3\n0.60 m/s'], b, [26.0, 53.3],
                              [0.26, 4.0], title='AntBot robot, 2.183 kg; 2 runs: cycles from '
                              'the joints, speed given (--robot-speed)',
                              efficiency=[0.01, 0.075])


def test_watts_stack_is_the_model_and_the_over_prediction_an_outline() -> None:
    fig = _watts()
    ax = fig.axes[0]
    title = ax.get_title()
    assert "Eq. 1 model's split against the measured P_in" in title
    assert 'cycles from the joints' in title and 'speed given' in title
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert 'Eq. 1 model: holding (basal at load)' in texts
    assert 'Eq. 1 model: moving, stance' in texts and 'Eq. 1 model: moving, swing' in texts
    over = [p for p in ax.patches if p.get_gid() == 'over_prediction']
    assert over and all(p.get_facecolor()[3] == 0.0 for p in over)       # no fill
    # the robot_3 bar: 66 W predicted, 53.3 W measured; the outline from 53.3 to 66 W
    tall = [p for p in over if p.get_height() > 1.0]
    assert tall[0].get_y() == pytest.approx(53.3) and \
        tall[0].get_y() + tall[0].get_height() == pytest.approx(66.0)
    # no filled patch lies over the swing segment's top (the model stack stays visible)
    filled_above = [p for p in ax.patches if p.get_facecolor()[3] > 0
                    and p.get_height() > 0 and p.get_y() >= 53.3 - 1e-9 and p.get_x() > 0.5]
    assert not filled_above
    plt.close(fig)


def test_watts_power_out_and_efficiency_written_per_bar() -> None:
    fig = _watts()
    ax = fig.axes[0]
    notes = [t.get_text() for t in ax.texts if t.get_gid() == 'power_out']
    assert notes == ['P_out 0.26 W\neta 1.0 %', 'P_out 4.00 W\neta 7.5 %']
    # above the bars: at or above the taller of model and measurement
    ys = [t.xy[1] for t in ax.texts if t.get_gid() == 'power_out']
    assert ys == pytest.approx([26.0, 66.0])
    # P_out is no longer a marker on the 0-70 W axis
    assert not any(ln.get_marker() == 'v' for ln in ax.get_lines())
    plt.close(fig)


def test_run_set_name() -> None:
    from hexapod_energy.cli import _run_set_name

    lab = [{'bag': 'demo_out/other_lab_robot', 'cycle_source': 'joints',
            'speed_source': 'given', 'gait': 'tripod', 'power_out_source': 'model'}]
    name = _run_set_name(lab)
    assert name.startswith('1 run (other_lab_robot): cycles from the joints')
    assert 'speed given (--robot-speed)' in name and 'gait given (--gait)' in name
    assert 'P_out from the Eq. 6 model' in name
    runs = [{'bag': f'demo_out/robot_{i}', 'cycle_source': 'gait_phase',
             'speed_source': 'gait_schedule', 'gait': 'tripod', 'power_out_source': 'model'}
            for i in range(4)]
    name = _run_set_name(runs)
    assert name.startswith('4 runs (robot_0 ... robot_3): cycles from /gait/phase')
    assert 'gait given' not in name


# --------------------------------------------------------------------- #9 bands


def _sweep_like(n: int = 4, pout_per_kg: float = 0.05) -> list[SweepCurve]:
    v = np.linspace(0.05, 0.6, 20)
    out = np.zeros((20, PAY.size), bool)
    out[:, 1:] = True                    # above 0 g extrapolated, like the demo's tripod
    return [_curve(f'step {70 + 20 * i} mm',
                   (38.0 + 4 * i + 2.0 / v)[:, None] * (1.0 - 0.3 * PAY[None, :]), v=v,
                   out=out, pout_per_kg=pout_per_kg) for i in range(n)]


def test_bands_told_apart_by_dashed_edges_and_a_grey_hatch() -> None:
    curves = _sweep_like()
    fig = plots.four_quadrant_figure(curves, title='Fig. 3B step length')
    ax4 = fig.axes[3]
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    edges = [ln for ln in ax4.get_lines() if ln.get_gid() == 'band_edge']
    assert len(edges) == len(curves)                        # one 500 g edge per curve
    assert [to_rgba(ln.get_color()) for ln in edges] == \
        [to_rgba(colors[i]) for i in range(len(curves))]
    assert all(ln.get_linestyle() == '--' for ln in edges)
    for ln, c in zip(edges, curves):
        assert_allclose(ln.get_ydata(), c.cot_per_mass[:, -1])
    hatched = [p for p in ax4.patches if p.get_hatch()]
    assert hatched
    # the hatch grey, never a curve's colour: overlapping bands' hatches do not mix
    assert all(to_rgba(p.get_edgecolor())[:3] == pytest.approx(to_rgba('0.5')[:3])
               for p in hatched)
    # the fills very light
    fills = [p for p in ax4.patches if not p.get_hatch()]
    assert all(p.get_facecolor()[3] <= plots.BAND_ALPHA + 1e-9 for p in fills)
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert 'dashed: band edge 500 g' in texts
    assert any(t.startswith('P_out band thinner than the line') for t in texts)
    plt.close(fig)
    # a payload that changes P_out a lot: its band shows, nothing said
    fig = plots.four_quadrant_figure(_sweep_like(2, pout_per_kg=2.0))
    texts = [t.get_text() for t in fig.legends[0].get_texts()]
    assert not any('thinner than the line' in t for t in texts)
    plt.close(fig)


# ---------------------------------------------------------------- #15 power map labels


def test_power_map_labels_dark_on_light_colours(monkeypatch) -> None:
    got: list[Any] = []
    monkeypatch.setattr(plots, '_save', lambda fig, stem: got.append(fig) or [])
    v, pay = np.linspace(0.1, 0.6, 20), np.linspace(0.0, 0.5, 6)
    pw = 4.0 * (v[:, None] / 0.6) ** 2.5 * (1.0 + 0.05 * pay[None, :])
    plots.power_map_plot(v, pay, pw, 'unused')
    ax = got[0].axes[0]
    labels = [(float(t.get_text().split()[0]), to_rgba(t.get_color())) for t in ax.texts]
    assert labels
    top = max(lv for lv, _ in labels)
    low = min(lv for lv, _ in labels)
    assert dict(labels)[top] == to_rgba('k')      # the yellow end
    assert dict(labels)[low] == to_rgba('w')      # the dark end
    plt.close(got[0])


# -------------------------------------------------------------------------- #16 items


def test_duplicate_curve_has_markers_even_where_extrapolated() -> None:
    v = np.linspace(0.05, 0.6, 24)
    cot = np.repeat((40 + 2 / v)[:, None], PAY.size, axis=1)
    out = np.zeros((24, PAY.size), bool)
    out[:4] = True
    tri = _curve('tripod beta 0.5', cot, v=v, out=out)
    twin = _curve('wave beta 0.5', cot, v=v, out=out)
    fig = plots.four_quadrant_figure([tri, twin])
    lines = [ln for ln in fig.axes[1].get_lines()
             if ln.get_label().startswith('wave beta 0.5')]
    assert lines[0].get_marker() == 'o' and lines[0].get_markevery() == 3
    assert lines[0].get_linestyle() == '--'
    plt.close(fig)
    # all extrapolated (Fig. 3C at 140 g): its markers alone over the earlier dotted curve
    allout = np.ones_like(out)
    fig = plots.four_quadrant_figure([_curve('tripod beta 0.5', cot, v=v, out=allout),
                                      _curve('wave beta 0.5', cot, v=v, out=allout)])
    twin = [ln for ln in fig.axes[1].get_lines()
            if ln.get_label().startswith('wave beta 0.5')][0]
    assert twin.get_marker() == 'o' and twin.get_linestyle() == 'None'
    plt.close(fig)


def test_legend_sits_just_below_the_quadrants() -> None:
    """``tight_layout(rect=(0, 0.035 rows + 0.01, ...))`` left a wide empty band."""
    fig = plots.four_quadrant_figure(_sweep_like(), title='Fig. 3B step length')
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    axes_bottom = min(ax.get_tightbbox(renderer).y0 for ax in fig.axes)
    legend_top = fig.legends[0].get_window_extent(renderer).y1
    gap = (axes_bottom - legend_top) / fig.bbox.height
    assert -0.005 < gap < 0.025
    plt.close(fig)


def test_model_note_gives_the_reason_efforts_were_refused(tmp_path, monkeypatch) -> None:
    """The note said 'no joint power from the bag' although the bag had efforts, refused
    as PWM load (P_out 71 W above P_in 53 W); it now says why. The where-the-watts-go plot
    gets the run set in its title."""
    import hexapod_energy.bag_io as bag_io
    from hexapod_energy.cli import build_parser, run
    from test_energy_cli import _write_bench, _write_robot

    _write_bench(tmp_path / 'bench')
    _write_robot(tmp_path / 'robot', 1.0)
    real = bag_io.read_robot_segments

    def with_efforts(path, **kw):
        return [dataclasses.replace(r, power_out_w=2.0 * r.power_in_w)
                for r in real(path, **kw)]
    monkeypatch.setattr(bag_io, 'read_robot_segments', with_efforts)
    seen: dict[str, Any] = {}
    real_watts = plots.watts_plot

    def watts(*a, **kw):
        seen.update(kw)
        return real_watts(*a, **kw)
    monkeypatch.setattr(plots, 'watts_plot', watts)
    doc = run(build_parser().parse_args([
        '--bench', str(tmp_path / 'bench'), '--robot', str(tmp_path / 'robot'),
        '--out', str(tmp_path / 'out'), '--no-progress']))
    r = doc['robot_runs'][0]
    assert r['power_out_source'] == 'model'
    # (the note names the model's P_out first since the energy review: 'P_out 0.3715 W from
    # the Eq. 6 model of AntBot's leg (...)')
    note = next(n for n in r['notes'] if n.startswith('P_out ') and 'from the Eq. 6 model' in n)
    assert 'no joint power from the bag' not in note
    assert 'joint efforts refused' in note and 'is not below P_in' in note
    assert 'PWM reading' in note
    assert seen['title'].startswith('AntBot robot, 2.183 kg; 1 run (robot): cycles from '
                                    '/gait/phase')
    assert seen['efficiency'] == [r['efficiency']]
