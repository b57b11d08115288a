"""Gait scheduler core after outside review B (F2 stand timing, F3 transitions that lifted a
side, F6 messages)."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_gait.config import check_static_support, min_supporting_per_side
from hexapod_gait.errors import HexapodGaitError, InfeasibleGaitError
from hexapod_gait.gait import make_gait
from hexapod_gait.gait_node import GaitParams, gait_from_params
from hexapod_gait.scheduler import GaitScheduler, side_support_ok
from hexapod_common.node_utils import validate_params


# ------------------------------------------------------------------ F2: a stand is not timed
@pytest.mark.parametrize('legs', [6, 8, 10, 12])
def test_a_wave_walked_by_speed_can_stand_at_its_walking_period(legs):
    """The stand was checked against the 0.16 s minimum swing at ``period`` 1 s (swing 1/n s):
    8, 10 and 12 legs could not stand (nor stop on Ctrl-C)."""
    beta = 1 - 1 / legs
    walk = gait_from_params(GaitParams(gait='wave', leg_count=legs, duty_factor=beta,
                                       speed=0.05))
    stand = gait_from_params(GaitParams(gait='wave', leg_count=legs, duty_factor=beta,
                                        speed=0.05, stand=True))
    assert stand.step_length_m == 0.0 and stand.step_height_m == 0.0
    assert stand.period_s == walk.period_s           # the stop changes the step, not the timing
    assert stand.duty_factor == walk.duty_factor
    assert stand.phase_offsets == walk.phase_offsets


def test_a_stand_whose_walking_speed_is_out_of_reach_keeps_the_period():
    stand = gait_from_params(GaitParams(gait='wave', leg_count=8, duty_factor=0.875, speed=0.6,
                                        period=1.5, stand=True))
    assert stand.period_s == 1.5 and stand.step_length_m == 0.0
    with pytest.raises(HexapodGaitError):                              # walking it is refused
        gait_from_params(GaitParams(gait='wave', leg_count=8, duty_factor=0.875, speed=0.6))


# ------------------------------------------------------------------ F3: transitions keep support
def _lifted_s(sched: GaitScheduler, t0: float, t1: float, dt: float = 0.004) -> float:
    """Time with every leg of one side in swing, from the scheduler's own states."""
    sides = np.array([name[0] for name in sched.leg_names])
    lifted = 0.0
    for t in np.arange(t0, t1, dt):
        st = sched.state(t)
        if min(int(st.in_stance[sides == s].sum()) for s in ('L', 'R')) == 0:
            lifted += dt
    return lifted


CASES = [
    # (legs, gait A, beta A, gait B, beta B, speed): the review's cases (transition_scan.py)
    (4, 'alternating', 0.5, 'wave', 0.75, 0.1),
    (4, 'alternating', 0.6, 'wave', 0.75, 0.05),
    (6, 'tetrapod', 0.5, 'alternating', 0.5, 0.05),
    (6, 'alternating', 0.5, 'wave', 0.75, 0.1),
]


@pytest.mark.parametrize('legs, ga, ba, gb, bb, speed', CASES)
@pytest.mark.parametrize('cycles', [1.0, 4.0])
def test_a_transition_between_supported_gaits_never_lifts_a_side(legs, ga, ba, gb, bb, speed,
                                                                 cycles):
    """Before: 4 legs alternating 0.5 -> wave 0.75 lifted a side 0.44 s (1 cycle), 1.7 s (4)."""
    a = gait_from_params(GaitParams(gait=ga, leg_count=legs, duty_factor=ba, speed=speed))
    b = gait_from_params(GaitParams(gait=gb, leg_count=legs, duty_factor=bb, speed=speed))
    for t_switch in (2.0, 2.0 + 0.37 * a.period_s):
        sched = GaitScheduler(a, 0.0, leg_count=legs, transition_cycles=cycles)
        sched.set_gait(b, t_switch)
        end = sched.transition_end_s
        assert _lifted_s(sched, t_switch, end + b.period_s) == 0.0
        # every schedule commanded on the way passes the live rule (exact per side)
        for t in np.linspace(t_switch, end, 201):
            assert min(min_supporting_per_side(sched.state(t).gait).values()) >= 1
        # and the target is reached, phase-continuously
        assert np.allclose(sched.state(end).gait.phase_offsets, b.phase_offsets)
        assert sched.state(end + 1e-9).gait == b
        t = np.arange(t_switch - 0.1, end + 0.1, 0.001)
        _, phi = sched.leg_phases(t)
        jump = np.abs(np.mod(np.diff(phi, axis=0) + 0.5, 1.0) - 0.5)
        assert jump.max() < 0.01


