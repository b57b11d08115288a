"""Review H of the live ``slip_fitter`` against ``hexapod-analyze slip`` (core, no ROS).

Finding 6: on a jog (``ld_plus_heavy``, mass 3.97 kg, slip+leg_damping, the offline ground,
offset and pitch) the node published two overlapping fits of one right stance, 2.012-2.131
and 2.030-2.096 s (lift-offs 35 ms apart, beyond the 30 ms the memory of fitted stances
allowed). Replayed through the core, the first window was a geometric one found in a world
frame still refitted on every step (under ``frame_every_s`` of path): its tilt swung with
the COM bounce, the ground under the robot moved by centimetres and the window by 30 ms
between steps. A stance overlapping one fitted (or skipped) before is never fitted again,
and a step without geometric edges no longer falls back to the clock's edges without a word.
(Waiting for the frame to settle was tried and left: a review of the change measured the
first stances of clean jogs 3-5 ms off with it, within 1.3 ms without.)
"""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification import online as online_mod
from slip_identification.errors import SlipError
from slip_identification.online import OnlineSlip
from slip_identification.stance import StanceWindow

from test_slip_online import BOX, events, geometric_setup

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


@pytest.fixture(scope='module')
def jog():
    run = edubot_sim.simulate_edubot('jogging', duration_s=3.5, seed=1)
    return run, geometric_setup(run)


def feed(run, setup, *, commands=False, world_frame=False, core=None):
    """OnlineSlip with geometric edges fed ``run`` in arrival order: the core and its fits,
    each with the newest mocap stamp (proprioception clock) of the step that gave it."""
    names, geo, frame, ground = setup
    off = run.truth['clock_offset_s']
    if core is None:
        core = OnlineSlip(box=BOX, mocap_offset_s=off, geometry=geo, ground_m=ground,
                          world_frame=frame if world_frame else None)
    fits = []
    for _, kind, i in events(run):
        if kind == 0:
            core.add_joint_state(float(run.t_s[i]), names, run.hip_velocity_rad_s[i],
                                 run.hip_position_rad[i])
            if commands:
                core.add_command(float(run.t_s[i]), names, run.target_velocity_rad_s[i])
        else:
            core.add_mocap(float(run.mocap_t_s[i]), run.mocap_position_m[i],
                           run.mocap_quat_xyzw[i])
            fits.extend((f, float(run.mocap_t_s[i]) - off) for f in core.step())
    return core, fits


def overlapping(fits):
    return [(a.tripod, a.touchdown_s, a.liftoff_s, b.touchdown_s, b.liftoff_s)
            for k, a in enumerate(fits) for b in fits[k + 1:]
            if a.tripod == b.tripod
            and min(a.liftoff_s, b.liftoff_s) > max(a.touchdown_s, b.touchdown_s)]


def test_geometric_windows_are_fitted_at_once_each_stance_once(jog):
    """Geometric windows are fitted on the first sample after lift-off in the young buffered
    frame, each stance once, within 5 ms of the simulator's single supports (waiting for the
    frame to rest on ``frame_every_s`` of path put these 3-5 ms off, within 1.3 ms without:
    a review of the change)."""
    run, setup = jog
    core, fits = feed(run, setup)
    assert len(fits) >= 6
    assert not overlapping([f for f, _ in fits])
    for f, _ in fits:
        tr = np.array(run.truth['single_support'][f.tripod])
        j = int(np.argmin(np.abs(tr[:, 0] - f.touchdown_s)))
        assert abs(f.touchdown_s - tr[j, 0]) < 0.005 and abs(f.liftoff_s - tr[j, 1]) < 0.005
    assert np.median(core.latency_s) < 0.02
    # a given world frame: the same, fitted on the first sample after lift-off
    core, fits = feed(run, setup, world_frame=True)
    assert np.median(core.latency_s) < 0.02


def test_a_moved_window_overlapping_a_fitted_stance_is_not_fitted_again(jog, monkeypatch):
    """The review's symptom: a right stance fitted on 2.012-2.131 s and again on
    2.030-2.096 s (lift-offs 35 ms apart). A window whose edges move by more than 30 ms after
    its fit is one stance: fitted once."""
    run, setup = jog
    _, ref = feed(run, setup, world_frame=True)
    first = next(f for f, _ in ref if f.tripod == 'right')
    orig = OnlineSlip._geometric_windows
    wide = StanceWindow(first.touchdown_s - 0.02, first.liftoff_s + 0.035, 'right', 0.0)

    def moving(self, tj, vj, tm, pm, qm):   # the window of a frame still swinging
        out = orig(self, tj, vj, tm, pm, qm)
        if out and tm[-1] < first.liftoff_s + 0.07:
            out = [wide if abs(w.touchdown_s - first.touchdown_s) < 0.01 else w
                   for w in out]
        return out

    monkeypatch.setattr(OnlineSlip, '_geometric_windows', moving)
    _, fits = feed(run, setup, world_frame=True)
    fits = [f for f, _ in fits]
    assert not overlapping(fits)       # both had been fitted
    assert sum(f.tripod == 'right' and f.touchdown_s < first.liftoff_s for f in fits) == 1


