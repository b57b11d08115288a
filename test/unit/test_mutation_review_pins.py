"""Pins found missing by a mutation review of the science core: each test fails on a
one-line change that gave wrong numbers and passed the suite."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_energy.dynamics import ANTBOT_LEG_SPEC
from hexapod_energy.prediction import OutputPowerModel, predict_power_in_w
from hexapod_energy.single_leg import stance_mask
from hexapod_gait.gait import make_gait


def test_antbot_leg_constants_are_designs():
    """DESIGN section 7: DH a = 53, 83, 146 mm; link masses 14.98, 111.8, 39.23 g in the
    coxa, femur, tibia order (swapping femur and tibia kept the leg's mass and passed)."""
    assert ANTBOT_LEG_SPEC.a_m == pytest.approx((0.053, 0.083, 0.146))
    assert ANTBOT_LEG_SPEC.link_masses_kg == pytest.approx((0.01498, 0.1118, 0.03923))


def test_power_map_period_is_step_over_beta_v():
    """Fig. 7D's map at speed v walks the period T = step / (beta v) (the paper's
    v = step / (beta T)); T = step / v passed the suite at beta 0.5 only because no test
    compared the map with P_out at a known period."""
    gait = make_gait('tripod', duty_factor=0.6, step_length_m=0.1)
    opm = OutputPowerModel()
    v = 0.25
    got = float(np.asarray(opm.power_map_w(gait, [v], [0.2])).ravel()[0])
    want = opm.power_out_w(gait.with_changes(period_s=0.1 / (0.6 * v)), payload_kg=0.2)
    assert got == pytest.approx(want, rel=1e-12)


class _Phases:
    """Phase powers that depend on the load: swing 1 W/kg, stance 10 W/kg."""

    def p_stance_w(self, t, m):
        return 2.0 + 10.0 * np.asarray(m, float) + 0 * np.asarray(t, float)

    def p_swing_w(self, t, m):
        return 1.0 + 1.0 * np.asarray(m, float) + 0 * np.asarray(t, float)


def test_swing_legs_are_unloaded_by_default():
    """Eq. 1: a swinging leg carries nothing (swing_load 'zero', the default): reading the
    swing surface at the stance legs' carried mass passed the suite."""
    gait = make_gait('tripod', duty_factor=0.5, step_length_m=0.1).with_changes(period_s=1.0)
    m_c = 2.4 / 3 - 0.1
    got = predict_power_in_w(_Phases(), gait, total_mass_kg=2.4, leg_mass_kg=0.1)
    assert got == pytest.approx(3 * (2.0 + 10.0 * m_c) + 3 * 1.0, rel=1e-12)
    carried = predict_power_in_w(_Phases(), gait, total_mass_kg=2.4, leg_mass_kg=0.1,
                                 swing_load='carried')
    assert carried == pytest.approx(3 * (2.0 + 10.0 * m_c) + 3 * (1.0 + m_c), rel=1e-12)


def test_contact_needs_the_tip_down_as_well_as_the_force():
    """The paper's split: force above the threshold AND the tip near the ground. A force
    reading held up while the tip is lifted (a load cell's slow decay) is swing."""
    z = np.concatenate([np.zeros(50), np.full(50, 0.03)])        # stance, then lifted
    fz = np.concatenate([np.full(50, 10.0), np.full(10, 10.0), np.zeros(40)])
    mask = stance_mask(fz, z, force_threshold_n=5.0)
    assert mask[:50].all()
    assert not mask[50:].any()


class _PhasesWithBasal(_Phases):
    def basal_power_at_w(self, m):
        return 1.5 + 5.0 * float(m)


def test_holding_power_of_swinging_legs_is_unloaded():
    """where_the_watts_go's holding part: stance legs hold their carried mass, swinging legs
    nothing (the swing legs' holding at the carried mass passed the suite)."""
    from hexapod_energy.prediction import power_breakdown_w

    gait = make_gait('tripod', duty_factor=0.5, step_length_m=0.1).with_changes(period_s=1.0)
    m_c = 2.4 / 3 - 0.1
    out = power_breakdown_w(_PhasesWithBasal(), gait, total_mass_kg=2.4, leg_mass_kg=0.1)
    assert out['holding_w'] == pytest.approx(3 * (1.5 + 5.0 * m_c) + 3 * 1.5, rel=1e-12)
    assert out['stance_w'] + out['swing_w'] == pytest.approx(out['predicted_w'], rel=1e-12)


def test_phase_powers_at_another_duty_factor():
    """At beta 0.6 (the suite walked 0.5 only, where beta and 1 - beta are one number): each
    phase's energy over its own nominal duration, and T_stance = beta T."""
    from hexapod_energy.single_leg import phase_powers

    t = np.arange(0, 10.0, 0.001)                      # 1 Hz, 10 cycles
    stance = (t % 1.0) < 0.6
    power = np.where(stance, 8.0, 3.0)
    s = phase_powers(t, power, t, stance, session_id='s', load_kg=0.1, frequency_hz=1.0,
                     duty_factor=0.6)
    assert s.t_stance_s == pytest.approx(0.6) and s.t_swing_s == pytest.approx(0.4)
    assert s.p_stance_w == pytest.approx(8.0, rel=1e-3)   # 1 ms samples
    assert s.p_swing_w == pytest.approx(3.0, rel=1e-3)


def test_lowess_is_a_tricube_weighted_local_plane_over_its_span():
    """Lowess2D against the definition (Cleveland: the span's nearest points, tricube
    weights, a weighted least-squares plane), evaluated by hand at a few points (a linear
    weight and an ignored span both passed the suite)."""
    from hexapod_energy.single_leg import Lowess2D

    rng = np.random.default_rng(4)
    x = rng.uniform(0, 1, (40, 2))
    y = np.sin(3 * x[:, 0]) + x[:, 1] ** 2
    model = Lowess2D(span=0.4).fit(x, y)
    scale = np.ptp(x, axis=0)
    k = int(np.ceil(0.4 * len(x)))
    for q in ([0.2, 0.3], [0.7, 0.8], [0.5, 0.1]):
        d = np.linalg.norm((x - q) / scale, axis=1)
        h = np.sort(d)[k - 1] * 1.0001 + 1e-12
        w = np.clip(1 - (d / h) ** 3, 0, None) ** 3
        design = np.column_stack([np.ones(len(x)), x / scale])
        coef = np.linalg.solve(design.T @ (w[:, None] * design), design.T @ (w * y))
        want = coef[0] + coef[1:] @ (np.asarray(q) / scale)
        assert float(model.predict(np.array([q]))[0]) == pytest.approx(want, rel=1e-6)


class _Memoriser:
    """A surface that returns the training value nearest the query (zero training error)."""

    def fit(self, x, y):
        self.x, self.y = np.asarray(x, float), np.asarray(y, float)
        return self

    def predict(self, x):
        d = np.linalg.norm(np.asarray(x, float)[:, None, :] - self.x[None], axis=2)
        return self.y[np.argmin(d, axis=1)]


def test_cross_validation_never_predicts_a_point_it_trained_on():
    """On pure noise a memorising surface has no skill: its cross-validated RMSE is about the
    noise's (sqrt 2 times), not 0. Training on the test points too (a mutation review: it
    passed the suite) would make the LOWESS/polynomial choice prefer overfitting."""
    from hexapod_energy.single_leg import cross_validated_rmse

    rng = np.random.default_rng(1)
    x = rng.uniform(0, 1, (60, 2))
    y = rng.normal(0, 1.0, 60)
    assert cross_validated_rmse(_Memoriser, x, y, folds=5) > 0.8


def test_basal_power_is_interpolated_over_load():
    """The 0 Hz sessions' basal power at a load between two of them is interpolated (their
    mean passed the suite)."""
    from hexapod_energy.single_leg import SingleLegModel

    model = SingleLegModel()
    model.basal_power_w_ = {0.0: 2.0, 0.1: 2.2, 0.5: 3.0}
    assert model.basal_power_at_w(0.3) == pytest.approx(2.6, rel=1e-12)
    assert model.basal_power_at_w(0.05) == pytest.approx(2.1, rel=1e-12)


def _table(y):
    """A residual window table of three runs with ``y`` as measured minus predicted [W]."""
    from hexapod_energy.effects_catalogue import WindowTable

    n = y.size
    tsum = np.full(n, 18 * 30.0)
    return WindowTable(
        run=np.repeat(np.arange(3), n // 3), t_s=np.tile(np.arange(n // 3) * 0.5, 3),
        duration_s=np.full(n, 0.5), measured_w=30.0 + y, predicted_w=np.full(n, 30.0),
        step_frequency_hz=np.repeat([1.0, 1.4, 1.8], n // 3), speed_mps=np.full(n, 0.2),
        current_sq_a2=np.ones(n), temp_excess_k=tsum - 18 * 28.0,
        stance_fraction=np.full((n, 6), 0.5), leg_names=tuple('ABCDEF'),
        extra={'temp_sum_c': tsum, 'servo_count': np.full(n, 18.0), 'temp_coldest_c': 30.0,
               'temp_bench_c': 28.0})


def test_residual_effect_standard_error_is_the_least_squares_one():
    """A basal power of 3 W under 0.5 W of white noise: its standard error is sigma /
    sqrt(n_train) (halving it passed the suite: every effect would have looked twice as
    certain)."""
    from hexapod_energy import residuals as R
    from hexapod_energy.effects_catalogue import BasalPower

    rng = np.random.default_rng(7)
    y = 3.0 + rng.normal(0.0, 0.5, 600)
    table = _table(y)
    held = R.split_mask(table)
    coef, se, *_ = R.EffectSelection()._fit([BasalPower()], table, ~held)
    n_train = int((~held).sum())
    assert coef[0] == pytest.approx(3.0, abs=0.1)
    assert se[0] == pytest.approx(0.5 / np.sqrt(n_train), rel=0.1)


def test_residual_selection_uses_the_bayesian_information_criterion():
    """BIC = n ln(SSE / n) + k ln n (AIC's 2k in its place passed the suite)."""
    from hexapod_energy.residuals import _bic

    assert _bic(12.0, 100, 3) == pytest.approx(100 * np.log(0.12) + 3 * np.log(100),
                                               rel=1e-12)
