"""Sweeps, four-quadrant plots and the gait recommendation on an analytic phase-power model."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_energy.errors import InvalidInputError
from hexapod_energy.plots import four_quadrant_plot, power_map_plot
from hexapod_energy.prediction import OutputPowerModel
from hexapod_energy.recommend import recommend_gait
from hexapod_energy.sweeps import STANDARD_SWEEPS, SweepSpec, run_standard_sweeps, sweep_curve


class Phase:
    """Basal 1.9 W per leg plus rate- and load-dependent parts."""

    def p_stance_w(self, t, m):
        f = 1 / np.asarray(t)
        return 1.9 + 0.45 * f + 0.05 * f**2 + 2.0 * np.asarray(m) * (1 + 0.2 * f)

    def p_swing_w(self, t, m):
        f = 1 / np.asarray(t)
        return 1.9 + 0.5 * f + 0.06 * f**2 + 0 * np.asarray(m)


class StubTrajectory:
    def __init__(self, gait, leg_index, **_kw):
        self.s = gait.step_length_m / 0.1

    def joints(self, t):
        t = np.asarray(t, float)[:, None]
        w = 2 * np.pi
        a = np.array([0.3, 0.25, -0.35]) * self.s
        q0 = np.array([0.0, 0.3, -1.6])
        return q0 + a * np.sin(w * t), a * w * np.cos(w * t), -a * w**2 * np.sin(w * t)


@pytest.fixture(scope='module')
def opm() -> OutputPowerModel:
    return OutputPowerModel(trajectory_factory=StubTrajectory, n_samples=64)


def test_curve_descriptors_consistent(opm) -> None:
    curve = sweep_curve(SweepSpec('t', 'tripod', 6, 0.5), Phase(), opm, n_speeds=10)
    assert_allclose(curve.speeds_mps[-1], 0.6, atol=1e-9)  # AntBot limits, beta 0.5, 100 mm
    m = curve.mass_kg[None, :]
    v = curve.speeds_mps[:, None]
    assert_allclose(curve.cot_per_mass, (curve.power_in_w - curve.power_out_w) / (m * v))
    assert_allclose(curve.efficiency, curve.power_out_w / curve.power_in_w)
    pts = curve.optimal_points()
    assert pts['min_cot_per_mass']['speed_mps'] == pytest.approx(0.6)
    assert curve.min_efficiency == pytest.approx(np.min(curve.efficiency))


def test_standard_sweeps_and_plots(opm, tmp_path) -> None:
    curves = run_standard_sweeps(Phase(), opm, n_speeds=8)
    assert set(curves) == set(STANDARD_SWEEPS)
    wave = curves['gait_type'][1]
    assert_allclose(wave.speeds_mps[-1], 0.1 / (0.83 * 0.16 / 0.17), rtol=1e-6)
    paths = four_quadrant_plot(curves['leg_count'], tmp_path / 'legs')
    assert [p.suffix for p in paths] == ['.png', '.svg']
    assert all(p.stat().st_size > 5000 for p in paths)
    pm = opm.power_map_w(wave_gait(), np.linspace(0.1, 0.6, 5), np.linspace(0, 0.5, 4))
    assert all(p.exists() for p in power_map_plot(np.linspace(0.1, 0.6, 5),
                                                 np.linspace(0, 0.5, 4), pm, tmp_path / 'pm'))


def wave_gait():
    from hexapod_gait.gait import make_gait
    return make_gait('tripod', duty_factor=0.5)


def test_recommendation_beats_or_equals_default(opm) -> None:
    rec = recommend_gait(Phase(), opm, speed_mps=0.26, payload_kg=0.2,
                         gaits=('alternating', 'wave'), step_lengths_m=(0.08, 0.10, 0.12))
    assert rec.default is not None
    assert rec.best.specific_cost_of_transport <= rec.default.specific_cost_of_transport
    assert rec.saving_fraction is not None and rec.saving_fraction >= 0
    assert rec.best.period_s * rec.best.duty_factor * 0.26 == pytest.approx(
        rec.best.step_length_m)


def test_recommendation_names_the_six_leg_alternating_gait_tripod(opm) -> None:
    """One gait, one name: the candidates' 'alternating' on 6 legs is the default's 'tripod'
    (an outside review: "alternating beta 0.50 ... (default tripod beta 0.5)")."""
    rec = recommend_gait(Phase(), opm, speed_mps=0.26, gaits=('alternating',),
                         duty_factors=(0.5,), step_lengths_m=(0.10,))
    assert rec.best.gait == rec.default.gait == 'tripod'
    assert rec.best.specific_cost_of_transport == pytest.approx(
        rec.default.specific_cost_of_transport)


def test_recommendation_refuses_unreachable_speed(opm) -> None:
    with pytest.raises(InvalidInputError, match='no feasible gait'):
        recommend_gait(Phase(), opm, speed_mps=5.0, gaits=('alternating',))


@pytest.fixture(scope='module')
def bench_model():
    """The analytic phase powers measured on a bench at 1-3 Hz (phases 0.167-0.5 s), loads
    0-0.6 kg: a fitted SingleLegModel that knows its sessions' range."""
    from hexapod_energy.single_leg import PhaseSample, SingleLegModel

    ph, rows = Phase(), []
    for load in (0.0, 0.2, 0.4, 0.6):
        for f in (0.0, 1.0, 1.5, 2.0, 2.5, 3.0):
            t = np.inf if f == 0 else 0.5 / f
            p_st = float(ph.p_stance_w(t if f else 1e9, load))
            p_sw = float(ph.p_swing_w(t if f else 1e9, 0.0))
            rows.append(PhaseSample(f'{load}-{f}', load, f, 0.5, t, t, p_st, p_sw,
                                    0.5 * (p_st + p_sw), 0.5, 100))
    return SingleLegModel().fit(rows)