def test_no_clock_edge_fallback_when_the_contacts_fail_for_a_step(jog, monkeypatch):
    """Contacts that cannot be found on a step (``leg_contacts`` raising) had made that step
    fit the clock's target edges, silently. The stances now wait for the geometric edges (the
    same fits as without the failure) and the failure is a warning, throttled."""
    run, setup = jog
    _, ref = feed(run, setup, commands=True, world_frame=True)
    orig = online_mod.leg_contacts
    calls = {'n': 0}

    def flaky(*a, **k):
        calls['n'] += 1
        if 150 <= calls['n'] < 175:       # about 0.2 s of steps in mid-run
            raise SlipError('mocap and hip angles do not overlap (simulated)')
        return orig(*a, **k)

    monkeypatch.setattr(online_mod, 'leg_contacts', flaky)
    core, fits = feed(run, setup, commands=True, world_frame=True)
    key = [(f.tripod, round(f.touchdown_s, 4), round(f.liftoff_s, 4)) for f, _ in fits]
    assert key == [(f.tripod, round(f.touchdown_s, 4), round(f.liftoff_s, 4)) for f, _ in ref]
    said = [w for w in core.warnings if 'geometric stance edges not found' in w]
    assert len(said) == 2 and '[10 steps so far]' in said[1]   # 1st and 10th of 25


def test_clock_edges_without_hip_angles_are_said(jog):
    """Geometric edges asked for but no hip angles (joint states without positions): the
    paper's clock edges are used, and a warning says so once (it had been silent)."""
    run, setup = jog
    names, geo, _, ground = setup
    off = run.truth['clock_offset_s']
    core = OnlineSlip(box=BOX, mocap_offset_s=off, geometry=geo, ground_m=ground)
    fits = []
    for _, kind, i in events(run):
        if kind == 0:
            core.add_joint_state(float(run.t_s[i]), names, run.hip_velocity_rad_s[i])
            core.add_command(float(run.t_s[i]), names, run.target_velocity_rad_s[i])
        else:
            core.add_mocap(float(run.mocap_t_s[i]), run.mocap_position_m[i],
                           run.mocap_quat_xyzw[i])
            fits.extend(core.step())
    assert fits
    said = [w for w in core.warnings if "clock edges" in w]
    assert len(said) == 1 and 'hip angles' in said[0]


def test_default_parameters_warn_at_startup_with_the_remedy():
    """Finding 7: with default parameters (no ground, no offset) the node's fits were far
    from offline (k 35-71 % low) and it said nothing; the startup warning names the
    consequence and the remedy, and ``hexapod-analyze slip`` prints the parameters."""
    import dataclasses
    import math

    pytest.importorskip('rclpy')
    from slip_identification.cli import live_params_line
    from slip_identification.slip_node import SlipParams, startup_notes

    (level, text), = startup_notes(dataclasses.replace(SlipParams(), calibration_strides=0.0))
    assert level == 'warning'
    for word in ('clock edges', 'no stream offset', '35-71 %', 'hexapod-analyze slip',
                 '-p ground:=', '-p mocap_offset:=', '-p pitch_offset:='):
        assert word in text
    given = dataclasses.replace(SlipParams(), ground=0.0128, mocap_offset=0.0256)
    assert startup_notes(given) == []
    assert [lv for lv, _ in startup_notes(dataclasses.replace(given, mocap_offset=0.0))] \
        == ['info']
    run = {'bag': 'b', 'edges': 'geometry', 'ground_m': 0.0128, 'offset_s': 0.02561,
           'frame': {'pitch_offset_deg': -1.5}}
    assert live_params_line(run).endswith(
        '-p ground:=0.0128 -p mocap_offset:=0.0256 -p pitch_offset:=-1.50')
    assert 'mocap_offset:=0.0256 only' in live_params_line({**run, 'ground_m': math.nan})
