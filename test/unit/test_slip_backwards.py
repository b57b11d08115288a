"""A robot walking backwards (negative speed along its heading) is read as such.

Before, the world x axis was always taken along the travel, so a robot walking backwards had
its front hips placed behind the COM and its pitch negated: a simulated EduBot jogging
backwards (the Buehler clock turned the other way) read its stream offset 11 ms off and its
single-support edges 10.7 ms RMS off (forward: 1.4 ms), and a bag of it had every hip negated
as "motors mounted mirrored". The direction now comes from the rigid body's heading and the
hips' sign of rotation: every hip turning backwards while the body moves against its x axis is
a robot walking backwards, and the world x is taken along the heading.
"""

from __future__ import annotations

import numpy as np
import pytest

from slip_identification.geometry import LegGeometry
from slip_identification.pipeline import analyze_run, run_data_from_sim

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


class Reversed:
    """A Buehler clock turning the hips backwards: every target angle and speed negated."""

    def __init__(self, clock):
        self.clock = clock
        self.period_s, self.duty_factor = clock.period_s, clock.duty_factor
        self.sweep_angle_rad, self.leg_offset_rad = clock.sweep_angle_rad, -clock.leg_offset_rad
        self.kp_norm, self.kd_norm = clock.kp_norm, clock.kd_norm     # the gait's PD gains

    def target_angle(self, t, tripod):
        return -self.clock.target_angle(t, tripod)

    def target_speed(self, t, tripod):
        return -self.clock.target_speed(t, tripod)


@pytest.fixture(scope='module')
def backwards():
    from hexapod_gait.buehler import BUEHLER_PRESETS

    return edubot_sim.simulate_edubot(Reversed(BUEHLER_PRESETS['jogging']), duration_s=5.0,
                                      seed=1)


def _edge_rms_ms(windows, run):
    single = run.truth['single_support']
    err = []
    for w in windows:
        iv = np.asarray(single[w.tripod])
        j = int(np.argmin(np.abs(iv[:, 0] - w.touchdown_s)))
        err += [w.touchdown_s - iv[j, 0], w.liftoff_s - iv[j, 1]]
    return 1e3 * float(np.sqrt(np.mean(np.square(err))))


def test_the_simulator_walks_backwards_through_its_volume(backwards):
    steady = backwards.t_s > backwards.params.settle_s
    assert np.mean(backwards.body_vx_m_s[steady]) < -0.3
    assert len(backwards.mocap_t_s) > 300      # the volume lies behind the start (was 180)


def test_walking_backwards_reads_its_edges_as_forward(backwards):
    res = analyze_run(run_data_from_sim(backwards), offset_s='auto', position_fit=False,
                      geometry=LegGeometry.from_params(backwards.params))
    assert res.frame['walks_backwards'] is True
    assert res.frame['heading_to_travel_deg'] > 170
    assert any(n.startswith('the robot walks backwards') for n in res.notes)
    assert abs(res.offset_s - backwards.truth['clock_offset_s']) < 2e-3   # was 11 ms off
    assert len(res.geometry_windows) >= 15
    assert _edge_rms_ms(res.geometry_windows, backwards) < 1.5            # was 10.7 ms
    assert res.speed_mps < -0.3 and res.sr > 0


def test_a_bag_of_it_keeps_its_hips(backwards, tmp_path):
    from hexapod_bench_drivers.edubot_bag import write_run
    from slip_identification.cli import analyze_bag, default_options

    write_run(tmp_path / 'back', backwards)
    out = analyze_bag(str(tmp_path / 'back'), default_options(position_fit=False))
    notes = ' '.join(out['run']['notes'])
    assert 'turn backwards over the run' not in notes        # not negated as mirrored motors
    assert out['run']['frame']['walks_backwards'] is True
    assert len(out['stances']) >= 10


def test_either_sign_alone_is_not_walking_backwards():
    from slip_identification.preprocess import walks_backwards

    t = np.linspace(0.0, 2.0, 50)
    path = np.column_stack([0.5 * t, 0.1 * t, 0.1 + 0 * t])      # moving along +x
    facing = np.tile([0.0, 0.0, 0.0, 1.0], (50, 1))               # body x along +x
    turned = np.tile([0.0, 0.0, 1.0, 0.0], (50, 1))               # yawed 180 deg
    assert walks_backwards(path, turned, [-7.0] * 6)[0]
    assert not walks_backwards(path, facing, [-7.0] * 6)[0]       # mirrored motors
    assert not walks_backwards(path, turned, [7.0] * 6)[0]        # rigid body created turned
    assert not walks_backwards(path, turned, [-7.0] * 5 + [7.0])[0]
