"""energy_monitor on a live simulated run (sim_robot + gait_scheduler on one executor), recorded,
then replayed offline through a fresh energy_monitor: the descriptors agree to 1e-9.

The simulated AX-18A servos report their load (PWM fraction) as effort, which is not a torque, so
the monitor takes P_out from the Eq. 6 model (``power_out_source=model``); a second check runs
the same bag with ``auto`` (efforts present -> effort-based P_out), equal live and offline too.
Run for the tripod (beta 0.5) and the wave gait (beta 5/6, one leg in swing at a time).
"""

from __future__ import annotations

import math

import pytest
from harness import Collector, ros_env
from hexapod_interfaces.msg import EnergeticDescriptors
from rclpy.parameter import Parameter

from hexapod_bench_drivers.sim_nodes import SimRobotNode
from hexapod_common.recorder_node import BagRecorderNode
from hexapod_common.replay import run_offline
from hexapod_energy.energy_node import EnergyMonitorNode
from hexapod_energy.prediction import OutputPowerModel
from hexapod_gait.gait import make_gait
from hexapod_gait.gait_node import GaitSchedulerNode

FIELDS = ('window', 'mass', 'speed', 'power_in', 'power_out', 'power_loss', 'efficiency',
          'cost_of_transport', 'specific_cost_of_transport', 'specific_resistance')
PAYLOAD_KG = 0.2


def _monitor_params(source: str) -> list[Parameter]:
    return [Parameter('current_sign', value='ros'), Parameter('power_out_source', value=source),
            Parameter('mass', value=2.183 + PAYLOAD_KG)]


def _same(a, b) -> None:
    assert (a.header.stamp.sec, a.header.stamp.nanosec) == \
        (b.header.stamp.sec, b.header.stamp.nanosec)
    for name in FIELDS:
        va, vb = getattr(a, name), getattr(b, name)
        assert (math.isnan(va) and math.isnan(vb)) or abs(va - vb) <= 1e-9, name


@pytest.mark.timeout(180)
@pytest.mark.parametrize('gait_name, beta, period_s', [('tripod', 0.5, 0.5),
                                                       ('wave', 5 / 6, 1.0)])
def test_live_sim_descriptors_equal_offline(tmp_path, gait_name, beta, period_s) -> None:
    bag = tmp_path / 'live'
    topics = ['gait/phase', 'joint_states', 'battery_state']
    with ros_env('energy_live') as env:
        recorder = env.make(BagRecorderNode, parameter_overrides=[
            Parameter('output', value=str(bag)), Parameter('topics', value=topics),
            Parameter('discovery_period', value=0.05)])
        energy = env.make(EnergyMonitorNode, parameter_overrides=_monitor_params('model'))
        out = Collector(env, EnergeticDescriptors, 'energy/descriptors')
        gait = env.make(GaitSchedulerNode, parameter_overrides=[
            Parameter('period', value=period_s), Parameter('gait', value=gait_name),
            Parameter('duty_factor', value=beta)])
        sim = env.make(SimRobotNode, parameter_overrides=[
            Parameter('payload', value=PAYLOAD_KG)])
        namespace = env.namespace
        assert env.spin_until(lambda: len(recorder.counts) == 3, 20)
        out.wait_for(env, 5, timeout_s=90)
        for node in (sim, gait):
            env.executor.remove_node(node)
            node.destroy_node()
            env.nodes.remove(node)
        env.spin_until(lambda: False, 0.3)  # drain in-flight messages (bounded wait)
        live = list(out.messages)
        assert energy.dropped == 0

    expected = OutputPowerModel().power_out_w(
        make_gait(gait_name, period_s=period_s, duty_factor=beta), payload_kg=PAYLOAD_KG)
    print(f'\nlive windows {len(live)}; model P_out {expected:.4f} W')
    for msg in live:
        print(f'  window {msg.window:.3f} s: P_in {msg.power_in:.3f} W, P_out '
              f'{msg.power_out:.4f} W, eta {msg.efficiency:.4f}, speed {msg.speed:.3f} m/s, '
              f'CoT/M {msg.specific_cost_of_transport:.2f}')
        assert msg.window == pytest.approx(period_s, abs=0.02)
        assert msg.power_out == pytest.approx(expected, rel=1e-12)
        assert 15.0 < msg.power_in < 80.0
        assert 0.003 < msg.efficiency < 0.07
        assert msg.mass == pytest.approx(2.183 + PAYLOAD_KG)

    replayed = {}
    for source in ('model', 'auto'):
        with ros_env('energy_offline') as env2:
            node = EnergyMonitorNode(context=env2.context, namespace=namespace,
                                     parameter_overrides=_monitor_params(source))
            env2.nodes.append(node)
            replayed[source] = run_offline([node], bag)[f'{namespace}/energy/descriptors']
    assert len(replayed['model']) >= len(live)
    for a, b in zip(live, replayed['model']):
        _same(a, b)
    # efforts are present in the bag, but they are AX load x stall torque, not torques: many
    # times the model's positive joint power, so auto refuses them and takes the model (same
    # windows, same numbers as 'model')
    auto = replayed['auto']
    assert [b.power_in for b in auto] == [b.power_in for b in replayed['model']]
    assert [b.power_out for b in auto] == [b.power_out for b in replayed['model']]
    print(f'  auto P_out {[round(b.power_out, 3) for b in auto]} W (efforts refused)')
