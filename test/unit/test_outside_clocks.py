"""A topic stamped on another clock (a micro-ROS battery board counting from its boot, a
motion-capture bridge passing the capture system's time): found from the bag's receive times,
moved onto the other topics' clock, noted (:mod:`hexapod_common.clocks`).

Before: the robot bag was refused ("no whole gait cycle with battery samples around it ...
stamped on different clocks?"), the bench bag lost its sessions, the SLIP run was refused
("motion capture ... and joint states ... do not overlap").
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_energy_cli import _write_bench
from test_outside_slow_sensors import _write_slow_battery_robot

from hexapod_common.clocks import ClockCheck
from hexapod_common.testbags import restamp_topic
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag, read_robot_bag
from hexapod_energy.residuals import read_residual_run

BOOT_CLOCK_S = 57.25      # a board counting seconds since its boot, the recorder at 0 s


def test_clock_groups():
    c = ClockCheck()
    for k in range(50):
        t = 0.01 * k
        c.observe('/a', 1000 + t + 0.002, 1000 + t)
        c.observe('/b', 1000 + t + 0.004, 1000 + t)
        c.observe('/c', 57 + t, 1000 + t)
    shifts, notes = c.shifts()
    assert list(shifts) == ['/c'] and shifts['/c'] == pytest.approx(943.003, abs=1e-6)
    assert '/c stamped on another clock' in notes[0]
    # a re-recorded replay: every topic far from the receive clock, together: nothing moved
    c = ClockCheck()
    for k in range(50):
        c.observe('/a', 0.01 * k, 5000 + 0.01 * k)
        c.observe('/b', 0.01 * k + 0.3, 5000 + 0.01 * k)
    assert c.shifts() == ({}, [])
    # two topics, two clocks: the one near the receive clock is the reference
    c = ClockCheck()
    for k in range(50):
        c.observe('/battery_state', 57 + 0.01 * k, 1000 + 0.01 * k)
        c.observe('/gait/phase', 1000.001 + 0.01 * k, 1000 + 0.01 * k)
    assert list(c.shifts()[0]) == ['/battery_state']


@pytest.fixture(scope='module')
def robot_bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('clocks')
    _write_slow_battery_robot(root / 'ref', battery_hz=50.0)
    return root / 'ref', restamp_topic(root / 'ref', root / 'boot', '/battery_state', BOOT_CLOCK_S)


def test_robot_bag_battery_on_a_boot_clock(robot_bags):
    ref_bag, boot_bag = robot_bags
    ref = read_robot_bag(ref_bag, mass_kg=2.3)
    got = read_robot_bag(boot_bag, mass_kg=2.3)    # was: BagContentError, no whole cycle
    assert got.windows == ref.windows
    assert got.power_in_w == pytest.approx(ref.power_in_w, rel=1e-9)
    assert any('/battery_state stamped on another clock' in n for n in got.extra['notes'])
    res_ref, res = read_residual_run(ref_bag), read_residual_run(boot_bag)
    np.testing.assert_allclose(res.t_s, res_ref.t_s, atol=1e-6)
    np.testing.assert_allclose(res.cycle_phase, res_ref.cycle_phase, atol=1e-6)
    assert any('another clock' in n for n in res.notes)


def test_bench_force_on_another_clock(tmp_path):
    _write_bench(tmp_path / 'ref')
    moved = restamp_topic(tmp_path / 'ref', tmp_path / 'moved', '/bench/ground_force', -1.7e9 + 3.0)
    a, da = bench_phase_samples(read_bench_bag(tmp_path / 'ref'))
    b, db = bench_phase_samples(read_bench_bag(moved))
    assert db['force_offset_s'] == pytest.approx(da['force_offset_s'], abs=1e-6)
    assert [s.p_stance_w for s in b] == pytest.approx([s.p_stance_w for s in a], rel=1e-9,
                                                      nan_ok=True)
    assert any('/bench/ground_force stamped on another clock' in n for n in db['notes'])


def test_slip_mocap_on_the_capture_systems_clock(tmp_path):
    """Motion capture stamped with the capture system's clock (1 h ahead) in a bag recorded on
    the robot: the run is analysed, its stream offset found from the data as before."""
    from test_outside_slip import MOCAP_OFFSET_S, _slip, _write

    from hexapod_bench_drivers.edubot_sim import simulate_edubot

    run = simulate_edubot('running', duration_s=4.0, seed=1)
    ref = _write(tmp_path / 'ref', run)
    moved = restamp_topic(ref, tmp_path / 'moved', '/mocap/body', 3600.0)
    code, doc = _slip(tmp_path, moved, 'out')
    assert code == 0 and not doc['failed_bags']
    r = doc['runs'][0]
    assert r['offset_s'] == pytest.approx(MOCAP_OFFSET_S, abs=2e-3)
    assert any('/mocap/body stamped on another clock' in n for n in r['notes'])
    _, ref_doc = _slip(tmp_path, ref, 'ref_out')
    assert len(doc['stances']) == len(ref_doc['stances'])
    json.dumps(doc)


def test_clock_check_samples_the_whole_bag_not_its_end() -> None:
    """An outside review: in a 600 s bag at 100 Hz only the last 60 s of /battery_state were
    received 3 s late; the check's ring buffer held only the last ~8k messages and moved the
    whole stream by 3 s. The kept samples now span the bag evenly: the median is the bag's."""
    from hexapod_common.clocks import ClockCheck

    check = ClockCheck()
    n = 60_000
    for k in range(n):
        t = 0.01 * k
        late = 3.0 if k >= 0.9 * n else 0.0
        check.observe('/battery_state', t, t + late)
        check.observe('/joint_states', t, t)
    shifts, _ = check.shifts()
    assert shifts == {}
    assert abs(check.medians()['/battery_state']) < 1e-9
