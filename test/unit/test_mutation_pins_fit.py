"""Pins for the per-stance SLIP fits (slip_identification.fit) found missing by a mutation
review: each test fails on a one-line change that passed the suite."""

from __future__ import annotations

import math

import numpy as np
import pytest

from slip_identification.errors import StanceRejectedError
from slip_identification.fit import SlipFitResult, SlipFitter, Stance, validate_stance
from slip_identification.synthetic import make_stance

NAMES = ('stiffness', 'rest_length', 'foot_x')
TRUE = np.array([3000.0, 0.15, 0.5])


def test_bic_is_the_gaussian_bayesian_information_criterion():
    """SlipFitResult.bic() = n log(RSS / n) + k log n (the model-comparison criterion of the
    extensions; k counts every fitted parameter). An AIC's 2 k penalises an extension
    log(n) / 2 times less (3.8 times at 2000 samples) and let it win on noise."""
    r = SlipFitResult(model='slip', estimator='nerr_nelder_mead',
                      params={'stiffness': 3000.0, 'rest_length': 0.15, 'foot_x': 0.5},
                      stderr={}, nerr=0.01, converged=True, iterations=1, evaluations=1,
                      samples=2000, touchdown_s=0.0, liftoff_s=2.0, rss=0.5)
    assert r.bic() == pytest.approx(2000 * math.log(0.5 / 2000) + 3 * math.log(2000),
                                    rel=1e-12)
    more = SlipFitResult(**{**r.__dict__, 'params': {**r.params, 'leg_damping': 1.0},
                            'rss': 0.4995})
    assert more.bic() > r.bic()          # 0.1 % less RSS does not pay for a parameter


def test_a_stance_with_non_uniform_sample_times_is_refused():
    """The fits integrate on one fixed step (t_s[1] - t_s[0] ...): a stance whose times are
    not uniform (a 1 kHz grid with a jittered sample) is refused as 'non_uniform' instead
    of being fitted on a time base it does not have."""
    good = make_stance(TRUE).stance
    validate_stance(good)
    t = good.t_s.copy()
    t[40] += 3e-4
    bad = Stance(t_s=t, state=good.state)
    with pytest.raises(StanceRejectedError, match='non_uniform'):
        validate_stance(bad)
    with pytest.raises(StanceRejectedError, match='non_uniform'):
        SlipFitter(stderr=False).fit([bad])


def test_the_first_nelder_mead_step_in_foot_x_is_7_5_mm():
    """The module's normalisation: foot_x is scaled by 0.15 m, so the Nelder-Mead initial
    simplex steps it by 7.5 mm (5 %) like l0, and xatol means 15 um on it. Stopped after the
    initial simplex (maxiter=1), the fit returns its best vertex: on a stance whose foot is
    17 mm ahead of the guess (the middle of its x range) with the guess's k and l0, the
    vertex 7.5 mm ahead. A 1 m scale made the step 5 cm (a third of a leg)."""
    s = make_stance(np.array([2000.0, 0.15, 0.5]), speed_mps=0.8, angle_rad=0.5,
                    vz_mps=-0.1).stance
    fx0 = 0.5 * (s.state[:, 0].min() + s.state[:, 0].max())
    assert 0.5 - fx0 == pytest.approx(0.0174, abs=1e-3)
    r = SlipFitter(maxiter=1, starts='paper', stderr=False).fit([s]).results_[0]
    assert (r.stiffness_npm, r.rest_length_m) == (2000.0, 0.15)
    assert r.foot_x_m - fx0 == pytest.approx(0.0075, rel=1e-9)


def _noisy_stances(n: int, block: int, sigma: float, seed: int) -> list[Stance]:
    """Exact 1 kHz stances (true TRUE) plus noise held over ``block`` samples (residuals
    correlated like states interpolated from mocap at 1 kHz / block), raw samples at that
    rate. The first state is noisy like the others (the paper's fit starts from it)."""
    base = make_stance(TRUE, speed_mps=0.8, angle_rad=0.3, vz_mps=-0.1).stance
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        e = np.repeat(rng.normal(0.0, sigma, (-(-base.n_samples // block), 4)), block,
                      axis=0)[:base.n_samples]
        state = base.state + e
        out.append(Stance(t_s=base.t_s, state=state, raw_t_s=base.t_s[::block],
                          raw_xz_m=state[::block][:, [0, 2]]))
    return out


def test_standard_errors_match_the_scatter_of_the_estimates():
    """Calibration of the paper's fit's standard errors: 60 realisations of one stance with
    1 mm noise correlated over 8 samples (states interpolated from 125 Hz mocap, 17 raw
    samples for 137 at 1 kHz), the first state as noisy as the others. The median reported
    standard error of k, l0 and foot_x is the scatter of the estimates within -20 % / +50 %
    (measured 1.02-1.25). Without the initial state's noise carried to the parameters they
    were 3-37 times too small (0.35, 0.031, 0.027): the fixed first state is the estimator's
    main error; a Jacobian twice too large gave 0.51-0.63."""
    stances = _noisy_stances(60, 8, 1e-3, seed=11)
    fits = SlipFitter(starts='paper').fit(stances).results_
    est = np.array([[r.params[k] for k in NAMES] for r in fits])
    se = np.array([[r.stderr[k] for k in NAMES] for r in fits])
    assert np.all(np.abs(np.mean(est, axis=0) - TRUE) < 0.5 * np.std(est, axis=0))
    ratio = np.median(se, axis=0) / np.std(est, axis=0, ddof=1)
    assert np.all((ratio > 0.8) & (ratio < 1.5)), ratio


def test_the_residual_variance_is_inflated_by_the_samples_per_raw_sample():
    """The 1 kHz residuals interpolated from raw samples are correlated: the residual part of
    the covariance is multiplied by (N - 1) / (n_raw - 1). On one noisy stance declared with
    raw samples at every, every 2nd and every 8th sample (inflation 1, 2, 8; the initial
    state's part unchanged), se^2 grows linearly in the inflation. Without it the three
    were equal."""
    base = _noisy_stances(1, 8, 1e-3, seed=5)[0]
    se2 = []
    for step in (1, 2, 8):
        st = Stance(t_s=base.t_s, state=base.state, raw_t_s=base.t_s[::step],
                    raw_xz_m=base.state[::step][:, [0, 2]])
        r = SlipFitter(starts='paper').fit([st]).results_[0]
        se2.append(np.array([r.stderr[k] for k in NAMES]) ** 2)
    d2, d8 = se2[1] - se2[0], se2[2] - se2[0]
    assert np.all(d2 > 1e-6 * se2[0])
    assert d8 == pytest.approx(7.0 * d2, rel=1e-4)


def test_reference_and_fast_fits_report_the_same_standard_errors():
    """The reference path (scipy Nelder-Mead on solve_ivp) and the fast path compute the
    same estimator; on stances with raw mocap samples 8 times sparser than the 1 kHz state
    they report the same standard errors (both inflated by N / n_raw, both carrying the
    initial state's noise): the reference's without the inflation were 2.9 times smaller."""
    stances = _noisy_stances(2, 8, 1e-3, seed=12)
    ref = SlipFitter(method='reference', starts='paper').fit(stances).results_
    fast = SlipFitter(starts='paper').fit(stances).results_
    for a, b in zip(ref, fast):
        for k in NAMES:
            assert a.stderr[k] == pytest.approx(b.stderr[k], rel=0.02), k
