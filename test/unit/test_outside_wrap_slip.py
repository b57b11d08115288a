"""Other labs' joint states for the SLIP side: wrapped hip angles and no velocities.

RHex-class hips turn continuously and many drivers log them wrapped into ``[-pi, pi)`` or
``[0, 2 pi)``; some publish positions without velocities. Before ``joints.py`` undid these,
the wrapped EduBot bag lost stances (splines across the wrap jumps, the geometry's psi
branches: 13 stances and 2 skipped instead of 15, offset 24.60 instead of 25.40 ms) and the
velocity-less bag was refused ("no JointState sample has velocities"). Here a simulated EduBot
bag (``hexapod_bench_drivers.edubot_bag``) is rewritten with rosbags' own ``Writer``:

- wrapped into ``[-pi, pi)`` (positions of ``/joint_states`` and ``/joint_commands``), and
  into ``[0, 2 pi)`` with the robot's hip zero 1 rad off (``--hip-zero -1``): the same stances
  as the original (touchdowns and lift-offs equal, stiffness within 1e-4: a last-bit change
  of the angles without any wrap, ``q + 1`` with ``--hip-zero -1``, moves the fits as much);
- without velocities: the same stance count, geometric edges within 0.2 ms, the paper's
  edges later by about 1.4 ms (the central difference averages the hip speed's steps over
  two samples; it has no lag, see ``test_derived_velocity_has_no_lag``).

Online (:class:`OnlineSlip`), the wrapped stream gives bit-identical fits and the
velocity-less one the same stances one joint-state period (10 ms) later.
"""

from __future__ import annotations

import argparse
import json
import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal
from rosbags.rosbag2 import StoragePlugin, Writer

from hexapod_common.conversions import JointStateSample
from slip_identification.cli import add_cli, read_run
from slip_identification.joints import (
    DERIVED_NOTE,
    JointFrameAssembler,
    assemble_joint_frames,
    derive_velocity,
    unwrap_positions,
)

HIPS = ('L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip')
E = np.zeros(0)
JS = 'sensor_msgs/msg/JointState'
TWO_PI = 2 * math.pi


def _wrap_pi(q):
    return (np.asarray(q) + math.pi) % TWO_PI - math.pi


