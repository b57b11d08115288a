"""Simulated hardware into rosbag2 bags: exact CDR, the drivers' topics, metadata, determinism."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from hexapod_bench_drivers import sim_cdr as cdr
from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.effects import METADATA_KEY, EffectSet, parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import CONFIG_KEY, DEFAULT_START_NS, write_trace
from hexapod_bench_drivers.sim_cli import main as cli_main
from hexapod_common.bags import iter_messages, new_msg, open_reader, stamp, typestore


def same_bytes(msg, msgtype: str, data: bytes) -> None:
    expected = bytes(typestore().serialize_cdr(msg, msgtype))
    assert data == expected


def test_fast_cdr_encoders_match_rosbags_byte_for_byte() -> None:
    t_ns = 1_700_000_000_123_456_789
    names = ['L1_coxa', 'L1_femur', 'R3_tibia']
    pos = np.array([0.1, -0.2, 0.3])
    same_bytes(new_msg('sensor_msgs/msg/JointState', header=stamp(t_ns), name=names,
                       position=pos, velocity=pos * 2, effort=pos * 3),
               'sensor_msgs/msg/JointState', cdr.joint_state(t_ns, names, pos, pos * 2, pos * 3))
    same_bytes(new_msg('sensor_msgs/msg/JointState', header=stamp(t_ns), name=names,
                       position=pos, velocity=pos),
               'sensor_msgs/msg/JointState', cdr.joint_state(t_ns, names, pos, pos, ()))
    nan = math.nan
    bat = new_msg('sensor_msgs/msg/BatteryState', header=stamp(t_ns, 'supply'), voltage=11.9,
                  temperature=nan, current=-3.25, charge=nan, capacity=nan,
                  design_capacity=nan, percentage=nan, power_supply_status=2,
                  power_supply_health=1, power_supply_technology=3, present=True)
    assert cdr.battery_state(t_ns, 11.9, -3.25, status=2, frame_id='supply') == \
        bytes(typestore().serialize_cdr(bat, 'sensor_msgs/msg/BatteryState'))
    legs = ['L1', 'L2', 'L3', 'R1', 'R2', 'R3']
    same_bytes(new_msg('hexapod_interfaces/msg/GaitPhase', header=stamp(t_ns), gait='tripod',
                       period=0.5, duty_factor=0.5, step_length=0.1, step_height=0.04,
                       cycle_phase=0.3, leg_names=legs,
                       phase_offsets=[0, 0.5, 0, 0.5, 0, 0.5],
                       in_stance=[True, False, True, False, True, False], supporting_legs=3),
               'hexapod_interfaces/msg/GaitPhase',
               cdr.gait_phase(t_ns, 'tripod', 0.5, 0.5, 0.1, 0.04, 0.3, legs,
                              [0, 0.5, 0, 0.5, 0, 0.5],
                              [True, False, True, False, True, False], 3))
    same_bytes(new_msg('hexapod_interfaces/msg/ServoStatus', header=stamp(t_ns), name=names,
                       temperature=[26, 27, 28], voltage=[11.9] * 3, load=[0.1, -0.2, 0.0],
                       error=[0, 4, 32]),
               'hexapod_interfaces/msg/ServoStatus',
               cdr.servo_status(t_ns, names, [26, 27, 28], [11.9] * 3, [0.1, -0.2, 0.0],
                                [0, 4, 32]))
    store = typestore()
    vec = store.types['geometry_msgs/msg/Vector3']
    wrench = new_msg('geometry_msgs/msg/WrenchStamped', header=stamp(t_ns, 'bench'),
                     wrench=store.types['geometry_msgs/msg/Wrench'](
                         force=vec(x=0.0, y=0.0, z=6.7), torque=vec(x=0.0, y=0.0, z=0.0)))
    same_bytes(wrench, 'geometry_msgs/msg/WrenchStamped',
               cdr.wrench_stamped(t_ns, (0.0, 0.0, 6.7), (0.0, 0.0, 0.0), 'bench'))
    point = new_msg('geometry_msgs/msg/PointStamped', header=stamp(t_ns, 'bench'),
                    point=store.types['geometry_msgs/msg/Point'](x=0.01, y=0.14, z=0.02))
    same_bytes(point, 'geometry_msgs/msg/PointStamped',
               cdr.point_stamped(t_ns, (0.01, 0.14, 0.02), 'bench'))


def decoded(path):
    out = []
    with open_reader(path) as reader:
        for m in iter_messages(reader):
            out.append((m.topic, m.stamp_ns, reader_types(m)))
    return out


def reader_types(m):
    return typestore().deserialize_cdr(m.data, m.msgtype)


def test_robot_bag_has_the_drivers_topics_and_the_effects_in_metadata(tmp_path) -> None:
    effects = parse_effects(['basal_power=2', 'time_offset=0.1'])
    tr = simulate_robot(0.5, RobotConfig(speed_mps=0.3), effects=effects, seed=5)
    counts = write_trace(tr, tmp_path / 'bag', seed=5)
    assert counts == {'/joint_states': 50, '/joint_commands': 50, '/gait/phase': 50,
                      '/servo_status': 5, '/battery_state': 50}
    meta = yaml.safe_load((tmp_path / 'bag' / 'metadata.yaml').read_text())
    custom = meta['rosbag2_bagfile_information']['custom_data']
    assert json.loads(custom[METADATA_KEY])['basal_power'] == {'value': 2.0, 'unit': 'W'}
    assert EffectSet.from_json(custom[METADATA_KEY]) == effects
    assert json.loads(custom[CONFIG_KEY])['seed'] == 5
    msgs = decoded(tmp_path / 'bag')
    bats = [(t, m) for topic, t, m in msgs if topic == '/battery_state']
    t0, bat = bats[0]
    assert bat.current < 0.0 and 11.8 < bat.voltage < 12.0
    stamp_ns = bat.header.stamp.sec * 10**9 + bat.header.stamp.nanosec
    assert stamp_ns - t0 == pytest.approx(0.1e9, abs=2)         # time_offset on the stamp only
    js = next(m for topic, _, m in msgs if topic == '/joint_states')
    assert list(js.name) == list(tr.joint_names) and len(js.effort) == 18
    gp = next(m for topic, _, m in msgs if topic == '/gait/phase')
    assert gp.gait == 'tripod' and gp.supporting_legs == 3 and list(gp.leg_names)[0] == 'L1'
    assert min(t for _, t, _ in msgs) >= DEFAULT_START_NS


def test_same_seed_gives_the_same_bag(tmp_path) -> None:
    bags = []
    for name in ('a', 'b'):
        tr = simulate_robot(0.3, RobotConfig(speed_mps=0.3), seed=11)
        write_trace(tr, tmp_path / name)
        bags.append(decoded(tmp_path / name))
    assert len(bags[0]) == len(bags[1])
    for (ta, sa, ma), (tb, sb, mb) in zip(*bags):
        assert (ta, sa) == (tb, sb)
        assert repr(ma) == repr(mb)


def test_bench_bag_has_sessions_force_and_tip(tmp_path) -> None:
    tr = simulate_bench(BenchPlan(loads_kg=(0.1,), frequencies_hz=(1.0,), walk_s=1.0,
                                  max_cool_s=10.0))
    counts = write_trace(tr, tmp_path / 'bench')
    assert counts['/bench/session'] == 4
    assert counts['/bench/ground_force'] == counts['/bench/leg_tip'] == counts['/joint_states']
    states = [m.state for topic, _, m in decoded(tmp_path / 'bench') if topic == '/bench/session']
    assert states == ['heating', 'walking', 'cooling', 'done']


def test_cli_robot_and_bench(tmp_path, capsys) -> None:
    rc = cli_main(['robot', '--out', str(tmp_path / 'r'), '--duration', '0.3', '--speed', '0.3',
                   '--effect', 'supply_resistance=0.2', '--seed', '2', '--no-progress'])
    assert rc == 0
    report = json.loads(capsys.readouterr().out)
    assert report['messages']['/joint_states'] == 30
    assert report['effects']['supply_resistance']['value'] == 0.2
    rc = cli_main(['bench', '--out', str(tmp_path / 'b'), '--duration', '0.5', '--loads', '0',
                   '--frequencies', '0,1', '--max-cool', '10', '--no-progress'])
    assert rc == 0
    assert json.loads(capsys.readouterr().out)['messages']['/bench/session'] == 7
    assert cli_main(['robot', '--out', str(tmp_path / 'x'), '--effect', 'nope=1']) == 2
    assert 'nope' in capsys.readouterr().err


def test_cached_gait_and_battery_encoders_on_every_alignment() -> None:
    """The GaitPhase and BatteryState encoders join cached constant blocks (names, counts,
    frame ids) around the numbers: equal to rosbags' bytes for gait names, frame ids and leg
    counts of every length (each shifts the alignment of what follows), empty sequences
    included, and the same block reused with other numbers."""
    rng = np.random.default_rng(5)
    for k in range(300):
        t_ns = int(rng.integers(0, 2**31 * 10**9))
        gait = 'g' * int(rng.integers(0, 12))
        n = int(rng.integers(0, 9))
        legs = [f'L{j}' + 'x' * int(rng.integers(0, 5)) for j in range(n)]
        offsets = rng.uniform(0, 1, n if k % 3 else 0).tolist()
        stance = (rng.uniform(0, 1, n) < 0.5).tolist()
        numbers = rng.normal(0, 1, 7).tolist()
        same_bytes(new_msg('hexapod_interfaces/msg/GaitPhase', header=stamp(t_ns), gait=gait,
                           period=numbers[0], duty_factor=numbers[1], step_length=numbers[2],
                           step_height=numbers[3], sweep_angle=numbers[4],
                           leg_offset=numbers[5], cycle_phase=numbers[6], leg_names=legs,
                           phase_offsets=offsets, in_stance=stance,
                           supporting_legs=sum(stance)),
                   'hexapod_interfaces/msg/GaitPhase',
                   cdr.gait_phase(t_ns, gait, numbers[0], numbers[1], numbers[2], numbers[3],
                                  numbers[6], legs, offsets, stance, sum(stance),
                                  sweep_angle_rad=numbers[4], leg_offset_rad=numbers[5]))
        frame = 'f' * int(rng.integers(0, 10))
        v, i = float(rng.uniform(6, 13)), float(rng.normal(0, 3))
        status = int(rng.integers(0, 5))
        bat = new_msg('sensor_msgs/msg/BatteryState', header=stamp(t_ns, frame), voltage=v,
                      temperature=math.nan, current=i, charge=math.nan, capacity=math.nan,
                      design_capacity=math.nan, percentage=math.nan,
                      power_supply_status=status, power_supply_health=1,
                      power_supply_technology=3, present=True)
        assert cdr.battery_state(t_ns, v, i, status=status, frame_id=frame) == \
            bytes(typestore().serialize_cdr(bat, 'sensor_msgs/msg/BatteryState'))
