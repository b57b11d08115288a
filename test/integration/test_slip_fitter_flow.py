"""slip_fitter message flow: a simulated EduBot run published on the three input topics.

Messages are published in arrival order (mocap arrives at true time; its stamps carry the
simulator's clock offset, which the node is told through ``mocap_offset``), one at a time,
each spun until the node has taken it, so the node sees the same sequence as the core fed
directly. Asserts the SlipFit count and values equal those of OnlineSlip on the same data, and
that every fit was made on motion capture at most 20 ms (simulated time) after its lift-off.
"""

from __future__ import annotations

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from numpy.testing import assert_allclose
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import JointState

from hexapod_common.conversions import s_to_stamp, stamp_to_s
from hexapod_interfaces.msg import SlipFit
from slip_identification.online import OnlineSlip
from slip_identification.preprocess import Box
from slip_identification.slip_node import SlipFitterNode

from harness import Collector, ros_env
from slip_stream import BOX, events, pose_msg

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _js(names, t_s, velocity):
    m = JointState()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t_s)
    m.name = list(names)
    m.position = [0.0] * len(names)
    m.velocity = [float(v) for v in velocity]
    return m


@pytest.mark.timeout(120)
def test_slip_fitter_publishes_core_fits_for_a_simulated_run():
    # mocap from 1.5 s (settle); the online world frame waits for 0.5 s of path
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    off = run.truth['clock_offset_s']
    # the reference: the core fed directly with the same (stamp-rounded) values
    core = OnlineSlip(box=Box(tuple(BOX[:3]), tuple(BOX[3:])), mocap_offset_s=off)
    expected = []
    for _, kind, i in events(run):
        if kind == 0:
            t = stamp_to_s(_js(names, run.t_s[i], []).header.stamp)
            core.add_joint_state(t, names, run.hip_velocity_rad_s[i])
            core.add_command(t, names, run.target_velocity_rad_s[i])
        else:
            t = stamp_to_s(pose_msg(run.mocap_t_s[i], [0, 0, 0], [0, 0, 0, 1]).header.stamp)
            core.add_mocap(t, run.mocap_position_m[i], run.mocap_quat_xyzw[i])
            expected.extend(core.step())
    assert len(expected) >= 8

    with ros_env('slipflow') as env:
        node = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('mocap_offset', value=off), Parameter('box', value=BOX),
            Parameter('calibration_strides', value=0.0)])   # the clock edges, as the core
        fits = Collector(env, SlipFit, 'slip/fit')
        src = env.add(rclpy.create_node('slip_src', context=env.context,
                                        namespace=env.namespace))
        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        pub_js = src.create_publisher(JointState, 'joint_states', qos)
        pub_cmd = src.create_publisher(JointState, 'joint_commands', qos)
        pub_mo = src.create_publisher(PoseStamped, 'mocap/body', qos)
        assert env.spin_until(lambda: pub_js.get_subscription_count() > 0
                              and pub_mo.get_subscription_count() > 0
                              and pub_cmd.get_subscription_count() > 0, 20.0)
        sent = 0
        for _, kind, i in events(run):
            if kind == 0:
                pubs = [(pub_js, _js(names, run.t_s[i], run.hip_velocity_rad_s[i])),
                        (pub_cmd, _js(names, run.t_s[i], run.target_velocity_rad_s[i]))]
            else:
                pubs = [(pub_mo, pose_msg(run.mocap_t_s[i], run.mocap_position_m[i],
                                       run.mocap_quat_xyzw[i]))]
            for pub, msg in pubs:
                pub.publish(msg)
                sent += 1
                n = sent
                while node.received < n:  # in order: the node takes each before the next
                    env.executor.spin_once(timeout_sec=5.0)
        got = fits.wait_for(env, len(expected), timeout_s=30.0)
        assert node.published == len(expected) == len(got)
        assert node.received == sent  # nothing lost
        assert node.loss.total() == 0   # and none counted missing on the simulator's streams

    for m, r in zip(got, expected):
        assert m.tripod == r.tripod
        assert stamp_to_s(m.header.stamp) == pytest.approx(r.touchdown_s, abs=1e-6)
        assert stamp_to_s(m.liftoff) == pytest.approx(r.liftoff_s, abs=1e-6)
        assert_allclose([m.stiffness, m.rest_length, m.foot_x, m.nerr],
                        [r.params['stiffness'], r.params['rest_length'], r.params['foot_x'],
                         r.nerr], rtol=1e-9)
        assert m.converged == r.converged and m.samples == r.samples
    lat_ms = 1e3 * np.array(node.core.latency_s)
    print(f'slip_fitter: {len(got)} fits, data latency median {np.median(lat_ms):.1f} ms, '
          f'max {lat_ms.max():.1f} ms (simulated time)')
    assert np.mean(lat_ms <= 20.0) >= 0.95
