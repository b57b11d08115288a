"""Motion-capture rigid bodies defined with other axes than the robot's.

- Any yaw of the rigid body (OptiTrack defines it with the axes the robot had when it was
  created): before, the pitch came from the body x axis, and an EduBot run whose body frame was
  turned 90 deg about z fitted no stance (213 too short). The pitch is now the body z's tilt
  towards the run: the same stances as the aligned run.
- Another axis up: refused, naming the axis that points up (from the COM's bounce), and
  ``--body-up AXIS`` gives the aligned run's stances.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from hexapod_common.bags import BagWriter, iter_messages, open_reader
from slip_identification.geometry import body_pitch_rad
from slip_identification.pipeline import body_up_rotation, rotate_body


def test_pitch_ignores_the_body_yaw():
    for yaw in (0.0, 37.0, 90.0, 180.0):
        q = (Rotation.from_euler('y', [[0.1], [-0.2]]) *
             Rotation.from_euler('z', yaw, degrees=True)).as_quat()
        np.testing.assert_allclose(body_pitch_rad(np.eye(3), q), [0.1, -0.2], atol=1e-12)


@pytest.mark.parametrize('axis', ['x', 'y', 'z', '-x', '-y', '-z'])
def test_body_up_rotation(axis):
    e = {'x': [1, 0, 0], 'y': [0, 1, 0], 'z': [0, 0, 1]}[axis.lstrip('-')]
    want = -np.array(e) if axis.startswith('-') else np.array(e)
    np.testing.assert_allclose(Rotation.from_quat(body_up_rotation(axis)).apply([0, 0, 1]),
                               want, atol=1e-12)
    q = Rotation.from_euler('xyz', [0.3, -0.2, 1.1]).as_quat()
    got = Rotation.from_quat(rotate_body(q[None], axis)[0]).apply([0, 0, 1])
    np.testing.assert_allclose(got, Rotation.from_quat(q).apply(want), atol=1e-12)


def _rewrite(src, dst, turn: Rotation) -> None:
    with open_reader(src) as r, BagWriter(dst) as w:
        for m in iter_messages(r):
            if m.topic != '/mocap/body':
                w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
                continue
            msg = r.deserialize(m.data, m.msgtype)
            o = msg.pose.orientation
            q = (Rotation.from_quat([o.x, o.y, o.z, o.w]) * turn).as_quat()
            o.x, o.y, o.z, o.w = (float(v) for v in q)
            w.write(m.topic, m.msgtype, msg, m.stamp_ns)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')
    root = tmp_path_factory.mktemp('bodyframe')
    # 4 s: the motion capture tracks the run from 1.5 to 4.0 s (6 s gave the same 15 stances,
    # edges and stiffness against the yawed and the y-up rigid bodies, and the same refusal)
    edubot_bag.write_edubot_bag(root / 'ed', 'running', duration_s=4.0, seed=1)
    _rewrite(root / 'ed', root / 'yawed', Rotation.from_euler('z', 90, degrees=True))
    _rewrite(root / 'ed', root / 'y_up', Rotation.from_euler('x', 90, degrees=True))
    return root


def _same(a, b):
    """Same stances: edges on the same 1 ms grid sample or the next (the rotated pitch differs
    in its last bits, which can move a crossing by a sample), median stiffness within 1 %."""
    assert len(a['stances']) == len(b['stances']) >= 10
    for x, y in zip(a['stances'], b['stances']):
        assert abs(x['touchdown'] - y['touchdown']) <= 1.001e-3
        assert abs(x['liftoff'] - y['liftoff']) <= 1.001e-3
    ka = np.array([x['stiffness'] for x in a['stances']])
    kb = np.array([x['stiffness'] for x in b['stances']])
    assert np.median(np.abs(kb / ka - 1)) < 0.01


def test_yawed_and_other_up_body_frames(bags):
    from slip_identification.cli import analyze_bag

    ref = analyze_bag(str(bags / 'ed'), {'edges': 'auto', 'offset': 'auto'})
    _same(ref, analyze_bag(str(bags / 'yawed'), {'edges': 'auto', 'offset': 'auto'}))
    refused = analyze_bag(str(bags / 'y_up'), {'edges': 'auto', 'offset': 'auto'})
    assert '--body-up y' in refused['error']
    # the user's word overrides the check (a robot that sways more than it bounces)
    kept = analyze_bag(str(bags / 'y_up'), {'edges': 'auto', 'offset': 'auto', 'body_up': 'z'})
    assert 'error' not in kept or 'body' not in kept['error']
    fixed = analyze_bag(str(bags / 'y_up'), {'edges': 'auto', 'offset': 'auto', 'body_up': 'y'})
    _same(ref, fixed)
    assert any('--body-up' in n for n in fixed['run']['notes'])
