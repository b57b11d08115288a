"""gait_scheduler and energy_monitor with a leg file: the actuator limits are AntBot's servo
limits measured on AntBot's leg, unless given with the leg file (``min_swing``/``min_stance``,
``limits``): then they were measured on that leg (``hexapod_gait.step_limits``).

Before, both scaled the limits to each step against the leg file's own 100 mm path, so at the
default 100 mm step a PhantomX-like leg (52/66/133 mm, joints 12 % and 15 % further than
AntBot's in stance and swing) walked AntBot's limits: 0.58 m/s was accepted (swing 0.172 s,
where the leg needs 0.185 s at the AX-18A's speed).
"""

from __future__ import annotations

import pytest
from harness import ros_env
from rclpy.parameter import Parameter

from hexapod_common.errors import ParameterError
from hexapod_energy.energy_node import EnergyMonitorNode
from hexapod_gait.gait_node import GaitSchedulerNode

PHANTOMX = """name: PhantomX-like
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.060, 0.070, 0.045]
neutral_tip_m: [0.14, 0.0, -0.10]
"""


def _overrides(**kw):
    return [Parameter(k, value=v) for k, v in kw.items()]


@pytest.mark.timeout(60)
def test_gait_node_limits_belong_to_the_leg_they_were_measured_on(tmp_path):
    leg = tmp_path / 'px.yaml'
    leg.write_text(PHANTOMX, encoding='utf8')
    with ros_env('limits_leg_gait') as env:
        # AntBot's leg walks it
        node = env.make(GaitSchedulerNode, parameter_overrides=_overrides(
            speed=0.58, startup_listen_s=0.0))
        assert node._gait.period_s == pytest.approx(0.1 / (0.5 * 0.58))
        # the PhantomX-like leg with AntBot's servo limits: refused, naming its maximum
        with pytest.raises(ParameterError, match='maximum speed is 0.54'):
            GaitSchedulerNode(context=env.context, namespace=env.namespace,
                              parameter_overrides=_overrides(speed=0.58,
                                                             leg_file=str(leg)))
        # limits given with the leg file were measured on it: its 100 mm step keeps them
        own = env.make(GaitSchedulerNode, node_name='gait_own', parameter_overrides=_overrides(
            speed=0.58, leg_file=str(leg), min_swing=0.16, min_stance=0.15,
            startup_listen_s=0.0))
        assert own.limits_on_leg and own._gait.period_s == pytest.approx(0.3448, abs=1e-4)
        assert not own.set_parameters_atomically([Parameter('speed', value=0.7)]).successful


@pytest.mark.timeout(60)
def test_energy_monitor_limits_belong_to_the_leg_they_were_measured_on(tmp_path):
    leg = tmp_path / 'px.yaml'
    leg.write_text(PHANTOMX, encoding='utf8')
    with ros_env('limits_leg_energy') as env:
        node = env.make(EnergyMonitorNode, parameter_overrides=_overrides(
            mass=2.237, leg_file=str(leg)))
        assert node.core.limits.measured_on.name == "AntBot's leg"
        given = env.make(EnergyMonitorNode, node_name='energy_own',
                         parameter_overrides=_overrides(mass=2.237, leg_file=str(leg),
                                                        limits=[0.16, 0.15, 3.0]))
        assert given.core.limits.measured_on.name == 'PhantomX-like'
