"""RHex-class robots whose hip motors are mounted mirrored (the right side, or every hip) report
forward rotation negative. Before, ``slip`` took the angles as they were and silently fitted
wrong stances (right hips negated: offset 30.7 ms instead of 25.4 ms, stiffness off by up to
39 %). Hips that turn backwards over the run are now negated, with a note giving the online
``slip_fitter`` ``hip_signs`` value; the fits equal the unmirrored bag's."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.bags import BagWriter, iter_messages, open_reader
from slip_identification.joints import rotation_signs


def test_rotation_signs():
    t = np.linspace(0, 2, 201)[:, None]
    q = np.hstack([6.0 * t, -6.0 * t, 0.4 * np.sin(6 * t), -0.4 * np.sin(6 * t) - 0.1 * t])
    q[5, 1] = np.nan
    assert list(rotation_signs(q)) == [1.0, -1.0, 1.0, 1.0]  # 3-DOF-like joints untouched
    assert list(rotation_signs(q[:, 1])) == [-1.0]


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')
    root = tmp_path_factory.mktemp('hipsigns')
    edubot_bag.write_edubot_bag(root / 'ed', 'running', duration_s=6.0, seed=1)
    for name, which in (('right', 'R'), ('all', '')):
        with open_reader(root / 'ed') as r, BagWriter(root / name) as w:
            for m in iter_messages(r):
                if m.topic in ('/joint_states', '/joint_commands'):
                    msg = r.deserialize(m.data, m.msgtype)
                    k = np.array([-1.0 if n.startswith(which) else 1.0 for n in msg.name])
                    for f in ('position', 'velocity', 'effort'):
                        v = np.asarray(getattr(msg, f), dtype=np.float64)
                        setattr(msg, f, v * k if v.size == k.size else v)
                    w.write(m.topic, m.msgtype, msg, m.stamp_ns)
                else:
                    w.write(m.topic, m.msgtype, m.data, m.stamp_ns)
    return root


@pytest.mark.parametrize('edges', ['auto', 'paper'])
def test_mirrored_hips_give_the_unmirrored_fits(bags, edges):
    from slip_identification.cli import analyze_bag

    ref = analyze_bag(str(bags / 'ed'), {'edges': edges})
    assert 'error' not in ref and len(ref['stances']) >= 10
    assert not any('turn backwards' in n for n in ref['run']['notes'])
    for name, signs in (('right', '[1.0, 1.0, 1.0, -1.0, -1.0, -1.0]'),
                        ('all', '[-1.0, -1.0, -1.0, -1.0, -1.0, -1.0]')):
        got = analyze_bag(str(bags / name), {'edges': edges})
        assert len(got['stances']) == len(ref['stances'])
        for x, y in zip(ref['stances'], got['stances']):
            assert (x['touchdown'], x['liftoff'], x['stiffness']) == \
                (y['touchdown'], y['liftoff'], y['stiffness'])
        note = [n for n in got['run']['notes'] if 'turn backwards' in n]
        assert len(note) == 1 and f'hip_signs:={signs}' in note[0]
        # every hip negated while the body moves along its heading: mirrored motors
        backwards = [n for n in got['run']['notes'] if 'read as motors mounted mirrored' in n]
        assert len(backwards) == (1 if name == 'all' else 0)
