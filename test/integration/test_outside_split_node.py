"""slip_fitter fed ``/joint_states`` split over one message per joint (another lab's driver).

A simulated EduBot run is published with each hip in its own JointState (right side first,
each stamped at its own read time, +-0.3 ms) and the commands split over two buses; every
message is spun until the node has taken it (arrival order as the core sees it). Before the
online assembler, the node dropped every message whose names were not the first one's and
published nothing. The fits must equal those of the core fed the same messages and number at
least 8.
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

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

BOX = [-10.0, -10.0, -10.0, 10.0, 10.0, 10.0]


def _js(names, t_s, position, velocity):
    m = JointState()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t_s)
    m.name = list(names)
    m.position = [float(v) for v in position]
    m.velocity = [float(v) for v in velocity]
    return m


def _pose(t_s, p, q):
    m = PoseStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t_s)
    m.header.frame_id = 'mocap'
    m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in p)
    (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
     m.pose.orientation.w) = (float(v) for v in q)
    return m


def _messages(run):
    """(topic, msg) in arrival order: one JointState per hip, commands per 3-hip bus."""
    names = [f'{leg}_hip' for leg in run.leg_names]
    off = run.truth['clock_offset_s']
    rng = np.random.default_rng(11)
    ev = sorted([(float(t), 0, i) for i, t in enumerate(run.t_s)]
                + [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)])
    out = []
    for _, kind, i in ev:
        if kind == 1:
            out.append(('mocap', _pose(run.mocap_t_s[i], run.mocap_position_m[i],
                                       run.mocap_quat_xyzw[i])))
            continue
        t = float(run.t_s[i])
        for j in (3, 0, 4, 1, 5, 2):
            out.append(('js', _js([names[j]], t + float(rng.uniform(-3e-4, 3e-4)),
                                  run.hip_position_rad[i][[j]],
                                  run.hip_velocity_rad_s[i][[j]])))
        for g in ((0, 1, 2), (3, 4, 5)):
            out.append(('cmd', _js([names[j] for j in g], t, [],
                                   run.target_velocity_rad_s[i][list(g)])))
    return out


@pytest.mark.timeout(180)
def test_slip_fitter_publishes_fits_from_split_joint_states():
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    off = run.truth['clock_offset_s']
    msgs = _messages(run)
    core = OnlineSlip(box=Box(tuple(BOX[:3]), tuple(BOX[3:])), mocap_offset_s=off)
    expected = []
    for kind, m in msgs:
        t = stamp_to_s(m.header.stamp)
        if kind == 'js':
            core.add_joint_state(t, tuple(m.name), np.array(m.velocity), np.array(m.position))
        elif kind == 'cmd':
            core.add_command(t, tuple(m.name), np.array(m.velocity))
        else:
            p, q = m.pose.position, m.pose.orientation
            core.add_mocap(t, np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]))
            expected.extend(core.step())
    assert core._joints.groups == 6 and len(expected) >= 8

    with ros_env('slipsplit') as env:
        node = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('mocap_offset', value=off), Parameter('box', value=BOX)])
        fits = Collector(env, SlipFit, 'slip/fit')
        src = env.add(rclpy.create_node('split_src', context=env.context,
                                        namespace=env.namespace))
        qos = QoSProfile(depth=200, reliability=ReliabilityPolicy.RELIABLE)
        pubs = {'js': src.create_publisher(JointState, 'joint_states', qos),
                'cmd': src.create_publisher(JointState, 'joint_commands', qos),
                'mocap': src.create_publisher(PoseStamped, 'mocap/body', qos)}
        assert env.spin_until(lambda: all(p.get_subscription_count() > 0
                                          for p in pubs.values()), 20.0)
        for sent, (kind, m) in enumerate(msgs, start=1):
            pubs[kind].publish(m)
            while node.received < sent:  # in order: the node takes each before the next
                env.executor.spin_once(timeout_sec=5.0)
        got = fits.wait_for(env, len(expected), timeout_s=30.0)
        assert node.published == len(expected) == len(got)
        assert node.received == len(msgs)
    for m, r in zip(got, expected):
        assert m.tripod == r.tripod
        assert stamp_to_s(m.header.stamp) == pytest.approx(r.touchdown_s, abs=1e-6)
        assert stamp_to_s(m.liftoff) == pytest.approx(r.liftoff_s, abs=1e-6)
        assert_allclose([m.stiffness, m.rest_length, m.foot_x],
                        [r.params['stiffness'], r.params['rest_length'], r.params['foot_x']],
                        rtol=1e-9)
