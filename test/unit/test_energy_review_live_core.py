"""Outside live review (lab robot publishers), the shared core: a mocap occlusion across a
window bound, NaN poses, one JointState per leg, a battery board stamping its uptime, the
switch of P_out between the efforts and the model, and the early clock check."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexapod_common.conversions import (
    BatterySample,
    GaitPhaseSample,
    JointStateSample,
    PoseSample,
)
from hexapod_energy.descriptors import (
    LEG_MISMATCH_NOTE,
    NONFINITE_POSE_NOTE,
    PARTIAL_POSE_NOTE,
    POSE_FALLBACK_NOTE,
    ArrivalClockGate,
    DescriptorAccumulator,
)

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
TRIPOD = np.array([0.0, 0.5, 0.0, 0.5, 0.0, 0.5])
V_MOCAP = 0.25   # the reviewer's body: x = 0.25 t, where the schedule says 0.1 / 0.5 = 0.2


def gait(t: float) -> GaitPhaseSample:
    return GaitPhaseSample(t, 'tripod', 1.0, 0.5, 0.1, 0.03, 0.0, 0.0, t % 1.0, LEGS,
                           TRIPOD, np.ones(6, bool), 3)


def joints(t: float, legs=LEGS, effort: bool = True) -> JointStateSample:
    names, q, qd, tau = [], [], [], []
    for k, leg in enumerate(legs):
        ph = 2 * math.pi * t + LEGS.index(leg)
        for j in ('hip', 'knee', 'ankle'):
            names.append(f'{leg}_{j}')
            q.append(0.3 * math.sin(ph))
            qd.append(0.3 * 2 * math.pi * math.cos(ph))
            tau.append(0.5 * math.cos(ph + math.pi / 3))
    return JointStateSample(t, tuple(names), np.array(q), np.array(qd),
                            np.array(tau) if effort else np.zeros(0))


def pose(t: float, x: float | None = None) -> PoseSample:
    return PoseSample(t, 'world', np.array([V_MOCAP * t if x is None else x, 0.0, 0.3]),
                      np.array([0.0, 0.0, 0.0, 1.0]))


def run(acc: DescriptorAccumulator, *, duration: float = 12.0, lost=(), nan: bool = False,
        per_leg: bool = False, battery_t=lambda t: t, effort: bool = True) -> list:
    """The reviewer's robot in stamp order: battery 10 Hz, gait 100 Hz, joints 250 Hz,
    mocap 120 Hz; ``lost``: (start, end) of mocap occlusions (no pose, or NaN poses)."""
    ev = [(t, 'b') for t in np.arange(0.0, duration, 0.1)]
    ev += [(t, 'g') for t in np.arange(0.0, duration, 0.01)]
    ev += [(t, 'j') for t in np.arange(0.0, duration, 0.004)]
    ev += [(t, 'm') for t in np.arange(0.0, duration, 1 / 120)]
    ev.sort()
    out = []
    for t, kind in ev:
        t = float(t)
        if kind == 'b':
            out += acc.add_battery(BatterySample(battery_t(t), 12.0,
                                                 -(3 + math.sin(2 * math.pi * t)), 50.0))
        elif kind == 'g':
            out += acc.add_gait_phase(gait(t))
        elif kind == 'j':
            for legs in ([(leg,) for leg in LEGS] if per_leg else [LEGS]):
                out += acc.add_joint_state(joints(t, legs, effort))
        else:
            if any(a <= t < b for a, b in lost):
                if nan:
                    acc.add_pose(pose(t, math.nan))
                continue
            acc.add_pose(pose(t))
    return out


def test_occlusion_across_a_window_bound_keeps_the_mocap_speed_and_says_so():
    """0.3 s without poses straddling a cycle boundary (36 frames): the window took the gait
    schedule's 0.200 m/s (specific resistance +25 %) without a word. Now the body position at
    the bound is interpolated across the gap (0.25 m/s) and the window says so."""
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, lost=[(4.85, 5.15), (9.85, 10.15)])
    assert len(out) >= 9
    for d in out:
        assert d.speed_source == 'mocap'
        assert d.speed_mps == pytest.approx(V_MOCAP, rel=1e-6)
    said = [d for d in out if any(w.startswith(PARTIAL_POSE_NOTE) for w in d.warnings)]
    assert len(said) == 4   # the two windows on each side of each occlusion


def test_a_long_occlusion_falls_back_to_the_schedule_with_a_warning():
    """Tracking lost for 2.5 s: the windows inside have no mocap speed; the schedule's stands
    in, and each such window says so (it did silently)."""
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, lost=[(4.7, 7.2)])
    fell = [d for d in out if d.speed_source == 'gait_schedule']
    assert fell and all(d.speed_mps == pytest.approx(0.2) for d in fell)
    for d in fell:
        assert any(w.startswith(POSE_FALLBACK_NOTE) and 'gait schedule' in w
                   for w in d.warnings), d.warnings
    partial = [d for d in out if any(w.startswith(PARTIAL_POSE_NOTE) for w in d.warnings)]
    assert partial and all(d.speed_mps == pytest.approx(V_MOCAP, rel=1e-6) for d in partial)


def test_nan_poses_are_dropped_with_a_note_not_published_as_nan_speed():
    """A bridge publishing NaN poses while tracking is lost: speed, CoT and SR read NaN in 2
    windows of 5 without a word."""
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, lost=[(4.85, 5.15)], nan=True)
    assert acc.nonfinite_poses_ == 36
    assert NONFINITE_POSE_NOTE in acc.notes_
    assert all(math.isfinite(d.speed_mps) and math.isfinite(d.specific_resistance)
               for d in out)
    assert all(d.speed_mps == pytest.approx(V_MOCAP, rel=1e-6) for d in out)


def test_one_joint_state_per_leg_is_not_a_leg_mismatch():
    """One JointState per leg (3 joints): only the last message's names were compared with
    the schedule's six legs, and every window warned that five legs had no joint."""
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, duration=6.0, per_leg=True)
    assert out
    assert not [w for d in out for w in d.warnings if w.startswith(LEG_MISMATCH_NOTE)]
    # a real mismatch is still said: the joints name 5 legs
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, duration=4.0)
    acc2 = DescriptorAccumulator(mass_kg=3.0)
    ev = []
    for t in np.arange(0.0, 4.0, 0.004):
        ev += acc2.add_joint_state(joints(float(t), LEGS[:5]))
        if abs(t * 100 - round(t * 100)) < 1e-6:
            ev += acc2.add_gait_phase(gait(float(t)))
        if abs(t * 10 - round(t * 10)) < 1e-6:
            ev += acc2.add_battery(BatterySample(float(t), 12.0, -3.0, 50.0))
    assert ev and all(any('R3' in w and w.startswith(LEG_MISMATCH_NOTE) for w in d.warnings)
                      for d in ev)


