"""``hexapod-analyze slip`` on an EduBot-like bag from another lab.

The bag is written here with rosbags' ``Writer`` from a simulated run's *true* ground-frame
body state (so the truth is exact): motion capture at 100 Hz instead of 120, in a lab frame
with z up but the robot running at 35 deg yaw, 2.7 m from the origin (and, in one case, the
origin 7 cm off the floor), the mocap clock 20 ms ahead; ``/joint_states`` without hip efforts
(and, in one case, without hip angles); no ``/gait/phase``.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from slip_identification.cli import add_cli

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

STORE = get_typestore(Stores.ROS2_JAZZY)
T = STORE.types
MOCAP_OFFSET_S = 0.02


@pytest.fixture(scope='module')
def sim_run():
    return edubot_sim.simulate_edubot('running', duration_s=4.0, seed=1)


def _header(t_s: float | None, frame: str = ''):
    ns = 0 if t_s is None else int(round(t_s * 1e9))
    return T['std_msgs/msg/Header'](
        stamp=T['builtin_interfaces/msg/Time'](sec=ns // 10**9, nanosec=ns % 10**9),
        frame_id=frame)


def _write(path, run, *, yaw_deg=35.0, shift_m=(2.4, -1.3, 0.0), rate_hz=100.0,
           hip_angles=True, shuffle_names=False, zero_stamps=False, nan_current=False,
           mocap_clock_s=MOCAP_OFFSET_S, t0_s=500.0, logic_pack_w=None, zero_current=False):
    yaw = math.radians(yaw_deg)
    rot = np.array([[math.cos(yaw), -math.sin(yaw), 0.0], [math.sin(yaw), math.cos(yaw), 0.0],
                    [0.0, 0.0, 1.0]])
    tf, fs = run.fine_t_s, run.fine_state  # true [x, vx, z, vz, pitch] at 1 kHz
    tn = np.arange(tf[0] + 0.3, tf[-1] - 0.3, 1.0 / rate_hz)
    x, z, pitch = (np.interp(tn, tf, fs[:, i]) for i in (0, 2, 4))
    pos = np.column_stack([x, np.zeros_like(x), z]) @ rot.T + np.asarray(shift_m)
    # body attitude: pitch about the body y axis, then the lab's yaw about z
    cy, sy, cp, sp = math.cos(yaw / 2), math.sin(yaw / 2), np.cos(pitch / 2), np.sin(pitch / 2)
    quat = np.column_stack([-sy * sp, cy * sp, sy * cp, cy * cp])
    names = [f'{leg}_hip' for leg in run.leg_names]
    nan = math.nan
    empty = np.zeros(0)
    msgs = []
    rng = np.random.default_rng(7)
    hdr = (lambda t, frame='': _header(None, frame)) if zero_stamps else _header
    for k, t in enumerate(run.t_s):
        ts = t0_s + t
        o = rng.permutation(len(names)) if shuffle_names else np.arange(len(names))
        msgs.append((ts, '/joint_states', 'sensor_msgs/msg/JointState',
                     T['sensor_msgs/msg/JointState'](
                         header=hdr(ts), name=[names[i] for i in o],
                         position=run.hip_position_rad[k][o] if hip_angles else empty,
                         velocity=run.hip_velocity_rad_s[k][o], effort=empty)))
        o = o[::-1] if shuffle_names else o  # commands in yet another order
        msgs.append((ts, '/joint_commands', 'sensor_msgs/msg/JointState',
                     T['sensor_msgs/msg/JointState'](
                         header=hdr(ts), name=[names[i] for i in o],
                         position=run.target_position_rad[k][o],
                         velocity=run.target_velocity_rad_s[k][o], effort=empty)))
        msgs.append((ts, '/battery_state', 'sensor_msgs/msg/BatteryState',
                     T['sensor_msgs/msg/BatteryState'](
                         header=hdr(ts), voltage=float(run.battery_voltage_v[k]),
                         temperature=nan,
                         current=nan if nan_current else 0.0 if zero_current
                         else float(run.battery_current_a[k]),
                         charge=nan,
                         capacity=nan, design_capacity=nan, percentage=nan,
                         power_supply_status=2, power_supply_health=0,
                         power_supply_technology=0, present=True,
                         cell_voltage=np.zeros(0, np.float32),
                         cell_temperature=np.zeros(0, np.float32), location='',
                         serial_number='')))
        if logic_pack_w is not None and k % 10 == 3:  # a logic pack beside the robot's
            msgs.append((ts, '/battery_state', 'sensor_msgs/msg/BatteryState',
                         T['sensor_msgs/msg/BatteryState'](
                             header=hdr(ts, 'logic'), voltage=7.4, temperature=nan,
                             current=-logic_pack_w / 7.4, charge=nan, capacity=nan,
                             design_capacity=nan, percentage=nan, power_supply_status=2,
                             power_supply_health=0, power_supply_technology=0, present=True,
                             cell_voltage=np.zeros(0, np.float32),
                             cell_temperature=np.zeros(0, np.float32), location='',
                             serial_number='')))
    for k, t in enumerate(tn):
        ts = t0_s + t + mocap_clock_s
        msgs.append((ts, '/mocap/body', 'geometry_msgs/msg/PoseStamped',
                     T['geometry_msgs/msg/PoseStamped'](
                         header=hdr(ts, 'lab_world'), pose=T['geometry_msgs/msg/Pose'](
                             position=T['geometry_msgs/msg/Point'](
                                 x=pos[k, 0], y=pos[k, 1], z=pos[k, 2]),
                             orientation=T['geometry_msgs/msg/Quaternion'](
                                 x=quat[k, 0], y=quat[k, 1], z=quat[k, 2], w=quat[k, 3])))))
    msgs.sort(key=lambda m: m[0])
    with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
        conns = {}
        for _, topic, typ, _ in msgs:
            if topic not in conns:
                conns[topic] = w.add_connection(topic, typ, typestore=STORE)
        for i, (ts, topic, typ, msg) in enumerate(msgs):
            w.write(conns[topic], int(ts * 1e9) + i, STORE.serialize_cdr(msg, typ))
    return path


def _slip(tmp_path, bag, name, *extra):
    """``slip`` on ``bag`` into ``tmp_path / name``: (exit code, slip.json). Without figures
    (--no-plots): these tests read slip.json only, and the figures cost about 2 s a run
    (test_output_folders.py and test_slip_figures_review_f2.py cover them)."""
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(['slip', str(bag), '--out', str(tmp_path / name), '--no-plots',
                          *extra])
    code = args.func(args)
    return code, json.loads((tmp_path / name / 'slip.json').read_text())


@pytest.fixture(scope='module')
def lab_doc(tmp_path_factory, sim_run):
    """``slip`` on the lab bag as written by default (35 deg yaw, shifted origin, 100 Hz,
    mocap 20 ms ahead): (exit code, slip.json). Two tests read this same analysis."""
    root = tmp_path_factory.mktemp('outside_slip_lab')
    return _slip(root, _write(root / 'lab', sim_run), 'out_lab')


def _medians(doc):
    return (float(np.median([s['stiffness'] for s in doc['stances']])),
            float(np.median([s['rest_length'] for s in doc['stances']])))


def test_other_lab_frame_100hz_no_efforts_no_gait_phase(tmp_path, sim_run, lab_doc):
    ref = _write(tmp_path / 'ref', sim_run, yaw_deg=0.0, shift_m=(0.0, 0.0, 0.0))
    code_ref, doc_ref = _slip(tmp_path, ref, 'out_ref')
    code, doc = lab_doc
    assert code == 0 and code_ref == 0 and not doc['failed_bags']
    run = doc['runs'][0]
    # the analysis does not depend on where the lab put its origin and axes
    assert run['edges'] == 'geometry' and run['offset_method'] == 'geometry'
    assert run['frame']['yaw_deg'] == pytest.approx(35.0, abs=0.05)
    assert run['offset_s'] == pytest.approx(MOCAP_OFFSET_S, abs=2e-3)
    assert run['ground_m'] == pytest.approx(0.0, abs=2e-3)
    assert len(doc['stances']) == len(doc_ref['stances']) >= 10
    np.testing.assert_allclose(_medians(doc), _medians(doc_ref), rtol=1e-3)
    assert run['frame']['box']['source'] == 'tracked_samples'
    notes = ' '.join(run['notes'])
    assert 'default 2 x 1 x 1 m box' in notes and 'no hip efforts' in notes
    assert 'no /gait/phase' in notes and doc['stances'][0]['gait'] == 'unknown'


def test_mocap_origin_off_the_floor_and_joint_name_order_changing(tmp_path, sim_run):
    bag = _write(tmp_path / 'lab', sim_run, shift_m=(2.4, -1.3, 0.07), shuffle_names=True)
    code, doc = _slip(tmp_path, bag, 'out')
    assert code == 0
    run = doc['runs'][0]
    assert run['ground_m'] == pytest.approx(0.07, abs=2e-3)
    assert run['offset_s'] == pytest.approx(MOCAP_OFFSET_S, abs=2e-3)
    assert len(doc['stances']) >= 10
    assert any('not on the floor' in n for n in run['notes'])


def test_no_hip_angles_falls_back_to_paper_edges_with_note(tmp_path, sim_run):
    bag = _write(tmp_path / 'lab', sim_run, hip_angles=False)
    code, doc = _slip(tmp_path, bag, 'out')
    assert code == 0
    run = doc['runs'][0]
    assert run['edges'] == 'paper' and run['offset_method'] == 'xcorr'
    assert run['geometry_edges'] == [] and len(doc['stances']) >= 10
    assert any("paper's shifted-clock edges" in n and 'hip angles' in n for n in run['notes'])


def test_zero_header_stamps_and_nan_battery_current(tmp_path, sim_run):
    bag = _write(tmp_path / 'lab', sim_run, zero_stamps=True, nan_current=True)
    code, doc = _slip(tmp_path, bag, 'out')
    assert code == 0 and not doc['failed_bags']
    run = doc['runs'][0]
    # receive times equal the stamps in this bag: the same offset and ground as with stamps
    assert run['offset_s'] == pytest.approx(MOCAP_OFFSET_S, abs=2e-3)
    assert run['ground_m'] == pytest.approx(0.0, abs=2e-3)
    assert len(doc['stances']) >= 10
    assert run['power_w'] is None and run['sr'] is None
    notes = ' '.join(run['notes'])
    assert 'zero header stamp' in notes and '/mocap/body' in notes
    assert 'no usable /battery_state' in notes


def test_mocap_on_another_clock_refused_in_one_line(tmp_path, sim_run):
    bag = _write(tmp_path / 'lab', sim_run, mocap_clock_s=-400.0)
    code, doc = _slip(tmp_path, bag, 'out')
    assert code == 2 and not doc["stances"]
    err = doc['failed_bags'][0]['error']
    assert '\n' not in err and 'overlap' in err
    # with the offset given (wrongly) and no hip angles (paper edges) the run gave 0 stances
    # and exit 0, silently; now the refusal names the clocks
    bag = _write(tmp_path / 'noangles', sim_run, mocap_clock_s=-400.0, hip_angles=False)
    code, doc = _slip(tmp_path, bag, 'out2', '--offset', '0.02')
    assert code == 2 and not doc["stances"]
    err = doc['failed_bags'][0]['error']
    assert '\n' not in err and 'different clocks' in err


def test_two_batteries_summed_for_the_specific_resistance(tmp_path, sim_run, lab_doc):
    """The robot's pack and a 4 W logic pack (frame_id ``logic``) on /battery_state: the run's
    power is their sum (it was their rate-weighted mean), and the specific resistance with it.
    (The robot's pack alone is the default lab bag, ``lab_doc``.)"""
    _, one = lab_doc
    _, two = _slip(tmp_path, _write(tmp_path / 'two', sim_run, logic_pack_w=4.0), 'two')
    p1, p2 = one['runs'][0]['power_w'], two['runs'][0]['power_w']
    assert p2 == pytest.approx(p1 + 4.0, rel=0.02)
    assert two['runs'][0]['sr'] == pytest.approx(one['runs'][0]['sr'] * p2 / p1, rel=1e-6)
    assert any('2 batteries on /battery_state' in n for n in two['runs'][0]['notes'])


def test_battery_current_always_zero_gives_no_power(tmp_path, sim_run):
    """A monitor that fills current 0 (no current sensor): the run's power and specific
    resistance are null, noted (they read 0 W and 0 before)."""
    code, doc = _slip(tmp_path, _write(tmp_path / 'z', sim_run, zero_current=True), 'z')
    run = doc['runs'][0]
    assert code == 0 and run['power_w'] is None and run['sr'] is None
    assert any('has current 0: the monitor does not measure it' in n for n in run['notes'])
