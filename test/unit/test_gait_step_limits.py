"""Outside review: the gait node (``build_gait``) checked the actuator limits of the 100 mm
bench step whatever the step, while ``hexapod-sim robot`` and the energy side scale them to the
step's joint path: a tripod at 140 mm and 0.8 m/s (T 0.35 s) was walked live, and a 6-leg wave
at 120 mm and T 0.96 s with a 0.16 s swing where that step needs 0.172 s. Every gait builder
now reads the limits on the step's path (:mod:`hexapod_gait.step_limits`, one source)."""

from __future__ import annotations

import dataclasses

import pytest

from hexapod_gait.config import build_gait
from hexapod_gait.errors import InfeasibleGaitError
from hexapod_gait.feasibility import ANTBOT_LIMITS, ActuatorLimits, max_speed_mps
from hexapod_gait.gait import make_gait
from hexapod_gait.scheduler import GaitScheduler
from hexapod_gait.step_limits import (
    check_feasible_for_step,
    limits_for_gait,
    limits_for_step,
    step_violations,
)


def test_the_bench_step_keeps_the_limits_exactly() -> None:
    assert limits_for_step(ANTBOT_LIMITS, 0.5, 0.10, 0.04) is ANTBOT_LIMITS
    assert limits_for_step(ANTBOT_LIMITS, 0.7, 0.1004, 0.04) is ANTBOT_LIMITS   # tolerance
    assert limits_for_step(ANTBOT_LIMITS, 0.5, 0.0, 0.0) is ANTBOT_LIMITS      # a stand
    # the default gait: tripod, beta 0.5, 100 mm; 0.6 m/s at T 1/3 s as before
    g = build_gait('tripod', speed_mps=0.6)
    assert g.period_s == pytest.approx(1 / 3)
    with pytest.raises(InfeasibleGaitError, match='maximum speed is 0.6 m/s'):
        build_gait('tripod', speed_mps=0.61)
    with pytest.raises(InfeasibleGaitError, match=r'swing lasts 0.1 s < minimum 0.16 s'):
        build_gait('tripod', period_s=0.2)


def test_longer_steps_need_longer_phases_and_the_readme_top_speeds() -> None:
    l140 = limits_for_step(ANTBOT_LIMITS, 0.5, 0.14, 0.04)
    assert (l140.min_swing_s, l140.min_stance_s) == pytest.approx((0.1923, 0.2214), abs=1e-4)
    assert l140.max_step_frequency_hz == 3.0
    # README: 0.63 m/s with 140 mm steps, 0.65 with 120 mm (tripod, beta 0.5)
    assert round(max_speed_mps(0.5, 0.14, l140), 2) == 0.63
    l120 = limits_for_step(ANTBOT_LIMITS, 0.5, 0.12, 0.04)
    assert round(max_speed_mps(0.5, 0.12, l120), 2) == 0.65
    wave = limits_for_step(ANTBOT_LIMITS, 5 / 6, 0.12, 0.04)
    assert wave.min_swing_s == pytest.approx(0.1722, abs=1e-4)


def test_build_gait_refuses_the_reviewers_gaits_naming_the_step_and_what_works() -> None:
    with pytest.raises(InfeasibleGaitError) as err:
        build_gait('tripod', speed_mps=0.8, step_length_m=0.14)
    msg = str(err.value)
    assert 'maximum speed is 0.6324 m/s' in msg and '140 mm step' in msg
    assert 'swing >= 0.192 s, stance >= 0.221 s' in msg
    with pytest.raises(InfeasibleGaitError) as err:
        build_gait('tripod', period_s=0.35, step_length_m=0.14)
    msg = str(err.value)
    assert 'swing 0.175 s below the 0.192 s a 140 mm step needs' in msg
    assert 'stance 0.175 s below the 0.221 s a 140 mm step needs' in msg
    assert 'period >= 0.4428 s: top speed 0.632 m/s' in msg
    with pytest.raises(InfeasibleGaitError,
                       match='swing 0.16 s below the 0.172 s a 120 mm step needs'):
        build_gait('wave', duty_factor=5 / 6, period_s=0.96, step_length_m=0.12)
    assert build_gait('wave', duty_factor=5 / 6, period_s=1.04, step_length_m=0.12)


