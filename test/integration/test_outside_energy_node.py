"""``energy_monitor`` fed by another lab: its own publisher QoS, JointState name order that
changes between messages, zero header stamps, and an old sqlite3 bag with an unknown type."""

from __future__ import annotations

import math

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time
from harness import Collector, capture_errors, ros_env
from hexapod_interfaces.msg import EnergeticDescriptors, GaitPhase
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import BatteryState, JointState

from hexapod_common.replay import run_offline
from hexapod_common.testbags import P0_W, downgrade_sqlite_bag, write_foreign_robot_bag
from hexapod_energy.energy_node import EnergyMonitorNode

P_AMP_W, VOLT_V, PERIOD_S = 1.5, 11.5, 2.0


def _stamp(t_s: float) -> Time:
    ns = int(round(t_s * 1e9))
    return Time(sec=ns // 10**9, nanosec=ns % 10**9)


def _pout_w(t_s: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    phase = 2 * np.pi * (t_s / PERIOD_S + np.arange(n) / 7)
    return 0.3 + 0.1 * np.sin(phase), 0.6 * np.cos(phase)


@pytest.mark.timeout(90)
@pytest.mark.parametrize('reliability', [ReliabilityPolicy.BEST_EFFORT,
                                         ReliabilityPolicy.RELIABLE],
                         ids=['best_effort', 'reliable'])
def test_outside_publisher_qos_and_shuffled_joint_names(reliability):
    qos = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=reliability,
                     durability=DurabilityPolicy.VOLATILE)
    legs = ('L1', 'L2', 'R1', 'R2')
    offsets = (0.75, 0.25, 0.5, 0.0)
    joints = [f'{leg}_{j}' for leg in legs for j in ('coxa', 'femur', 'tibia')]
    rng = np.random.default_rng(3)
    t0 = 1000.0
    with ros_env('outside_qos') as env:
        env.make(EnergyMonitorNode, parameter_overrides=[Parameter('current_sign', value='auto'),
                                                         Parameter('mass', value=2.0)])
        out = Collector(env, EnergeticDescriptors, 'energy/descriptors')
        lab = env.add(rclpy.create_node('other_lab_driver', context=env.context,
                                        namespace=env.namespace))
        pubs = {'battery': lab.create_publisher(BatteryState, 'battery_state', qos),
                'gait': lab.create_publisher(GaitPhase, 'gait/phase', qos),
                'joints': lab.create_publisher(JointState, 'joint_states', qos)}
        assert env.spin_until(lambda: all(p.get_subscription_count() >= 1
                                          for p in pubs.values()), 20)
        truth = []
        for k, t in enumerate(np.arange(0.0, 12.0, 0.02)):
            ts = t0 + t
            eff, vel = _pout_w(t, len(joints))
            truth.append(float(np.sum(np.clip(eff * vel, 0, None))))
            order = rng.permutation(len(joints))  # another driver: name order not fixed
            js = JointState(name=[joints[i] for i in order], position=list(0.1 * vel[order]),
                            velocity=list(vel[order]), effort=list(eff[order]))
            js.header.stamp = _stamp(ts)
            pubs['joints'].publish(js)
            phase = float(t / PERIOD_S) % 1.0
            stance = [bool(((phase - o) % 1.0) < 0.75) for o in offsets]
            g = GaitPhase(gait='wave', period=PERIOD_S, duty_factor=0.75, step_length=0.06,
                          step_height=0.03, cycle_phase=phase, leg_names=list(legs),
                          phase_offsets=list(offsets), in_stance=stance,
                          supporting_legs=sum(stance))
            g.header.stamp = _stamp(ts)
            pubs['gait'].publish(g)
            if k % 5 == 0:
                power = P0_W + P_AMP_W * math.sin(2 * math.pi * t / PERIOD_S)
                b = BatteryState(voltage=VOLT_V, current=power / VOLT_V)  # positive: discharge
                b.header.stamp = _stamp(ts)
                pubs['battery'].publish(b)
            for _ in range(3):
                env.executor.spin_once(timeout_sec=0.0)
        msgs = out.wait_for(env, 4, timeout_s=30)
    for m in msgs:
        assert m.window == pytest.approx(PERIOD_S, abs=0.03)
        assert m.power_in == pytest.approx(P0_W, rel=0.01)
        assert m.power_out == pytest.approx(float(np.mean(truth)), rel=0.05)


@pytest.mark.timeout(90)
def test_offline_foxy_bag_zero_stamps_unknown_type(tmp_path):
    bag = tmp_path / 'foxy'
    truth = write_foreign_robot_bag(bag, legs=8, zero_stamps=True, msgdef=False,
                                    unknown_topic=True)
    downgrade_sqlite_bag(bag, 4)
    with ros_env('outside_offline') as env:
        # the bag's topics are the contract's, so the node is not namespaced (offline only)
        node = EnergyMonitorNode(context=env.context, parameter_overrides=[
            Parameter('current_sign', value='ros'), Parameter('mass', value=2.0)])
        env.nodes.append(node)
        captured = run_offline([node], str(bag))
        assert node.dropped == 0
    msgs = captured['/energy/descriptors']
    assert len(msgs) >= 4
    for m in msgs:
        assert m.window == pytest.approx(PERIOD_S, abs=0.03)
        assert m.power_in == pytest.approx(P0_W, rel=3e-3)
        assert m.power_out == pytest.approx(float(np.mean(truth['pout'][:, 1])), rel=0.05)


@pytest.mark.timeout(90)
def test_two_batteries_on_one_topic_are_summed(tmp_path):
    """A servo pack (30 W) and a logic pack (5 W) on battery_state, told apart by frame_id:
    the node publishes their sum (it published their rate-weighted mean, 25.8 W), as the
    offline reader does; ``battery_source`` keeps one."""
    from hexapod_common.testbags import write_two_battery_robot_bag
    from hexapod_energy.bag_io import read_robot_bag

    bag = tmp_path / 'packs'
    write_two_battery_robot_bag(bag)
    offline = read_robot_bag(bag, mass_kg=2.0)
    got = {}
    with ros_env('outside_packs') as env:
        for keep in ('', 'servo'):
            node = EnergyMonitorNode(context=env.context, parameter_overrides=[
                Parameter('current_sign', value='auto'), Parameter('mass', value=2.0),
                Parameter('battery_source', value=keep)])
            env.nodes.append(node)
            got[keep] = run_offline([node], str(bag))['/energy/descriptors']
    assert len(got['']) >= 20
    for m in got[''][1:]:
        assert m.power_in == pytest.approx(35.0, rel=2e-3)
    assert float(np.mean([m.power_in for m in got[''][1:]])) == pytest.approx(
        offline.power_in_w, rel=1e-3)
    for m in got['servo']:
        assert m.power_in == pytest.approx(30.0, rel=2e-3)


@pytest.mark.timeout(90)
def test_battery_on_another_clock_is_reported(tmp_path):
    """A battery board stamping from its boot (57 s) in a robot recorded at 1000 s: live, its
    samples never meet a gait window; the node says why, once, as an error."""
    from hexapod_common.testbags import restamp_topic, write_two_battery_robot_bag

    write_two_battery_robot_bag(tmp_path / 'ref', logic_w=0.0)
    bag = restamp_topic(tmp_path / 'ref', tmp_path / 'boot', '/battery_state', 57.0 - 1000.0)
    errors = _errors_offline(bag)
    assert len(errors) == 1 and errors[0].startswith('battery_state stamped on another clock')
    assert 'from the node clock' in errors[0]


@pytest.mark.timeout(90)
def test_battery_current_always_zero_is_reported(tmp_path):
    """A monitor without a current sensor that publishes 0 A: reported once, as an error."""
    from hexapod_common.testbags import write_two_battery_robot_bag

    bag = tmp_path / 'z'
    write_two_battery_robot_bag(bag, servo_w=0.0, logic_w=0.0)
    errors = _errors_offline(bag)
    assert len(errors) == 1 and 'does not measure it' in errors[0]


def _errors_offline(bag) -> list[str]:
    """The errors an energy_monitor logs while ``bag`` is replayed through it."""
    with ros_env('outside_errors') as env:
        node = EnergyMonitorNode(context=env.context, parameter_overrides=[
            Parameter('current_sign', value='ros'), Parameter('mass', value=2.0)])
        env.nodes.append(node)
        errors = capture_errors(node)
        run_offline([node], str(bag))
    return errors


@pytest.mark.timeout(90)
def test_battery_in_millivolts(tmp_path):
    """A driver publishing the voltage in millivolts: the node divides it (it published 1000
    times the power), warning once, as the offline reader does."""
    from hexapod_common.testbags import rewrite_bag, write_two_battery_robot_bag

    def millivolts(topic, msg):
        if topic == '/battery_state':
            msg.voltage *= 1000.0

    def milliamps_too(topic, msg):  # the same driver's current in mA (under 1 A: < 1000)
        if topic == '/battery_state':
            msg.voltage *= 1000.0
            msg.current *= 1000.0

    write_two_battery_robot_bag(tmp_path / 'v', logic_w=0.0)
    rewrite_bag(tmp_path / 'v', tmp_path / 'mv', millivolts)
    rewrite_bag(tmp_path / 'v', tmp_path / 'mvma', milliamps_too)
    got = {}
    for name in ('v', 'mv', 'mvma'):
        with ros_env('outside_mv') as env:
            node = EnergyMonitorNode(context=env.context, parameter_overrides=[
                Parameter('current_sign', value='ros'), Parameter('mass', value=2.0)])
            env.nodes.append(node)
            got[name] = [m.power_in for m in
                         run_offline([node], str(tmp_path / name))['/energy/descriptors']]
    assert len(got['mv']) == len(got['v']) == len(got['mvma']) >= 10
    np.testing.assert_allclose(got['mv'], got['v'], rtol=1e-9)
    np.testing.assert_allclose(got['mvma'], got['v'], rtol=1e-6)


@pytest.mark.timeout(90)
def test_leg_file_for_the_model_output_power(tmp_path):
    """``-p leg_file:=phantom.yaml``: the Eq. 6 P_out of another robot's leg (it was AntBot's
    leg for every robot), the figure the offline model gives."""
    from hexapod_common.testbags import write_two_battery_robot_bag
    from hexapod_energy.leg_description import load_leg_description
    from hexapod_gait.gait import make_gait

    leg_file = tmp_path / 'phantom.yaml'
    leg_file.write_text('a_m: [0.052, 0.082, 0.155]\nlink_masses_kg: [0.025, 0.14, 0.09]\n'
                        'neutral_tip_m: [0.15, 0.0, -0.13]\n')
    write_two_battery_robot_bag(tmp_path / 'bag', logic_w=0.0)
    got = {}
    for name, extra in (('ant', []), ('phantom', [Parameter('leg_file', value=str(leg_file))])):
        with ros_env('outside_leg') as env:
            node = EnergyMonitorNode(context=env.context, parameter_overrides=[
                Parameter('current_sign', value='ros'), Parameter('mass', value=2.5),
                Parameter('robot_mass', value=2.5), *extra])
            env.nodes.append(node)
            got[name] = run_offline([node], str(tmp_path / 'bag'))['/energy/descriptors']
    gait = make_gait('tripod', period_s=0.5, step_length_m=0.1)
    expected = float(load_leg_description(leg_file).output_power_model(2.5).power_out_w(gait))
    assert len(got['phantom']) >= 10
    for m in got['phantom']:
        assert m.power_out == pytest.approx(expected, rel=1e-6)
    assert got['ant'][0].power_out != pytest.approx(expected, rel=0.05)