def _turning(n=300, dt=0.01, seed=0):
    """Hips turning forwards at 8-25 rad/s (as a running RHex), uneven stamps."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(np.full(n, dt) + rng.uniform(-1e-3, 1e-3, n))
    om, ph = 2 * np.pi * 3.0, np.arange(6.0)
    w = 16.5 + 8.5 * np.sin(om * t[:, None] + ph)
    q = 16.5 * t[:, None] - 8.5 / om * np.cos(om * t[:, None] + ph) + 0.7 * ph - 2.0
    return t, q, w


# -- core functions ---------------------------------------------------------------------
def test_unwrap_positions_both_conventions_and_nan():
    t, q, _ = _turning()
    for wrapped in (_wrap_pi(q), q % TWO_PI):
        u, wraps = unwrap_positions(wrapped)
        # the first sample keeps its branch: the truth up to one multiple of 2 pi per joint
        k = np.round((u[0] - q[0]) / TWO_PI)
        assert_allclose(u - TWO_PI * k, q, atol=1e-12)
        assert wraps == int(np.abs(np.round(np.diff(wrapped, axis=0) / TWO_PI)).sum()) > 40
    same, wraps = unwrap_positions(q)
    assert same is q and wraps == 0  # nothing to undo: the input itself (bit-identical)
    w = _wrap_pi(q)
    w[10:13, 2] = np.nan  # a joint's dropped readings stay NaN, the rest is unwrapped
    u, _ = unwrap_positions(w)
    assert np.isnan(u[10:13, 2]).all()
    ok = np.isfinite(u[:, 2])
    assert_allclose(np.diff(u[ok, 2]), np.diff(q[ok, 2]), atol=1e-12)


def test_derived_velocity_has_no_lag():
    """Central differences on uneven stamps: second-order accurate and unbiased in time, where
    a backward difference lags by half a sample period."""
    rng = np.random.default_rng(2)
    t = np.cumsum(0.01 + rng.uniform(-1e-3, 1e-3, 400))
    om = 2 * np.pi * 2.0
    q, v = np.sin(om * t), om * np.cos(om * t)
    d = derive_velocity(t, q)
    assert np.abs(d - v)[1:-1].max() < 0.02 * om  # om^3 dt^2 / 6 relative: 0.7 %
    inner = slice(5, -5)

    def lag_s(est):  # best time shift of the estimate against the truth
        taus = np.linspace(-0.01, 0.01, 2001)
        err = [np.mean((np.interp(t[inner] - tau, t, v) - est[inner]) ** 2) for tau in taus]
        return float(taus[int(np.argmin(err))])

    assert abs(lag_s(d)) < 2e-4
    back = np.r_[d[0], np.diff(q) / np.diff(t)]
    assert lag_s(back) == pytest.approx(0.005, abs=5e-4)
    # repeated stamps (two messages at one time): the last one's speed, no division by 0
    tt = np.r_[t[:10], t[9], t[10:20]]
    qq = np.r_[q[:10], q[9], q[10:20]]
    dd = derive_velocity(tt, qq)
    assert np.all(np.isfinite(dd)) and dd[9] == dd[10]


def test_full_frames_with_velocities_are_bit_identical():
    t, q, w = _turning(n=100)
    samples = [JointStateSample(float(t[k]), HIPS, q[k].copy(), w[k].copy(), E)
               for k in range(t.size)]
    a = assemble_joint_frames(samples)
    assert a.notes == () and a.wraps == 0 and not a.derived
    assert_array_equal(a.position, q)
    assert_array_equal(a.velocity, w)
    asm = JointFrameAssembler()
    frames = [f for s in samples for f in asm.add(s.t_s, s.names, s.velocity, s.position)]
    assert asm.notes == [] and len(frames) == t.size
    assert_array_equal(np.array([f.position for f in frames]), q)
    assert_array_equal(np.array([f.velocity for f in frames]), w)


@pytest.mark.parametrize('split', [False, True])
def test_wrapped_and_velocity_less_frames_offline_and_online(split):
    t, q, w = _turning()
    wrapped = _wrap_pi(q)

    def samples(with_velocity):
        out = []
        for k in range(t.size):
            v = w[k] if with_velocity else E
            if split:  # one message per servo bus, the right bus read 2 ms later
                out.append(JointStateSample(float(t[k]), HIPS[:3], wrapped[k, :3],
                                            v[:3] if v.size else E, E))
                out.append(JointStateSample(float(t[k] + 0.002), HIPS[3:], wrapped[k, 3:],
                                            v[3:] if v.size else E, E))
            else:
                out.append(JointStateSample(float(t[k]), HIPS, wrapped[k], v, E))
        return out

    for with_velocity in (True, False):
        ss = samples(with_velocity)
        a = assemble_joint_frames(ss)
        assert a.wraps > 40 and a.derived is (not with_velocity)
        assert any(n.startswith('hip angles wrapped at +-pi: unwrapped (') for n in a.notes)
        assert (DERIVED_NOTE in a.notes) is (not with_velocity)
        # continuous angles, speeds the truth's (derived: within the central difference's
        # error on the 3 Hz speed modulation; split: linear interpolation between samples)
        ts = [t + (0.002 if split and j >= 3 else 0.0) for j in range(6)]
        qt = np.array([np.interp(a.t_s, ts[j], q[:, j]) for j in range(6)]).T
        k = np.round((a.position[0] - qt[0]) / TWO_PI)
        assert_allclose(a.position - TWO_PI * k, qt, atol=0.02 if split else 1e-12)
        wt = np.array([np.interp(a.t_s, ts[j], w[:, j]) for j in range(6)]).T
        inner = slice(2, -2)
        assert np.abs(a.velocity - wt)[inner].max() < (0.2 if split or not with_velocity
                                                       else 1e-12)
        # online: the same frames (derived: each one frame later, none at the last stamp)
        asm = JointFrameAssembler()
        frames = [f for s in ss for f in asm.add(s.t_s, s.names, s.velocity, s.position)]
        assert asm.wraps == a.wraps and asm.derived is (not with_velocity)
        assert len(asm.notes) == (1 if with_velocity else 2)
        tf = np.array([f.t_s for f in frames])
        i = np.searchsorted(a.t_s, tf)
        assert_array_equal(a.t_s[i], tf)
        assert tf.size >= a.t_s.size - (3 if split else 1)
        qo = np.array([f.position for f in frames])
        vo = np.array([f.velocity for f in frames])
        assert_allclose(qo, a.position[i], atol=1e-12, rtol=0)
        assert_allclose(vo, a.velocity[i], atol=1e-9, rtol=1e-12)


# -- bags -------------------------------------------------------------------------------
edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')


def _rewrite(src, dst, fn, topics=('/joint_states', '/joint_commands')):
    """Copy bag ``src`` to ``dst`` with ``fn(msg)`` applied to the JointStates of ``topics``."""
    from hexapod_common.bags import open_reader, typestore

    store = typestore()
    with open_reader(src) as reader, \
            Writer(dst, version=9, storage_plugin=StoragePlugin.MCAP) as wr:
        conns = {c.topic: wr.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in reader.connections}
        for conn, t_ns, data in reader.messages():
            if conn.topic in topics:
                msg = store.deserialize_cdr(data, JS)
                fn(conn.topic, msg)
                data = store.serialize_cdr(msg, JS)
            wr.write(conns[conn.topic], t_ns, data)
    return dst


def _set_position(f):
    def fn(topic, msg):
        if len(msg.position):
            msg.position = f(np.asarray(msg.position, dtype=np.float64))
    return fn


def _no_velocity(topic, msg):
    if topic == '/joint_states':
        msg.velocity = np.zeros(0, dtype=np.float64)


def _wrapped_no_velocity(topic, msg):
    _set_position(_wrap_pi)(topic, msg)
    _no_velocity(topic, msg)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('wrap')
    ref = edubot_bag.write_edubot_bag(root / 'ref', 'running', duration_s=4.0, seed=1)
    return {
        'ref': ref,
        'wrap': _rewrite(ref, root / 'wrap', _set_position(_wrap_pi)),
        # a robot whose hip angle is 1 rad at the EduBot's zero, logged in [0, 2 pi)
        'zero_2pi': _rewrite(ref, root / 'zero_2pi',
                             _set_position(lambda q: (q + 1.0) % TWO_PI)),
        'zero': _rewrite(ref, root / 'zero', _set_position(lambda q: q + 1.0)),
        'novel': _rewrite(ref, root / 'novel', _wrapped_no_velocity),
    }


@pytest.fixture(scope='module')
def ref_doc(tmp_path_factory, bags):
    return _slip(tmp_path_factory.mktemp('ref'), bags['ref'], 'ref')


def _slip(tmp_path, bag, name, *extra):
    """``slip`` on ``bag`` (exit 0, no bag refused): its slip.json. Without figures
    (--no-plots): these tests read slip.json only."""
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(['slip', str(bag), '--out', str(tmp_path / name), '--no-plots',
                          *extra])
    assert args.func(args) == 0
    doc = json.loads((tmp_path / name / 'slip.json').read_text())
    assert not doc['failed_bags']
    return doc


def _edge_diffs(ref, doc, key):
    """Per reference edge, the nearest same-tripod edge's touchdown and lift-off differences."""
    out = []
    for e in ref['runs'][0][key]:
        same = [x for x in doc['runs'][0][key] if x['tripod'] == e['tripod']]
        m = min(same, key=lambda x: abs(x['touchdown'] - e['touchdown']))
        out.append((m['touchdown'] - e['touchdown'], m['liftoff'] - e['liftoff']))
    return np.array(out)