def test_sweep_points_outside_the_bench_are_flagged_and_drawn(opm, bench_model,
                                                               tmp_path) -> None:
    curve = sweep_curve(SweepSpec('t', 'tripod', 6, 0.5), bench_model, opm, n_speeds=12,
                        payloads_kg=(0.0, 0.5), load_offset_kg=0.166)
    t_stance = 0.1 / curve.speeds_mps
    # bench stances 0.167-0.5 s; outside beyond 10 % of the longest: T above 0.55 s
    slow = 1.0 / t_stance < 2.0 / 1.1
    assert curve.outside_bench[:, 0].tolist() == slow.tolist()
    assert slow[0] and not slow[-1]
    assert any(r.startswith('stance ') for r in curve.outside_reasons)
    d = curve.to_dict()
    assert d['outside_bench'] == curve.outside_bench.tolist()
    assert 'outside_bench' in d['optimal_points']['min_cot_per_mass']
    paths = four_quadrant_plot([curve], tmp_path / 'fq')
    assert all(p.stat().st_size > 5000 for p in paths)


def test_recommendation_stays_inside_the_bench(opm, bench_model) -> None:
    """At 0.15 m/s only configurations whose phases the bench measured compete (the others'
    P_in is an extrapolation); at 0.05 m/s none is measured: the best is returned with a note
    saying it is an extrapolation."""
    rec = recommend_gait(bench_model, opm, speed_mps=0.15, payload_kg=0.2,
                         gaits=('alternating', 'wave'), load_offset_kg=0.166)
    assert rec.best.outside_bench == ()
    assert rec.outside_bench > 0 and 'were not considered' in rec.note
    assert rec.to_dict()['outside_bench'] == rec.outside_bench
    slow = recommend_gait(bench_model, opm, speed_mps=0.05, gaits=('alternating',),
                          step_lengths_m=(0.1,), load_offset_kg=0.166)
    assert slow.best.outside_bench and 'extrapolation' in slow.note
