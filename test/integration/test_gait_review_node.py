"""gait_scheduler node after the outside review: live-robot refusals (a side without support,
too short transitions, period in speed mode) and a real stand (FINDINGS G1, G2, G4-G6)."""

from __future__ import annotations

import pytest
from harness import Collector, ctrl_c, ros_env
from hexapod_interfaces.msg import GaitPhase
from rclpy.parameter import Parameter

from hexapod_common.errors import ParameterError
from hexapod_gait.gait_node import EXIT_NOT_STOOD, GaitSchedulerNode


def _overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


@pytest.mark.timeout(60)
def test_wave_at_half_duty_factor_is_refused_at_start_and_at_run_time():
    with ros_env('gaitrev') as env:
        with pytest.raises(ParameterError, match='lifts every leg of side'):
            GaitSchedulerNode(context=env.context, namespace=env.namespace,
                              parameter_overrides=_overrides(gait='wave'))
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(rate=50.0))
        Collector(env, GaitPhase, 'gait/phase').wait_for(env, 5)
        [bad] = node.set_parameters([Parameter('gait', value='wave')])
        assert not bad.successful and '1 - 1/n = 0.8333' in bad.reason
        assert node.params.gait == 'tripod'
        ok = node.set_parameters_atomically([Parameter('gait', value='wave'),
                                             Parameter('duty_factor', value=5 / 6)])
        assert ok.successful


@pytest.mark.timeout(60)
def test_too_short_transition_and_period_in_speed_mode_are_refused():
    with ros_env('gaitrev') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(rate=50.0))
        [bad] = node.set_parameters([Parameter('transition_cycles', value=0.001)])
        assert not bad.successful and 'must be >= 0.5' in bad.reason
        [ok] = node.set_parameters([Parameter('speed', value=0.3)])
        assert ok.successful
        [bad] = node.set_parameters([Parameter('period', value=2.0)])
        assert not bad.successful and 'ignored while speed = 0.3 m/s' in bad.reason
        ok = node.set_parameters_atomically([Parameter('speed', value=0.0),
                                             Parameter('period', value=2.0)])
        assert ok.successful and node.params.period == 2.0


@pytest.mark.timeout(60)
def test_stand_publishes_every_leg_in_stance_and_walks_again():
    with ros_env('gaitrev') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            rate=50.0, period=0.5, speed=0.0))
        phases = Collector(env, GaitPhase, 'gait/phase')
        phases.wait_for(env, 10)
        assert min(m.supporting_legs for m in phases.messages[:10]) == 3
        [ok] = node.set_parameters([Parameter('stand', value=True)])
        assert ok.successful
        assert env.spin_until(lambda: phases.messages[-1].step_length == 0.0
                              and phases.messages[-1].step_height == 0.0, 20)
        n = len(phases.messages)
        phases.wait_for(env, n + 30)
        for m in phases.messages[n:]:
            assert all(m.in_stance) and m.supporting_legs == 6
        [ok] = node.set_parameters([Parameter('stand', value=False)])
        assert ok.successful
        assert env.spin_until(lambda: phases.messages[-1].step_length == 0.1, 20)
        assert env.spin_until(lambda: phases.messages[-1].supporting_legs == 3, 20)


@pytest.mark.timeout(90)
@pytest.mark.parametrize('signals, stood', [(1, True), (2, False)])
def test_a_signal_stands_the_legs_before_the_node_exits(signals, stood):
    """Ctrl-C stopped the commands wherever the legs were (a bench leg froze 35 mm above the
    ground; the sequencer later cut its torque there): now the legs stand, then the node
    exits; a second signal exits at once."""
    from hexapod_gait.gait_node import stand_on_signals

    with ros_env('gaitrev') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            rate=50.0, period=0.5, transition_cycles=1.0))
        phases = Collector(env, GaitPhase, 'gait/phase')
        phases.wait_for(env, 10)
        ctrl_c(stand_on_signals, node, signals)
        assert env.spin_until(node.finished.done, 20)
        # a second signal leaves the legs where they are: exit 1 (it was 0; an outside review)
        assert node.finished.result() == (0 if stood else EXIT_NOT_STOOD)
        settled = node.scheduler.state(node._now_s()).gait.step_length_m == 0.0
        assert settled is stood and node.params.stand is stood
        if stood:   # the last command published is the stand, every leg in stance
            assert env.spin_until(lambda: phases.messages[-1].step_length == 0.0
                                  and all(phases.messages[-1].in_stance), 5)


@pytest.mark.timeout(60)
def test_a_signal_ends_the_node_when_its_simulated_clock_stands_still():
    """use_sim_time with no /clock: the gait timer never ticks, so the stand never began and
    SIGINT / SIGTERM were ignored until SIGKILL (an outside review). A steady-clock timer now
    handles the signal and, the node's clock not moving, ends it with exit code 1 after
    stop_timeout_s + 1 s of wall time."""
    from hexapod_gait.gait_node import stand_on_signals

    with ros_env('gaitsim') as env:
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            rate=50.0, period=0.5, stop_timeout_s=0.5) + [
                Parameter('use_sim_time', value=True)])
        ctrl_c(stand_on_signals, node)
        assert env.spin_until(node.finished.done, 30)
        assert node.finished.result() == EXIT_NOT_STOOD