def test_speed_mode_picks_a_period_the_step_can_walk() -> None:
    for length, v in ((0.14, 0.6), (0.14, 0.6323), (0.12, 0.649), (0.07, 0.4)):
        g = build_gait('tripod', speed_mps=v, step_length_m=length)
        assert g.speed_mps == pytest.approx(v)
        check_feasible_for_step(g, ANTBOT_LIMITS)
    # a lift other than the bench's is named
    with pytest.raises(InfeasibleGaitError, match=r'140 mm step \(60 mm lift\) needs'):
        build_gait('tripod', period_s=0.35, step_length_m=0.14, step_height_m=0.06)
    # limits None: no check (as before)
    assert build_gait('tripod', speed_mps=0.8, step_length_m=0.14, limits=None)


def test_gait_node_sim_and_energy_read_the_same_limits() -> None:
    from types import SimpleNamespace

    from hexapod_bench_drivers.sim_cli import _infeasible
    from hexapod_energy.prediction import geometry_limits

    bench = SimpleNamespace(bench_step_=(0.10, 0.04))
    for name, beta, period, length, height in (
            ('tripod', 0.5, 0.35, 0.14, 0.04), ('tripod', 0.5, 0.45, 0.14, 0.04),
            ('wave', 5 / 6, 0.96, 0.12, 0.04), ('ripple', 0.7, 0.5, 0.07, 0.02),
            ('tripod', 0.5, 0.4, 0.12, 0.06)):
        g = make_gait(name, duty_factor=beta, period_s=period, step_length_m=length,
                      step_height_m=height)
        assert limits_for_gait(g, ANTBOT_LIMITS) == geometry_limits(bench, g, ANTBOT_LIMITS)
        node_ok = not step_violations(g, ANTBOT_LIMITS)
        assert node_ok == (not _infeasible(g, support=False)), (name, period, length)
        try:
            build_gait(name, duty_factor=beta, period_s=period, step_length_m=length,
                       step_height_m=height)
            built = True
        except InfeasibleGaitError:
            built = False
        assert built == node_ok


def test_the_scheduler_refuses_a_step_beyond_its_limits_at_run_time() -> None:
    ok = make_gait('tripod', period_s=0.5, step_length_m=0.14)
    sched = GaitScheduler(make_gait('tripod'), 0.0, limits=ActuatorLimits())
    sched.set_gait(ok, 0.0)
    with pytest.raises(InfeasibleGaitError, match='a 140 mm step needs'):
        sched.set_gait(ok.with_changes(period_s=0.35), 5.0)
    with pytest.raises(InfeasibleGaitError, match='a 140 mm step needs'):
        GaitScheduler(ok.with_changes(period_s=0.35), 0.0, limits=ActuatorLimits())


def test_the_bench_sequencer_refuses_a_session_the_gait_node_refuses() -> None:
    from hexapod_bench_drivers.sequencer import PlanError, SessionSpec, _check_gaits

    s = SessionSpec(session_id='s1', load_kg=0.0, frequency_hz=2.8, duty_factor=0.5,
                    step_length_m=0.14, step_height_m=0.04, duration_s=10.0)
    with pytest.raises(PlanError, match='a 140 mm step needs'):
        _check_gaits([s], None)
    _check_gaits([dataclasses.replace(s, frequency_hz=2.2)], None)


def test_a_stand_is_not_checked() -> None:
    from hexapod_gait.gait_node import GaitParams, gait_from_params

    p = GaitParams(stand=True, step_length=0.14, speed=0.8)
    g = gait_from_params(p)
    assert g.step_length_m == 0.0 and g.period_s == 1.0   # the walking gait is refused
    p = GaitParams(stand=True, step_length=0.14, speed=0.6)
    assert gait_from_params(p).period_s == pytest.approx(0.14 / (0.5 * 0.6))


def test_a_shorter_path_keeps_the_bench_limits():
    """A review: unfloored, a 20 mm step at beta 0.9 and T 0.333 s walked 33 ms swings
    (three commands at 100 Hz); a 10 mm step's minimal swing fell to 18 ms."""
    from hexapod_gait.config import build_gait
    from hexapod_gait.errors import HexapodGaitError
    from hexapod_gait.feasibility import ActuatorLimits
    from hexapod_gait.step_limits import limits_for_step

    lim = ActuatorLimits()
    for length, height in ((0.02, 0.0), (0.01, 0.005), (0.06, 0.01)):
        short = limits_for_step(lim, 0.75, length, height)
        assert short.min_swing_s == lim.min_swing_s
        assert short.min_stance_s == lim.min_stance_s
    with pytest.raises(HexapodGaitError, match='swing'):
        build_gait('tripod', leg_count=6, duty_factor=0.9, period_s=1 / 3,
                   step_length_m=0.02, step_height_m=0.0, limits=lim)
    longer = limits_for_step(lim, 0.5, 0.14, 0.04)
    assert longer.min_swing_s == pytest.approx(0.192, abs=1e-3)