def test_a_safe_transition_keeps_the_plain_ramp():
    """Tripod -> wave on 6 legs was safe: same duration and schedule as before the fix."""
    tripod = make_gait('tripod', period_s=1.0)
    wave = make_gait('wave', duty_factor=5 / 6, period_s=1.0)
    sched = GaitScheduler(tripod)
    sched.set_gait(wave, 1.0)
    assert sched.transition_end_s == 2.0
    mid = sched.state(1.5).gait
    assert mid.duty_factor == pytest.approx(0.5 + (5 / 6 - 0.5) * 0.5)


def test_a_staged_transition_raises_the_duty_factor_before_moving_the_offsets():
    a = gait_from_params(GaitParams(gait='alternating', leg_count=6, duty_factor=0.5,
                                    speed=0.1))
    b = gait_from_params(GaitParams(gait='wave', leg_count=6, duty_factor=0.75, speed=0.1))
    sched = GaitScheduler(a, 0.0, leg_count=6)
    sched.set_gait(b, 1.0)
    s1 = 1.0 + (sched.transition_end_s - 1.0) / 2      # two stages: raise, then move
    first = sched.state(s1 - 1e-6).gait
    assert first.duty_factor == pytest.approx(0.75, abs=1e-6)
    assert np.allclose(first.phase_offsets, a.phase_offsets)
    assert sched.state(sched.transition_end_s + 1e-9).gait == b


def test_a_transition_that_must_lift_a_side_is_refused_and_nothing_changes():
    """Two legs of a side that have to cross each other: every path puts them in phase."""
    names = ('L1', 'L2', 'R1', 'R2')
    a = make_gait('custom', leg_count=4, duty_factor=0.75, period_s=1.0,
                  phase_offsets=(0.0, 0.5, 0.0, 0.5))
    b = a.with_changes(phase_offsets=(0.4, 0.1, 0.4, 0.1))
    assert a.leg_names == names
    check_static_support(a)
    check_static_support(b)
    sched = GaitScheduler(a, 0.0, leg_count=4)
    with pytest.raises(InfeasibleGaitError, match='lift every leg of one side'):
        sched.set_gait(b, 1.0)
    assert sched.target == a and sched.state(1.5).gait == a


def test_side_support_ok_is_exact_on_touching_stance_intervals():
    wave4 = make_gait('wave', leg_count=4, duty_factor=0.75)      # stance arcs just touch
    sides = [n[0] for n in wave4.leg_names]
    theta = np.array([wave4.phase_offsets])
    assert side_support_ok(theta, [0.75], sides).tolist() == [True]
    assert side_support_ok(theta, [0.74], sides).tolist() == [False]


def test_gaits_that_already_lift_a_side_ramp_as_before():
    """Offline use (the wave at 0.5 is computable offline): no rule to keep, no refusal."""
    a = make_gait('wave', duty_factor=0.5, period_s=1.0)
    b = make_gait('tripod', period_s=1.0)
    sched = GaitScheduler(a)
    sched.set_gait(b, 1.0)
    assert sched.transition_end_s == 2.0


# ------------------------------------------------------------------ F6: messages
@pytest.mark.parametrize('legs', [0, -2, 5])
def test_leg_count_message_names_both_rules(legs):
    with pytest.raises(Exception, match='must be even and >= 2'):
        validate_params(GaitParams, {'leg_count': legs})


def test_a_flight_phase_is_named_with_the_duty_factor_it_needs():
    with pytest.raises(HexapodGaitError) as err:
        gait_from_params(GaitParams(gait='alternating', leg_count=8, duty_factor=0.3))
    msg = str(err.value)
    assert 'flight phase' in msg and 'no leg on the ground for 40 %' in msg
    assert '>= 0.5 on 8 legs' in msg and '0.875' not in msg


def test_a_lost_side_names_the_duty_factor_this_gait_needs():
    with pytest.raises(HexapodGaitError) as err:
        gait_from_params(GaitParams(gait='wave', leg_count=8, duty_factor=0.5))
    msg = str(err.value)
    assert 'lifts every leg of side' in msg and 'flight' not in msg
    # the smallest duty factor that keeps a leg down on each side, exact
    assert '>= 0.625' in msg and '1 - 1/n = 0.875' in msg
    check_static_support(make_gait('wave', leg_count=8, duty_factor=0.625))
    with pytest.raises(InfeasibleGaitError):
        check_static_support(make_gait('wave', leg_count=8, duty_factor=0.62))
