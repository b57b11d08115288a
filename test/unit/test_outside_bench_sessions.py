"""Bench bags recorded without /bench/session (another lab's bench: one bag per session, the
load written down): `energy --bench-sessions CSV` analyses them like our sessions.

Each simulated session is cut to its walking interval and its /bench/session (and, in one
variant, /gait/phase) dropped; the phase powers must equal those of the original bag, with the
frequency taken from /gait/phase or, without it, from the leg tip's period."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.bags import typestore
from hexapod_energy.bag_io import (
    BenchSessionSpec,
    bench_phase_samples,
    merge_bench_data,
    read_bench_bag,
    read_bench_sessions_file,
)
from hexapod_energy.cli import main
from hexapod_energy.errors import BagContentError

LOADS = (0.0, 0.3)
FREQS = (0.0, 1.0, 1.5, 2.0, 2.5)


def _walking_bags(src: Path, root: Path, *, drop_gait: bool) -> list[tuple[Path, float, float]]:
    """One bag per walking session of ``src`` (its stamps only), without /bench/session."""
    store = typestore()
    with AnyReader([src], default_typestore=store) as r:
        sessions = []
        for c, t, raw in r.messages([c for c in r.connections if c.topic == '/bench/session']):
            m = r.deserialize(raw, c.msgtype)
            sessions.append((t, m.state, m.session_id, m.load_mass, m.frequency))
        spans, cur = [], None
        for t, state, sid, load, freq in sessions + [(2**63, 'end', '', 0, 0)]:
            if cur is not None and (state != 'walking' or sid != cur[1]):
                spans.append((cur[0], t, cur[2], cur[3]))
                cur = None
            if state == 'walking' and cur is None:
                cur = (t, sid, load, freq)
        out = []
        drop = {'/bench/session'} | ({'/gait/phase'} if drop_gait else set())
        for i, (t0, t1, load, freq) in enumerate(spans):
            dst = root / f's{i}'
            with Writer(dst, version=8) as w:
                conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                         for c in r.connections if c.topic not in drop}
                for c, t, raw in r.messages([c for c in r.connections
                                             if c.topic not in drop]):
                    if t0 <= t < t1:
                        w.write(conns[c.id], t, raw)
            out.append((dst, float(load), float(freq)))
    return out


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    root = tmp_path_factory.mktemp('bench')
    plan = BenchPlan(loads_kg=LOADS, frequencies_hz=FREQS, walk_s=5.0)
    write_trace(simulate_bench(plan, seed=4), root / 'orig')
    data = read_bench_bag(root / 'orig')
    refs = {split: bench_phase_samples(data, phase_split=split)[0]
            for split in ('schedule', 'contact')}
    return root, {split: {(s.load_kg, s.frequency_hz): s for s in ref}
                  for split, ref in refs.items()}


@pytest.fixture(scope='module')
def session_bags(bench, tmp_path_factory):
    """:func:`_walking_bags` of the bench, cut once per variant (with and without
    /gait/phase) for every test that reads them; a test's sessions file goes beside them (its
    bag names relative to the file's folder). Read only."""
    root, _ = bench
    made: dict[bool, list[tuple[Path, float, float]]] = {}

    def get(drop_gait: bool) -> list[tuple[Path, float, float]]:
        if drop_gait not in made:
            made[drop_gait] = _walking_bags(root / 'orig', tmp_path_factory.mktemp('sessions'),
                                            drop_gait=drop_gait)
        return made[drop_gait]
    return get


