"""Feeding ``slip_fitter`` a simulated EduBot run message by message, and the reference fits.

Shared by the integration tests that publish another lab's joint states (split over several
messages, wrapped, without velocities) into the node: the messages, the core
(:class:`slip_identification.online.OnlineSlip`) fed the same values, the node fed them in
order (each taken before the next), and the comparison of the published fits with the core's.
"""

from __future__ import annotations

from typing import Any

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

__all__ = ['BOX', 'assert_same_fits', 'core_fits', 'events', 'js_msg', 'mocap_msg', 'node_fits',
           'pose_msg']

#: a box holding every mocap sample
BOX = [-10.0, -10.0, -10.0, 10.0, 10.0, 10.0]


def js_msg(names: Any, t_s: float, position: Any, velocity: Any) -> JointState:
    m = JointState()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t_s)
    m.name = list(names)
    m.position = [float(v) for v in position]
    m.velocity = [float(v) for v in velocity]
    return m


def pose_msg(t_s: float, p: Any, q: Any) -> PoseStamped:
    m = PoseStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t_s)
    m.header.frame_id = 'mocap'
    m.pose.position.x, m.pose.position.y, m.pose.position.z = (float(v) for v in p)
    (m.pose.orientation.x, m.pose.orientation.y, m.pose.orientation.z,
     m.pose.orientation.w) = (float(v) for v in q)
    return m


def mocap_msg(run: Any, i: int) -> tuple[str, PoseStamped]:
    """``('mocap', PoseStamped)`` of the run's ``i``-th motion-capture sample."""
    return 'mocap', pose_msg(run.mocap_t_s[i], run.mocap_position_m[i], run.mocap_quat_xyzw[i])


def events(run: Any) -> list[tuple[float, int, int]]:
    """(time in the proprioception clock, 0 = joint sample / 1 = mocap sample, index), sorted."""
    off = run.truth['clock_offset_s']
    return sorted([(float(t), 0, i) for i, t in enumerate(run.t_s)]
                  + [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)])


def core_fits(msgs: list[tuple[str, Any]], offset_s: float) -> tuple[OnlineSlip, list[Any]]:
    """The core fed ``(kind, msg)`` (kind ``js``, ``cmd`` or ``mocap``) in order."""
    core = OnlineSlip(box=Box(tuple(BOX[:3]), tuple(BOX[3:])), mocap_offset_s=offset_s)
    fits: list[Any] = []
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


def node_fits(prefix: str, msgs: list[tuple[str, Any]], offset_s: float, n_expected: int,
              params: tuple[Parameter, ...] = ()) -> tuple[dict[str, int], list[Any]]:
    """Publish ``msgs`` in order into a fresh ``slip_fitter`` (each taken before the next) and
    collect ``n_expected`` fits; returns the node's counters and the fits."""
    with ros_env(prefix) as env:
        node = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('mocap_offset', value=offset_s), Parameter('box', value=BOX),
            # the clock edges' core, as core_fits: no self-calibration
            Parameter('calibration_strides', value=0.0), *params])
        fits = Collector(env, SlipFit, 'slip/fit')
        src = env.add(rclpy.create_node(f'{prefix}_src', context=env.context,
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
        got = fits.wait_for(env, n_expected, timeout_s=30.0)
        counters = {'published': node.published, 'received': node.received,
                    'notes_logged': node._notes_logged}
    return counters, got


def assert_same_fits(got: list[Any], expected: list[Any]) -> None:
    """Published SlipFit messages equal the core's fits."""
    assert len(got) == len(expected)
    for m, r in zip(got, expected):
        assert m.tripod == r.tripod
        assert stamp_to_s(m.header.stamp) == pytest.approx(r.touchdown_s, abs=1e-6)
        assert stamp_to_s(m.liftoff) == pytest.approx(r.liftoff_s, abs=1e-6)
        assert_allclose([m.stiffness, m.rest_length, m.foot_x],
                        [r.params['stiffness'], r.params['rest_length'], r.params['foot_x']],
                        rtol=1e-9)
