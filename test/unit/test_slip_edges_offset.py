"""Stance edges and the stream offset on simulated runs: proprioceptive (proprio_edges.py) and
geometric (geometry.py) estimators against the simulator's truth.

Figures printed (pytest -s). The issue's bars get one test each at the end (3 seeds x running,
jogging, pace, walk; stances counted from the steady state on, slip_identification.steady):
the ground height (frame translation) within 2 mm and the offset within 2 ms are met on all
(with the output-error refinement of the ground and offset fit, geometry.py); the edges within
5 ms for 95 % of stances on all four gaits (100 % on each over seeds 1-12).
Figures in the bar tests' docstrings.

Legacy estimators on the retuned simulator (0.105 m legs, stances of 35-70 ms, 60 % aerial):
the contact estimator (effort onsets against ballistic body-height breaks, nominal stance now
3/4 of the time between alternating touchdowns) is within a few ms; the joint estimator refuses
some runs (running seeds 1-3 of 5 s) and is 13-23 ms off on 5 s jogging runs, so 'auto'
without a geometry tries contact, then joint, then the cross-correlation.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from slip_identification.errors import SlipDataError
from slip_identification.geometry import (
    LegGeometry,
    body_pitch_rad,
    fit_ground_offset,
    leg_contacts,
    single_support,
)
from slip_identification.pipeline import (
    TRIPODS,
    RunData,
    _up_from_quats,
    analyze_run,
    run_data_from_sim,
)
from slip_identification.preprocess import Box, fit_world_frame
from slip_identification.steady import steady_start_s
from slip_identification.proprio_edges import (
    alternating_touchdowns,
    effort_onsets,
    estimate_offset_contacts,
    refine_touchdowns,
    tripod_touchdowns,
)

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

BOX = Box((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))


def run_data(run) -> RunData:
    return run_data_from_sim(run, with_effort=True)


def edge_errors_ms(res, run) -> np.ndarray:
    """(m, 2) fitted window minus the truth single-support interval [ms]."""
    out = []
    for f in res.fits:
        tr = np.array(run.truth['single_support'][f.tripod])
        j = int(np.argmin(np.abs(tr[:, 0] - f.touchdown_s)))
        out.append((f.touchdown_s - tr[j, 0], f.liftoff_s - tr[j, 1]))
    return 1e3 * np.array(out).reshape(-1, 2)


def _try(f):
    try:
        return f()
    except SlipDataError as err:
        return err


@pytest.fixture(scope='module')
def runs():
    out = []
    for run in edubot_sim.simulate_edubot_batch('running', duration_s=4.5, seeds=(1, 5)):
        rd = run_data(run)
        off = run.truth['clock_offset_s']
        res = {
            'auto': analyze_run(rd, box=BOX, offset_s='auto', position_fit=False),
            'joint': _try(lambda: analyze_run(rd, box=BOX, offset_s='joint',
                                              position_fit=False)),
            'contact': analyze_run(rd, box=BOX, offset_s='contact', position_fit=False),
            'xcorr': analyze_run(rd, box=BOX, offset_s='xcorr', position_fit=False),
            'paper': analyze_run(rd, box=BOX, offset_s=off, position_fit=False),
            'effort': analyze_run(rd, box=BOX, offset_s=off, position_fit=False,
                                  edges='effort'),
        }
        out.append((run, res))
    return out


def test_effort_onsets_interpolated_and_braking_spikes_ignored():
    t = np.arange(0.0, 3.0, 0.01)
    onsets = np.array([0.203, 0.5371, 0.8649, 1.2, 1.5312, 1.8655, 2.2018, 2.5333])
    e = np.full(t.size, 0.05)
    rise_s = 0.02
    for a in onsets:
        k = (t >= a) & (t < a + 0.12)
        e[k] = 0.05 + 0.55 * np.minimum((t[k] - a) / rise_s, 1.0)
        spike = int(np.searchsorted(t, a + 0.15))
        e[spike] = -1.2  # braking when the clock switches phase: not a load
    got = effort_onsets(t, e)
    assert got.size == onsets.size
    # the crossing of the 15 % threshold on a linear rise, interpolated between 100 Hz samples:
    # late by the threshold's place on the ramp (0.15 * rise time), within a quarter sample
    # (linear interpolation across the ramp's corner)
    np.testing.assert_allclose(got, onsets + 0.15 * rise_s, atol=2.5e-3)


def test_tripod_touchdowns_first_leg_and_refine():
    t = np.arange(0.0, 2.0, 0.01)
    names = ('L1_hip', 'L2_hip', 'L3_hip', 'R1_hip', 'R2_hip', 'R3_hip')
    e = np.full((t.size, 6), 0.05)
    starts = {'L1_hip': 0.012, 'R2_hip': 0.006, 'L3_hip': 0.0013}
    period = 0.33
    for name, a in starts.items():
        for c in range(1, 6):  # stances at c * period + start, 100 ms long
            k = (t >= c * period + a) & (t < c * period + a + 0.1)
            e[k, names.index(name)] = 0.6
    td = tripod_touchdowns(names, t, e, ('L1', 'R2', 'L3'))
    assert td.size == 5
    # a step onset is known to one sample interval; the first leg of each tripod counts
    expected = period * np.arange(1, 6) + 0.0013
    assert np.all((td >= expected - 1e-9) & (td <= expected + 0.01))
    w, moved = refine_touchdowns(np.array([[td[0] - 0.02, td[0] + 0.1], [0.1, 0.2]]), td)
    assert moved.tolist() == [True, False]
    assert w[0, 0] == td[0] and w[1, 0] == 0.1 and w[0, 1] == pytest.approx(td[0] + 0.1)
    with pytest.raises(SlipDataError, match='effort must be'):
        tripod_touchdowns(names, t, e[:, :3], ('L1',))


def test_offset_from_contacts_refuses_too_little_data():
    with pytest.raises(SlipDataError, match='mocap samples'):
        estimate_offset_contacts([0.1, 0.4], np.arange(5) / 120, np.zeros(5))
    with pytest.raises(SlipDataError, match='touchdowns'):
        estimate_offset_contacts([0.1], np.arange(100) / 120, np.zeros(100))


def test_stream_offset_from_contacts_on_simulated_runs(runs):
    for run, res in runs:
        off = run.truth['clock_offset_s']
        e_c = 1e3 * (res['contact'].offset_s - off)
        e_x = 1e3 * (res['xcorr'].offset_s - off)
        e_j = ('refused' if isinstance(res['joint'], SlipDataError)
               else f"{1e3 * (res['joint'].offset_s - off):+.1f} ms")
        print(f'seed {run.seed}: offset error contact {e_c:+.1f} ms, joint {e_j}, '
              f'xcorr {e_x:+.1f} ms')
        assert res['contact'].offset_method == 'contact'
        # 'auto' with efforts and no geometry: the first proprioceptive estimator that
        # accepts the run
        assert res['auto'].offset_method in ('contact', 'joint')
        assert res['auto'].edges == 'paper'  # no geometry given
        assert abs(e_c) <= 10.0


def test_contact_offset_on_simulated_jogging():
    run = edubot_sim.simulate_edubot('jogging', duration_s=4.5, seed=2)
    res = analyze_run(run_data(run), box=BOX, offset_s='contact', position_fit=False)
    err_ms = 1e3 * (res.offset_s - run.truth['clock_offset_s'])
    print(f'jogging seed 2: contact offset error {err_ms:+.2f} ms, {len(res.fits)} stances')
    assert abs(err_ms) <= 6.0


def test_alternating_touchdowns_drop_spurious_onsets():
    t, w = alternating_touchdowns({'left': [0.10, 0.17, 0.44], 'right': [0.27, 0.60, 0.66]})
    np.testing.assert_allclose(t, [0.10, 0.27, 0.44, 0.60])
    assert w.tolist() == [0, 1, 0, 1]


def test_effort_touchdown_against_truth(runs):
    """Effort onsets mark the first leg's touchdown; on the retuned simulator the single-support
    start is that touchdown in running (aerial phases), so it is compared there."""
    for run, res in runs:
        ep = edge_errors_ms(res['paper'], run)
        ee = edge_errors_ms(res['effort'], run)
        print(f'seed {run.seed}: paper td median {np.median(ep[:, 0]):+.1f} ms '
              f'({np.mean(np.abs(ep[:, 0]) <= 5):.0%} within 5 ms), lift-off median '
              f'{np.median(ep[:, 1]):+.1f} ms ({np.mean(np.abs(ep[:, 1]) <= 5):.0%}); effort td '
              f'median {np.median(ee[:, 0]):+.1f} ms ({np.mean(np.abs(ee[:, 0]) <= 5):.0%}); '
              f'{len(ee)} stances')
        assert len(ee) >= 8
        assert res['effort'].edges == 'effort'
        # the effort onset is nearer the truth than the clock edge
        assert np.median(np.abs(ee[:, 0])) < np.median(np.abs(ep[:, 0]))


def test_effort_edges_need_efforts(runs):
    run, _ = runs[0]
    rd = dataclasses.replace(run_data(run), joint_effort=None)
    with pytest.raises(SlipDataError, match='joint_effort'):
        analyze_run(rd, box=BOX, edges='effort')
    with pytest.raises(SlipDataError, match="edges must be"):
        analyze_run(rd, box=BOX, edges='clock')
    # 'auto' falls back to the cross-correlation without efforts
    assert analyze_run(rd, box=BOX, offset_s='auto', position_fit=False).offset_method == 'xcorr'


# --------------------------------------------------------------------------------------------
# Issue 7 bars on simulated runs, one test per bar, with the geometric estimators
# (slip_identification.geometry: the half-circle leg's rest height against the hip height)
# --------------------------------------------------------------------------------------------
BAR_GAITS = ('running', 'jogging', 'pace', 'walk')
BAR_SEEDS = (1, 2, 3)


def _geometry_figures(run) -> dict:
    """Offset error [ms], ground error [mm] and single-support edge errors [ms] of one run.

    The same steps as analyze_run(geometry=...): world frame from the mocap path and attitude,
    pitch, ground and offset fitted from no prior offset (0 +- 60 ms), contacts, single support.
    The truth ground height is the simulator's, seen from the fitted frame along the tracked
    path (mean of world height minus true COM height).
    """
    frame = fit_world_frame(run.mocap_position_m, up_mocap=_up_from_quats(run.mocap_quat_xyzw))
    pw = frame.to_world(run.mocap_position_m)
    pitch = body_pitch_rad(frame.rotation, run.mocap_quat_xyzw)
    off = run.truth['clock_offset_s']
    ground = float(np.mean(pw[:, 2] - np.interp(run.mocap_t_s - off, run.fine_t_s,
                                                 run.fine_state[:, 2])))
    geo = LegGeometry.from_params(run.params)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    args = (geo, names, run.t_s, run.hip_position_rad, run.hip_velocity_rad_s, run.mocap_t_s,
            pw[:, 2], pitch)
    fit = fit_ground_offset(*args, initial_offset_s=0.0, offset_range_s=0.06, x_m=pw[:, 0])
    contacts, unknown = leg_contacts(*args, offset_s=fit.offset_s, ground_m=fit.ground_m,
                                     fit=fit, x_m=pw[:, 0])
    ss = single_support(contacts, TRIPODS, unknown)
    # steady state (the paper's runs): from where the pitch repeats with the clock period
    t_steady = steady_start_s(run.mocap_t_s, pitch, run.clock.period_s) - fit.offset_s
    e = []
    n_transient = 0
    for tp, iv in ss.items():
        tr = np.array(run.truth['single_support'][tp])
        for a, b in iv:
            if a < t_steady:
                n_transient += 1
                continue
            j = int(np.argmin(np.abs(tr[:, 0] - a)))
            e.append((a - tr[j, 0], b - tr[j, 1]))
    return {'offset_ms': 1e3 * (fit.offset_s - off), 'ground_mm': 1e3 * (fit.ground_m - ground),
            'transient': n_transient, 'steady_s': t_steady,
            'edges_ms': 1e3 * np.array(e).reshape(-1, 2)}


@pytest.fixture(scope='module')
def bar_figures():
    out = {}
    for gait in BAR_GAITS:
        for run in edubot_sim.simulate_edubot_batch(gait, duration_s=4.5, seeds=BAR_SEEDS):
            f = _geometry_figures(run)
            e = f['edges_ms']
            ok = np.all(np.abs(e) <= 5.0, axis=1)
            print(f"{gait:8s} seed {run.seed}: offset {f['offset_ms']:+.2f} ms, ground "
                  f"{f['ground_mm']:+.2f} mm, {len(e)} stances ({f['transient']} before the "
                  f"steady state at {f['steady_s']:.2f} s), {np.mean(ok):.0%} within 5 ms "
                  f'(td median {np.median(e[:, 0]):+.1f}, lift-off median '
                  f'{np.median(e[:, 1]):+.1f} ms)')
            out[gait, run.seed] = f
    return out


def _edges_ok(f) -> float:
    return float(np.mean(np.all(np.abs(f['edges_ms']) <= 5.0, axis=1)))


def test_issue_bar_edges_within_5ms(bar_figures):
    """Touchdown and lift-off within 5 ms for >= 95 % of single-support stances (geometric
    edges, steady state): all four gaits, 3 seeds each (100 % on each; pace since the ground's
    slope comes from whole strides, walk since the edges are pooled over strides: 100 / 80 /
    100 % before, a front leg landing 8.8 ms late on seed 2). Over seeds 1-12: 100 % on each
    gait."""
    for gait in BAR_GAITS:
        for seed in BAR_SEEDS:
            f = bar_figures[gait, seed]
            # pace and walk: start-up transients; walk: 5 stances in 4.5 s
            assert len(f['edges_ms']) >= {'pace': 3, 'walk': 5}.get(gait, 8)
            assert _edges_ok(f) >= 0.95, (gait, seed, f['edges_ms'])


def test_issue_bar_ground_within_2mm(bar_figures):
    """The mocap frame's vertical translation (ground height) within 2 mm: all four gaits,
    3 seeds each (within 0.15 mm); its rotation (0.5 deg) is test_slip_sim_frame.py."""
    for (gait, seed), f in bar_figures.items():
        assert abs(f['ground_mm']) <= 2.0, (gait, seed, f['ground_mm'])


def test_issue_bar_offset_within_2ms(bar_figures):
    """Stream offset within 2 ms on all four gaits, 3 seeds each (running +0.6 to +0.7 ms,
    jogging +1.1 to +1.4, pace -0.2 to -0.4, walk -0.1 / -1.2 / -0.8; leg damping time from
    the robot description; the ground's slope fitted with it; output-error refinement),
    searched from 0 +- 60 ms. Without the output-error refinement walk seed 2 was -4.3 ms
    (0.1 s windows, a shallow optimum)."""
    for gait in BAR_GAITS:
        for seed in BAR_SEEDS:
            f = bar_figures[gait, seed]
            assert abs(f['offset_ms']) <= 2.0, (gait, seed, f['offset_ms'])