def test_read_run_unwraps_and_derives(bags):
    ref = read_run(bags['ref'])
    wrap = read_run(bags['wrap'])
    assert_array_equal(wrap.joint_velocity, ref.joint_velocity)
    k = np.round((wrap.joint_position[0] - ref.joint_position[0]) / TWO_PI)
    assert_allclose(wrap.joint_position - TWO_PI * k, ref.joint_position, atol=1e-9, rtol=0)
    assert [n for n in wrap.notes if n not in ref.notes] == [
        "hip angles wrapped at +-pi: unwrapped (72 jump(s) of 2 pi undone, each sample the "
        "2 pi representative nearest the joint's previous one)"]
    novel = read_run(bags['novel'])
    assert DERIVED_NOTE in novel.notes
    assert_array_equal(novel.joint_t_s, ref.joint_t_s)
    # central differences of the 100 Hz angles against the simulator's own hip speeds: the
    # same away from the speed steps (stance/swing switches)
    err = np.abs(novel.joint_velocity - ref.joint_velocity)
    assert np.median(err) < 0.05 and np.sqrt(np.mean(err ** 2)) < 2.0


def test_wrapped_bags_give_the_original_stances(tmp_path, bags, ref_doc):
    ref = ref_doc
    assert len(ref['stances']) >= 9
    k_ref = np.array([s['stiffness'] for s in ref['stances']])
    for key, extra, note in (('wrap', (), 'hip angles wrapped at +-pi'),
                             ('zero_2pi', ('--hip-zero', '-1.0'), 'hip angles wrapped into '
                                                                   '[0, 2 pi)'),
                             ('zero', ('--hip-zero', '-1.0'), None)):
        doc = _slip(tmp_path, bags[key], key, *extra)
        run = doc['runs'][0]
        assert len(doc['stances']) == len(ref['stances']) and run['skipped'] == 0, key
        assert run['edges'] == 'geometry' and run['offset_method'] == 'geometry'
        for a, b in zip(ref['stances'], doc['stances']):
            assert (a['tripod'], a['touchdown'], a['liftoff']) == \
                (b['tripod'], b['touchdown'], b['liftoff']), key
        k = np.array([s['stiffness'] for s in doc['stances']])
        # the fits' sensitivity to the last bits of the angles ('zero' has no wrap at all)
        assert_allclose(k, k_ref, rtol=1e-4)
        assert run['offset_s'] == pytest.approx(ref['runs'][0]['offset_s'], abs=1e-6)
        assert np.abs(_edge_diffs(ref, doc, 'geometry_edges')).max() < 1e-5
        assert np.abs(_edge_diffs(ref, doc, 'paper_edges')).max() < 1e-9
        assert any(n.startswith(note) for n in run['notes']) if note else \
            not any('wrapped' in n for n in run['notes'])


