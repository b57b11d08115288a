"""Full joint frames from JointState messages split over name groups (``joints.py``), offline
and online, and the online SLIP core fed split messages."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from hexapod_common.conversions import JointStateSample
from slip_identification.errors import SlipDataError
from slip_identification.joints import (
    JointFrameAssembler,
    assemble_joint_frames,
    missing_joints,
)
from slip_identification.online import OnlineSlip
from slip_identification.preprocess import Box

HIPS = ('L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip')
E = np.zeros(0)
OMEGA = 2 * math.pi * 1.5  # rad/s of the test signals


def _truth(t, j):
    """Joint j's angle [rad] and speed [rad/s] at t: smooth, distinct per joint."""
    return (np.sin(OMEGA * t + j), OMEGA * np.cos(OMEGA * t + j))


def _split_samples(groups, rates_hz, offsets_s, *, t_end_s=2.0, jitter_s=0.0, seed=0):
    """Messages of each group at its own rate and phase, in arrival (stamp) order."""
    rng = np.random.default_rng(seed)
    out = []
    for g, rate, off in zip(groups, rates_hz, offsets_s):
        for t in np.arange(off, t_end_s, 1.0 / rate):
            ts = float(t + rng.uniform(-jitter_s, jitter_s))
            q, v = zip(*(_truth(ts, HIPS.index(n)) for n in g))
            out.append(JointStateSample(ts, tuple(g), np.array(q), np.array(v), E))
    out.sort(key=lambda s: s.t_s)
    return out


def _online(samples, **kw):
    asm = JointFrameAssembler(**kw)
    frames = []
    for s in samples:
        frames.extend(asm.add(s.t_s, s.names, s.velocity, s.position))
    return asm, frames


def test_full_frames_are_returned_unchanged_in_the_first_order():
    rng = np.random.default_rng(1)
    samples = []
    for k in range(50):
        o = rng.permutation(6)
        samples.append(JointStateSample(0.01 * k, tuple(HIPS[i] for i in o),
                                        np.arange(6.0)[o], np.arange(6.0)[o] + k, E))
    a = assemble_joint_frames(samples)
    assert a.groups == 1 and a.note == '' and a.effort is None
    order = samples[0].names
    assert a.names == order
    assert_array_equal(a.t_s, 0.01 * np.arange(50))
    for k in range(50):
        assert_array_equal(a.velocity[k], [HIPS.index(n) + k for n in order])
    asm, frames = _online(samples)
    assert not asm.split and len(frames) == 50
    assert_array_equal(np.array([f.velocity for f in frames]), a.velocity)


@pytest.mark.parametrize('case', ['buses', 'singles_jitter', 'rates'])
def test_split_groups_match_the_truth_offline_and_online(case):
    if case == 'buses':  # two servo buses read 3 ms apart
        groups, rates, offs, jit = [HIPS[:3], HIPS[3:]], [100, 100], [0.0, 0.003], 0.0
    elif case == 'singles_jitter':  # one message per joint, own read time +-0.5 ms
        groups, rates, offs, jit = [[h] for h in HIPS], [100] * 6, \
            [0.001 * j for j in range(6)], 5e-4
    else:  # per leg side at slightly different rates
        groups, rates, offs, jit = [HIPS[:3], HIPS[3:]], [100, 97], [0.0, 0.004], 0.0
    samples = _split_samples(groups, rates, offs, jitter_s=jit)
    a = assemble_joint_frames(samples)
    assert a.groups == len(groups) and set(a.names) == set(HIPS)
    assert f'split over {len(groups)} name groups' in a.note
    assert a.rate_hz == pytest.approx(max(rates), rel=0.05)
    # never extrapolated: frames inside the span every joint covers
    firsts = [min(s.t_s for s in samples if n in s.names) for n in HIPS]
    lasts = [max(s.t_s for s in samples if n in s.names) for n in HIPS]
    assert a.t_s[0] >= max(firsts) and a.t_s[-1] <= min(lasts)
    assert a.t_s.size >= 2.0 * max(rates) - 6
    cols = [a.names.index(h) for h in HIPS]
    q_true = np.column_stack([_truth(a.t_s, j)[0] for j in range(6)])
    v_true = np.column_stack([_truth(a.t_s, j)[1] for j in range(6)])
    # linear interpolation of a sine over a sample interval dt: error <= w^2 dt^2 / 8
    bound = OMEGA ** 2 * (1.0 / min(rates) + 2 * jit) ** 2 / 8
    assert np.abs(a.position[:, cols] - q_true).max() <= bound * 1.01
    assert np.abs(a.velocity[:, cols] - v_true).max() <= bound * OMEGA * 1.01
    asm, frames = _online(samples)
    assert asm.split and asm.names == a.names and asm.groups == len(groups)
    t_on = np.array([f.t_s for f in frames])
    # online: the same frames (the first few are held back while the set is learnt)
    common, i_on, i_off = np.intersect1d(t_on, a.t_s, return_indices=True)
    assert common.size >= a.t_s.size - 3
    assert_allclose(np.array([f.velocity for f in frames])[i_on], a.velocity[i_off],
                    rtol=0, atol=1e-12)
    assert_allclose(np.array([f.position for f in frames])[i_on], a.position[i_off],
                    rtol=0, atol=1e-12)


