"""Single-leg method: stream alignment, phase split, phase powers, surface fits."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_energy.errors import FitError, InvalidInputError, NotFittedError
from hexapod_energy.single_leg import (
    Lowess2D,
    PhaseSample,
    PolySurface,
    SingleLegModel,
    align_offset_s,
    cross_validated_rmse,
    phase_powers,
    stance_mask,
)


def _walk(t: np.ndarray, freq_hz: float, beta: float = 0.5):
    """Ideal bench signals: stance while cycle phase < beta; force 5 N, tip lifted 40 mm."""
    phase = (t * freq_hz) % 1.0
    stance = phase < beta
    swing_phase = np.clip((phase - beta) / (1 - beta), 0, 1)
    z = np.where(stance, 0.0, 0.04 * np.sin(np.pi * swing_phase))
    force = np.where(stance, 5.0, 0.0)
    return stance, force, z


def test_align_recovers_known_offset() -> None:
    rng = np.random.default_rng(1)
    t_tip = np.arange(0, 20, 1 / 120)  # 120 Hz mocap
    t_true = np.arange(0, 20, 1 / 500)  # 500 Hz force
    _, force, _ = _walk(t_true, 1.3)
    _, _, z = _walk(t_tip, 1.3)
    offset = 0.037
    t_force_stamped = t_true - offset  # force clock lags: stamps early by 37 ms
    est = align_offset_s(t_force_stamped, force + rng.normal(0, 0.2, t_true.shape), t_tip, z)
    assert abs(est - offset) < 0.003


def test_align_rejects_short_streams() -> None:
    with pytest.raises(InvalidInputError, match='overlap'):
        align_offset_s([0, 0.1, 0.2, 0.3], [1, 2, 3, 4], [0, 0.1, 0.2, 0.3], [1, 2, 3, 4])


def test_stance_mask_matches_truth() -> None:
    t = np.arange(0, 10, 0.002)
    truth, force, z = _walk(t, 2.0, 0.6)
    mask = stance_mask(force, z)
    assert np.mean(mask == truth) > 0.999


def test_phase_powers_levels_and_basal() -> None:
    t = np.arange(0, 10, 0.01)
    stance, _, _ = _walk(t, 1.0)
    power = np.where(stance, 7.0, 4.0)
    s = phase_powers(t, power, t, stance, session_id='a', load_kg=0.1, frequency_hz=1.0,
                     duty_factor=0.5)
    assert_allclose([s.p_stance_w, s.p_swing_w, s.t_stance_s], [7.0, 4.0, 0.5])
    b = phase_powers(t, np.full_like(t, 3.0), t, stance, session_id='b', load_kg=0.1,
                     frequency_hz=0.0, duty_factor=0.5)
    assert b.p_stance_w == b.p_swing_w == 3.0 and np.isinf(b.t_stance_s)


def _truth(rate_hz, load_kg):
    return 1.8 + 0.35 * rate_hz + 0.06 * rate_hz**2 + 2.5 * load_kg + 0.4 * load_kg * rate_hz


def _plan(noise_w: float = 0.0, seed: int = 0) -> list[PhaseSample]:
    rng = np.random.default_rng(seed)
    out = []
    for load in (0.0, 0.095, 0.141, 0.187, 0.515):
        for f in (0.0, 0.4, 0.8, 1.2, 1.6, 2.0, 2.5, 3.0):
            rate = 2 * f  # beta 0.5 -> 1 / T_phase = 2 f
            p_st = _truth(rate, load) + rng.normal(0, noise_w)
            p_sw = _truth(rate, 0.2 * load) + rng.normal(0, noise_w)
            t_ph = np.inf if f == 0 else 0.5 / f
            if f == 0:
                p_sw = p_st
            out.append(PhaseSample(f'{load}-{f}', load, f, 0.5, t_ph, t_ph, p_st, p_sw,
                                   0.5 * (p_st + p_sw), 0.5, 100))
    return out


def test_surface_fit_recovers_truth_and_picks_by_cv() -> None:
    model = SingleLegModel().fit(_plan())
    # an exact polynomial surface: the polynomial has zero CV error and must be chosen
    assert model.chosen_ == {'stance': 'poly', 'swing': 'poly'}
    t_st = np.array([0.2, 0.35, 0.7])
    load = np.array([0.05, 0.3, 0.4])
    assert_allclose(model.p_stance_w(t_st, load), _truth(1 / t_st, load), rtol=1e-9)
    assert model.basal_power_w_[0.515] == pytest.approx(_truth(0.0, 0.515))
    assert model.cv_rmse_w_['stance']['poly'] < model.cv_rmse_w_['stance']['lowess']


def test_lowess_wins_on_a_shape_the_polynomial_lacks() -> None:
    rng = np.random.default_rng(3)
    x = np.stack([rng.uniform(0, 6, 60), rng.uniform(0, 0.5, 60)], axis=1)
    y = 3 + 4 * np.tanh(2 * (x[:, 0] - 3)) + 2 * x[:, 1]
    cv_lo = cross_validated_rmse(lambda: Lowess2D(0.3), x, y)
    cv_po = cross_validated_rmse(PolySurface, x, y)
    assert cv_lo < cv_po


def test_lowess_reproduces_a_plane_exactly() -> None:
    rng = np.random.default_rng(2)
    x = rng.uniform(0, 1, size=(30, 2))
    y = 2.0 + 3.0 * x[:, 0] - 1.5 * x[:, 1]
    pred = Lowess2D(0.8).fit(x, y).predict([[0.3, 0.7], [1.2, -0.1]])
    assert_allclose(pred, [2.0 + 0.9 - 1.05, 2.0 + 3.6 + 0.15], rtol=1e-8)


def test_noisy_fit_error_is_reported() -> None:
    model = SingleLegModel().fit(_plan(noise_w=0.1, seed=5))
    assert 0.03 < model.fit_rmse_w_['stance'] < 0.2
    assert set(model.summary()) >= {'chosen', 'cv_rmse_w', 'fit_rmse_w', 'basal_power_w'}


def test_errors() -> None:
    with pytest.raises(NotFittedError):
        SingleLegModel().p_stance_w(0.3, 0.1)
    with pytest.raises(FitError, match='>= 5 walking sessions'):
        SingleLegModel().fit(_plan()[:3])
    with pytest.raises(InvalidInputError, match='span'):
        Lowess2D(0.0)


def test_domain_is_the_sessions_range_and_outside_is_named() -> None:
    """Walking sessions 0.4-3 Hz at beta 0.5 (phases 0.167-1.25 s), loads 0-0.515 kg: a
    prediction inside reads no reason, a slower stance, a faster swing or a heavier load each
    name the quantity and the bench's range."""
    model = SingleLegModel().fit(_plan())
    assert model.domain_['stance'] == {'rate_hz': (0.8, 6.0), 'load_kg': (0.0, 0.515)}
    assert model.outside_domain('stance', 0.5, 0.3) == []
    assert model.outside_domain('stance', 1.35, 0.3) == []       # within 10 % of 1.25 s
    [slow] = model.outside_domain('stance', 2.0, 0.3)
    assert slow.startswith('stance 2 s outside') and '0.167-1.25 s' in slow
    [fast] = model.outside_domain('swing', 0.1, 0.0)
    assert fast.startswith('swing 0.1 s outside')
    [heavy] = model.outside_domain('stance', 0.5, 0.8)
    assert heavy == "stance load 0.8 kg outside the bench's 0-0.515 kg"
    assert model.summary()['domain']['swing']['rate_hz'] == [0.8, 6.0]


