"""The live slip_fitter's self-calibration (slip_identification.calibration): without a ground
parameter the node had used the paper's clock edges and no stream offset (stiffness 35-71 % off
the offline analysis). It now buffers the first strides and runs `hexapod-analyze slip`'s own
estimators on them: the same values as the offline analysis given the same samples, within a
fraction of a millisecond and a millimetre of the whole run's; the buffered stances are fitted
with them as a core given those values as parameters fits them."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from hexapod_common.conversions import JointStateSample
from slip_identification.calibration import (
    Calibration,
    SelfCalibration,
    calibrate,
)
from slip_identification.cli import analyze_data, default_options
from slip_identification.geometry import LegGeometry
from slip_identification.online import OnlineSlip
from slip_identification.pipeline import run_data_from_sim
from slip_identification.preprocess import Box

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

BOX = Box()   # the node's default box


@pytest.fixture(scope='module')
def running() -> Any:
    return edubot_sim.simulate_edubot('running', duration_s=4.5, seed=1)


def _events(run: Any, *, positions: bool = True) -> list[tuple[Any, ...]]:
    """The samples in arrival order as the node passes them on: joint states (positions,
    velocities, efforts) and commands at their stamps, motion capture at its true time with
    the simulator's clock offset in its stamps."""
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    off = run.truth['clock_offset_s']
    out: list[tuple[float, int, tuple[Any, ...]]] = []
    for i, t in enumerate(run.t_s):
        q = run.hip_position_rad[i] if positions else np.zeros(0)
        out.append((float(t), 0, ('js', JointStateSample(float(t), names, q,
                                                         run.hip_velocity_rad_s[i],
                                                         run.hip_effort_nm[i]))))
        out.append((float(t), 1, ('cmd', JointStateSample(float(t), names, np.zeros(0),
                                                          run.target_velocity_rad_s[i],
                                                          np.zeros(0)))))
    for i, t in enumerate(run.mocap_t_s):
        out.append((float(t) - off, 2, ('mocap', float(t), run.mocap_position_m[i],
                                        run.mocap_quat_xyzw[i])))
    return [e for _, _, e in sorted(out, key=lambda x: (x[0], x[1]))]


def _core(cal: Calibration) -> OnlineSlip:
    if not cal.ok:
        return OnlineSlip(box=BOX)
    return OnlineSlip(box=BOX, geometry=LegGeometry(), ground_m=cal.ground_m,
                      mocap_offset_s=cal.offset_s,
                      pitch_offset_rad=math.radians(cal.pitch_offset_deg))


def _self_calibration(background: bool = False) -> tuple[SelfCalibration, list[Any]]:
    seen: list[Any] = []

    def run_calibration(run: Any) -> Calibration:
        seen.append(run)
        return calibrate(run, geometry=LegGeometry(), box=BOX)

    return SelfCalibration(6.0, run_calibration, _core, box=BOX, background=background), seen


def _feed(sc: SelfCalibration, events: list[tuple[Any, ...]]) -> int:
    """Offer every sample; the index of the one that started the calibration (-1: none)."""
    due = -1
    for k, e in enumerate(events):
        assert sc.offer(*e)
        if due < 0 and sc.state != 'collecting':
            due = k
    return due


def test_calibration_is_the_offline_analysis_on_the_buffered_samples(running):
    sc, seen = _self_calibration()
    events = _events(running)
    due = _feed(sc, events)
    assert due > 0 and sc.state == 'ready'
    (rd,) = seen
    # the buffer: joint states from a second before the motion capture entered the box, up
    # to six strides (0.331 s each) of it; the arrays as the offline reader gives them
    assert rd.joint_t_s.size > 250 and rd.mocap_t_s[0] == running.mocap_t_s[0]
    assert 6 * 0.331 <= rd.mocap_t_s[-1] - rd.mocap_t_s[0] < 6 * 0.331 + 0.15
    k0 = int(np.searchsorted(running.t_s, rd.joint_t_s[0]))
    n = rd.joint_t_s.size
    assert np.array_equal(rd.joint_t_s, running.t_s[k0:k0 + n])
    assert np.array_equal(rd.joint_position, running.hip_position_rad[k0:k0 + n])
    assert np.array_equal(rd.joint_effort, running.hip_effort_nm[k0:k0 + n])
    # identical to `hexapod-analyze slip` (its options) on the same samples
    res = analyze_data(rd, default_options(position_fit=False)).result
    cal = sc.result
    assert cal is not None and cal.ok, cal
    assert cal.ground_m == res.ground_m and cal.offset_s == res.offset_s
    assert cal.pitch_offset_deg == res.frame['pitch_offset_deg']
    assert cal.offset_method == 'geometry'
    # within the offline analysis' own on the whole run (its values at 0.04 ms, 0.21 mm)
    whole = analyze_data(run_data_from_sim(running),
                         default_options(position_fit=False)).result
    assert abs(cal.offset_s - whole.offset_s) < 1e-3
    assert abs(cal.ground_m - whole.ground_m) < 1e-3
    assert abs(cal.pitch_offset_deg - whole.frame['pitch_offset_deg']) < 0.5
    assert cal.stride_s == pytest.approx(running.clock.period_s, rel=0.05)


