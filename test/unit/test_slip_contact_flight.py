"""The contact offset estimator's assumption, checked on the data: an aerial phase.

``estimate_offset_contacts`` finds touchdowns where the body height leaves a ballistic
parabola. On a gait where a tripod always carries the body (simulated EduBot walk and pace)
there is no such break: its touchdowns moved late by about the search width with each
iteration, and the estimate was 63-75 ms off on clean walks (the median of three iterations'
drift, not a measurement). With motion-capture windows on the track's gap rule (30 ms) it was
accepted under dropouts too, and the geometric fit started from it settled 9.6 and 12.9 ms off
on two of three walks with 10 % of the poses missing in pairs. Now the estimator fits gravity
free around its stances (``contact.free_fall_gravity``: 9.7-9.9 m/s^2 running and jogging,
1.5-2.6 pace, 0.5 walk) and refuses a run below half of g, so 'auto' starts from the
cross-correlation.

Starting there, the half-stride check once took a start whose output-error refinement had
failed: its equation-error residual (0.164 mm over 0.1 s windows with three free parameters
each) is not comparable with a refined fit's (0.202 mm), and a clean walk went 524 ms off;
and where the aliases fit alike (a reviewer's clock without flight: 0.219 against 0.226 mm)
it kept the cross-correlation's, 300 ms off. With efforts the tie now goes to the offset
nearest zero: the hip-effort estimators' assumption (clocks within a quarter stride), which
decided it while they accepted such runs.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from slip_identification.errors import SlipDataError
from slip_identification.geometry import GeometryFit, LegGeometry
from slip_identification.pipeline import (
    TRIPODS,
    RunResult,
    _half_stride_check,
    _up_from_quats,
    analyze_run,
    run_data_from_sim,
)
from slip_identification.preprocess import fit_world_frame
from slip_identification.proprio_edges import (
    alternating_touchdowns,
    estimate_offset_contacts,
    tripod_touchdowns,
)

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _pairs_missing(n: int, seed: int, frac: float = 0.10) -> np.ndarray:
    """Indices of ``frac`` of ``n`` samples, missing in pairs (two samples: 17 ms at 120 Hz)
    with at least one sample between pairs."""
    rng = np.random.default_rng(seed)
    starts: list[int] = []
    while len(starts) < int(round(frac * n / 2)):
        s = int(rng.integers(5, n - 7))
        if all(abs(s - o) > 2 for o in starts):
            starts.append(s)
    return np.sort(np.concatenate([[s, s + 1] for s in starts]))


def _contact_inputs(run):
    """The contact estimator's inputs as analyze_run builds them (touchdowns, mocap, height)."""
    rd = run_data_from_sim(run)
    frame = fit_world_frame(rd.mocap_position_m, up_mocap=_up_from_quats(rd.mocap_quat_xyzw))
    z = frame.to_world(rd.mocap_position_m)[:, 2]
    td = alternating_touchdowns({tp: tripod_touchdowns(rd.joint_names, rd.joint_t_s,
                                                       rd.joint_effort, TRIPODS[tp])
                                 for tp in TRIPODS})[0]
    stance_s = float(min(0.12, 0.75 * np.median(np.diff(td))))
    return td, np.asarray(rd.mocap_t_s), z, stance_s


@pytest.mark.parametrize('gait,low,high', [('running', 9.3, 10.3), ('walk', -1.0, 2.0)])
def test_free_fall_gravity_is_g_only_between_aerial_stances(gait, low, high) -> None:
    from slip_identification.contact import free_fall_gravity

    # noise-free heights at 120 Hz around the simulator's true touchdowns; lift-offs true, at
    # most 3/4 of the way to the next touchdown (a walk's stances overlap: the estimator's
    # nominal stance)
    run = edubot_sim.simulate_edubot(gait, duration_s=3.0, seed=1,
                                     effects={'mocap_noise': 0.0})
    t = np.arange(0.5, 2.95, 1 / 120.0)
    z = np.interp(t, run.fine_t_s, run.fine_state[:, 2])
    c = np.concatenate([np.array(run.truth['tripod_contact'][tp]) for tp in TRIPODS])
    c = c[np.argsort(c[:, 0])]
    c[:-1, 1] = np.minimum(c[:-1, 1], c[:-1, 0] + 0.75 * np.diff(c[:, 0]))
    c = c[(c[:, 0] > 0.6) & (c[:, 1] < 2.85)]
    g = free_fall_gravity(t, z, c)
    assert np.isfinite(g).sum() >= 3
    print(f'{gait}: gravity fitted free around {c.shape[0]} stances {np.round(g, 2)}')
    assert low < np.nanmedian(g) < high


def test_contact_offset_refuses_a_walk_and_keeps_running() -> None:
    walk = edubot_sim.simulate_edubot('walk', duration_s=4.0, seed=1)
    td, tm, z, stance_s = _contact_inputs(walk)
    # was accepted: +67.9 ms off the truth
    with pytest.raises(SlipDataError, match='does not fall freely between stances'):
        estimate_offset_contacts(td, tm, z, stance_s=stance_s)
    running = edubot_sim.simulate_edubot('running', duration_s=4.0, seed=1)
    td, tm, z, stance_s = _contact_inputs(running)
    off, _ = estimate_offset_contacts(td, tm, z, stance_s=stance_s)
    assert abs(off - running.truth['clock_offset_s']) < 6e-3           # +3.8 ms, as before


