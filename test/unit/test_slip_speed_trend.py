"""`slip` says when its gravity assumption may not hold: a run that speeds up or slows down
steadily, and a ground tilted from the motion capture's z axis.

An outside review's runner on a 2 deg downhill slope (speed 1.0 -> 1.4 m/s over 8 stances)
read the paper estimator's stiffness +12 to +39 % with nothing said: the SLIP fits take gravity
normal to the fitted ground, so the along-ground part of it is left to the spring. A steady
run is not warned; the same run with a constant forward acceleration of 0.35 m/s^2 added to
its motion capture (what a 2 deg slope's gravity gives a free runner) is, with the slope that
acceleration corresponds to.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from slip_identification import pipeline
from slip_identification.geometry import LegGeometry
from slip_identification.pipeline import analyze_run, run_data_from_sim

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

ACCEL = 0.35


@pytest.fixture(scope='module')
def running():
    return edubot_sim.simulate_edubot('running', duration_s=6.0, seed=4)


def _analyze(run, data=None):
    return analyze_run(data or run_data_from_sim(run), offset_s='auto',
                       geometry=LegGeometry.from_params(run.params))


def _trend_warnings(res):
    return [w for w in res.warnings if 'steadily over its' in w]


def test_a_steady_run_is_not_warned(running):
    res = _analyze(running)
    trend = res.frame['speed_trend']
    print(trend)
    assert abs(trend['accel_mps2']) < 0.05 and trend['cycles'] >= 3
    assert not _trend_warnings(res)
    # the simulator's mocap frame is tilted 3 deg from the ground (mocap_misalignment)
    assert any(n.startswith('gravity is taken normal to the fitted ground, which is tilted 3.0')
               for n in res.notes), res.notes


def test_a_steadily_accelerating_run_is_warned_with_its_slope(running):
    data = run_data_from_sim(running)
    rot = np.asarray(running.truth['frame']['mocap_from_ground_rotation'])
    travel = rot @ np.array([1.0, 0.0, 0.0])        # the ground's x axis in the mocap frame
    t = np.asarray(data.mocap_t_s, dtype=float)
    shift = 0.5 * ACCEL * (t - t[0]) ** 2
    data = dataclasses.replace(data, mocap_position_m=np.asarray(data.mocap_position_m)
                               + shift[:, None] * travel[None, :])
    res = _analyze(running, data)
    trend = res.frame['speed_trend']
    print(trend, _trend_warnings(res))
    assert trend['accel_mps2'] == pytest.approx(ACCEL, rel=0.1)
    assert trend['slope_equivalent_deg'] == pytest.approx(
        math.degrees(math.asin(ACCEL / 9.81)), rel=0.1)
    (warning,) = _trend_warnings(res)
    assert 'speeds up' in warning and 'gravity normal to the fitted ground' in warning
    assert warning in res.notes


def test_no_tilt_note_on_a_level_mocap_frame():
    run = edubot_sim.simulate_edubot('running', duration_s=4.0, seed=4,
                                     effects={'mocap_misalignment': 0.0})
    res = _analyze(run)
    assert res.frame['tilt_deg'] < pipeline.GROUND_TILT_NOTE_DEG
    assert not any(n.startswith('gravity is taken normal') for n in res.notes)
