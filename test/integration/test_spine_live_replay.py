"""The spine end to end: simulated source -> energy_monitor live, recorded, replayed offline."""

from __future__ import annotations

import math

import pytest
from harness import Collector, ros_env
from hexapod_interfaces.msg import EnergeticDescriptors
from rclpy.parameter import Parameter

from hexapod_common.bags import open_reader
from hexapod_common.recorder_node import BagRecorderNode
from hexapod_common.replay import run_offline
from hexapod_common.spine_source import SpineSourceNode, spine_power_w
from hexapod_energy.energy_node import EnergyMonitorNode

FIELDS = ('window', 'mass', 'speed', 'power_in', 'power_out', 'power_loss', 'efficiency',
          'cost_of_transport', 'specific_cost_of_transport', 'specific_resistance')


@pytest.mark.timeout(120)
def test_live_descriptors_equal_replayed_ones(tmp_path):
    bag = tmp_path / 'spine'
    topics = ['gait/phase', 'joint_states', 'battery_state']
    with ros_env('spine') as env:
        recorder = env.make(BagRecorderNode, parameter_overrides=[
            Parameter('output', value=str(bag)), Parameter('topics', value=topics),
            Parameter('discovery_period', value=0.05)])
        energy = env.make(EnergyMonitorNode, parameter_overrides=[
            Parameter('current_sign', value='ros')])
        out = Collector(env, EnergeticDescriptors, 'energy/descriptors')
        source = env.make(SpineSourceNode, parameter_overrides=[
            Parameter('period', value=0.5)])
        namespace = env.namespace
        out.wait_for(env, 4, timeout_s=60)
        live = list(out.messages)
        # the recorder must have subscribed to every topic; let it drain
        assert env.spin_until(lambda: len(recorder.counts) == 3, 10)
        env.executor.remove_node(source)
        source.destroy_node()
        env.nodes.remove(source)
        env.spin_until(lambda: False, 0.3)  # drain in-flight messages (bounded wait)
        recorded = dict(recorder.counts)
        assert energy.dropped == 0
    # the bag holds what the recorder counted
    with open_reader(bag) as reader:
        in_bag = {c.topic: c.msgcount for c in reader.connections}
    assert {k: v for k, v in in_bag.items() if v} == recorded

    # power_in is the mean of -V*I with I negative while discharging
    for msg in live:
        assert 12.0 < msg.power_in < 12.0 + 10.0 / 0.5 + 4.0
        assert msg.window == pytest.approx(0.5, abs=0.02)

    with ros_env('spine_offline') as env2:
        offline_node = EnergyMonitorNode(context=env2.context, namespace=namespace,
                                         parameter_overrides=[
                                             Parameter('current_sign', value='ros')])
        env2.nodes.append(offline_node)
        captured = run_offline([offline_node], bag)
    replayed = captured[f'{namespace}/energy/descriptors']
    assert len(replayed) >= len(live)
    for a, b in zip(live, replayed):
        assert (a.header.stamp.sec, a.header.stamp.nanosec) == \
            (b.header.stamp.sec, b.header.stamp.nanosec)
        for name in FIELDS:
            va, vb = getattr(a, name), getattr(b, name)
            assert (math.isnan(va) and math.isnan(vb)) or abs(va - vb) <= 1e-9, name


def test_spine_power_is_positive():
    assert all(spine_power_w(t * 0.01, 1.0) > 12.0 for t in range(100))
