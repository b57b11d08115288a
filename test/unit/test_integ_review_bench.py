"""Outside integration review (an emulated lab bench driven by the project's own nodes):

- D2: a motion-capture tip (/bench/leg_tip) with the project's gait_scheduler, whose
  /gait/phase carries six legs: the bench leg was only found from /joint_states when the tip
  was absent, so the default phase split fell back to contact in silence (P_stance +19..+37 %,
  P_swing -18..-42 % against the emulator's V*I split by the leg's schedule). The leg now
  comes from /joint_states whenever it names one leg (or --bench-leg), and an unknown leg is a
  top-level warning (energy.json "warnings" and stderr).
- D1: sessions labelled 2 Hz that walked the gait node's 1 Hz were analysed as 2 Hz; the
  session's frequency is checked against /gait/phase's period, warned and the walked one used.
- D8: a short plan (4 walking sessions) was refused with "needs >= 6 sessions" (and 6 sessions
  with 4 walking later), and nothing was written; the first message now names the minimum of
  walking sessions and energy.json keeps the sessions' phase powers.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.testbags import rewrite_bag
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag
from hexapod_energy.cli import main
from hexapod_energy.errors import FitError
from hexapod_energy.single_leg import PhaseSample, SingleLegModel

SIX = ['L1', 'L2', 'L3', 'R1', 'R2', 'R3']
#: the tripod group of the bench leg R2 (the simulator's leg)
WITH_R2 = {'L1', 'L3', 'R2'}


def _six_legs(topic: str, msg) -> None:
    """/gait/phase of a tripod gait_scheduler: six legs, R2 the bench leg."""
    if topic != '/gait/phase':
        return
    (leg,), (st,), (off,) = msg.leg_names, msg.in_stance, msg.phase_offsets
    assert leg == 'R2'
    standing = msg.step_length == 0.0 and msg.step_height == 0.0
    msg.leg_names = list(SIX)
    msg.in_stance = np.array([bool(st) if (n in WITH_R2 or standing) else not st
                              for n in SIX], dtype=bool)
    msg.phase_offsets = np.array([off if n in WITH_R2 else (off + 0.5) % 1.0 for n in SIX])


#: the topics :func:`_six_legs` edits (the rewrites copy the others' messages as stored)
GAIT = {'/gait/phase'}


def _two_legs_on_joint_states(topic: str, msg) -> None:
    """A driver publishing two legs' joints (a robot's joints file on the bench)."""
    _six_legs(topic, msg)
    if topic == '/joint_states':
        names = list(msg.name)
        msg.name = names + [n.replace('R2', 'L1') for n in names]
        for key in ('position', 'velocity', 'effort'):
            v = np.asarray(getattr(msg, key), dtype=float)
            if v.size:
                setattr(msg, key, np.concatenate([v, v]))


@pytest.fixture(scope='module')
def benches(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp('integ_bench')
    plan = BenchPlan(loads_kg=(0.0, 0.3), frequencies_hz=(0.0, 0.75, 1.5, 2.25), walk_s=4.0)
    write_trace(simulate_bench(plan, seed=2), root / 'one')
    out = {'one': root / 'one'}
    out['six'] = rewrite_bag(root / 'one', root / 'six', _six_legs, topics=GAIT)
    out['six_two_js'] = rewrite_bag(root / 'one', root / 'six_two_js',
                                    _two_legs_on_joint_states,
                                    topics=GAIT | {'/joint_states'})
    return out


@pytest.fixture(scope='module')
def one_ref(benches) -> tuple[list[PhaseSample], dict]:
    """The one-leg bag's phase powers and diagnostics, the reference of the rewritten bags'
    (read once for the tests that compare with it). Read only."""
    return bench_phase_samples(read_bench_bag(benches['one']))


def _powers(samples: list[PhaseSample]) -> np.ndarray:
    return np.array([[s.load_kg, s.frequency_hz, s.p_stance_w, s.p_swing_w]
                     for s in samples])


def test_six_leg_schedule_takes_the_bench_leg_from_joint_states(benches, one_ref):
    ref, ref_diag = one_ref
    assert ref_diag['phase_split'] == 'schedule' and not ref_diag['warnings']
    data = read_bench_bag(benches['six'])
    got, diag = bench_phase_samples(data)
    # before: 'contact' (the leg unknown with /bench/leg_tip present), only a note
    assert diag['phase_split'] == 'schedule', diag['notes']
    assert not diag['warnings']
    assert any('bench leg R2 (from /joint_states)' in n for n in diag['notes'])
    np.testing.assert_allclose(_powers(got), _powers(ref), rtol=1e-12)


def test_unknown_bench_leg_is_a_top_level_warning(benches, one_ref, tmp_path, capsys):
    data = read_bench_bag(benches['six_two_js'])
    got, diag = bench_phase_samples(data)
    assert diag['phase_split'] == 'contact'
    assert any('bench leg is not identified' in w and "['L1', 'R2']" in w
               for w in diag['warnings']), diag['warnings']
    # the contact split asked for: the leg is not needed, a note only
    _, diag = bench_phase_samples(data, phase_split='contact')
    assert not diag['warnings'] and any('not identified' in n for n in diag['notes'])
    assert main(['--bench', str(benches['six_two_js']), '--out', str(tmp_path / 'a'),
                 '--no-progress']) == 0
    doc = json.loads((tmp_path / 'a' / 'energy.json').read_text())
    assert any('bench leg is not identified' in w for w in doc.get('warnings', []))
    assert 'bench leg is not identified' in capsys.readouterr().err
    # --bench-leg names it: the schedule split, the one-leg bag's numbers, no warning
    assert main(['--bench', str(benches['six_two_js']), '--bench-leg', 'R2', '--out',
                 str(tmp_path / 'b'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'b' / 'energy.json').read_text())
    assert not doc.get('warnings')
    assert doc['bench']['diagnostics'][0]['phase_split'] == 'schedule'
    ref, _ = one_ref
    np.testing.assert_allclose(
        [[s['p_stance_w'], s['p_swing_w']] for s in doc['bench']['fit']['sessions']],
        [[s.p_stance_w, s.p_swing_w] for s in ref], rtol=1e-12)
    assert main(['--bench', str(benches['six_two_js']), '--bench-leg', 'R9', '--out',
                 str(tmp_path / 'c'), '--no-progress']) == 2
    assert 'R9 is not on /gait/phase' in capsys.readouterr().err


def test_session_labelled_another_frequency_than_walked(benches, one_ref, tmp_path, capsys):
    def relabel(topic: str, msg) -> None:
        _six_legs(topic, msg)
        if topic == '/bench/session' and msg.frequency == 1.5:
            msg.frequency = 3.0   # the sequencer's label; the gait node walked 1.5 Hz

    bag = rewrite_bag(benches['one'], tmp_path / 'relabelled', relabel,
                      topics=GAIT | {'/bench/session'})
    ref, _ = one_ref
    got, diag = bench_phase_samples(read_bench_bag(bag))
    named = [w for w in diag['warnings'] if 'labelled 3 Hz but /gait/phase walked 1.5 Hz' in w]
    assert len(named) == 2, diag['warnings']   # one per load, each naming its session
    assert {w.split(':')[0] for w in named} == {
        f'session {s.session_id}' for s in ref if s.frequency_hz == 1.5}
    np.testing.assert_allclose(_powers(got), _powers(ref), rtol=1e-12)
    assert [s.t_stance_s for s in got] == [s.t_stance_s for s in ref]
    assert main(['--bench', str(bag), '--out', str(tmp_path / 'e'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'e' / 'energy.json').read_text())
    assert sum('walked 1.5 Hz' in w for w in doc['warnings']) == 2
    assert 'walked 1.5 Hz' in capsys.readouterr().err


def test_a_standing_schedule_matches_a_0_hz_session(benches):
    """The gait_scheduler stands with step 0 at its period: a 0 Hz session, no warning."""
    def stand_with_period(topic: str, msg) -> None:
        _six_legs(topic, msg)
        if topic == '/gait/phase' and msg.period == 0.0:
            msg.period = 1.0

    data = read_bench_bag(rewrite_bag(benches['one'], benches['one'].parent / 'stand',
                                      stand_with_period, topics=GAIT))
    _, diag = bench_phase_samples(data)
    assert not diag['warnings']


def _walking_plan(n_walking: int) -> list[PhaseSample]:
    out = []
    for i in range(n_walking):
        load, f = (0.0, 0.3)[i % 2], 0.5 + 0.4 * i
        t = 0.5 / f
        out.append(PhaseSample(f's{i}', load, f, 0.5, t, t, 3 + f + 5 * load, 4 + 2 * f,
                               3.5 + 1.5 * f, 0.5, 100))
    for load in (0.0, 0.3):
        p = 2 + 5 * load
        out.append(PhaseSample(f'b{load}', load, 0.0, 0.5, np.inf, np.inf, p, p, p, 0.5, 100))
    return out


def test_the_first_refusal_names_the_walking_sessions_needed():
    model = SingleLegModel()
    need = model.min_walking_sessions()
    assert need == 5
    SingleLegModel().fit(_walking_plan(need))   # the minimum fits
    with pytest.raises(FitError, match=f'needs >= {need} walking sessions .* got {need - 1} '
                                       f'walking of {need + 1} sessions'):
        SingleLegModel().fit(_walking_plan(need - 1))
    assert SingleLegModel(folds=2).min_walking_sessions() == 8
    SingleLegModel(folds=2).fit(_walking_plan(8))
    with pytest.raises(FitError, match='>= 8 walking'):
        SingleLegModel(folds=2).fit(_walking_plan(7))


def test_a_refused_fit_still_writes_the_sessions(tmp_path, capsys):
    plan = BenchPlan(loads_kg=(0.0, 0.3), frequencies_hz=(0.0, 1.0, 2.0), walk_s=3.0)
    write_trace(simulate_bench(plan, seed=5), tmp_path / 'short')
    out = tmp_path / 'out'
    assert main(['--bench', str(tmp_path / 'short'), '--out', str(out),
                 '--no-progress']) == 2
    err = capsys.readouterr().err
    assert 'needs >= 5 walking sessions' in err and 'got 4 walking of 6' in err
    assert 'bench.sessions' in err
    doc = json.loads((out / 'energy.json').read_text())
    assert doc['bench']['fit'] is None
    assert len(doc['bench']['sessions']) == 6
    assert doc['errors'] and '>= 5 walking sessions' in doc['errors'][0]
    ref, _ = bench_phase_samples(read_bench_bag(tmp_path / 'short'))
    np.testing.assert_allclose([s['p_stance_w'] for s in doc['bench']['sessions']],
                               [s.p_stance_w for s in ref], rtol=1e-12)


def test_session_labelled_another_duty_factor_than_walked(benches, one_ref, tmp_path):
    """The frequency matched but the duty factor did not (the gait node left at beta 0.6):
    it was not compared; now the walked duty factor is used, warned."""
    def relabel(topic: str, msg) -> None:
        _six_legs(topic, msg)
        if topic == '/bench/session' and msg.frequency == 1.5:
            msg.duty_factor = 0.6   # the sequencer's label; the gait node walked 0.5

    bag = rewrite_bag(benches['one'], tmp_path / 'relabelled_beta', relabel,
                      topics=GAIT | {'/bench/session'})
    ref, _ = one_ref
    got, diag = bench_phase_samples(read_bench_bag(bag))
    named = [w for w in diag['warnings']
             if 'duty_factor labelled 0.6 but /gait/phase walked 0.5' in w]
    assert len(named) == 2, diag['warnings']
    np.testing.assert_allclose(_powers(got), _powers(ref), rtol=1e-12)
    assert [s.t_stance_s for s in got] == [s.t_stance_s for s in ref]
