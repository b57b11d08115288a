"""slip_fitter's self-calibration and the node's end, and its skip log (an outside review).

- Destroyed while the worker ran, the node's worker ran on for seconds and then woke the
  destroyed guard condition: an InvalidHandle traceback in the thread. Destroyed after the
  worker was done but before the executor took the hand-over, the fits it had computed were
  never published (10 on a simulated EduBot running bag).
- ``_log_skips`` logged ``frame_not_ready`` (info) and the other reasons (warning) from one
  call site: rclpy refuses a second severity there, and the ValueError stopped the node (a run
  with two passes through the volume, whose hand-over logged both at once).
"""

from __future__ import annotations

import math
import threading
from typing import Any

import pytest
from geometry_msgs.msg import PoseStamped
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from hexapod_common.conversions import s_to_stamp
from hexapod_interfaces.msg import SlipFit
from slip_identification import slip_node
from slip_identification.calibration import Calibration
from slip_identification.online import OnlineSkip
from slip_identification.slip_node import SlipFitterNode

from harness import ros_env

NAMES = [f'{side}{k}_hip' for side in 'LR' for k in (1, 2, 3)]
W = 2.0 * math.pi   # a stride of 1 s


def _js(t: float) -> JointState:
    m = JointState()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t)
    m.name = NAMES
    m.position = [W * t] * 6
    m.velocity = [W] * 6
    m.effort = [0.0] * 6
    return m


def _pose(t: float) -> PoseStamped:
    m = PoseStamped()
    m.header.stamp.sec, m.header.stamp.nanosec = s_to_stamp(t)
    m.pose.position.z = 0.1
    m.pose.orientation.w = 1.0
    return m


class _Blocking:
    """The estimators' stand-in: waits until released, then refuses."""

    def __init__(self) -> None:
        self.go = threading.Event()

    def __call__(self, run: Any) -> Calibration:
        assert self.go.wait(30.0)
        return Calibration(refused='a stand-in')


def _calibrating(node: SlipFitterNode, stand_in: _Blocking) -> None:
    """Feed the node (its callbacks, in order) until its worker runs the stand-in."""
    node.calibration._calibrate_run = stand_in
    t = 0.0
    while node.calibration.state == 'collecting':
        assert t < 5.0
        node._on_js(_js(t))
        node._on_mocap(_pose(t))
        t += 0.01


@pytest.mark.timeout(60)
def test_destroyed_while_the_worker_runs_no_traceback_and_no_wake():
    errors: list[Any] = []
    hook, threading.excepthook = threading.excepthook, errors.append
    try:
        with ros_env('slipstop') as env:
            node = env.make(SlipFitterNode, parameter_overrides=[
                Parameter('calibration_strides', value=1.0), Parameter('input_timeout_s',
                                                                        value=0.0)])
            stand_in = _Blocking()
            _calibrating(node, stand_in)
            env.executor.remove_node(node)
            env.nodes.remove(node)
            node.destroy_node()
            stand_in.go.set()
            assert node.calibration.wait(30.0)
    finally:
        threading.excepthook = hook
    # before: InvalidHandle (the destroyed guard condition) raised in the worker
    assert not errors, [str(e.exc_value) for e in errors]
    assert node.calibration.state == 'calibrating'


@pytest.mark.timeout(60)
def test_destroyed_before_the_hand_over_publishes_the_fits_computed(monkeypatch):
    with ros_env('slipstop') as env:
        node = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('calibration_strides', value=1.0), Parameter('input_timeout_s',
                                                                    value=0.0)])
        stand_in = _Blocking()
        stand_in.go.set()
        _calibrating(node, stand_in)
        assert node.calibration.wait(30.0) and node.calibration.state == 'ready'
        computed = object()   # a fit the worker computed (stands for a SlipFitResult)
        node.calibration._fits = [computed]
        sent: list[Any] = []
        monkeypatch.setattr(slip_node, 'result_to_msg',
                            lambda r: SlipFit(model='computed') if r is computed else None)
        node.pub.publish = sent.append
        env.executor.remove_node(node)   # the executor never ran the hand-over
        env.nodes.remove(node)
        node.destroy_node()
    # before: never published
    assert [m.model for m in sent] == ['computed'] and node.calibration.state == 'done'


@pytest.mark.timeout(60)
def test_skips_of_both_severities_are_logged():
    with ros_env('slipskip') as env:
        node = env.make(SlipFitterNode, parameter_overrides=[
            Parameter('input_timeout_s', value=0.0)])
        node.core.skipped.extend([OnlineSkip(1.0, 1.1, 'left', 'frame_not_ready'),
                                  OnlineSkip(2.0, 2.1, 'right', 'mocap_gap')])
        node._log_skips()   # before: ValueError (severity changed at one call site)
        assert node.skipped_counts == {'frame_not_ready': 1, 'mocap_gap': 1}
