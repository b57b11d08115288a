"""gait_scheduler node: /gait/phase and /joint_commands agree with the core; run-time changes."""

from __future__ import annotations

import numpy as np
import pytest
from harness import Collector, ros_env
from hexapod_interfaces.msg import GaitPhase
from numpy.testing import assert_allclose, assert_array_equal
from rclpy.parameter import Parameter
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import JointState

from hexapod_common.conversions import gait_phase_from_msg, joint_state_from_msg
from hexapod_gait.buehler import BUEHLER_PRESETS
from hexapod_gait.gait import make_gait
from hexapod_gait.gait_node import GaitSchedulerNode
from hexapod_gait.kinematics import LegKinematics
from hexapod_gait.trajectory import LegTrajectory


def _since(msg, t0_ns: int) -> float:
    """Seconds from ``t0_ns`` to the message stamp, in integer nanoseconds first: wall-clock
    seconds as one float carry only about 0.2 us."""
    ns = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
    return (ns - t0_ns) * 1e-9


def _overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


@pytest.mark.timeout(60)
def test_phase_and_commands_reproduce_core():
    with ros_env('gait') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            gait='tetrapod', duty_factor=0.7, period=0.9, step_length=0.12))
        phases = Collector(env, GaitPhase, 'gait/phase')
        cmds = Collector(env, JointState, 'joint_commands')
        phases.wait_for(env, 40)
        cmds.wait_for(env, 40)
        g = make_gait('tetrapod', duty_factor=0.7, period_s=0.9, step_length_m=0.12)
        trajs = [LegTrajectory(g, i) for i in range(6)]
        t0 = node.t0_ns
        for msg in phases.messages[:40]:
            s = gait_phase_from_msg(msg)
            t = _since(msg, t0)
            assert s.gait == 'tetrapod' and s.leg_names == g.leg_names
            assert_allclose(s.phase_offsets, g.phase_offsets)
            assert (s.period_s, s.duty_factor, s.step_length_m) == (0.9, 0.7, 0.12)
            assert_allclose(s.cycle_phase, g.cycle_phase(t)[0], atol=1e-8)
            assert_array_equal(s.in_stance, g.stance_mask(t)[0])
            assert s.supporting_legs == g.supporting_legs(t)[0]
        for msg in cmds.messages[:40]:
            j = joint_state_from_msg(msg)
            t = _since(msg, t0)
            assert j.names[:3] == ('L1_coxa', 'L1_femur', 'L1_tibia') and len(j.names) == 18
            q = np.concatenate([tr.joints(t)[0][0] for tr in trajs])
            qd = np.concatenate([tr.joints(t)[1][0] for tr in trajs])
            assert_allclose(j.position, q, atol=1e-7)
            assert_allclose(j.velocity, qd, atol=1e-6)


@pytest.mark.timeout(60)
def test_runtime_change_is_smooth_and_infeasible_request_is_refused():
    with ros_env('gait') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(period=1.0))
        cmds = Collector(env, JointState, 'joint_commands')
        phases = Collector(env, GaitPhase, 'gait/phase')
        cmds.wait_for(env, 20)
        [bad] = node.set_parameters([Parameter('period', value=0.2)])
        assert not bad.successful and 'swing lasts 0.1 s < minimum 0.16 s' in bad.reason
        bad = node.set_parameters_atomically([Parameter('leg_count', value=4),
                                              Parameter('gait', value='alternating')])
        assert not bad.successful and 'leg count cannot change while walking' in bad.reason
        bad = node.set_parameters_atomically([Parameter('speed', value=0.5),
                                              Parameter('duty_factor', value=0.7)])
        assert not bad.successful and 'maximum speed is 0.2679 m/s' in bad.reason
        assert node.params.speed == 0.0 and node.params.duty_factor == 0.5
        [ok] = node.set_parameters([Parameter('duty_factor', value=0.7)])
        assert ok.successful, ok.reason
        n0 = len(cmds.messages)
        cmds.wait_for(env, n0 + 250)  # through the 1 s transition and beyond
        kin = LegKinematics()
        q = np.array([m.position for m in cmds.messages])
        tips = kin.forward(q.reshape(-1, 3)).reshape(len(q), 6, 3)
        moves = np.linalg.norm(np.diff(tips, axis=0), axis=2).max(axis=1)
        stamps = np.array([joint_state_from_msg(m).t_s for m in cmds.messages])
        gaps = np.diff(stamps)
        # no jump: per-tick motion bounded by the fastest steady swing (beta 0.7 at T = 1 s,
        # 8.55 mm per 10 ms) scaled to the actual tick length, plus 1 mm
        assert np.all(moves <= 0.855 * gaps / 0.01 + 1e-3)
        last = gait_phase_from_msg(phases.messages[-1])
        assert last.duty_factor == 0.7 and node.params.duty_factor == 0.7
        assert len(cmds.messages) > n0 + 200  # kept walking throughout


@pytest.mark.timeout(60)
def test_buehler_clock_on_sim_time():
    with ros_env('gait') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            gait='buehler', preset='walk', use_sim_time=True))
        clock_pub = node.create_publisher(Clock, '/clock', 10)
        cmds = Collector(env, JointState, 'joint_commands')
        t_sim = [100.0]

        def advance():
            t_sim[0] += 0.01
            msg = Clock()
            msg.clock.sec, msg.clock.nanosec = int(t_sim[0]), int(round(t_sim[0] % 1 * 1e9))
            clock_pub.publish(msg)
            return len(cmds.messages) >= 30
        assert env.spin_until(advance, 30.0)
        walk = BUEHLER_PRESETS['walk']
        t0 = node.t0_ns
        assert node.t0_s >= 100.0  # the node's clock is the simulated one
        tripods = ['left', 'right', 'left', 'right', 'left', 'right']
        for msg in cmds.messages[:30]:
            j = joint_state_from_msg(msg)
            assert j.names == ('L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip')
            assert 100.0 <= j.t_s <= t_sim[0] + 1e-9
            ref = [walk.target_angle(_since(msg, t0), tr)[0] for tr in tripods]
            assert_allclose(j.position, ref, atol=1e-6)
