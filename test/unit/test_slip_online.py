"""Online stance fitting (OnlineSlip) on a simulated EduBot run fed in arrival order.

Latency is measured in simulated time: the newest motion-capture sample (proprioception clock)
at the moment a stance is fitted, minus that stance's lift-off. Compute time is a benchmark
figure (bench/bench_slip.py), never asserted here.
"""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification.online import OnlineSlip
from slip_identification.pipeline import RunData, analyze_run, run_data_from_sim
from slip_identification.preprocess import Box

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

BOX = Box((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))


def run_data(run) -> RunData:
    return run_data_from_sim(run, with_effort=False)


def events(run):
    """(arrival time [s], kind, index) in arrival order: mocap arrives at true time."""
    off = run.truth['clock_offset_s']
    ev = [(float(t), 0, i) for i, t in enumerate(run.t_s)]
    ev += [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)]
    ev.sort()
    return ev


@pytest.fixture(scope='module')
def running():
    return edubot_sim.simulate_edubot('running', duration_s=4.0, seed=3)


def feed(run, ev=None):
    """OnlineSlip fed a simulated run in arrival order (or the events ``ev``): the core and
    its fits."""
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    core = OnlineSlip(box=BOX, mocap_offset_s=run.truth['clock_offset_s'])
    fits = []
    for _, kind, i in events(run) if ev is None else ev:
        if kind == 0:
            core.add_joint_state(float(run.t_s[i]), names, run.hip_velocity_rad_s[i])
            core.add_command(float(run.t_s[i]), names, run.target_velocity_rad_s[i])
        else:
            core.add_mocap(float(run.mocap_t_s[i]), run.mocap_position_m[i],
                           run.mocap_quat_xyzw[i])
            fits.extend(core.step())
    return core, fits


@pytest.fixture(scope='module')
def online(running):
    return feed(running)


def test_online_latency_in_simulated_time(online):
    core, fits = online
    # about 1.9 s of in-volume mocap; the first 0.5 s builds the world frame (frame_not_ready)
    assert len(fits) >= 8
    assert {s.reason for s in core.skipped} <= {'frame_not_ready'}
    lat_ms = 1e3 * np.array(core.latency_s)
    print(f'online data latency: median {np.median(lat_ms):.1f} ms, '
          f'p95 {np.percentile(lat_ms, 95):.1f} ms, max {lat_ms.max():.1f} ms')
    assert np.all(lat_ms >= 0.0)
    # typically fitted on the first 120 Hz mocap sample after lift-off
    assert np.median(lat_ms) <= 1e3 / 120.0 + 1e-6
    assert np.mean(lat_ms <= 20.0) >= 0.95


def test_online_fits_match_offline_pipeline(running, online):
    _, fits = online
    off = analyze_run(run_data(running), box=BOX, offset_s=running.truth['clock_offset_s'],
                      position_fit=False)
    # offline, a steady clock's edges come from all its cycles (stance.steady_clock), online
    # halfway between two command samples: the same stances up to 5 ms
    t0 = max(fits[0].touchdown_s, off.fits[0].touchdown_s) - 6e-3
    a = [f for f in fits if f.touchdown_s >= t0]
    b = [f for f in off.fits if f.touchdown_s >= t0 and f.liftoff_s <= fits[-1].liftoff_s + 6e-3]
    assert abs(len(a) - len(b)) <= 1
    pairs = [(x, min(b, key=lambda y: abs(y.touchdown_s - x.touchdown_s))) for x in a]
    pairs = [(x, y) for x, y in pairs if abs(x.touchdown_s - y.touchdown_s) < 0.015]
    print("dtd ms", [round(1e3 * (x.touchdown_s - y.touchdown_s), 1) for x, y in pairs])
    assert len(pairs) >= len(a) - 1
    # online spline ends at lift-off and its world frame comes from the buffer, so values
    # differ a little from the whole-run offline fit
    dk = np.array([abs(x.params['stiffness'] - y.params['stiffness']) / y.params['stiffness']
                   for x, y in pairs])
    dl = np.array([abs(x.params['rest_length'] - y.params['rest_length'])
                   for x, y in pairs])
    print(f'online vs offline: median |dk|/k {np.median(dk):.3f}, median |dl0| '
          f'{1e3 * np.median(dl):.2f} mm over {len(pairs)} stances')
    assert np.median(dk) < 0.05
    assert np.median(dl) < 0.002
    # no fit in another minimum: from the paper's start alone, one online stance stopped at
    # k 1985 N/m (nerr 0.14) where the offline one found 7401 (0.049): 73 % off; the rest
    # (up to 18 %) is the edges, halfway between two 100 Hz command samples online
    assert np.max(dk) < 0.3
    assert all(x.tripod == y.tripod for x, y in pairs)


