"""``energy_monitor`` fed malformed messages (an outside review of broken inputs): battery
samples below or at 0 V and gait schedules no gait has are dropped, said, and publish
nothing wrong; the node keeps publishing the windows it can."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from harness import ros_env
from rclpy.parameter import Parameter

from hexapod_common.replay import run_offline
from hexapod_common.testbags import rewrite_bag
from hexapod_energy.energy_node import EnergyMonitorNode


@pytest.fixture(scope='module')
def robot(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from hexapod_bench_drivers.sim_cli import main as sim_main

    bag = tmp_path_factory.mktemp('robust_node') / 'robot'
    assert sim_main(['robot', '--out', str(bag), '--duration', '6']) == 0
    return bag


def _windows(bag: Path) -> tuple[list, list[str]]:
    """The descriptors an energy_monitor publishes from ``bag`` and its warnings."""
    with ros_env('robust') as env:
        node = EnergyMonitorNode(context=env.context, parameter_overrides=[
            Parameter('mass', value=2.183)])
        env.nodes.append(node)
        warnings: list[str] = []
        # captured, not passed on: rclpy ties a throttled call's filters to its call site
        node.get_logger().warning = lambda msg, **kw: warnings.append(msg)
        out = run_offline([node], str(bag))['/energy/descriptors']
    return out, warnings


@pytest.mark.timeout(90)
def test_battery_below_0_v_is_dropped_live(robot, tmp_path):
    """One sample in 10 at -V read every live window's P_in 20.5 % low, without a word."""
    k = [0]

    def edit(topic, msg):
        k[0] += 1
        if k[0] % 10 == 0:
            msg.voltage = -msg.voltage

    bad = rewrite_bag(robot, tmp_path / 'neg', edit, topics=['/battery_state'])
    ref, _ = _windows(robot)
    got, warnings = _windows(bad)
    assert len(got) >= len(ref) - 1 >= 3
    p_ref = sum(m.power_in for m in ref) / len(ref)
    for m in got:
        assert m.power_in == pytest.approx(p_ref, rel=0.01)
    assert any('not a battery voltage' in w for w in warnings)


@pytest.mark.timeout(90)
@pytest.mark.parametrize('field, value', [('duty_factor', 1.5), ('step_length', -0.1),
                                          ('leg_names', [])])
def test_gait_schedule_no_gait_has_publishes_nothing_wrong(robot, tmp_path, field, value):
    """Live windows from such a schedule read speed 0.067 m/s and SR 19.7 (duty factor 1.5),
    efficiency 0.396 from refused efforts (negative step), P_out 0 W (no legs); now the
    messages are dropped and the windows (cycles from the joint positions) keep their P_in
    with speed and P_out unknown (NaN)."""
    def edit(topic, msg):
        setattr(msg, field, value)

    bad = rewrite_bag(robot, tmp_path / 'bad', edit, topics=['/gait/phase'])
    ref, _ = _windows(robot)
    got, warnings = _windows(bad)
    assert len(got) >= 3
    p_ref = sum(m.power_in for m in ref) / len(ref)
    for m in got:
        # cycles from the joint positions: other window bounds (the start-up one 6.6 % up)
        assert m.power_in == pytest.approx(p_ref, rel=0.1)
        for value_ in (m.speed, m.power_out, m.efficiency, m.specific_resistance):
            assert math.isnan(value_)
    assert any('dropped a GaitPhase message' in w for w in warnings)


@pytest.mark.timeout(90)
def test_each_kind_of_dropped_message_is_said(robot, tmp_path, capfd):
    """One 5 s throttle over every dropped message: NaN battery samples hid a schedule whose
    every message was dropped (duty factor 1.5), and a steady stream was said every 5 s. Now
    each kind is said on its 1st, 10th, 100th ... occurrence, with the count."""
    k = [0]

    def edit(topic, msg):
        if topic == '/gait/phase':
            msg.duty_factor = 1.5
        else:
            k[0] += 1
            if k[0] % 10 == 0:
                msg.current = float('nan')

    bad = rewrite_bag(robot, tmp_path / 'bad', edit, topics=['/battery_state', '/gait/phase'])
    capfd.readouterr()
    with ros_env('robust_drops') as env:
        node = EnergyMonitorNode(context=env.context, parameter_overrides=[
            Parameter('mass', value=2.183)])
        env.nodes.append(node)
        run_offline([node], str(bad))
    err = capfd.readouterr().err.splitlines()
    battery = [x for x in err if 'dropped a BatteryState message' in x]
    gait = [x for x in err if 'dropped a GaitPhase message' in x]
    assert len(battery) == 2 and '[10 such messages so far]' in battery[1], battery
    assert len(gait) == 3 and '[100 such messages so far]' in gait[2], gait
