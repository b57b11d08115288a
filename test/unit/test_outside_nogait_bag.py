"""Another lab's servo hexapod without ``/gait/phase``: ``ros2 bag record /joint_states
/battery_state [/odom]`` analysed offline on cycles found from the joint positions.

The bags are written with rosbags' own ``Writer`` from a simulated AntBot run
(``hexapod_bench_drivers.robot_sim``); the same run written with ``/gait/phase`` is the
reference. Without the joint-derived cycles these bags are refused (``/gait/phase`` missing).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_common.testbags import foreign_typestore
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.errors import BagContentError

T0_S = 1_750_000_000.0
WOBBLE_M = 0.004  # body surge once per step: odometry is not a straight line


def _header(T: Any, t_s: float, frame: str = '') -> Any:
    ns = int(round((T0_S + t_s) * 1e9))
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id=frame)


def write_lab_bag(path: Path, trace: Any, *, gait_phase: bool = False, odom: bool = True,
                  effort: bool = True, battery_every: int = 2, storage: str = 'sqlite3',
                  mocap: bool = False) -> None:
    """The simulated run as another lab records it: /joint_states (100 Hz, efforts optional),
    /battery_state (every ``battery_every``-th sample), /odom at 50 Hz (position v t plus a
    surge once per step), and /gait/phase only when asked (the reference)."""
    store = foreign_typestore()
    T = store.types
    cfg = trace.config
    period = float(trace.period_s[0])
    speed = float(trace.speed_mps[0])
    nan = math.nan
    msgs: list[tuple[float, str, str, Any]] = []
    for k, t in enumerate(trace.t_s):
        msgs.append((t, '/joint_states', 'sensor_msgs/msg/JointState',
                     T['sensor_msgs/msg/JointState'](
                         header=_header(T, t), name=list(trace.joint_names),
                         position=trace.position_rad[k], velocity=trace.velocity_rad_s[k],
                         effort=trace.effort_nm[k] if effort else np.zeros(0))))
        if k % battery_every == 0:
            msgs.append((t + 1e-4, '/battery_state', 'sensor_msgs/msg/BatteryState',
                         T['sensor_msgs/msg/BatteryState'](
                             header=_header(T, t), voltage=float(trace.battery_voltage_v[k]),
                             temperature=25.0, current=float(trace.battery_current_a[k]),
                             charge=nan, capacity=nan, design_capacity=nan, percentage=nan,
                             power_supply_status=2, power_supply_health=0,
                             power_supply_technology=0, present=True,
                             cell_voltage=np.zeros(0, np.float32),
                             cell_temperature=np.zeros(0, np.float32), location='',
                             serial_number='')))
        if odom and k % 2 == 0:
            x = speed * t + (WOBBLE_M * math.sin(2 * math.pi * t / period) if period else 0)
            pose = T['geometry_msgs/msg/Pose'](
                position=T['geometry_msgs/msg/Point'](x=x, y=0.0, z=0.0),
                orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0))
            twist = T['geometry_msgs/msg/Twist'](
                linear=T['geometry_msgs/msg/Vector3'](x=speed, y=0.0, z=0.0),
                angular=T['geometry_msgs/msg/Vector3'](x=0.0, y=0.0, z=0.0))
            msgs.append((t + 2e-4, '/odom', 'nav_msgs/msg/Odometry', T['nav_msgs/msg/Odometry'](
                header=_header(T, t, 'odom'), child_frame_id='base_link',
                pose=T['geometry_msgs/msg/PoseWithCovariance'](pose=pose,
                                                               covariance=np.zeros(36)),
                twist=T['geometry_msgs/msg/TwistWithCovariance'](twist=twist,
                                                                 covariance=np.zeros(36)))))
        if mocap and k % 2 == 1:  # 50 Hz, the robot walking along the mocap frame's y
            y = speed * t + (WOBBLE_M * math.sin(2 * math.pi * t / period) if period else 0)
            msgs.append((t + 2e-4, '/mocap/body', 'geometry_msgs/msg/PoseStamped',
                         T['geometry_msgs/msg/PoseStamped'](
                             header=_header(T, t, 'mocap'), pose=T['geometry_msgs/msg/Pose'](
                                 position=T['geometry_msgs/msg/Point'](x=0.5, y=y, z=0.1),
                                 orientation=T['geometry_msgs/msg/Quaternion'](
                                     x=0.0, y=0.0, z=0.0, w=1.0)))))
        if gait_phase:
            stance = np.asarray(trace.in_stance[k], bool)
            msgs.append((t + 3e-4, '/gait/phase', 'hexapod_interfaces/msg/GaitPhase',
                         T['hexapod_interfaces/msg/GaitPhase'](
                             header=_header(T, t), gait=str(trace.gait_name[k]), period=period,
                             duty_factor=float(trace.duty_factor[k]),
                             step_length=float(trace.step_length_m[k]),
                             step_height=float(trace.step_height_m[k]), sweep_angle=0.0,
                             leg_offset=0.0, cycle_phase=float(trace.cycle_phase[k]),
                             leg_names=list(trace.leg_names),
                             phase_offsets=np.array(trace.phase_offsets, float),
                             in_stance=stance, supporting_legs=int(stance.sum()))))
    assert cfg['simulator'] == 'robot'
    msgs.sort(key=lambda m: m[0])
    plugin = StoragePlugin.SQLITE3 if storage == 'sqlite3' else StoragePlugin.MCAP
    with Writer(path, version=8, storage_plugin=plugin) as w:
        conns: dict[str, Any] = {}
        for i, (t, topic, typ, msg) in enumerate(msgs):
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=store)
            w.write(conns[topic], int((T0_S + t + 5e-4) * 1e9) + i,
                    store.serialize_cdr(msg, typ))


def simulated_run(legs: int = 6, gait: str = 'tripod', speed_mps: float = 0.3,
                  duration_s: float = 12.0, seed: int = 2) -> Any:
    duty = 0.5 if gait == 'tripod' else 1 - 1 / legs
    return simulate_robot(duration_s, RobotConfig(leg_count=legs, gait=gait, speed_mps=speed_mps,
                                                  duty_factor=duty), seed=seed)


@pytest.fixture(scope='module')
def tripod_run():
    return simulated_run()


def test_joint_states_battery_odom_only(tmp_path, tripod_run):
    """The brief's acceptance: windows, P_in within 1 % of the /gait/phase analysis, speed
    within 2 % of the true one, P_out from the efforts, notes for every fallback."""
    write_lab_bag(tmp_path / 'ref', tripod_run, gait_phase=True, odom=False)
    write_lab_bag(tmp_path / 'lab', tripod_run)
    ref = read_robot_bag(tmp_path / 'ref', mass_kg=2.183)
    lab = read_robot_bag(tmp_path / 'lab', mass_kg=2.183)
    period = float(tripod_run.period_s[0])
    assert lab.gait is None and lab.extra['cycle_source'] == 'joints'
    assert lab.windows >= 8
    np.testing.assert_allclose(lab.extra['period_s'], period, rtol=0.01)
    np.testing.assert_allclose(lab.power_in_w, ref.power_in_w, rtol=0.01)
    np.testing.assert_allclose(lab.speed_mps, 0.3, rtol=0.02)
    assert lab.extra['speed_source'] == 'odometry'
    np.testing.assert_allclose(lab.power_out_w, ref.power_out_w, rtol=0.03)
    assert lab.extra['leg_names'] == sorted(tripod_run.leg_names)
    notes = ' '.join(lab.extra['notes'])
    assert 'no /gait/phase' in notes and '/odom' in notes


def test_no_speed_source_nan_with_note_and_given_speed(tmp_path, tripod_run):
    write_lab_bag(tmp_path / 'lab', tripod_run, odom=False)
    run = read_robot_bag(tmp_path / 'lab', mass_kg=2.183)
    assert math.isnan(run.speed_mps) and math.isfinite(run.power_in_w)
    assert any('speed unknown' in n for n in run.extra['notes'])
    given = read_robot_bag(tmp_path / 'lab', mass_kg=2.183, speed_mps=0.25)
    assert given.speed_mps == 0.25 and given.extra['speed_source'] == 'given'
    assert given.power_in_w == run.power_in_w


def test_no_efforts_pout_unknown(tmp_path, tripod_run):
    write_lab_bag(tmp_path / 'lab', tripod_run, effort=False)
    run = read_robot_bag(tmp_path / 'lab', mass_kg=2.183)
    assert math.isnan(run.power_out_w) and run.windows >= 8
    assert any('no joint efforts' in n for n in run.extra['notes'])


def test_standing_robot_refused_naming_why(tmp_path):
    trace = simulate_robot(8.0, RobotConfig(period_s=0.0), seed=1)
    write_lab_bag(tmp_path / 'lab', trace, odom=False)
    with pytest.raises(BagContentError) as err:
        read_robot_bag(tmp_path / 'lab', mass_kg=2.183)
    text = str(err.value)
    assert 'standing' in text and '/gait/phase' in text and '\n' not in text


def test_gait_phase_bag_unchanged_by_odom_and_auto(tmp_path, tripod_run):
    """With /gait/phase present the joint path is not taken (auto), whatever else is there."""
    write_lab_bag(tmp_path / 'ref', tripod_run, gait_phase=True, odom=False)
    a = read_robot_bag(tmp_path / 'ref', mass_kg=2.183)
    b = read_robot_bag(tmp_path / 'ref', mass_kg=2.183, cycle_source='gait_phase')
    assert a.windows == b.windows and a.power_in_w == b.power_in_w
    assert a.speed_mps == b.speed_mps and a.extra['cycle_source'] == 'gait_phase'
    assert a.extra['speed_source'] == 'gait_schedule'


def test_mocap_speed_ranks_before_odometry(tmp_path, tripod_run):
    write_lab_bag(tmp_path / 'lab', tripod_run, mocap=True, storage='mcap')
    run = read_robot_bag(tmp_path / 'lab', mass_kg=2.183)
    assert run.extra['speed_source'] == 'mocap' and run.windows >= 8
    np.testing.assert_allclose(run.speed_mps, 0.3, rtol=0.02)


def test_auto_on_a_gait_phase_stream_equals_the_gait_phase_path(tripod_run):
    """Live ``auto`` (joints fed until /gait/phase arrives) gives the gait-phase numbers."""
    from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
    from hexapod_energy.descriptors import DescriptorAccumulator

    tr = tripod_run
    results = {}
    for source in ('auto', 'gait_phase'):
        acc = DescriptorAccumulator(mass_kg=2.183, cycle_source=source)
        out = []
        for k, t in enumerate(tr.t_s):
            out += acc.add_joint_state(JointStateSample(
                t, tr.joint_names, tr.position_rad[k], tr.velocity_rad_s[k], tr.effort_nm[k]))
            out += acc.add_battery(BatterySample(t, tr.battery_voltage_v[k],
                                                 tr.battery_current_a[k], 25.0))
            stance = np.asarray(tr.in_stance[k], bool)
            out += acc.add_gait_phase(GaitPhaseSample(
                t, 'tripod', float(tr.period_s[k]), 0.5, 0.1, 0.04, 0.0, 0.0,
                float(tr.cycle_phase[k]), tr.leg_names, np.array(tr.phase_offsets), stance,
                int(stance.sum())))
        results[source] = [(d.t_end_s, d.power_in_w, d.power_out_w, d.speed_mps) for d in out]
    assert len(results['auto']) >= 8 and results['auto'] == results['gait_phase']
