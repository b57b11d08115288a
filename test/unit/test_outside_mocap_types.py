"""Motion capture as other bridges publish it, and clock-driven gaits' unknown speed.

- ``/mocap/body`` as ``geometry_msgs/TransformStamped`` (vicon_bridge), ``PoseWithCovarianceStamped``
  or ``nav_msgs/Odometry``: read like the contract's PoseStamped (before: an AttributeError
  on ``msg.pose``, so such bags gave no mocap at all); the live nodes take ``mocap_type``.
- A Buehler-clock ``/gait/phase`` (RHex class: step length 0) does not know the robot's speed.
  ``energy`` took it as 0 m/s outside the mocap volume and averaged it with the mocap speed
  (EduBot running: 0.36 m/s reported against 0.88 m/s measured); those windows are now of
  unknown speed and the run's speed is the mocap windows'.
- Motion capture at 60 Hz: the geometry fit's 0.1 s windows held 6 samples and were all
  dropped ("0 gap-free mocap windows"); they are lengthened to 9 samples. Stances of 60 ms
  then hold 3-4 samples: those are skipped as too short, the others keep their edges.
- A y-up motion-capture frame (OptiTrack): the mocap speed is the displacement over whole cycles
  in all three axes (the height returns after a cycle); the x-y distance read 0.818 m/s instead
  of 0.878 on the EduBot run expressed y-up.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hexapod_common.bags import BagWriter, iter_messages, new_msg, open_reader
from hexapod_common.conversions import MOCAP_TYPES, pose_from_msg

Q = dict(x=0.0, y=0.0, z=0.38268343236508984, w=0.9238795325112867)


def _pose(msgtype: str):
    hdr = new_msg('std_msgs/msg/Header', stamp=new_msg('builtin_interfaces/msg/Time', sec=3,
                                                        nanosec=500_000_000), frame_id='world')
    pos = dict(x=1.0, y=2.0, z=0.1)
    if msgtype.endswith('TransformStamped'):
        return new_msg(msgtype, header=hdr, child_frame_id='body', transform=new_msg(
            'geometry_msgs/msg/Transform',
            translation=new_msg('geometry_msgs/msg/Vector3', **pos),
            rotation=new_msg('geometry_msgs/msg/Quaternion', **Q)))
    pose = new_msg('geometry_msgs/msg/Pose', position=new_msg('geometry_msgs/msg/Point', **pos),
                   orientation=new_msg('geometry_msgs/msg/Quaternion', **Q))
    if msgtype.endswith('PoseStamped'):
        return new_msg(msgtype, header=hdr, pose=pose)
    wc = new_msg('geometry_msgs/msg/PoseWithCovariance', pose=pose)
    if msgtype.endswith('Odometry'):
        return new_msg(msgtype, header=hdr, child_frame_id='body', pose=wc)
    return new_msg(msgtype, header=hdr, pose=wc)


@pytest.mark.parametrize('msgtype', sorted(MOCAP_TYPES.values()))
def test_every_mocap_type_gives_the_same_pose(msgtype):
    s = pose_from_msg(_pose(msgtype))
    assert s.t_s == 3.5 and s.frame_id == 'world'
    assert list(s.position_m) == [1.0, 2.0, 0.1]
    assert list(s.orientation_xyzw) == [Q['x'], Q['y'], Q['z'], Q['w']]


def test_a_non_pose_is_refused():
    msg = new_msg('sensor_msgs/msg/BatteryState')
    with pytest.raises(ValueError, match='not a body pose'):
        pose_from_msg(msg)


@pytest.fixture(scope='module')
def edubot_bags(tmp_path_factory):
    edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')
    root = tmp_path_factory.mktemp('mocap_types')
    edubot_bag.write_edubot_bag(root / 'ed', 'running', duration_s=6.0, seed=1)
    with open_reader(root / 'ed') as r, BagWriter(root / 'vicon') as w:
        for m in iter_messages(r):
            if m.topic != '/mocap/body':
                w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
                continue
            msg = r.deserialize(m.data, m.msgtype)
            p, q = msg.pose.position, msg.pose.orientation
            tf = new_msg('geometry_msgs/msg/TransformStamped', header=msg.header,
                         child_frame_id='edubot', transform=new_msg(
                             'geometry_msgs/msg/Transform', translation=new_msg(
                                 'geometry_msgs/msg/Vector3', x=p.x, y=p.y, z=p.z),
                             rotation=q))
            w.write(m.topic, 'geometry_msgs/msg/TransformStamped', tf, m.stamp_ns)
    turn = Rotation.from_euler('x', -90, degrees=True)   # z-up -> y-up
    with open_reader(root / 'ed') as r, BagWriter(root / 'y_up') as w:
        for m in iter_messages(r):
            if m.topic != '/mocap/body':
                w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
                continue
            msg = r.deserialize(m.data, m.msgtype)
            p, o = msg.pose.position, msg.pose.orientation
            p.x, p.y, p.z = (float(v) for v in turn.apply([p.x, p.y, p.z]))
            o.x, o.y, o.z, o.w = (float(v) for v in (
                turn * Rotation.from_quat([o.x, o.y, o.z, o.w])).as_quat())
            w.write(m.topic, m.msgtype, msg, m.stamp_ns)
    return root


def test_sixty_hertz_mocap(edubot_bags: Path, tmp_path):
    from slip_identification.cli import analyze_bag

    with open_reader(edubot_bags / 'ed') as r, BagWriter(tmp_path / 'm60') as w:
        k = 0
        for m in iter_messages(r):
            if m.topic == '/mocap/body':
                k += 1
                if k % 2 == 0:
                    continue
            w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
    opts = {'edges': 'auto', 'offset': 'auto'}
    ref = analyze_bag(str(edubot_bags / 'ed'), opts)
    got = analyze_bag(str(tmp_path / 'm60'), opts)
    assert 'error' not in got, got.get('error')
    assert abs(got['run']['offset_s'] - ref['run']['offset_s']) < 2e-3
    assert len(got['stances']) >= 5
    assert {s['reason'] for s in got['skipped']} <= {'too_short'}
    td = np.array([s['touchdown'] for s in ref['stances']])
    for s in got['stances']:
        assert np.min(np.abs(td - s['touchdown'])) < 2e-3


def test_y_up_mocap_gives_the_same_speed(edubot_bags: Path):
    from hexapod_energy.bag_io import read_robot_bag

    ref = read_robot_bag(edubot_bags / 'ed', mass_kg=3.31)
    y_up = read_robot_bag(edubot_bags / 'y_up', mass_kg=3.31)
    assert y_up.speed_mps == pytest.approx(ref.speed_mps, rel=1e-9)
    assert y_up.power_in_w == ref.power_in_w


def test_vicon_bridge_transforms_give_the_same_slip_fits(edubot_bags: Path, tmp_path):
    from slip_identification.cli import analyze_bag

    opts = {'edges': 'auto'}
    a = analyze_bag(str(edubot_bags / 'ed'), opts)
    b = analyze_bag(str(edubot_bags / 'vicon'), opts)
    assert 'error' not in a and 'error' not in b
    assert len(a['stances']) == len(b['stances']) >= 10
    for x, y in zip(a['stances'], b['stances']):
        assert (x['touchdown'], x['liftoff'], x['stiffness']) == \
            (y['touchdown'], y['liftoff'], y['stiffness'])


def test_clock_gait_speed_is_not_zero(edubot_bags: Path):
    from hexapod_energy.bag_io import read_robot_bag

    for name in ('ed', 'vicon'):
        run = read_robot_bag(edubot_bags / name, mass_kg=3.31)
        assert run.gait.step_length_m == 0.0          # the Buehler clock's schedule
        sources = {d.speed_source for d in run.extra['windows']}
        assert sources == {'mocap', 'none'}
        mocap = [d.speed_mps for d in run.extra['windows'] if d.speed_source == 'mocap']
        assert run.speed_mps == pytest.approx(sum(mocap) / len(mocap), rel=0.02)
        assert 0.7 < run.speed_mps < 1.1               # EduBot running, not ~0.36 m/s
        assert all(math.isnan(d.speed_mps) for d in run.extra['windows']
                   if d.speed_source == 'none')
        assert any('speed unknown in' in n for n in run.extra['notes'])


def test_costs_of_transport_are_over_the_tracked_windows(edubot_bags: Path, tmp_path):
    """Motion capture over part of a run: the specific resistance and the costs of transport
    divide the power of the windows with a known speed by that speed. Before, the run's P_in
    over every window (its start too) was divided by the tracked windows' speed: on a
    simulated EduBot jogging bag 39.6 W over 15 windows against 35.3 W over the 8 tracked."""
    import json

    from hexapod_common.analyze_cli import main as analyze
    from hexapod_energy.bag_io import read_robot_bag

    run = read_robot_bag(edubot_bags / 'ed', mass_kg=3.31)
    wins = run.extra['windows']
    tracked = [d for d in wins if math.isfinite(d.speed_mps)]
    assert 0 < len(tracked) < len(wins)
    span = run.extra['speed_span']
    w = np.array([d.window_s for d in tracked])
    p_in = float(np.sum(w * [d.power_in_w for d in tracked]) / w.sum())
    p_out = float(np.sum(w * [d.power_out_w for d in tracked]) / w.sum())
    assert span['windows'] == len(tracked)
    assert span['power_in_w'] == pytest.approx(p_in, rel=1e-12)
    assert span['power_out_w'] == pytest.approx(p_out, rel=1e-12)

    assert analyze(['energy', '--robot', str(edubot_bags / 'ed'), '--robot-mass', '3.31',
                    '--out', str(tmp_path / 'o'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'o' / 'energy.json').read_text())
    r = doc['robot_runs'][0]
    v = r['speed']
    assert r['measured_power_in_w'] == pytest.approx(run.power_in_w, rel=1e-12)
    assert r['specific_resistance'] == pytest.approx(p_in / (3.31 * 9.81 * v), rel=1e-3)
    assert r['specific_resistance'] != pytest.approx(run.power_in_w / (3.31 * 9.81 * v),
                                                     rel=1e-3)
    if r['power_out_source'] == 'effort':
        assert r['cost_of_transport'] == pytest.approx((p_in - p_out) / v, rel=1e-9)
    assert r['speed_span']['windows'] == len(tracked)
    assert any('cost of transport and specific resistance over those' in n
               for n in r['notes'])