def test_velocity_less_bag_gives_the_original_stances(tmp_path, bags, ref_doc):
    """Was refused ('no JointState sample has velocities'). The geometric edges are the
    original's; the paper's edges move later by ~1.4 ms (sample-quantised shift of the
    smoothed speed steps; central differences have no lag)."""
    ref = ref_doc
    doc = _slip(tmp_path, bags['novel'], 'novel')
    run = doc['runs'][0]
    assert len(doc['stances']) == len(ref['stances']) and run['skipped'] == 0
    assert DERIVED_NOTE in run['notes']
    assert any(n.startswith('hip angles wrapped at +-pi') for n in run['notes'])
    geo = _edge_diffs(ref, doc, 'geometry_edges')
    paper = _edge_diffs(ref, doc, 'paper_edges')
    print(f'no velocities: geometric edges |d| max {1e3 * np.abs(geo).max():.3f} ms, paper '
          f'edges mean {1e3 * paper.mean():+.3f} ms, offset '
          f"{1e3 * (run['offset_s'] - ref['runs'][0]['offset_s']):+.4f} ms")
    assert np.abs(geo).max() < 2e-4
    assert 0.0 < paper.mean() < 3e-3 and np.abs(paper).max() < 3e-3
    assert run['offset_s'] == pytest.approx(ref['runs'][0]['offset_s'], abs=2e-4)
    for a, b in zip(ref['stances'], doc['stances']):
        assert a['tripod'] == b['tripod']
        assert abs(a['touchdown'] - b['touchdown']) <= 1.0001e-3
        assert abs(a['liftoff'] - b['liftoff']) <= 1.0001e-3
    k_ref = np.median([s['stiffness'] for s in ref['stances']])
    assert np.median([s['stiffness'] for s in doc['stances']]) == pytest.approx(k_ref, rel=0.01)


