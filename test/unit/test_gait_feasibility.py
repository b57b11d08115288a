"""Speed and feasibility under AntBot actuator limits (issue 3, item 2; paper Fig. 3A/3C)."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from hexapod_gait.errors import InvalidGaitError
from hexapod_gait.feasibility import (
    ActuatorLimits,
    InfeasibleGaitError,
    check_feasible,
    max_speed_for_gait_mps,
    max_speed_mps,
    min_period_s,
    period_for_speed,
)
from hexapod_gait.gait import make_gait


@pytest.mark.parametrize('beta, step_m, expected_mps', [
    (0.5, 0.10, 0.60),
    (0.6, 0.10, 0.42),
    (0.7, 0.10, 0.27),
    (0.83, 0.10, 0.13),
    (0.5, 0.14, 0.84),
])
def test_paper_maximum_speeds(beta, step_m, expected_mps):
    assert abs(max_speed_mps(beta, step_m) - expected_mps) <= 0.01


def test_wave_gait_maximum_speed_and_binding_limits():
    wave = make_gait('wave', duty_factor=0.83, step_length_m=0.10)
    assert abs(max_speed_for_gait_mps(wave) - 0.13) <= 0.01
    # beta 0.5: the 3 Hz cap binds (T = 1/3 s); beta 0.7: the 0.16 s swing binds
    assert_allclose(min_period_s(0.5), 1 / 3)
    assert_allclose(min_period_s(0.7), 0.16 / 0.3)
    assert_allclose(min_period_s(0.1), 0.15 / 0.1)


def test_period_for_speed_round_trip_and_refusal():
    T = period_for_speed(0.26, 0.7, 0.10)
    g = make_gait('tripod', duty_factor=0.7, period_s=T)
    assert_allclose(g.speed_mps, 0.26)
    check_feasible(g)
    with pytest.raises(InfeasibleGaitError, match=r'maximum speed is 0\.2679 m/s') as err:
        period_for_speed(0.30, 0.7, 0.10)
    assert 'minimum swing 0.16 s' in str(err.value)
    with pytest.raises(InfeasibleGaitError, match='speed_mps'):
        period_for_speed(0.0, 0.5, 0.10)


def test_exact_limit_is_feasible_and_beyond_is_refused_with_reasons():
    check_feasible(make_gait('tripod', duty_factor=0.5, period_s=1 / 3))
    with pytest.raises(InfeasibleGaitError) as err:
        check_feasible(make_gait('tripod', duty_factor=0.5, period_s=0.3))
    msg = str(err.value)
    assert 'swing lasts 0.15 s < minimum 0.16 s' in msg
    assert 'step frequency 3.333 Hz > maximum 3 Hz' in msg
    with pytest.raises(InfeasibleGaitError, match='stance lasts'):
        check_feasible(make_gait('tripod', duty_factor=0.2, period_s=0.5))


def test_custom_limits_and_validation():
    fast = ActuatorLimits(min_swing_s=0.05, min_stance_s=0.05, max_step_frequency_hz=10.0)
    assert_allclose(max_speed_mps(0.5, 0.1, fast), 0.1 / (0.5 * 0.1))
    with pytest.raises(InvalidGaitError, match='min_swing_s'):
        ActuatorLimits(min_swing_s=0.0)
    with pytest.raises(InvalidGaitError, match='duty_factor'):
        max_speed_mps(1.2, 0.1)


@settings(max_examples=200, deadline=None)
@given(beta=st.floats(0.05, 0.95), step=st.floats(0.01, 0.2), frac=st.floats(0.01, 1.0))
def test_every_speed_up_to_max_is_feasible(beta, step, frac):
    v = frac * max_speed_mps(beta, step)
    g = make_gait('alternating', duty_factor=beta, step_length_m=step,
                  period_s=period_for_speed(v, beta, step))
    check_feasible(g)
    assert_allclose(g.speed_mps, v, rtol=1e-12)
