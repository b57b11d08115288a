"""3-DOF leg kinematics from the DH table (issue 3, item 3)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.testing import assert_allclose

from hexapod_gait.kinematics import (
    ANTBOT_LEG,
    DHParameters,
    LegKinematics,
    UnreachableError,
)

KIN = LegKinematics()


def test_forward_hand_calculation():
    # femur horizontal, tibia straight down: tip 53 + 83 mm out, 146 mm down
    assert_allclose(KIN.forward([0.0, 0.0, -math.pi / 2]), [[0.136, 0.0, -0.146]], atol=1e-15)
    # coxa at 90 degrees, everything stretched: tip on +y at 282 mm
    assert_allclose(KIN.forward([math.pi / 2, 0.0, 0.0]), [[0.0, 0.282, 0.0]], atol=1e-15)
    # femur up 90 degrees, tibia stretched: tip 229 mm above the femur joint
    assert_allclose(KIN.forward([0.0, math.pi / 2, 0.0]), [[0.053, 0.0, 0.229]], atol=1e-15)
    assert ANTBOT_LEG.link_masses_kg == (0.01498, 0.1118, 0.03923)


def test_frames_agree_with_forward():
    rng = np.random.default_rng(0)
    for q in rng.uniform(-2, 2, size=(20, 3)):
        frames = KIN.frames(q)
        assert len(frames) == 4
        assert_allclose(frames[0], np.eye(4))
        assert_allclose(frames[-1][:3, 3], KIN.forward(q)[0], atol=1e-15)
        # joint 2 axis (z of frame 1) is horizontal: alpha1 = pi/2
        assert abs(frames[1][2, 2]) < 1e-15


def test_jacobian_and_bias_acceleration_against_finite_differences():
    rng = np.random.default_rng(1)
    h = 1e-6
    for q, qd in zip(rng.uniform(-2, 2, (20, 3)), rng.uniform(-3, 3, (20, 3))):
        J = KIN.jacobian(q)
        Jn = np.column_stack([(KIN.forward(q + h * e) - KIN.forward(q - h * e))[0] / (2 * h)
                              for e in np.eye(3)])
        assert_allclose(J, Jn, atol=1e-9)
        hh = 1e-4
        acc = (KIN.forward(q + hh * qd) - 2 * KIN.forward(q) + KIN.forward(q - hh * qd)) / hh**2
        assert_allclose(KIN.bias_acceleration(q, qd), acc, atol=1e-6)


def reachable_knee_up_q():
    # The analytic inverse returns the coxa angle atan2(y, x): sample configurations with the
    # tip in front of the coxa axis (radial reach > 10 mm) and away from the straight-knee
    # singularity (|q3| > 0.05 rad), inside the AX-18A joint limits.
    return st.tuples(
        st.floats(-1.5, 1.5), st.floats(-1.5, 1.5), st.floats(-2.6, -0.05),
    ).filter(lambda q: KIN.forward(q)[0, :2] @ np.array([math.cos(q[0]), math.sin(q[0])]) > 0.01)


@settings(max_examples=400, deadline=None)
@given(q=reachable_knee_up_q())
def test_inverse_of_forward_returns_joint_angles_knee_up(q):
    assert_allclose(KIN.inverse(KIN.forward(q), branch='knee_up')[0], q, rtol=0, atol=1e-9)


@settings(max_examples=200, deadline=None)
@given(q=reachable_knee_up_q())
def test_inverse_of_forward_returns_joint_angles_knee_down(q):
    q_down = np.array(q)
    q_down[2] = -q_down[2]
    p = KIN.forward(q_down)
    if p[0, :2] @ np.array([math.cos(q[0]), math.sin(q[0])]) <= 0.01:
        return
    q_back = KIN.inverse(p, branch='knee_down', check_limits=False)[0]
    assert_allclose(q_back, q_down, rtol=0, atol=1e-9)


def test_vectorised_inverse_and_branches_differ():
    q = np.array([[0.2, 0.3, -1.4], [-0.4, -0.2, -0.9]])
    p = KIN.forward(q)
    assert_allclose(KIN.inverse(p), q, atol=1e-12)
    down = KIN.inverse(p, branch='knee_down', check_limits=False)
    assert np.all(down[:, 2] > 0)
    assert_allclose(KIN.forward(down), p, atol=1e-15)


def test_unreachable_target_names_target_and_reach():
    with pytest.raises(UnreachableError) as err:
        KIN.inverse([0.4, 0.0, -0.1])
    msg = str(err.value)
    assert '(0.4, 0.0, -0.1)' in msg
    assert 'reach is [0.063, 0.229] m' in msg
    with pytest.raises(UnreachableError, match='reach'):
        KIN.inverse([0.0, 0.0, 0.0])  # closer than |a2 - a3| to the femur joint either way


def test_joint_limits_are_enforced():
    tight = LegKinematics(DHParameters(joint_limits_rad=((-0.5, 0.5), (-1, 1), (-2, 0))))
    p = KIN.forward([1.0, 0.0, -1.0])
    with pytest.raises(UnreachableError, match='outside the joint limits'):
        tight.inverse(p)
    assert not tight.within_limits([1.0, 0.0, -1.0])[0]
    assert tight.within_limits([0.4, 0.0, -1.0])[0]


def test_theta_offsets_and_vertical_offset():
    dh = DHParameters(theta_offset_rad=(0.0, 0.1, -math.pi / 2), d_m=(0.02, 0.0, 0.0))
    kin = LegKinematics(dh)
    q = np.array([0.3, 0.2, 0.4])
    assert_allclose(kin.forward(q)[0], kin.frames(q)[-1][:3, 3], atol=1e-15)
    assert_allclose(kin.inverse(kin.forward(q))[0], q, atol=1e-12)


def test_unsupported_dh_structure_is_refused():
    with pytest.raises(ValueError, match='alpha'):
        LegKinematics(DHParameters(alpha_rad=(0.0, 0.0, 0.0)))


def test_tip_behind_the_coxa_axis_uses_the_turned_coxa():
    # 10 mm behind the coxa axis (radial reach R < 0 along the coxa direction 0.4 rad), 20 mm
    # up: the usual solution would need the tip 43 mm from the femur joint (< 63 mm reach)
    p = np.array([-0.01 * np.cos(0.4), -0.01 * np.sin(0.4), 0.02])
    q = KIN.inverse(p, check_limits=False)[0]
    assert_allclose(KIN.forward(q)[0], p, atol=1e-15)
    assert_allclose(q[0], 0.4, atol=1e-12)