def test_overlapping_groups_take_the_most_recent_value():
    # the whole robot at 50 Hz and L1 alone at 100 Hz; at shared stamps the later message wins
    samples = []
    for k in range(40):
        t = 0.02 * k
        samples.append(JointStateSample(t, HIPS, np.zeros(6), np.full(6, 1.0), E))
        samples.append(JointStateSample(t, ('L1_hip',), np.zeros(1), np.array([2.0]), E))
        samples.append(JointStateSample(t + 0.01, ('L1_hip',), np.zeros(1), np.array([3.0]),
                                        E))
    a = assemble_joint_frames(samples)
    assert a.groups == 2
    # time base: the densest group inside the common span (L1's 100 Hz stamps)
    assert_allclose(np.diff(a.t_s), 0.01, atol=1e-12)
    l1 = a.velocity[:, a.names.index('L1_hip')]
    on_grid = np.isclose((a.t_s / 0.02) % 1.0, 0.0, atol=1e-6) | \
        np.isclose((a.t_s / 0.02) % 1.0, 1.0, atol=1e-6)
    assert_array_equal(l1[on_grid], 2.0)   # not the full message's 1.0 at the same stamp
    assert_array_equal(l1[~on_grid], 3.0)
    assert_array_equal(a.velocity[:, a.names.index('R3_hip')], 1.0)


def test_groups_that_never_cover_the_joints_are_refused_naming_them():
    assert missing_joints(('L1_hip', 'L2_hip', 'R1_hip')) == ['R2_hip']
    assert missing_joints(('L2_coxa', 'R2_coxa', 'L2_femur')) == \
        ['L1_coxa', 'L1_femur', 'R1_coxa', 'R1_femur', 'R2_femur']
    assert missing_joints(('joint_a', 'joint_b')) == []
    samples = _split_samples([HIPS[:3], HIPS[3:5]], [100, 100], [0.0, 0.002])
    with pytest.raises(SlipDataError, match=r"never names joint\(s\) \['R3_hip'\]"):
        assemble_joint_frames(samples)
    with pytest.raises(SlipDataError, match=r"\['R1_hip', 'R2_hip', 'R3_hip'\]"):
        assemble_joint_frames(_split_samples([HIPS[:3]], [100], [0.0]))
    asm = JointFrameAssembler()
    with pytest.raises(SlipDataError, match=r"\['R3_hip'\]"):
        for s in samples:
            assert asm.add(s.t_s, s.names, s.velocity, s.position) == []
    # raised once: later messages are dropped silently (the node logs one line)
    assert asm.add(5.0, HIPS[:3], np.zeros(3), np.zeros(3)) == []