def test_buffered_stances_are_fitted_as_with_the_values_given(running):
    """The hand-over: every sample (those buffered, and those offered while the worker
    runs) reaches the calibrated core in arrival order, so its fits are those of a core
    given the calibration's values from the start; the first clock-edge-free fits."""
    events = _events(running)
    sc, _ = _self_calibration(background=True)
    _feed(sc, events)      # the worker starts mid-way; the rest is offered meanwhile
    assert sc.wait(120.0)
    core, cal, fits = sc.take()
    assert sc.state == 'done' and not sc.offer(*events[-1])
    ref = _core(cal)
    expected = []
    for e in events:
        if e[0] == 'js':
            ref.add_joint_state(e[1].t_s, e[1].names, e[1].velocity, e[1].position)
        elif e[0] == 'cmd':
            ref.add_command(e[1].t_s, e[1].names, e[1].velocity)
        else:
            ref.add_mocap(e[1], e[2], e[3])
            expected.extend(ref.step())
    assert len(fits) == len(expected) >= 8
    for a, b in zip(fits, expected):
        assert (a.tripod, a.touchdown_s, a.liftoff_s) == (b.tripod, b.touchdown_s, b.liftoff_s)
        assert a.params == b.params
    assert core.geometry is not None and core.ground_m == cal.ground_m
    # the stiffness of the whole run offline (11.1 kN/m); the clock edges read 4.0 kN/m
    k = np.median([f.params['stiffness'] for f in fits])
    whole = analyze_data(run_data_from_sim(running), default_options(position_fit=False))
    k_off = np.median([f.params['stiffness'] for f in whole.result.fits])
    assert abs(k / k_off - 1) < 0.05, (k, k_off)


def test_a_run_without_hip_angles_is_refused_with_the_reason(running):
    """No hip angles: no geometric ground; the core is today's (clock edges) and the
    reason is given."""
    sc, _ = _self_calibration()
    _feed(sc, _events(running, positions=False))
    core, cal, fits = sc.take()
    assert not cal.ok and 'hip angles' in cal.refused
    assert core.geometry is None
    assert cal.line().startswith('self-calibration refused: ')


def test_a_standing_start_is_not_calibrated_on(running):
    """Hips that do not turn restart the window: a robot standing in the volume before it
    runs is calibrated on its running only."""
    names = tuple(f'{leg}_hip' for leg in running.leg_names)
    sc, seen = _self_calibration()
    q0 = running.hip_position_rad[0]
    p0, r0 = running.mocap_position_m[0], running.mocap_quat_xyzw[0]
    off = running.truth['clock_offset_s']
    for k in range(300):   # 3 s standing at 100 Hz before the run's own stamps
        t = -3.0 + 0.01 * k
        sc.offer('js', JointStateSample(t, names, q0, np.zeros(6), np.zeros(6)))
        sc.offer('mocap', t + off, p0, r0)
    assert sc.state == 'collecting'
    _feed(sc, _events(running))
    (rd,) = seen
    # the window restarts every 0.1 s while the hips stand: at most its last 0.1 s is kept
    # (without the restarts all 3 s of standing were in it)
    assert rd.mocap_t_s[0] >= off - 0.1 - 1e-9
    assert sc.result is not None and sc.result.ok
    whole = analyze_data(run_data_from_sim(running),
                         default_options(position_fit=False)).result
    assert abs(sc.result.offset_s - whole.offset_s) < 1e-3
    assert abs(sc.result.ground_m - whole.ground_m) < 1e-3


def test_a_run_that_ends_before_the_window_is_due_says_why(running):
    """A run shorter than the window (here its first second) published nothing and said
    nothing; ``pending`` now gives the motion capture tracked against the strides awaited
    (the node logs it when it stops, or when a replayed bag ends)."""
    sc, seen = _self_calibration()
    events = _events(running)
    t_end = running.mocap_t_s[0] + 1.0
    short = [e for e in events if (e[1].t_s if e[0] != 'mocap' else e[1]) < t_end]
    _feed(sc, short)
    assert sc.state == 'collecting' and not seen
    why = sc.pending()
    assert why.startswith('the self-calibration was not due') and 'of the 6 strides' in why
    tracked = float(why.split('spans ')[1].split(' s')[0])
    assert 0.9 < tracked <= 1.0
    strides = float(why.split('(')[1].split(' strides')[0])
    assert strides == pytest.approx(tracked / running.clock.period_s, abs=0.2)
    empty, _ = _self_calibration()
    assert empty.pending() == ''   # nothing came at all: the node's input watch says that
    outside, _ = _self_calibration()
    _feed(outside, [e for e in short if e[0] != 'mocap'])
    assert 'never started' in outside.pending()
    _feed(sc, events)
    assert sc.pending() == ''   # due: nothing pending