@pytest.mark.parametrize('drop_gait', [False, True], ids=['gait_phase', 'tip_period'])
def test_one_bag_per_session_gives_the_sessions_phase_powers(bench, session_bags, drop_gait):
    """Merged (one bench: the force offset and sign from every session) the one-session bags
    give the original's phase powers (split by the commanded schedule with /gait/phase, by
    contact without it); each frequency's source is noted."""
    _, refs = bench
    ref = refs['contact' if drop_gait else 'schedule']
    bags = session_bags(drop_gait)
    datas = [read_bench_bag(bag, BenchSessionSpec(load_kg=load)) for bag, load, _ in bags]
    for d, (_, _, freq) in zip(datas, bags):
        [note] = [n for n in d.notes if n.startswith('no /bench/session')]
        source = '/gait/phase' if not drop_gait else \
            'leg tip period' if freq else 'the leg tip stays within'
        assert f'from {source}' in note
    samples, diag = bench_phase_samples(merge_bench_data(datas))
    assert len(samples) == len(ref)
    for s in samples:
        r = min((r for k, r in ref.items() if k[0] == s.load_kg),
                key=lambda r: abs(r.frequency_hz - s.frequency_hz))
        assert s.frequency_hz == pytest.approx(r.frequency_hz, rel=2e-3, abs=1e-12)
        # the leg tip's period is within 0.1 % of the schedule's: the whole-cycle window moves
        np.testing.assert_allclose([s.p_stance_w, s.p_swing_w], [r.p_stance_w, r.p_swing_w],
                                   rtol=5e-3 if drop_gait else 2e-3)
    assert not any('force sign not checked' in n for n in diag['notes'])


def test_cli_reads_the_sessions_file_and_fits(bench, session_bags, tmp_path):
    _, refs = bench
    ref = refs['contact']
    bags = session_bags(True)
    csv = bags[0][0].parent / 'cli_sessions.csv'
    lines = ['# one row per bag; empty frequency: from the bag', 'bag,load_kg,frequency_hz']
    lines += [f'{b.name},{load},' for b, load, _ in bags]
    csv.write_text('\n'.join(lines) + '\n')
    assert main(['--bench-sessions', str(csv), '--out', str(tmp_path / 'out'),
                 '--no-progress']) == 0
    doc = json.loads((tmp_path / 'out' / 'energy.json').read_text())
    got = {(s['load_kg'], round(s['frequency_hz'], 2)): s
           for s in doc['bench']['fit']['sessions']}
    assert set(got) == {(k[0], k[1]) for k in ref}
    assert doc['bench']['bags'] == [str(b) for b, _, _ in bags]


def test_sessions_file_from_a_spreadsheet(tmp_path):
    """A byte-order mark, semicolons, CRLF line ends and capitalised headers (a spreadsheet
    saved in another locale) read like the plain CSV; relative paths from the file's folder."""
    (tmp_path / 'runs' / 'l1').mkdir(parents=True)   # beside the file; l2 is not
    f = tmp_path / 'runs' / 's.csv'
    f.write_bytes('\ufeffBag; Load_kg; frequency_hz\r\nl1; 0.2; 1.5\r\nl2;0;\r\n'
                  .encode('utf-8'))
    got = read_bench_sessions_file(f)
    assert got == {str(tmp_path / 'runs' / 'l1'): BenchSessionSpec(0.2, 1.5),
                   'l2': BenchSessionSpec(0.0)}


def test_sessions_file_errors_name_the_line(tmp_path):
    bad = tmp_path / 'a.csv'
    bad.write_text('bag,load\nx,0.1\n')
    with pytest.raises(BagContentError, match='bag and load_kg'):
        read_bench_sessions_file(bad)
    bad.write_text('bag,load_kg\nx,heavy\n')
    with pytest.raises(BagContentError, match='line 2: load_kg'):
        read_bench_sessions_file(bad)
    bad.write_text('bag,load_kg,duty_factor\nx,0.1,1.5\n')
    with pytest.raises(BagContentError, match='duty_factor'):
        read_bench_sessions_file(bad)


def test_a_bag_with_its_own_sessions_is_not_also_in_the_file(bench):
    root, _ = bench
    with pytest.raises(BagContentError, match='records /bench/session'):
        read_bench_bag(root / 'orig', BenchSessionSpec(load_kg=0.1))


