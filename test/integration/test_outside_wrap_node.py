"""slip_fitter fed another lab's joint states: hip angles wrapped into [-pi, pi), no velocities.

A simulated EduBot run is published with ``/joint_states`` carrying wrapped positions and an
empty velocity array (commands as the gait node sends them); every message is spun until the
node has taken it. Before ``JointFrameAssembler`` derived the speeds, every such message was
dropped ('has 0 velocities') and nothing was published. The fits must equal those of the core
fed the same messages (at least 8), the core must report both fallbacks, and the stances must
be those of the run with the simulator's velocities and unwrapped angles (same count, edges
within 2.5 ms: the paper's edges move by ~1.5 ms with central-difference speeds).
"""

from __future__ import annotations

import math

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


def _messages(run, *, wrapped_no_velocity: bool):
    names = [f'{leg}_hip' for leg in run.leg_names]
    off = run.truth['clock_offset_s']
    ev = sorted([(float(t), 0, i) for i, t in enumerate(run.t_s)]
                + [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)])
    out = []
    for _, kind, i in ev:
        if kind == 1:
            out.append(('mocap', _pose(run.mocap_t_s[i], run.mocap_position_m[i],
                                       run.mocap_quat_xyzw[i])))
            continue
        t = float(run.t_s[i])
        q = run.hip_position_rad[i]
        if wrapped_no_velocity:
            out.append(('js', _js(names, t, (q + math.pi) % (2 * math.pi) - math.pi, [])))
        else:
            out.append(('js', _js(names, t, q, run.hip_velocity_rad_s[i])))
        out.append(('cmd', _js(names, t, run.target_position_rad[i],
                               run.target_velocity_rad_s[i])))
    return out


def _core_fits(msgs, off):
    core = OnlineSlip(box=Box(tuple(BOX[:3]), tuple(BOX[3:])), mocap_offset_s=off)
    fits = []
    for kind, m in msgs:
        t = stamp_to_s(m.header.stamp)
        if kind == 'js':
            core.add_joint_state(t, tuple(m.name), np.array(m.velocity), np.array(m.position))
        elif kind == 'cmd':
            core.add_command(t, tuple(m.name), np.array(m.velocity))
        else:
            p, q = m.pose.position, m.pose.orientation
            core.add_mocap(t, np.array([p.x, p.y, p.z]), np.array([q.x, q.y, q.z, q.w]))
            fits.extend(core.step())
    return core, fits


@pytest.mark.timeout(180)
def test_slip_fitter_publishes_fits_from_wrapped_velocity_less_joint_states():
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    off = run.truth['clock_offset_s']
    msgs = _messages(run, wrapped_no_velocity=True)
    core, expected = _core_fits(msgs, off)
    assert len(expected) >= 8 and core._joints.derived and core._joints.wraps > 20
    assert [n.split(':')[0] for n in core.notes] == [
        'no joint velocities', 'hip angles wrapped (jumps of 2 pi between samples)']
    _, ref = _core_fits(_messages(run, wrapped_no_velocity=False), off)
    assert len(ref) == len(expected)
    for a, b in zip(ref, expected):
        assert a.tripod == b.tripod
        assert abs(a.touchdown_s - b.touchdown_s) <= 2.5e-3
        assert abs(a.liftoff_s - b.liftoff_s) <= 2.5e-3

    with ros_env('slipwrap') as env:
        node = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('mocap_offset', value=off), Parameter('box', value=BOX)])
        fits = Collector(env, SlipFit, 'slip/fit')
        src = env.add(rclpy.create_node('wrap_src', context=env.context,
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
        assert node._notes_logged == 2  # each fallback logged once
    for m, r in zip(got, expected):
        assert m.tripod == r.tripod
        assert stamp_to_s(m.header.stamp) == pytest.approx(r.touchdown_s, abs=1e-6)
        assert stamp_to_s(m.liftoff) == pytest.approx(r.liftoff_s, abs=1e-6)
        assert_allclose([m.stiffness, m.rest_length, m.foot_x],
                        [r.params['stiffness'], r.params['rest_length'], r.params['foot_x']],
                        rtol=1e-9)
