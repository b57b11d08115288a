"""Tip trajectories and joint trajectories (issue 3, item 4)."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_gait.gait import make_gait
from hexapod_gait.kinematics import LegKinematics
from hexapod_gait.trajectory import (
    ANTBOT_NEUTRAL_TIP_M,
    LegTrajectory,
    default_forward_axis,
    tip_path,
)

BETAS = (0.3, 0.5, 0.6, 0.7, 5 / 6)


def boundary_times(traj: LegTrajectory, cycles: int = 3) -> np.ndarray:
    g = traj.gait
    theta = g.phase_offsets[traj.leg_index]
    k = np.arange(cycles)
    return np.concatenate([(k + theta) * g.period_s, (k + theta + g.duty_factor) * g.period_s])


@pytest.mark.parametrize('beta', BETAS)
@pytest.mark.parametrize('leg', [0, 1, 4])
def test_position_velocity_acceleration_continuous_at_phase_boundaries(beta, leg):
    g = make_gait('tripod', duty_factor=beta, period_s=0.9, step_length_m=0.12)
    traj = LegTrajectory(g, leg)
    tb = boundary_times(traj)
    d = 1e-12
    for f, tol in ((traj.tip, 1e-9), (traj.tip_velocity, 1e-9), (traj.tip_acceleration, 1e-7)):
        jump = np.abs(f(tb + d) - f(tb - d)).max()
        assert jump < tol, (f.__name__, jump)
    # and the jumps really are at those instants: the swing is not trivially flat
    assert np.abs(traj.tip_acceleration(tb + 0.1 * g.swing_time_s)).max() > 1.0


@pytest.mark.parametrize('beta', BETAS)
def test_path_pieces_meet_exactly(beta):
    eps = 1e-13
    lo = tip_path([beta - eps, 1 - eps], duty_factor=beta, step_length_m=0.1, step_height_m=0.04)
    hi = tip_path([beta, 0.0], duty_factor=beta, step_length_m=0.1, step_height_m=0.04)
    for name in ('u', 'du', 'z', 'dz', 'ddu', 'ddz'):
        assert_allclose(getattr(lo, name), getattr(hi, name), atol=1e-9, err_msg=name)


def test_stance_is_a_straight_ground_line_at_constant_speed_and_swing_lifts_by_step_height():
    g = make_gait('tripod', duty_factor=0.6, period_s=1.2, step_length_m=0.10,
                  step_height_m=0.04)
    traj = LegTrajectory(g, 3)  # R1, forward axis +y
    assert default_forward_axis('R1') == (0.0, 1.0, 0.0)
    t = np.linspace(0, 2 * g.period_s, 4001)
    p, v = traj.tip(t), traj.tip_velocity(t)
    st = traj.in_stance(t)
    z0 = ANTBOT_NEUTRAL_TIP_M[2]
    assert_allclose(p[st, 2], z0, atol=1e-15)
    assert_allclose(p[st, 0], ANTBOT_NEUTRAL_TIP_M[0], atol=1e-15)
    assert_allclose(v[st, 1], -g.speed_mps, rtol=1e-12)  # body moves forward by v
    assert_allclose(np.abs(v[st][:, [0, 2]]), 0.0, atol=1e-15)
    assert p[~st, 2].min() >= z0 - 1e-12
    assert_allclose(p[~st, 2].max(), z0 + 0.04, rtol=1e-6)
    # the stance covers the step length: from +L/2 to -L/2
    stance_y = p[st, 1]
    assert_allclose([stance_y.max(), stance_y.min()], [0.05, -0.05], atol=1e-4)


def test_joint_trajectories_are_consistent_with_tip_trajectory():
    g = make_gait('wave', duty_factor=5 / 6, period_s=1.5, step_length_m=0.14)
    kin = LegKinematics()
    for leg in range(6):
        traj = LegTrajectory(g, leg, kinematics=kin)
        # random instants: a central difference straddling a spline knot would see the jump
        # of the third derivative there
        t = np.sort(np.random.default_rng(leg).uniform(0, g.period_s, 300))
        q, qd, qdd = traj.joints(t)
        assert_allclose(kin.forward(q), traj.tip(t), atol=1e-12)
        assert_allclose(kin.tip_velocity(q, qd), traj.tip_velocity(t), atol=1e-12)
        h = 1e-6
        _, qd_p, _ = traj.joints(t + h)
        _, qd_m, _ = traj.joints(t - h)
        assert_allclose((qd_p - qd_m) / (2 * h), qdd, rtol=1e-6, atol=1e-4)
        assert np.all(q[:, 2] < 0)  # knee up
