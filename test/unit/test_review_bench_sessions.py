"""Outside review A, F3 and F5-F8: bench sessions whose bounds are wrong or missing.

Small lab-style bench bags (no /gait/phase: the contact split) with exactly known phase powers
(:func:`hexapod_common.testbags.write_lab_bench_bag`): one bag per session with standing
before and after the walk (F3), lost /bench/session messages (F5), loads written in grams
(F6), no 0 Hz session (F7) and back-to-back one-session bags (F8)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexapod_common.testbags import lab_bench_truth, write_lab_bench_bag
from hexapod_energy.bag_io import (
    BenchData,
    BenchSessionSpec,
    bench_phase_samples,
    merge_bench_data,
    read_bench_bag,
    read_bench_sessions_file,
)
from hexapod_energy.cli import main
from hexapod_energy.errors import BagContentError
from hexapod_energy.prediction import NO_BASAL_NOTE

PLAN = [(0.0, 0.0), (0.0, 1.0), (0.0, 2.0), (0.2, 0.0), (0.2, 1.0), (0.2, 2.0)]


def _check_truth(samples, rtol=0.01):
    for s in samples:
        t = lab_bench_truth(s.load_kg, s.frequency_hz)
        if s.frequency_hz > 0:
            np.testing.assert_allclose([s.p_stance_w, s.p_swing_w], [t['stance'], t['swing']],
                                       rtol=rtol, err_msg=s.session_id)
        else:
            assert s.p_mean_w == pytest.approx(t['basal'], rel=rtol)


# F3: one bag per session (--bench-sessions), recorded by hand: standing before and after

def _one_session_bags(root, plan, **kw):
    out = []
    for k, (load, freq) in enumerate(plan):
        path = root / f'b{k}'
        write_lab_bench_bag(path, [(load, freq)], with_session_topic=False,
                            t0_s=1_700_000_000.0 + 20.0 * k, **kw)
        out.append((path, load, freq))
    return out


def test_one_session_bag_standing_is_cut_off(tmp_path):
    """2 s standing + 8 s walking + 2.5 s standing per bag: analysed as walking the standing
    read P_swing about -30 %; the walking part from the leg tip's steps is exact, and the
    note says what was left out."""
    bags = _one_session_bags(tmp_path, [(0.2, 0.5), (0.2, 1.0)], heat_s=2.0, walk_s=8.0,
                             cool_s=2.5)
    for path, load, freq in bags:
        data = read_bench_bag(path, BenchSessionSpec(load, freq, 0.5))
        [note] = [n for n in data.notes if n.startswith('no /bench/session')]
        assert 'left out as standing' in note, note
        samples, _ = bench_phase_samples(data)
        _check_truth(samples)


def test_one_session_bag_pause_inside_the_walk_is_warned(tmp_path):
    [(path, load, freq)] = _one_session_bags(tmp_path, [(0.2, 1.0)], walk_s=8.0,
                                             pause=(3.0, 3.0))
    data = read_bench_bag(path, BenchSessionSpec(load, freq, 0.5))
    assert any('makes no step for 3.' in w and '1 stretch' in w for w in data.warnings), \
        data.warnings


# F5: lost /bench/session messages

def _bench(tmp_path, **kw):
    path = tmp_path / 'bench'
    plan = write_lab_bench_bag(path, PLAN, **kw)
    data = read_bench_bag(path)
    return plan, *bench_phase_samples(data)


def test_lost_cooling_ends_the_walk_where_stepping_stops(tmp_path):
    """Message 4 is s001's 'cooling': its walk ran 1.5 s into standing (P_swing -25 % in the
    review's bag), silently."""
    _, samples, diag = _bench(tmp_path, drop_msgs=(5,))
    assert len(samples) == len(PLAN)
    _check_truth(samples)
    assert any('s001' in w and 'no step in the last 1.' in w for w in diag['warnings'])


def test_lost_walking_recovers_the_walk_from_the_steps(tmp_path):
    """s001's 'walking' (message 4) lost: the session was silently gone."""
    _, samples, diag = _bench(tmp_path, drop_msgs=(4,))
    assert sorted(s.session_id for s in samples) == sorted(
        f's{k:03d}_L{lo:g}_f{f:g}' for k, (lo, f) in enumerate(PLAN))
    _check_truth(samples)
    assert any('s001' in w and 'never reports state walking' in w and 'steps at 1 Hz' in w
               for w in diag['warnings'])


def test_lost_walking_of_a_standing_session_is_warned(tmp_path):
    _, samples, diag = _bench(tmp_path, drop_msgs=(10,))   # s003 (0.2 kg, 0 Hz) 'walking'
    assert len(samples) == len(PLAN) - 1
    assert any('s003' in w and 'left out' in w for w in diag['warnings'])


def test_missed_first_messages_are_warned(tmp_path):
    """The latched first messages missed (a recorder started late): the 0 Hz session of the
    first load and its 6.5 s of data were silently gone."""
    _, samples, diag = _bench(tmp_path, drop_msgs=(0, 1, 2))
    assert len(samples) == len(PLAN) - 1
    [w] = [w for w in diag['warnings'] if 'before the first /bench/session' in w]
    assert w.startswith('6.5 s of bench data'), w


def test_intact_bench_has_no_session_warning(tmp_path):
    _, samples, diag = _bench(tmp_path)
    _check_truth(samples)
    assert diag['warnings'] == []


