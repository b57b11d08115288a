"""Outside review of the sweeps and their plots: the leg-count sweep's robot mass (body + its
own legs, as the authors' code) and the payload bands drawn against ``outside_bench``."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_energy.plots import four_quadrant_figure
from hexapod_energy.prediction import OutputPowerModel
from hexapod_energy.sweeps import run_standard_sweeps, standard_sweeps
from test_energy_sweeps import Phase, StubTrajectory  # the analytic phase model


@pytest.fixture(scope='module')
def opm() -> OutputPowerModel:
    return OutputPowerModel(trajectory_factory=StubTrajectory, n_samples=64)


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for lg in fig.legends for t in lg.get_texts()]


@pytest.mark.parametrize('robot_legs', [6, 4])
def test_leg_count_sweep_adds_the_legs_to_the_body(opm, robot_legs) -> None:
    """Fig. 3D: robot_mass = body + N m_leg (the authors' p4_benchDataEstimation.m); it held
    the given mass for 4, 6 and 8 legs. The given mass is the robot's with its own legs."""
    m_leg, big_m = opm.robot.leg_mass_kg, opm.robot.mass_kg
    specs = {'leg_count': standard_sweeps(robot_legs)['leg_count']}
    curves = run_standard_sweeps(Phase(), opm, sweeps=specs, n_speeds=6)['leg_count']
    body = big_m - robot_legs * m_leg
    for c in curves:
        k = c.spec.leg_count
        assert c.robot_mass_kg == pytest.approx(body + k * m_leg)
        assert_allclose(c.mass_kg, body + k * m_leg + c.payloads_kg)
        # P_out and CoT/M of the heavier (lighter) robot, not of the given one
        heavier = OutputPowerModel(
            robot=type(opm.robot)(mass_kg=body + k * m_leg, leg=opm.robot.leg),
            trajectory_factory=StubTrajectory, n_samples=64)
        from hexapod_gait.gait import make_gait
        gait = make_gait('alternating', leg_count=k, period_s=1.0)
        periods = c.spec.step_length_m / (c.spec.duty_factor * c.speeds_mps)
        assert_allclose(c.power_out_w, heavier.power_out_w(gait, payload_kg=c.payloads_kg,
                                                           periods_s=periods), rtol=1e-9)
        assert_allclose(c.cot_per_mass, (c.power_in_w - c.power_out_w)
                        / (c.mass_kg[None, :] * c.speeds_mps[:, None]))
        d = c.to_dict()
        assert d['robot_mass_kg'] == pytest.approx(body + k * m_leg)
        assert d['mass_rule'].startswith(f'body {body:.4g} kg')
        if k == robot_legs:
            assert c.robot_mass_kg == pytest.approx(big_m)   # the given mass, unchanged
    assert len({round(c.robot_mass_kg, 6) for c in curves}) == 3
    fig = four_quadrant_figure(curves)
    texts = _legend_texts(fig)
    for c in curves:
        assert any(t.startswith(f'{c.spec.label}, {c.robot_mass_kg:.4g} kg') for t in texts)
    assert f'body {body:.4g} kg' in fig._suptitle.get_text()
    import matplotlib.pyplot as plt
    plt.close(fig)


def test_other_sweeps_keep_the_given_mass(opm) -> None:
    specs = standard_sweeps(6)
    curves = run_standard_sweeps(Phase(), opm, sweeps={'duty_factor': specs['duty_factor']},
                                 n_speeds=4)['duty_factor']
    assert all(c.robot_mass_kg == pytest.approx(opm.robot.mass_kg) for c in curves)
    assert all(c.to_dict()['mass_rule'] == '' for c in curves)


def _patches(ax):
    """(hatched, solid) fill polygons of the band on ``ax``: their vertices."""
    hatched, solid = [], []
    for p in ax.patches:
        verts = p.get_path().vertices
        if p.get_hatch():
            hatched.append(verts)
        elif p.get_facecolor()[3] > 0.1:
            solid.append(verts)
    return hatched, solid


def test_payload_band_is_hatched_where_it_is_extrapolated() -> None:
    """The band was one solid shade although every tripod payload above 0 g lay outside the
    bench (``outside_bench``): the part above the last in-bench payload is now hatched."""
    import matplotlib.pyplot as plt

    from hexapod_energy.sweeps import SweepCurve, SweepSpec

    k, m = 6, 3
    v = np.linspace(0.1, 0.6, k)
    pay = np.array([0.0, 0.25, 0.5])
    p_out = 0.5 + v[:, None] * (1 + pay[None, :])
    p_in = 20.0 + 10 * v[:, None] + 5 * pay[None, :]
    mass = 2.0 + pay
    out = np.zeros((k, m), bool)
    out[3:, 1:] = True            # the payloads beyond 0 g leave the bench from the 4th speed
    curve = SweepCurve(SweepSpec('c'), v, pay, mass, p_in, p_out, p_out / p_in,
                       (p_in - p_out) / (mass * v[:, None]), p_in / (mass * 9.81 * v[:, None]),
                       out)
    fig = four_quadrant_figure([curve])
    ax4 = fig.axes[3]                                  # CoT/M vs speed
    hatched, solid = _patches(ax4)
    assert hatched and solid
    # the solid band spans the speeds where every payload is on the bench, the hatched one
    # the rest; neither reaches into the other
    assert max(vs[:, 0].max() for vs in solid) == pytest.approx(v[2])
    assert min(vs[:, 0].min() for vs in hatched) == pytest.approx(v[2])
    assert max(vs[:, 0].max() for vs in hatched) == pytest.approx(v[-1])
    assert any('extrapolated beyond the bench' in t for t in _legend_texts(fig))
    plt.close(fig)
    # all on the bench: one solid band, no hatch, no legend entry
    inside = SweepCurve(curve.spec, v, pay, mass, p_in, p_out, curve.efficiency,
                        curve.cot_per_mass, curve.specific_resistance, np.zeros((k, m), bool))
    fig = four_quadrant_figure([inside])
    hatched, solid = _patches(fig.axes[3])
    assert not hatched and len(solid) == 1
    assert not any('extrapolated beyond' in t for t in _legend_texts(fig))
    plt.close(fig)
    # the nominal payload outside too: the whole band there is hatched
    out2 = np.zeros((k, m), bool)
    out2[:2] = True
    outer = SweepCurve(curve.spec, v, pay, mass, p_in, p_out, curve.efficiency,
                       curve.cot_per_mass, curve.specific_resistance, out2)
    fig = four_quadrant_figure([outer])
    hatched, solid = _patches(fig.axes[3])
    assert max(vs[:, 0].max() for vs in hatched) == pytest.approx(v[2])
    assert min(vs[:, 0].min() for vs in solid) == pytest.approx(v[2])
    plt.close(fig)


def test_prediction_plot_rings_extrapolated_runs() -> None:
    import matplotlib.pyplot as plt

    from hexapod_energy.plots import prediction_figure

    fig = prediction_figure([0.1, 0.3, 0.9], [20.0, 30.0, 90.0], [21.0, 29.0, 70.0],
                            labels=['a', 'b', 'c'], outside=[False, False, True])
    ax = fig.axes[0]
    texts = [t.get_text() for t in ax.get_legend().get_texts()]
    assert 'Eq. 1 extrapolated beyond the bench' in texts
    rings = [c for c in ax.collections if c.get_label() == 'Eq. 1 extrapolated beyond the bench']
    assert len(rings) == 1 and rings[0].get_offsets().tolist() == [[90.0, 70.0]]
    plt.close(fig)
    fig = prediction_figure([0.1], [20.0], [21.0])
    assert not any('extrapolated' in t.get_text() for t in fig.axes[0].get_legend().get_texts())
    plt.close(fig)
