"""Phase-continuous gait changes while walking (issue 3, item 6)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from hexapod_gait.buehler import BUEHLER_PRESETS
from hexapod_gait.errors import InfeasibleGaitError, InvalidGaitError
from hexapod_gait.feasibility import ActuatorLimits
from hexapod_gait.gait import make_gait
from hexapod_gait.scheduler import GaitScheduler, smoothstep
from hexapod_gait.trajectory import LegTrajectory

TICK_S = 0.01  # 100 Hz commands


def max_tick_move_m(sched: GaitScheduler, t: np.ndarray) -> float:
    p = sched.tip_targets(t)
    return float(np.linalg.norm(np.diff(p, axis=0), axis=2).max())


def test_steady_scheduler_reproduces_core_gait_and_trajectory():
    g = make_gait('ripple', duty_factor=0.7, period_s=1.1, step_length_m=0.12)
    t0 = 3.3
    sched = GaitScheduler(g, t0)
    assert sched.joint_names[:3] == ('L1_coxa', 'L1_femur', 'L1_tibia')
    trajs = [LegTrajectory(g, i) for i in range(6)]
    for t in np.linspace(t0, t0 + 2.5, 37):
        st = sched.state(t)
        assert_allclose(st.cycle_phase, g.cycle_phase(t - t0)[0], atol=1e-12)
        assert_allclose(st.leg_phase, g.leg_phase(t - t0)[0], atol=1e-12)
        assert st.supporting_legs == g.supporting_legs(t - t0)[0]
        assert st.transition == 1.0 and st.gait == g
        names, q, qd = sched.joint_targets(t)
        q_ref = np.concatenate([tr.joints(t - t0)[0][0] for tr in trajs])
        qd_ref = np.concatenate([tr.joints(t - t0)[1][0] for tr in trajs])
        assert_allclose(q, q_ref, atol=1e-12)
        assert_allclose(qd, qd_ref, atol=1e-12)


def test_duty_factor_switch_moves_no_tip_more_than_1mm_per_tick_in_a_slow_walk():
    # A 10 s cycle keeps the steady tip motion under 1 mm per 100 Hz tick, so any jump
    # caused by the switch would show up directly.
    g = make_gait('tripod', duty_factor=0.5, period_s=10.0)
    t = np.arange(0.0, 40.0, TICK_S)
    sched = GaitScheduler(g, 0.0)
    sched.set_gait(g.with_changes(duty_factor=0.7), 12.345)
    assert max_tick_move_m(sched, t) <= 1e-3
    # An instantaneous switch at the same instant jumps by centimetres.
    old, new = GaitScheduler(g, 0.0), GaitScheduler(g.with_changes(duty_factor=0.7), 0.0)
    naive = np.where((t < 12.345)[:, None, None], old.tip_targets(t), new.tip_targets(t))
    assert np.linalg.norm(np.diff(naive, axis=0), axis=2).max() > 0.02


@pytest.mark.parametrize('t_switch', [0.0, 0.31, 1.234, 1.5])
def test_duty_factor_switch_adds_no_jump_at_walking_speed(t_switch):
    g = make_gait('tripod', duty_factor=0.5, period_s=1.0)
    g7 = g.with_changes(duty_factor=0.7)
    t = np.arange(0.0, 5.0, TICK_S)
    steady = max(max_tick_move_m(GaitScheduler(x, 0.0), t) for x in (g, g7))
    sched = GaitScheduler(g, 0.0)
    sched.set_gait(g7, t_switch)
    assert max_tick_move_m(sched, t) <= steady + 1e-3
    # settled on the new gait, phase-continuously
    st = sched.state(4.5)
    assert st.gait.duty_factor == 0.7 and st.transition == 1.0
    assert_allclose(st.leg_phase, g7.leg_phase_at(st.cycle_phase)[0], atol=1e-12)


def test_cycle_phase_is_continuous_through_a_period_change():
    g = make_gait('tripod', period_s=1.0)
    sched = GaitScheduler(g, 0.0)
    sched.set_gait(g.with_changes(period_s=0.5), 0.7)
    t = np.arange(0.0, 4.0, 1e-3)
    c, _ = sched.leg_phases(t)
    dc = np.mod(np.diff(c) + 0.5, 1.0) - 0.5
    assert dc.min() > 0 and dc.max() <= 2e-3 + 1e-12  # frequency between 1 and 2 Hz
    assert_allclose(dc[:600], 1e-3, rtol=1e-9)
    assert_allclose(dc[-500:], 2e-3, rtol=1e-9)
    # transition lasts one period of the slower gait; its average frequency is 1.5 Hz
    assert_allclose((c[1700] - c[700]) % 1.0, (0.5 * 1.0 + 0.5 * 2.0) % 1.0, atol=1e-9)


def test_gait_switch_tripod_to_wave_is_continuous_and_settles():
    tripod = make_gait('tripod', duty_factor=0.5, period_s=1.2)
    wave = make_gait('wave', duty_factor=5 / 6, period_s=1.2)
    t = np.arange(0.0, 6.0, TICK_S)
    steady = max(max_tick_move_m(GaitScheduler(x, 0.0), t) for x in (tripod, wave))
    sched = GaitScheduler(tripod, 0.0)
    sched.set_gait(wave, 0.8)
    assert max_tick_move_m(sched, t) <= steady + 1e-3
    st = sched.state(5.0)
    assert st.gait.name == 'wave'
    assert_allclose(st.gait.phase_offsets, wave.phase_offsets, atol=1e-12)
    assert st.supporting_legs == 5


def test_joint_velocity_during_transition_is_the_derivative_of_position():
    g = make_gait('tetrapod', duty_factor=2 / 3, period_s=1.0)
    sched = GaitScheduler(g, 0.0)
    sched.set_gait(g.with_changes(step_length_m=0.14, step_height_m=0.03, period_s=0.8), 0.25)
    h = 1e-6
    for t in (0.3, 0.61, 0.9):
        _, q, qd = sched.joint_targets(t)
        _, qp, _ = sched.joint_targets(t + h)
        _, qm, _ = sched.joint_targets(t - h)
        assert_allclose(qd, (qp - qm) / (2 * h), rtol=1e-5, atol=1e-5)


def test_change_during_a_transition_starts_from_the_current_parameters():
    g = make_gait('tripod', period_s=1.0)
    sched = GaitScheduler(g, 0.0)
    sched.set_gait(g.with_changes(duty_factor=0.7), 1.0)
    before = sched.tip_targets([1.5])
    sched.set_gait(g.with_changes(duty_factor=0.6), 1.5)
    assert_allclose(sched.tip_targets([1.5]), before, atol=1e-12)
    assert sched.state(1.5).gait.duty_factor == pytest.approx(0.6 + 0.0 * smoothstep(0.5), 0.2)
    assert sched.state(10.0).gait.duty_factor == 0.6


def test_infeasible_or_incompatible_changes_are_refused_and_walking_continues():
    g = make_gait('tripod', duty_factor=0.5, period_s=0.5)
    sched = GaitScheduler(g, 0.0, limits=ActuatorLimits())
    before = sched.state(1.0)
    with pytest.raises(InfeasibleGaitError, match='swing lasts'):
        sched.set_gait(g.with_changes(duty_factor=0.7, period_s=0.4), 0.9)
    with pytest.raises(InvalidGaitError, match='leg count'):
        sched.set_gait(make_gait('alternating', leg_count=4), 0.9)
    with pytest.raises(InvalidGaitError, match='Buehler'):
        sched.set_gait(BUEHLER_PRESETS['walk'], 0.9)
    after = sched.state(1.0)
    assert_array_equal(after.leg_phase, before.leg_phase)
    assert after.gait == g
    with pytest.raises(InvalidGaitError, match='before the last change'):
        sched.set_gait(g, -1.0)


def test_buehler_scheduler_matches_clock_and_transitions_smoothly():
    walk, pace = BUEHLER_PRESETS['walk'], BUEHLER_PRESETS['pace']
    sched = GaitScheduler(walk, 0.0)
    assert sched.joint_names == ('L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip')
    tripod = ['left', 'right', 'left', 'right', 'left', 'right']
    for t in (0.0, 0.2, 0.77, 2.5):
        _, q, qd = sched.joint_targets(t)
        assert_allclose(q, [walk.target_angle(t, tr)[0] for tr in tripod], atol=1e-12)
        assert_allclose(qd, [walk.target_speed(t, tr)[0] for tr in tripod], atol=1e-12)
    sched.set_gait(pace, 2.6)
    t = np.arange(0.0, 8.0, TICK_S)
    q = np.array([sched.joint_targets(x)[1] for x in t])
    step = np.diff(q, axis=0)
    assert step.min() > 0  # hips keep turning forward
    # while sweep, offset and duty cycle ramp, the hip may run a little faster than either
    # clock's fast phase, but never jumps (a jump would be a sizeable fraction of a turn)
    fastest = max(walk.fast_speed_rad_s, pace.fast_speed_rad_s)
    assert step.max() <= 1.1 * fastest * TICK_S
    st = sched.state(7.9)
    assert st.clock == pace and st.gait.name == 'buehler'
