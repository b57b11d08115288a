"""gait_scheduler node after outside review B: a walking 8-leg wave stands on Ctrl-C (F2), a stop
that cannot stand exits non-zero (F2), and a run-time change never publishes a schedule with a
whole side in the air (F3)."""

from __future__ import annotations

import pytest
from harness import Collector, ctrl_c, ros_env
from hexapod_interfaces.msg import GaitPhase
from rcl_interfaces.msg import SetParametersResult
from rclpy.parameter import Parameter

from hexapod_gait.gait_node import EXIT_NOT_STOOD, GaitSchedulerNode, stand_on_signals


def _overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


def _sigint(node: GaitSchedulerNode) -> None:
    ctrl_c(stand_on_signals, node)


@pytest.mark.timeout(90)
def test_a_walking_eight_leg_wave_stands_on_ctrl_c():
    """Before: the stand was refused (0.125 s swing at period 1 s) and the node exited 0 with
    the legs where they were."""
    with ros_env('gaitrevb') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            rate=50.0, gait='wave', leg_count=8, duty_factor=0.875, speed=0.05,
            transition_cycles=0.5, stop_timeout_s=20.0))
        phases = Collector(env, GaitPhase, 'gait/phase')
        phases.wait_for(env, 5)
        _sigint(node)
        assert env.spin_until(node.finished.done, 30)
        assert node.finished.result() == 0 and node.params.stand
        # the last stand message may still be on its way when the node resolves finished
        assert env.spin_until(lambda: phases.messages[-1].step_length == 0.0
                              and all(phases.messages[-1].in_stance), 5)
        last = phases.messages[-1]
        assert last.step_length == 0.0 and all(last.in_stance) and len(last.in_stance) == 8
        assert last.period == pytest.approx(phases.messages[0].period)   # walking period kept


@pytest.mark.timeout(90)
def test_a_stop_that_cannot_stand_exits_non_zero():
    with ros_env('gaitrevb') as env:
        # the stand is refused (here by a callback standing for any refusal)
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(rate=50.0))
        node.add_on_set_parameters_callback(lambda ps: SetParametersResult(
            successful=not any(p.name == 'stand' for p in ps), reason='test refuses stand'))
        Collector(env, GaitPhase, 'gait/phase').wait_for(env, 5)
        _sigint(node)
        assert env.spin_until(node.finished.done, 20)
        assert node.finished.result() == EXIT_NOT_STOOD == 1
        assert not node.params.stand
    with ros_env('gaitrevb') as env:
        # the stand does not settle within stop_timeout_s (a 2 s transition, 0.05 s allowed)
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            rate=50.0, period=2.0, stop_timeout_s=0.05))
        Collector(env, GaitPhase, 'gait/phase').wait_for(env, 5)
        _sigint(node)
        assert env.spin_until(node.finished.done, 20)
        assert node.finished.result() == EXIT_NOT_STOOD
        assert node.scheduler.state(node._now_s()).gait.step_length_m > 0.0


@pytest.mark.timeout(90)
def test_a_runtime_change_never_publishes_a_side_in_the_air():
    """4 legs, alternating 0.5 -> wave 0.75 (both accepted): before, /gait/phase showed the
    right side with no leg in stance for 0.44 s of the transition."""
    with ros_env('gaitrevb') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            rate=100.0, gait='alternating', leg_count=4, duty_factor=0.5, speed=0.1))
        phases = Collector(env, GaitPhase, 'gait/phase')
        phases.wait_for(env, 5)
        ok = node.set_parameters_atomically([Parameter('gait', value='wave'),
                                             Parameter('duty_factor', value=0.75)])
        assert ok.successful
        n0 = len(phases.messages)
        end = node.scheduler.transition_end_s
        assert env.spin_until(lambda: node._now_s() > end + 0.5, 30)
        during = phases.messages[n0 - 1:]
        assert len(during) > 100
        assert during[-1].gait == 'wave' and during[-1].duty_factor == 0.75
        for m in during:
            side = {'L': 0, 'R': 0}
            for name, down in zip(m.leg_names, m.in_stance):
                side[name[0]] += int(down)
            assert min(side.values()) >= 1, (m.phase_offsets, m.duty_factor, m.in_stance)