def test_a_battery_on_its_uptime_clock_is_said_once_not_flooded():
    """A battery board without time sync (stamps = its uptime): 'no /battery_state for
    1795857615.9 s' was noted at every accepted sample (3 times a second). Now once, naming
    another clock."""
    t0 = 1_795_857_600.0
    acc = DescriptorAccumulator(mass_kg=3.0)
    ev = [(t0 + t, 'g') for t in np.arange(0.0, 20.0, 0.01)]
    ev += [(t0 + t, 'bb') for t in np.arange(8.0, 20.0, 0.1)]
    ev.sort()
    out = []
    for t, kind in ev:
        if kind == 'g':
            out += acc.add_gait_phase(gait(float(t)))
        else:
            out += acc.add_battery(BatterySample(float(t - t0 - 6.0), 12.0, -3.0, 50.0))
    battery = [n for n in acc.notes_ if 'battery_state' in n]
    assert len(battery) <= 2, battery
    assert any('another clock' in n for n in battery), battery
    assert not out


def test_the_window_names_its_p_out_source():
    acc = DescriptorAccumulator(mass_kg=3.0)
    out = run(acc, duration=4.0)
    assert out and {d.power_out_source for d in out} == {'effort'}
    acc = DescriptorAccumulator(mass_kg=3.0, power_out_model=lambda g, m: 0.398)
    out = run(acc, duration=4.0, effort=False)
    assert out and {d.power_out_source for d in out} == {'model'}
    assert all(d.power_out_w == 0.398 for d in out)


def test_arrival_clock_gate_finds_a_late_unsynced_board_at_its_first_message():
    """The 200th/2000th-message judgement missed a board joining late; the gate refuses its
    first message, says so once, and takes it back when its stamps are on the others'."""
    now = 1_795_857_600.0
    g = ArrivalClockGate()
    for k in range(50):
        for topic in ('gait/phase', 'joint_states', 'mocap/body'):
            assert g.observe(topic, now + k * 0.01 - 0.002, now + k * 0.01)[0]
    keep, level, text = g.observe('battery_state', 3.2, now + 0.6)
    assert not keep and level == 'error' and 'another clock' in text
    assert 'gait/phase' in text and 'uptime' in text
    assert g.observe('battery_state', 3.3, now + 0.7) == (False, '', '')
    assert g.observe('gait/phase', now + 0.8, now + 0.8)[0]
    keep, level, text = g.observe('battery_state', now + 0.9, now + 0.9)
    assert keep and level == 'info'
    assert g.refused == 2 and g.reported == {'battery_state'} and not g.foreign
    # a replay or a looped bag moves every topic together: nothing refused
    g = ArrivalClockGate()
    for k in range(20):
        for topic in ('battery_state', 'gait/phase', 'joint_states'):
            assert g.observe(topic, 1000.0 + k * 0.01, now + k * 0.01)[0]
    # under use_sim_time before /clock (node clock 0), one topic against one: no judgement
    g = ArrivalClockGate()
    assert g.observe('gait/phase', now, 0.0)[0]
    assert g.observe('battery_state', 3.0, 0.0)[0]