def test_online_walk_fits_each_single_support_once():
    """The walk's stances overlap (duty factor above 0.5). When a stance lifts off, the other
    tripod has touched down but not yet lifted off: its stance is open at the newest sample.
    Counting whole stances only, the online fitter fitted every walk stance whole (up to its
    lift-off, with the other tripod down) and, once the other tripod lifted off, its
    single-support part again: 15 fits for the offline analysis' 8. Now each single-support
    window once, the offline ones within 5 ms."""
    run = edubot_sim.simulate_edubot('walk', duration_s=6.0, seed=3)
    _, fits = feed(run)
    off = analyze_run(run_data(run), box=BOX, offset_s=run.truth['clock_offset_s'],
                      position_fit=False)
    assert len(fits) >= 6
    for a, b in zip(fits, fits[1:]):
        assert b.touchdown_s >= a.liftoff_s - 1e-9, 'single-support windows overlap'
    for f in fits:
        match = [g for g in off.fits if abs(g.touchdown_s - f.touchdown_s) < 0.005]
        assert match, f'online stance at {f.touchdown_s:.3f} s not found offline'
        assert match[0].tripod == f.tripod
        assert abs(match[0].liftoff_s - f.liftoff_s) < 0.005


def geometric_setup(run):
    """Joint names, leg geometry, world frame and ground height (the offline geometric fit
    of the same run) for feeding OnlineSlip with geometric edges."""
    from slip_identification.geometry import LegGeometry, body_pitch_rad, fit_ground_offset
    from slip_identification.pipeline import _up_from_quats
    from slip_identification.preprocess import fit_world_frame

    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    geo = LegGeometry.from_params(run.params)
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    pw = frame.to_world(run.mocap_position_m)
    ground = fit_ground_offset(geo, names, run.t_s, run.hip_position_rad,
                               run.hip_velocity_rad_s, run.mocap_t_s, pw[:, 2],
                               body_pitch_rad(frame.rotation, run.mocap_quat_xyzw),
                               initial_offset_s=run.truth['clock_offset_s'],
                               fix_offset=True).ground_m
    return names, geo, frame, ground


def feed_geometric(run, setup, *, commands=False, gap=(-1.0, -1.0)):
    """OnlineSlip with geometric edges fed a simulated run in arrival order (the clock's
    commands too when asked; motion capture within ``gap`` [s, proprioception clock] left
    out): the core and its fits."""
    names, geo, frame, ground = setup
    off = run.truth['clock_offset_s']
    core = OnlineSlip(box=BOX, mocap_offset_s=off, geometry=geo, ground_m=ground,
                      world_frame=frame)
    fits = []
    for _, kind, i in events(run):
        if kind == 0:
            core.add_joint_state(float(run.t_s[i]), names, run.hip_velocity_rad_s[i],
                                 run.hip_position_rad[i])
            if commands:
                core.add_command(float(run.t_s[i]), names, run.target_velocity_rad_s[i])
        elif not gap[0] <= float(run.mocap_t_s[i]) - off <= gap[1]:
            core.add_mocap(float(run.mocap_t_s[i]), run.mocap_position_m[i],
                           run.mocap_quat_xyzw[i])
            fits.extend(core.step())
    return core, fits


def test_online_geometric_edges_against_truth():
    """With a robot description, a world frame and its ground height (here from the offline
    geometric fit of the same run), OnlineSlip fits the legs' geometric single-support
    windows: edges within 5 ms of the simulator's, each fitted on the first mocap samples
    after its lift-off."""
    run = edubot_sim.simulate_edubot('running', duration_s=3.5, seed=2)
    setup = geometric_setup(run)
    core, fits = feed_geometric(run, setup, commands=True)
    assert len(fits) >= 6
    # the geometric edges need no clock commands (a robot that does not publish them)
    _, bare = feed_geometric(run, setup)
    assert [(f.touchdown_s, f.liftoff_s, f.params) for f in bare] == \
        [(f.touchdown_s, f.liftoff_s, f.params) for f in fits]
    err = []
    for f in fits:
        tr = np.array(run.truth['single_support'][f.tripod])
        j = int(np.argmin(np.abs(tr[:, 0] - f.touchdown_s)))
        err.append((f.touchdown_s - tr[j, 0], f.liftoff_s - tr[j, 1]))
    err_ms = 1e3 * np.array(err)
    lat_ms = 1e3 * np.array(core.latency_s)
    print(f'online geometric edges: {len(fits)} stances, |error| max {np.abs(err_ms).max():.1f} '
          f'ms, latency median {np.median(lat_ms):.1f} ms, max {lat_ms.max():.1f} ms')
    assert np.mean(np.all(np.abs(err_ms) <= 5.0, axis=1)) >= 0.95
    assert np.mean(lat_ms <= 20.0) >= 0.95
    with pytest.raises(Exception, match='ground_m'):
        OnlineSlip(box=BOX, geometry=setup[1])


