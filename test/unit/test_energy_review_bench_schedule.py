"""Outside review (octopod lab), A1 and A2: the bench's ``/gait/phase`` against what the bench
measured.

A1: one bag per session (``--bench-sessions``) recorded 0.5-1.5 s past the last step. The leg
tip cannot tell that standing from the last stance (it is cut only beyond 1.25 ground times +
0.1 s), so it was analysed as walking: P_stance 2.25 W for 2.70 W (-16.7 %) at 0.75 Hz with a
1.0 s tail, no warning. ``/gait/phase`` says ``stand`` there: the schedule's walk is the
session.

A2: a ``--bench-leg`` of the other tripod swaps stance and swing in every session (Eq. 1
-23 %, silently). The schedule's stance is checked against the contact the bench measures
(force and tip), per cycle: most cycles disagreeing is refused, naming the legs that agree;
the right leg passes unchanged.
"""

from __future__ import annotations

import pytest

from energy_bench_bags import p_stance, p_swing, session_bag
from hexapod_energy.bag_io import (
    BenchSessionSpec,
    bench_phase_samples,
    merge_bench_data,
    read_bench_bag,
)
from hexapod_energy.errors import BagContentError

SESSIONS = ((0.0, 0.0), (0.0, 0.75), (0.0, 1.5), (0.4, 0.75))   # (load kg, frequency Hz)


def _bench(root, *, tail_s=0.0, legs=('L1',), bench='L1', bench_leg=None):
    datas, t0 = [], 1000.0
    for i, (load, freq) in enumerate(SESSIONS):
        path = root / f's{i}'
        t0 = session_bag(path, load=load, freq=freq, tail_s=tail_s, t0=t0, legs=legs,
                         bench=bench) + 0.005
        datas.append(read_bench_bag(path, BenchSessionSpec(load, freq, 0.5),
                                    bench_leg=bench_leg))
    return merge_bench_data(datas)


@pytest.mark.parametrize('tail_s', [0.5, 1.0, 1.5])
def test_standing_after_the_walk_is_cut_where_the_schedule_stands(tmp_path, tail_s):
    data = _bench(tmp_path, tail_s=tail_s)
    samples, diag = bench_phase_samples(data)
    walking = [s for s in samples if s.frequency_hz > 0]
    assert len(walking) == 3
    for s in walking:
        t_st = 0.5 / s.frequency_hz
        assert s.p_stance_w == pytest.approx(p_stance(t_st, s.load_kg), rel=0.01), s
        assert s.p_swing_w == pytest.approx(p_swing(t_st, s.load_kg), rel=0.01), s
    notes = ' '.join(diag['notes'])
    assert 'where /gait/phase walks' in notes
    assert f'{tail_s:.1f} s after left out as standing' in notes


def test_a_wrong_bench_leg_is_refused_naming_the_legs_that_agree(tmp_path):
    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    data = _bench(tmp_path, legs=legs, bench='R2', bench_leg='R1')
    with pytest.raises(BagContentError) as err:
        bench_phase_samples(data)
    msg = str(err.value)
    assert 'R1' in msg and 'disagrees with the contact' in msg
    assert 'L1 or L3 or R2' in msg and '--bench-leg' in msg
    # asked for, the contact split goes on
    samples, _ = bench_phase_samples(data, phase_split='contact')
    assert len(samples) == 4


def test_the_right_bench_leg_passes_unchanged(tmp_path):
    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    data = _bench(tmp_path, legs=legs, bench='R2', bench_leg='R2')
    samples, diag = bench_phase_samples(data)
    assert diag['phase_split'] == 'schedule'
    for s in samples:
        if s.frequency_hz > 0:
            t_st = 0.5 / s.frequency_hz
            assert s.p_stance_w == pytest.approx(p_stance(t_st, s.load_kg), rel=0.01)
            assert s.p_swing_w == pytest.approx(p_swing(t_st, s.load_kg), rel=0.01)