def test_no_interpolation_over_a_dropout_and_angles_unwrapped():
    samples = _split_samples([HIPS[:3], HIPS[3:]], [100, 100], [0.0, 0.004], t_end_s=3.0)
    # the right bus is silent from 1.0 to 1.5 s
    samples = [s for s in samples if not (s.names == HIPS[3:] and 1.0 < s.t_s < 1.5)]
    a = assemble_joint_frames(samples)
    assert not np.any((a.t_s > 1.01) & (a.t_s < 1.49))
    assert a.dropped >= 45 and 'in joint gaps dropped' in a.note
    # angles wrapped into (-pi, pi] by a driver come out continuous
    t = np.arange(0.0, 1.0, 0.01)
    wrapped = []
    for k, tk in enumerate(t):
        for g, off in ((HIPS[:3], 0.0), (HIPS[3:], 0.005)):
            q = np.full(3, 20.0 * (tk + off))
            wrapped.append(JointStateSample(tk + off, g, np.angle(np.exp(1j * q)),
                                            np.full(3, 20.0), E))
    a = assemble_joint_frames(wrapped)
    assert_allclose(np.diff(a.position, axis=0),
                    np.repeat(20.0 * np.diff(a.t_s)[:, None], 6, axis=1), atol=1e-9)
    asm, frames = _online(wrapped)
    q_on = np.array([f.position for f in frames])
    assert_allclose(np.diff(q_on, axis=0),
                    np.repeat(20.0 * np.diff([f.t_s for f in frames])[:, None], 6, axis=1),
                    atol=1e-9)


def test_online_state_stays_bounded():
    samples = _split_samples([[h] for h in HIPS], [100] * 6, [0.0005 * j for j in range(6)],
                             t_end_s=60.0, jitter_s=2e-4)
    asm = JointFrameAssembler()
    n = 0
    for s in samples:
        n += len(asm.add(s.t_s, s.names, s.velocity, s.position))
        assert len(asm._pending) <= 8 and all(len(h) <= asm.history for h in asm._hist)
    assert n >= 5990 and asm.dropped <= 2


edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def test_online_slip_fed_split_messages_fits_the_same_stances():
    run = edubot_sim.simulate_edubot('running', duration_s=3.7, seed=4)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    off = run.truth['clock_offset_s']
    box = Box((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))
    ev = sorted([(float(t), 0, i) for i, t in enumerate(run.t_s)]
                + [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)])
    rng = np.random.default_rng(3)
    fits = {}
    for mode in ('full', 'six'):
        core = OnlineSlip(box=box, mocap_offset_s=off)
        out = []
        for _, kind, i in ev:
            if kind == 1:
                core.add_mocap(run.mocap_t_s[i], run.mocap_position_m[i],
                               run.mocap_quat_xyzw[i])
                out.extend(core.step())
                continue
            t = float(run.t_s[i])
            if mode == 'full':
                core.add_joint_state(t, names, run.hip_velocity_rad_s[i],
                                     run.hip_position_rad[i])
                core.add_command(t, names, run.target_velocity_rad_s[i])
            else:  # one message per joint, right side first, jittered stamps
                for j in (3, 0, 4, 1, 5, 2):
                    tj = t + float(rng.uniform(-3e-4, 3e-4))
                    core.add_joint_state(tj, (names[j],), run.hip_velocity_rad_s[i][[j]],
                                         run.hip_position_rad[i][[j]])
                    core.add_command(t, (names[j],), run.target_velocity_rad_s[i][[j]])
        fits[mode] = out
        if mode == 'six':
            assert core._joints.split and core._joints.groups == 6
            assert set(core.names) == set(names)
    ref, got = fits['full'], fits['six']
    assert len(ref) >= 8 and abs(len(got) - len(ref)) <= 1
    for r in ref:
        g = min((x for x in got if x.tripod == r.tripod),
                key=lambda x: abs(x.touchdown_s - r.touchdown_s))
        assert abs(g.touchdown_s - r.touchdown_s) <= 2e-3
        assert abs(g.liftoff_s - r.liftoff_s) <= 2e-3
    k_ref = np.median([r.params['stiffness'] for r in ref])
    k_got = np.median([r.params['stiffness'] for r in got])
    assert k_got == pytest.approx(k_ref, rel=0.02)