# -- online -----------------------------------------------------------------------------
edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def test_online_wrapped_and_velocity_less_streams():
    from slip_identification.geometry import LegGeometry, body_pitch_rad, fit_ground_offset
    from slip_identification.online import OnlineSlip
    from slip_identification.pipeline import _up_from_quats
    from slip_identification.preprocess import Box, fit_world_frame

    run = edubot_sim.simulate_edubot('running', duration_s=3.5, seed=2)
    off = run.truth['clock_offset_s']
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    geo = LegGeometry.from_params(run.params)
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    pw = frame.to_world(run.mocap_position_m)
    ground = fit_ground_offset(geo, names, run.t_s, run.hip_position_rad,
                               run.hip_velocity_rad_s, run.mocap_t_s, pw[:, 2],
                               body_pitch_rad(frame.rotation, run.mocap_quat_xyzw),
                               initial_offset_s=off, fix_offset=True).ground_m
    ev = sorted([(float(t), 0, i) for i, t in enumerate(run.t_s)]
                + [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)])

    def feed(q, with_velocity):
        core = OnlineSlip(box=Box((-10.0,) * 3, (10.0,) * 3), mocap_offset_s=off, geometry=geo,
                          ground_m=ground, world_frame=frame)
        fits = []
        for _, kind, i in ev:
            if kind == 0:
                core.add_joint_state(float(run.t_s[i]), names,
                                     run.hip_velocity_rad_s[i] if with_velocity else E, q[i])
            else:
                core.add_mocap(float(run.mocap_t_s[i]), run.mocap_position_m[i],
                               run.mocap_quat_xyzw[i])
                fits.extend(core.step())
        return core, fits

    _, ref = feed(run.hip_position_rad, True)
    assert len(ref) >= 6
    key = [(f.tripod, f.touchdown_s, f.liftoff_s, f.params) for f in ref]
    for wrapped in (_wrap_pi(run.hip_position_rad), run.hip_position_rad % TWO_PI):
        core, fits = feed(wrapped, True)
        assert [(f.tripod, f.touchdown_s, f.liftoff_s, f.params) for f in fits] == key
        assert core.notes[0].startswith('hip angles wrapped (jumps of 2 pi between samples)')
    core, fits = feed(_wrap_pi(run.hip_position_rad), False)
    assert len(core.notes) == 2 and core.notes[0].startswith('no joint velocities')
    assert len(fits) == len(ref)
    for a, b in zip(ref, fits):
        assert a.tripod == b.tripod
        assert abs(a.touchdown_s - b.touchdown_s) <= 1.0001e-3
        assert abs(a.liftoff_s - b.liftoff_s) <= 1.0001e-3
    assert np.median([f.params['stiffness'] for f in fits]) == pytest.approx(
        np.median([f.params['stiffness'] for f in ref]), rel=0.02)