# F6: loads in grams

def test_bench_loads_in_grams_are_refused(tmp_path):
    path = tmp_path / 'g'
    write_lab_bench_bag(path, [(0.0, 0.0), (0.5, 1.0)], walk_s=2.0, load_scale=1000.0)
    with pytest.raises(BagContentError, match='look like grams.*500 g is 0.5 kg'):
        read_bench_bag(path)
    csv = tmp_path / 's.csv'
    csv.write_text('bag,load_kg\nb0,0\nb1,500\n')
    with pytest.raises(BagContentError, match='look like grams'):
        read_bench_sessions_file(csv)


def test_gram_loads_under_the_bound_refused_against_the_robot_mass(tmp_path, capsys):
    """Loads 0 and 20 "kg" (grams) for a 2.2 kg robot: exit 2 through the input-error path."""
    path = tmp_path / 'g'
    write_lab_bench_bag(path, [(0.0, 0.0), (0.02, 1.0)], walk_s=2.0, load_scale=1000.0)
    code = main(['--bench', str(path), '--robot-mass', '2.2', '--out', str(tmp_path / 'o'),
                 '--no-progress'])
    assert code == 2
    err = capsys.readouterr().err
    assert 'bench load 20 kg' in err and 'robot' in err and 'grams' in err


# F7: no 0 Hz session

def test_no_standing_session_is_said(tmp_path, capsys):
    path = tmp_path / 'b'
    write_lab_bench_bag(path, [(lo, f) for lo in (0.0, 0.2, 0.4) for f in (1.0, 2.0)],
                        walk_s=3.0)
    assert main(['--bench', str(path), '--out', str(tmp_path / 'o'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'o' / 'energy.json').read_text())
    assert doc['bench']['fit']['basal_power_w'] == {}
    assert NO_BASAL_NOTE in doc['warnings']
    assert 'no 0 Hz (standing) session' in capsys.readouterr().err


def test_watts_figure_says_why_the_holding_split_is_missing():
    from hexapod_energy.plots import watts_figure

    nan = float('nan')
    fig = watts_figure(['run'], [{'stance_w': 10.0, 'swing_w': 12.0, 'holding_w': nan}],
                       [20.0], [1.0])
    texts = [t.get_text() for t in fig.axes[0].get_legend().get_texts()]
    assert any('no 0 Hz (standing) session' in t for t in texts)


# F8: back-to-back one-session bags

def _data(t0, n=200, dt=0.005, stamp_end_step=True):
    t = t0 + dt * np.arange(n)
    end = t[-1] + (dt if stamp_end_step else 0.0)
    z = np.zeros(n)
    return BenchData(f'bag{t0:g}', t, np.full(n, 12.0), np.full(n, -0.2), t, z, t, z,
                     [{'t_s': t0, 'session_id': f'bag{t0:g}', 'state': 'walking',
                       'load_kg': 0.1, 'frequency_hz': 0.0, 'duty_factor': 0.5},
                      {'t_s': end, 'session_id': f'bag{t0:g}', 'state': 'end'}])


def test_back_to_back_bags_merge():
    """The second bag starts 0.3 ms before the first one's last stamp (the session's end, its
    last stamp plus a step, 5.3 ms after): one bench, in stamp order; more than a step of
    overlap is not, and says why."""
    a = _data(0.0)
    b = _data(0.995 - 0.0003)
    merged = merge_bench_data([b, a])
    assert merged is not None
    assert np.all(np.diff(merged.battery_t_s) >= 0)
    assert merged.sessions[1]['t_s'] <= merged.sessions[2]['t_s']
    why: list[str] = []
    assert merge_bench_data([a, _data(0.9)], why) is None
    assert why and 'overlap by 0.095 s' in why[0]


def test_abandoned_merge_is_warned(tmp_path, capsys):
    """Two one-session bags recorded at the same time: analysed one by one, and said so."""
    for name in ('b0', 'b1'):
        write_lab_bench_bag(tmp_path / name, [(0.1, 1.0)], walk_s=3.0,
                            with_session_topic=False)
    csv = tmp_path / 's.csv'
    csv.write_text('bag,load_kg,frequency_hz\nb0,0.1,1\nb1,0.1,1\n')
    main(['--bench-sessions', str(csv), '--out', str(tmp_path / 'o'), '--no-progress'])
    doc = json.loads((tmp_path / 'o' / 'energy.json').read_text())
    assert any('analysed one by one' in w and 'overlap by' in w for w in doc['warnings'])
    assert 'analysed one by one' in capsys.readouterr().err


def test_walking_loads_beyond_the_standing_sessions_are_named():
    """A lost first 0 Hz session (0 kg) left that load's basal power held from 0.1 kg's
    without a word of its own (review of the change)."""
    from types import SimpleNamespace

    from hexapod_energy.cli import _loads_without_basal

    def model(basal, walking):
        return SimpleNamespace(basal_power_w_={m: 2.0 for m in basal}, samples_=[
            SimpleNamespace(load_kg=m, frequency_hz=1.0) for m in walking])

    assert _loads_without_basal(model((0.1, 0.5), (0.0, 0.1, 0.3, 0.5, 0.6))) == [0.0, 0.6]
    assert _loads_without_basal(model((0.0, 0.5), (0.0, 0.2, 0.5))) == []
