"""An outside review's live graph on a PhantomX-class leg (``sim_robot``, ``gait_scheduler``
and ``energy_monitor``, all ``-p leg_file``, no mass given): the monitor assumed AntBot's
2.183 kg where ``sim_robot`` walks AntBot's body with the file's legs (2.237 kg), and read
``gait_scheduler``'s stand (period kept, step 0) as a Buehler clock: P_out NaN and a note about
rotating legs, where ``hexapod-analyze energy`` reads that stand as P_out 0 W."""

from __future__ import annotations

import math

import pytest
from harness import Collector, ros_env
from hexapod_interfaces.msg import EnergeticDescriptors
from rclpy.parameter import Parameter

from hexapod_bench_drivers.sim_nodes import SimRobotNode
from hexapod_energy.energy_node import EnergyMonitorNode
from hexapod_gait.gait_node import GaitSchedulerNode

LEG_YAML = """name: review PX leg
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.030, 0.065, 0.080]
neutral_tip_m: [0.125, 0.0, -0.095]
"""
ROBOT_KG = 2.183 - 6 * (0.01498 + 0.1118 + 0.03923) + 6 * 0.175


@pytest.mark.timeout(120)
def test_live_monitor_mass_and_stand_on_a_leg_file(tmp_path) -> None:
    leg = tmp_path / 'px.yaml'
    leg.write_text(LEG_YAML)
    with ros_env('px_live') as env:
        energy = env.make(EnergyMonitorNode, parameter_overrides=[
            Parameter('current_sign', value='ros'), Parameter('leg_file', value=str(leg)),
            Parameter('power_out_source', value='model')])
        assert energy.core.mass_kg == pytest.approx(ROBOT_KG, abs=1e-9)
        assert any('0.175 kg legs' in w and '2.237 kg' in w for w in energy.start_warnings)
        out = Collector(env, EnergeticDescriptors, 'energy/descriptors')
        gait = env.make(GaitSchedulerNode, parameter_overrides=[
            Parameter('leg_file', value=str(leg)), Parameter('period', value=0.5)])
        sim = env.make(SimRobotNode, parameter_overrides=[Parameter('leg_file', value=str(leg))])
        assert sim.live.sim.config.robot_mass_kg == pytest.approx(energy.core.mass_kg,
                                                                  abs=1e-12)
        out.wait_for(env, 2, timeout_s=60)
        assert gait.set_parameters([Parameter('stand', value=True)])[0].successful
        walking = len(out.messages)
        out.wait_for(env, walking + 3, timeout_s=60)
        stands = [m for m in out.messages[walking + 1:]]
    for m in stands:
        assert m.mass == pytest.approx(ROBOT_KG, abs=1e-9)
        assert m.power_out == 0.0, m          # NaN before (read as a Buehler clock)
        assert math.isnan(m.speed)
    warned = ' '.join(energy._warned)
    assert 'Buehler' not in warned, warned