def _retype(src: Path, dst: Path) -> Path:
    """The leg tip as a rigid body (PoseStamped) and the force as a load cell's bare
    std_msgs/Float64 (no header: the bag's receive time, which the simulator writes equal to
    the stamp)."""
    from hexapod_common.bags import new_msg

    store = typestore()
    types = {'/bench/leg_tip': 'geometry_msgs/msg/PoseStamped',
             '/bench/ground_force': 'std_msgs/msg/Float64'}
    with AnyReader([src], default_typestore=store) as r, Writer(dst, version=8) as w:
        conns = {c.id: w.add_connection(c.topic, types.get(c.topic, c.msgtype), typestore=store)
                 for c in r.connections}
        for c, t, raw in r.messages():
            if c.topic in types:
                m = r.deserialize(raw, c.msgtype)
                if c.topic == '/bench/leg_tip':
                    out = new_msg(types[c.topic], header=m.header, pose=new_msg(
                        'geometry_msgs/msg/Pose', position=new_msg(
                            'geometry_msgs/msg/Point', x=m.point.x, y=m.point.y, z=m.point.z)))
                else:
                    assert t == m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
                    out = new_msg(types[c.topic], data=float(m.wrench.force.z))
                raw = store.serialize_cdr(out, types[c.topic])
            w.write(conns[c.id], t, raw)
    return dst


def test_tip_as_pose_and_force_as_bare_float_give_the_same_sessions(bench, tmp_path):
    """(The contact split, where the tip and the force label the phases.)"""
    root, refs = bench
    ref = refs['contact']
    data = read_bench_bag(_retype(root / 'orig', tmp_path / 'retyped'))
    samples, diag = bench_phase_samples(data, phase_split='contact')
    assert [(s.p_stance_w, s.p_swing_w) for s in samples] == \
        [(ref[(s.load_kg, s.frequency_hz)].p_stance_w, ref[(s.load_kg, s.frequency_hz)].p_swing_w)
         for s in samples]
    assert any('/bench/ground_force' in n and 'without a header' in n for n in diag['notes'])


def test_a_force_of_another_type_is_named(bench, tmp_path):
    from hexapod_common.conversions import wrench_from_msg

    with pytest.raises(ValueError, match='is not a force'):
        wrench_from_msg(object())


def test_a_bag_without_sessions_given_with_bench_names_the_option(session_bags):
    bag, _, _ = session_bags(False)[0]
    with pytest.raises(BagContentError, match='--bench-sessions CSV'):
        read_bench_bag(bag)


@pytest.mark.parametrize('drop_gait', [False, True])
def test_one_session_bags_keep_their_step_geometry(session_bags, tmp_path, drop_gait):
    """A review of the step-geometry mapping: a bench given with --bench-sessions never knew
    its step length and height (the CSV's step_length_m alone, no height, the bags' own
    /gait/phase unused), so other steps were read at their durations alone in silence. The
    geometry now comes from /gait/phase, else from the file's step_length_m and
    step_height_m; without either, energy.json warns."""
    bags = session_bags(drop_gait)
    csv = bags[0][0].parent / 'geometry_sessions.csv'
    head = 'bag,load_kg' + ('' if not drop_gait else ',step_length_m,step_height_m')
    rows = [f'{b.name},{load}' + ('' if not drop_gait else ',0.1,0.04') for b, load, _ in bags]
    csv.write_text('\n'.join([head, *rows]) + '\n')
    assert main(['--bench-sessions', str(csv), '--out', str(tmp_path / 'out'),
                 '--no-progress']) == 0
    doc = json.loads((tmp_path / 'out' / 'energy.json').read_text())
    assert doc['bench']['fit']['step_geometry_m'] == {'step_length': 0.1, 'step_height': 0.04}
    assert not any('record no step length' in w for w in doc.get('warnings', []))
    if drop_gait:   # neither /gait/phase nor the columns: unknown, and said
        csv.write_text('\n'.join(['bag,load_kg', *[f'{b.name},{load}' for b, load, _ in bags]])
                       + '\n')
        assert main(['--bench-sessions', str(csv), '--out', str(tmp_path / 'o2'),
                     '--no-progress']) == 0
        doc = json.loads((tmp_path / 'o2' / 'energy.json').read_text())
        assert doc['bench']['fit']['step_geometry_m'] is None
        assert any('record no step length' in w for w in doc['warnings'])
