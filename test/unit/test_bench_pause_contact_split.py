"""A short pause inside a bench walk split by contact (no /gait/phase): the leg stands on the
ground, then walks on. Its ground time (1.6 s for a 1 s pause at 1 Hz) stayed under the
"no step" warning's 2.5 typical ground times + 0.1 s (1.65 s) and was split as walking:
P_stance +2.9 %, P_swing -20 % with no warning (outside review; at 0.5 Hz a 2 s pause read
+15 % and -33 %). The pause is now left out of both phases, with a warning naming the
session and the pause."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.testbags import write_lab_bench_bag
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag

PLAN = [(0.0, 0.0), (0.0, 1.0), (0.2, 1.0), (0.0, 0.5)]


def _powers(path, **kw):
    plan = write_lab_bench_bag(path, PLAN, **kw)
    samples, diag = bench_phase_samples(read_bench_bag(path))
    return ({s.session_id: (s.p_stance_w, s.p_swing_w) for s in samples if s.frequency_hz},
            diag, plan)


@pytest.fixture(scope='module')
def clean(tmp_path_factory):
    return _powers(tmp_path_factory.mktemp('clean') / 'bag', walk_s=10.0)


@pytest.mark.parametrize('pause', [(2.0, 1.0), (2.0, 2.0), (4.0, 1.3)])
def test_a_pause_is_left_out_of_both_phases(tmp_path, clean, pause):
    ref, ref_diag, _ = clean
    got, diag, plan = _powers(tmp_path / 'bag', walk_s=10.0, pause=pause)
    assert got.keys() == ref.keys()
    for sid in ref:
        np.testing.assert_allclose(got[sid], ref[sid], rtol=0.01, err_msg=sid)
    assert ref_diag['warnings'] == []
    for p in plan[1:]:
        sid = p['session_id']
        mine = [w for w in diag['warnings'] if w.startswith(f'session {sid}:')]
        # one warning per session, naming the pause where it is (s from 'walking'), and not
        # the old one that said the pause was analysed as walking
        assert len(mine) == 1, diag['warnings']
        a, b = pause[0], pause[0] + pause[1]
        assert f'{pause[1]:.1f} s in 1 pause(s)' in mine[0], mine
        assert f'({a:.1f}-{b:.1f} s after its \'walking\' message)' in mine[0], mine
        assert mine[0].endswith('left out of both phases'), mine


def test_the_reviewed_case_6_s_walk_at_1_hz(tmp_path):
    """The review's case: a 1 s pause 2 s into a 6 s walk at 1 Hz (P_stance +2.9 to +4 %,
    P_swing -20 %, no warning before)."""
    plan = [(0.0, 0.0), (0.0, 1.0), (0.2, 1.0)]
    out = {}
    for name, pause in (('clean', None), ('paused', (2.0, 1.0))):
        write_lab_bench_bag(tmp_path / name, plan, walk_s=6.0, pause=pause)
        out[name] = bench_phase_samples(read_bench_bag(tmp_path / name))
    (a, _), (b, diag) = out['clean'], out['paused']
    for x, y in zip(a, b):
        np.testing.assert_allclose([y.p_stance_w, y.p_swing_w], [x.p_stance_w, x.p_swing_w],
                                   rtol=0.01, err_msg=x.session_id)
    assert [w.split(':')[0] for w in diag['warnings']] == \
        ['session s001_L0_f1', 'session s002_L0.2_f1'], diag['warnings']
