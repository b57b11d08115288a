"""Gait from the node's flat parameter set: speed picks the period, refusals give reasons."""

from __future__ import annotations

import pytest
from numpy.testing import assert_allclose

from hexapod_gait.buehler import BUEHLER_PRESETS, BuehlerClock
from hexapod_gait.config import build_gait, check_reachable
from hexapod_gait.errors import InfeasibleGaitError, InvalidGaitError, UnreachableError
from hexapod_gait.gait import make_gait


def test_speed_chooses_the_period():
    g = build_gait('tripod', duty_factor=0.6, step_length_m=0.1, speed_mps=0.4)
    assert_allclose(g.period_s, 0.1 / (0.6 * 0.4))
    assert_allclose(g.speed_mps, 0.4)


def test_refusals_name_the_reason():
    with pytest.raises(InfeasibleGaitError, match='maximum speed is 0.6 m/s'):
        build_gait('tripod', speed_mps=0.7)
    with pytest.raises(InfeasibleGaitError, match='step frequency'):
        build_gait('wave', duty_factor=0.5, period_s=0.25)
    with pytest.raises(UnreachableError, match='step length 0.4 m'):
        build_gait('tripod', step_length_m=0.4, period_s=2.0)
    with pytest.raises(InvalidGaitError, match='preset'):
        build_gait('tripod', preset='walk')
    with pytest.raises(InvalidGaitError, match='preset must be one of'):
        build_gait('buehler', preset='sprint')


def test_buehler_from_parameters_and_presets():
    assert build_gait('buehler', preset='jogging') == BUEHLER_PRESETS['jogging']
    c = build_gait('buehler', period_s=0.5, duty_factor=0.4, sweep_angle_rad=0.9,
                   leg_offset_rad=0.1)
    assert c == BuehlerClock(period_s=0.5, duty_factor=0.4, sweep_angle_rad=0.9,
                             leg_offset_rad=0.1)


def test_paper_gaits_are_reachable_for_antbot():
    for beta in (0.3, 0.5, 0.7, 5 / 6):
        for step in (0.04, 0.10, 0.14):
            check_reachable(make_gait('tripod', duty_factor=beta, step_length_m=step))