def test_live_review_fit_frame_and_mocap_offset_buffer():
    """A review of the live node: (1) with geometric edges the stances were fitted in the
    buffered frame, heights from the mocap origin's plane, so every rest length came out the
    ground height too long (12.4 mm, 11 % of l0); the fit frame now puts the ground at z = 0
    as the offline analysis does. (2) The mocap buffer was trimmed by the raw stamp: a capture
    clock 5 s ahead (mocap_offset 5 s) lost every sample, one 1000 s behind grew the buffer
    without bound."""
    from slip_identification.geometry import LegGeometry

    run = edubot_sim.simulate_edubot('running', duration_s=2.0, seed=2)
    geo = LegGeometry.from_params(run.params)
    core = OnlineSlip(box=BOX, geometry=geo, ground_m=0.0128)
    pm = run.mocap_position_m
    qm = run.mocap_quat_xyzw
    tm = run.mocap_t_s
    inside = np.ones(len(tm), dtype=bool)
    world = core._world_frame(tm, pm, qm, inside)
    fit = core._fit_frame(tm, pm, qm, inside)
    dz = world.to_world(pm)[:, 2] - fit.to_world(pm)[:, 2]
    assert np.allclose(dz, 0.0128, atol=1e-12)
    counts = []
    for offset in (0.0, 5.0, -1000.0):
        core = OnlineSlip(box=BOX, mocap_offset_s=offset, buffer_s=0.2)
        for t, p, q in zip(tm, pm, qm):
            core.add_mocap(float(t) + offset, p, q)
        kept = [m[0] for m in core._mocap]
        assert kept and kept[-1] - kept[0] <= 0.2 + 1e-9
        assert kept[-1] == pytest.approx(float(tm[-1]))
        counts.append(len(kept))
    assert counts[1] == counts[0] == counts[2]


@pytest.fixture(scope='module')
def geometric_feed():
    """A 6 s running run (mocap 1.5-3.9 s) fed with geometric edges, without or with a gap
    (start, end) in its motion capture [s, proprioception clock]: the core and its fits."""
    run = edubot_sim.simulate_edubot('running', duration_s=6.0, seed=2)
    setup = geometric_setup(run)

    def feed(gap=(-1.0, -1.0)):
        return feed_geometric(run, setup, gap=gap)

    return feed, feed()


@pytest.mark.parametrize('gap', [(2.5, 2.54), (2.5, 2.6), (2.7, 3.02), (2.2, 2.6),
                                 (2.0, 2.9), (2.5, 3.5), (3.0, 3.01)])
def test_online_geometric_stances_lost_to_a_mocap_gap_are_skipped_once_each(geometric_feed,
                                                                            gap):
    """With geometric edges, stances a motion-capture gap cuts or hides were left out without
    a word (the offline analysis lists them as mocap_gap); a first fix caught only pieces cut
    by a gap shorter than the contact window, merged two stances around a 320 ms gap and
    clipped their times (an outside review: a 1 s dropout lost 7 stances, 0 skipped). Each
    lost stance is now one skip, placed between the fits of its tripod either side of the
    gap by the stride the hips turn at (one turn a stride): its times within 10 ms; the other stances are fitted as
    without the gap (a 10 ms gap, one missing sample, loses none)."""
    feed, (clean, fits) = geometric_feed
    assert clean.skipped == [] and len(fits) >= 12
    core, got = feed(gap)

    def key(f):
        return f.tripod, round(f.liftoff_s, 2)

    lost = [f for f in fits if not any(g.tripod == f.tripod and abs(g.liftoff_s - f.liftoff_s)
                                       < 0.01 for g in got)]
    assert all(any(f.tripod == g.tripod and abs(g.liftoff_s - f.liftoff_s) < 0.01
                   for f in fits) for g in got)          # nothing new fitted
    skips = [s for s in core.skipped if s.reason == 'mocap_gap']
    assert len(skips) == len(lost), (gap, [key(f) for f in lost], skips)
    for f in lost:
        s, = [s for s in skips if s.tripod == f.tripod
              and abs(s.liftoff_s - f.liftoff_s) < 0.01]
        assert abs(s.touchdown_s - f.touchdown_s) < 0.01
    assert [s.reason for s in core.skipped if s.reason != 'mocap_gap'] == []


def test_joint_states_received_out_of_stamp_order_give_the_same_fits(running, online):
    """An outside review (another lab's bag replayed into slip_fitter): 20 % of /joint_states
    received 15 ms late, after their successors, took 5 of 16 stances' stiffness -1.2 to
    +2.5 % (re-stamped as repeats, then buffered in arrival order). Each row is now inserted
    at its own stamp: the stances are those of the in-order feed."""
    _, ref = online
    rng = np.random.default_rng(3)
    ev = [(a + (0.015 if kind == 0 and i and rng.random() < 0.2 else 0.0), kind, i)
          for a, kind, i in events(running)]
    ev.sort()
    assert any(k == 0 and j < i for (_, k, i), (_, _, j) in zip(ev, ev[1:]) if k == 0)
    _, fits = feed(running, ev)
    got = {round(f.touchdown_s, 4): f.params['stiffness'] for f in fits}
    want = {round(f.touchdown_s, 4): f.params['stiffness'] for f in ref}
    common = set(got) & set(want)
    assert len(common) >= len(want) - 1
    # before: 5 of 11 stances at the in-order feed's touchdowns. Now all, the stiffness
    # within 0.3 % on 10 of 11, 2.8 % on one (a shift computed before a late sample came)
    rel = np.array([abs(got[t] / want[t] - 1) for t in common])
    assert np.median(rel) < 3e-3 and rel.max() < 0.05