def test_bench_domain_check_of_gaits() -> None:
    """Eq. 1 reads the stance surface at beta T and every carried load of L(t), the swing
    surface at (1 - beta) T: a tripod inside the bench's range is clean; the wave gait at
    0.05 m/s (stance 2 s) and a four-legged robot's 2-leg support (heavier legs) are not."""
    from hexapod_gait.gait import make_gait

    from hexapod_energy.prediction import bench_domain_check

    model = SingleLegModel().fit(_plan())
    tripod = make_gait('tripod', duty_factor=0.5, period_s=1.0)
    assert bench_domain_check(model, tripod, total_mass_kg=1.5, leg_mass_kg=0.166) == [[]]
    slow = bench_domain_check(model, tripod, total_mass_kg=1.5, leg_mass_kg=0.166,
                              periods_s=[1.0, 4.0])
    assert slow[0] == [] and any(r.startswith('stance 2 s') for r in slow[1])
    quad = make_gait('alternating', leg_count=4, duty_factor=0.5, period_s=1.0)
    [reasons] = bench_domain_check(model, quad, total_mass_kg=1.5, leg_mass_kg=0.166)
    assert reasons and all('load' in r for r in reasons)       # (1.5 - 0.33) / 2 = 0.58 kg

    class Analytic:   # not a fitted SingleLegModel: never flagged
        def p_stance_w(self, t, m):
            return np.ones_like(t)

    assert bench_domain_check(Analytic(), quad, total_mass_kg=1.5) == [[]]


def test_summary_holds_the_surfaces_and_the_step_geometry() -> None:
    """An outside review: energy.json's bench fit held no surface coefficients, so Eq. 1
    could not be re-evaluated from it; the chosen surfaces are in the summary now, with the
    regressors' names, and the tip path the sessions walked (None when not recorded)."""
    import dataclasses

    model = SingleLegModel().fit(_plan())
    surf = model.summary()['surfaces']
    assert surf['stance']['kind'] == 'poly'
    t_st, load = np.array([0.2, 0.7]), np.array([0.05, 0.4])
    terms = {'1': 1.0, 'f': 1 / t_st, 'f^2': 1 / t_st ** 2, 'm': load, 'm f': load / t_st}
    again = sum(c * terms[n] for c, n in zip(surf['stance']['coef'], surf['stance']['terms']))
    assert_allclose(again, model.p_stance_w(t_st, load), rtol=1e-12)
    assert model.summary()['step_geometry_m'] is None
    walked = [dataclasses.replace(s, step_length_m=0.1, step_height_m=0.04) for s in _plan()]
    assert SingleLegModel().fit(walked).summary()['step_geometry_m'] == \
        {'step_length': 0.1, 'step_height': 0.04}
    mixed = [dataclasses.replace(s, step_length_m=0.1 + 0.04 * (k % 2), step_height_m=0.04)
             for k, s in enumerate(_plan())]
    with pytest.raises(InvalidInputError, match='different step lengths'):
        SingleLegModel().fit(mixed)
