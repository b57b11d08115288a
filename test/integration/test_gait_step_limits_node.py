"""gait_scheduler after an outside review: the actuator limits are read on the step's own joint
path (``hexapod_gait.step_limits``), as ``hexapod-sim robot`` and the energy side read them.
Before, ``gait_scheduler --ros-args -p speed:=0.8 -p step_length:=0.14`` walked T 0.35 s
(swing = stance = 0.175 s) where a 140 mm step needs 0.192 s and 0.221 s."""

from __future__ import annotations

import pytest
from harness import Collector, ros_env
from hexapod_interfaces.msg import GaitPhase
from rclpy.parameter import Parameter

from hexapod_common.errors import ParameterError
from hexapod_gait.gait_node import GaitSchedulerNode, main


def _overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


@pytest.mark.timeout(30)   # before the fix it walked until stopped
def test_the_console_script_refuses_a_step_beyond_its_limits_in_one_line(capsys,
                                                                        monkeypatch):
    monkeypatch.delenv('HEXAPOD_DEBUG', raising=False)
    assert main(['gait_scheduler', '--ros-args', '-p', 'speed:=0.8',
                 '-p', 'step_length:=0.14']) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1 and 'Traceback' not in err[0], err
    assert 'maximum speed is 0.6324 m/s' in err[0] and '140 mm step' in err[0]


@pytest.mark.timeout(60)
def test_a_step_beyond_its_limits_is_refused_at_start_and_at_run_time():
    with ros_env('gaitstep') as env:
        with pytest.raises(ParameterError,
                           match='swing 0.175 s below the 0.192 s a 140 mm step needs'):
            GaitSchedulerNode(context=env.context, namespace=env.namespace,
                              parameter_overrides=_overrides(period=0.35, step_length=0.14))
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(rate=50.0))
        phases = Collector(env, GaitPhase, 'gait/phase')
        phases.wait_for(env, 5)
        bad = node.set_parameters_atomically([Parameter('speed', value=0.8),
                                              Parameter('step_length', value=0.14)])
        assert not bad.successful and 'maximum speed is 0.6324 m/s' in bad.reason
        bad = node.set_parameters_atomically([
            Parameter('gait', value='wave'), Parameter('duty_factor', value=5 / 6),
            Parameter('period', value=0.96), Parameter('step_length', value=0.12)])
        assert not bad.successful
        assert 'swing 0.16 s below the 0.172 s a 120 mm step needs' in bad.reason
        assert (node.params.gait, node.params.step_length, node.params.speed) == \
            ('tripod', 0.1, 0.0)
        # what the message offers works: 0.63 m/s on 140 mm steps
        ok = node.set_parameters_atomically([Parameter('speed', value=0.63),
                                             Parameter('step_length', value=0.14)])
        assert ok.successful, ok.reason
        n = len(phases.messages)
        phases.wait_for(env, n + 80)   # through the 1 s transition (50 Hz)
        last = phases.messages[-1]
        assert last.step_length == pytest.approx(0.14)
        assert last.period == pytest.approx(0.14 / (0.5 * 0.63))