@pytest.mark.parametrize('seed,draw', [(1, 0), (3, None)])
def test_walk_auto_offset_starts_from_the_cross_correlation(seed, draw) -> None:
    # seed 1 with 10 % of the poses missing in pairs: the geometric fit started from the
    # contact estimate (75 ms off) settled 9.6 ms off; clean seed 3 from the
    # cross-correlation: the half-stride check took an unrefined start, 524 ms off
    run = edubot_sim.simulate_edubot('walk', duration_s=4.0, seed=seed)
    rd = run_data_from_sim(run)
    if draw is not None:
        p = np.array(rd.mocap_position_m, dtype=float)
        q = np.array(rd.mocap_quat_xyzw, dtype=float)
        idx = _pairs_missing(p.shape[0], 1000 + draw)
        p[idx] = np.nan
        q[idx] = np.nan
        rd = dataclasses.replace(rd, mocap_position_m=p, mocap_quat_xyzw=q)
    res = analyze_run(rd, offset_s='auto', position_fit=False,
                      geometry=LegGeometry.from_params(run.params))
    err_ms = 1e3 * (res.offset_s - run.truth['clock_offset_s'])
    print(f'walk seed {seed} draw {draw}: offset error {err_ms:+.2f} ms')
    assert abs(err_ms) < 1.5                                # clean runs: -0.12 and -0.75 ms
    assert res.frame['offset_initial'] == 'xcorr'
    assert any('refused the run' in n and 'fall freely' in n for n in res.notes)
    # the ambiguity warning does not ask for the efforts the run has
    assert not any('record hip efforts' in w for w in res.warnings)


def test_half_stride_check_takes_no_unrefined_start(monkeypatch) -> None:
    import slip_identification.pipeline as pl

    def fit(*args, initial_offset_s, **kw):
        # the alias's refinement failed: its equation-error rms is lower, not better
        return GeometryFit(offset_s=initial_offset_s, ground_m=0.0,
                           rms_m=1.64e-4 if initial_offset_s < 0 else 2.06e-4, windows=9,
                           damping_ratio_s=0.0, unrefined=initial_offset_s < 0)

    monkeypatch.setattr(pl, 'fit_ground_offset', fit)
    t = np.arange(0.0, 3.0, 0.01)
    w = np.full(t.size, 2 * np.pi / 1.047)
    first = GeometryFit(offset_s=0.025, ground_m=0.0, rms_m=2.02e-4, windows=12,
                        damping_ratio_s=0.0)
    for efforts in (False, True):
        res = RunResult()
        got = _half_stride_check(first, (), np.zeros(3), {'left': w, 'right': w}, t, 0.1, res,
                                 with_efforts=efforts)
        assert got is first                                 # was the start 0.52 s earlier
        assert not any('half a stride off' in n for n in res.notes)
    # a refined start that fits clearly better is still taken
    monkeypatch.setattr(pl, 'fit_ground_offset', lambda *a, initial_offset_s, **k: GeometryFit(
        offset_s=initial_offset_s, ground_m=0.0,
        rms_m=1.64e-4 if initial_offset_s < 0 else 2.06e-4, windows=9, damping_ratio_s=0.0))
    got = _half_stride_check(first, (), np.zeros(3), {'left': w, 'right': w}, t, 0.1,
                             RunResult())
    assert got.offset_s < -0.4


def test_half_stride_tie_with_efforts_goes_to_the_offset_nearest_zero(monkeypatch) -> None:
    import slip_identification.pipeline as pl

    monkeypatch.setattr(pl, 'fit_ground_offset', lambda *a, initial_offset_s, **k: GeometryFit(
        offset_s=initial_offset_s, ground_m=0.0, rms_m=2.21e-4, windows=12,
        damping_ratio_s=0.0))
    t = np.arange(0.0, 3.0, 0.01)
    w = np.full(t.size, 2 * np.pi / 0.6)
    first = GeometryFit(offset_s=-0.2744, ground_m=0.0, rms_m=2.19e-4, windows=12,
                        damping_ratio_s=0.0)
    res = RunResult()
    got = _half_stride_check(first, (), np.zeros(3), {'left': w, 'right': w}, t, 0.1, res,
                             with_efforts=True)
    assert got.offset_s == pytest.approx(-0.2744 + 0.3, abs=1e-3)
    [note] = [n for n in res.notes if 'ambiguous by half a stride' in n]
    assert 'nearest zero' in note and '--offset' in note
    assert not any('half a stride' in x for x in res.warnings)
    assert res.frame['offset_half_stride']['chosen_offset_s'] == got.offset_s
    # without efforts the first fit is kept and the ambiguity warned, as before
    res = RunResult()
    assert _half_stride_check(first, (), np.zeros(3), {'left': w, 'right': w}, t, 0.1,
                              res) is first
    assert any('record hip efforts' in x for x in res.warnings)


def test_reviewer_clock_without_flight_from_the_cross_correlation() -> None:
    """A reviewer's clock (test_slip_offset_starts): seed 4's body never falls freely
    (contact refused); from the cross-correlation the fit landed half a stride off (-299.6 ms,
    the aliases' residuals within 3 %); the tie now goes to the offset nearest zero. Before
    the contact estimator refused such runs: 16.8 ms off from its start."""
    from hexapod_gait.buehler import BuehlerClock

    clock = BuehlerClock(period_s=2 * np.pi / 10.5, duty_factor=0.5, sweep_angle_rad=1.0,
                         leg_offset_rad=0.2, kp_norm=0.7, kd_norm=0.0)
    run = edubot_sim.simulate_edubot(clock, duration_s=6.0, seed=4)
    res = analyze_run(run_data_from_sim(run), offset_s='auto',
                      geometry=LegGeometry.from_params(run.params), position_fit=False)
    err_ms = 1e3 * (res.offset_s - run.truth['clock_offset_s'])
    print(f'reviewer clock seed 4: offset error {err_ms:+.2f} ms')
    assert abs(err_ms) < 1.0                                # -0.35 ms
    assert res.frame['offset_initial'] == 'xcorr'
