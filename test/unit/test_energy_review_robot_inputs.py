"""Outside review (octopod lab), robot-bag input mistakes that gave wrong numbers silently:

* A4: a gait node left at leg_count 6 on an 8-leg robot: the live windows warned (legs with
  joints the schedule does not name), the offline ``energy.json`` had no word of it;
* A5: ``/gait/phase`` step_length in mm: speed 160 m/s, CoT/M and SR 1000x low, accepted;
* B1: joint velocities in deg/s with positions in rad: P_out 57x too large (21.5 W for 0.375
  W, efficiency 0.597) passed every plausibility test.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from rosbags.rosbag2 import Writer

from hexapod_common.bags import open_reader
from hexapod_common.testbags import foreign_typestore
from hexapod_common.testbags import write_foreign_robot_bag as write_bag
from hexapod_energy.bag_io import read_robot_bag
from hexapod_energy.cli import main
from hexapod_energy.descriptors import LEG_MISMATCH_NOTE, MAX_SPEED_MPS, SCHEDULE_SPEED_NOTE

MASS = 2.0


def _rewrite(src, dst, topic, edit):
    store = foreign_typestore()
    with open_reader(src) as reader, Writer(dst, version=9) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in reader.connections}
        for conn, t_ns, data in reader.messages():
            if conn.topic == topic:
                msg = store.deserialize_cdr(data, conn.msgtype)
                edit(msg)
                data = store.serialize_cdr(msg, conn.msgtype)
            w.write(conns[conn.id], t_ns, data)
    return dst


def _notes(run) -> str:
    return ' '.join(run.extra.get('notes', ()))


def _cli(bag, out):
    assert main(['--robot', str(bag), '--robot-mass', str(MASS), '--no-progress',
                 '--out', str(out)]) == 0
    doc = json.loads((out / 'energy.json').read_text())
    return doc, doc['robot_runs'][0]


@pytest.fixture(scope='module')
def src(tmp_path_factory):
    root = tmp_path_factory.mktemp('robot_inputs')
    write_bag(root / 'src', legs=6, duration_s=12.0, storage='mcap')
    return root


def test_fewer_legs_on_the_schedule_reach_the_offline_warnings(src, tmp_path):
    def four_legs(msg):
        msg.leg_names = list(msg.leg_names)[:4]
        msg.phase_offsets = np.asarray(msg.phase_offsets)[:4]
        msg.in_stance = np.asarray(msg.in_stance)[:4]

    bag = _rewrite(src / 'src', tmp_path / 'legs4', '/gait/phase', four_legs)
    run = read_robot_bag(bag, mass_kg=MASS)
    assert LEG_MISMATCH_NOTE in _notes(run) and 'leg_count?' in _notes(run)
    doc, _ = _cli(bag, tmp_path / 'o')
    assert any(LEG_MISMATCH_NOTE in w for w in doc['warnings'])
    # the schedule of all the legs: nothing said
    ref = read_robot_bag(src / 'src', mass_kg=MASS)
    assert LEG_MISMATCH_NOTE not in _notes(ref)


def test_a_schedule_speed_in_millimetres_is_refused_as_a_speed(src, tmp_path):
    ref = read_robot_bag(src / 'src', mass_kg=MASS)

    def millimetres(msg):
        msg.step_length = msg.step_length * 1000.0
        msg.step_height = msg.step_height * 1000.0

    bag = _rewrite(src / 'src', tmp_path / 'mm', '/gait/phase', millimetres)
    assert ref.speed_mps * 1000 > MAX_SPEED_MPS
    run = read_robot_bag(bag, mass_kg=MASS)
    assert math.isnan(run.speed_mps)
    assert SCHEDULE_SPEED_NOTE in _notes(run) and 'millimetres' in _notes(run)
    doc, r = _cli(bag, tmp_path / 'o')
    assert r['speed'] is None and r['specific_resistance'] is None
    assert r['specific_cost_of_transport'] is None
    assert any(SCHEDULE_SPEED_NOTE in w for w in doc['warnings'])
    # metres: the speed stands
    assert 0 < ref.speed_mps < MAX_SPEED_MPS and SCHEDULE_SPEED_NOTE not in _notes(ref)


def _consistent_joints(src, dst, *, factor=1.0):
    """``src`` with positions that integrate the velocities (rad), the velocities times
    ``factor`` (180 / pi: deg/s; 30 / pi: rpm; 3.2: a gear ratio)."""
    from hexapod_common.testbags import PERIOD_S

    def edit(msg):
        t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        phase = 2 * np.pi * (t / PERIOD_S + np.arange(len(msg.name)) / 7)
        msg.position = 0.6 * PERIOD_S / (2 * np.pi) * np.sin(phase)
        msg.velocity = 0.6 * np.cos(phase) * factor

    return _rewrite(src, dst, '/joint_states', edit)


def test_velocities_in_degrees_per_second_are_converted_to_joint_power(src, tmp_path):
    """B1 gave deg/s velocities the model's P_out; now the unit is recognised from the
    positions' derivative and converted, P_out from the efforts as with rad/s (a known gap)."""
    from hexapod_energy.descriptors import VELOCITY_CONVERTED_NOTE, VELOCITY_UNITS_NOTE
    from test_energy_review_zero_effort import _live

    ok = _consistent_joints(src / 'src', tmp_path / 'rad')
    ref = read_robot_bag(ok, mass_kg=MASS)
    _, r_ok = _cli(ok, tmp_path / 'o_rad')
    assert r_ok['power_out_source'] == 'effort'
    assert VELOCITY_UNITS_NOTE not in _notes(ref) and VELOCITY_CONVERTED_NOTE not in _notes(ref)
    live_ok = _live(ok)
    for name, factor in (('deg/s', 180 / np.pi), ('rpm', 30 / np.pi)):
        bag = _consistent_joints(src / 'src', tmp_path / name.replace('/', '_'),
                                 factor=factor)
        run = read_robot_bag(bag, mass_kg=MASS)
        assert run.power_out_w == pytest.approx(ref.power_out_w, rel=1e-9)
        said = [n for n in run.extra['notes'] if n.startswith(VELOCITY_CONVERTED_NOTE)]
        assert len(said) == 1 and f'velocities are {name}' in said[0], said
        assert VELOCITY_UNITS_NOTE not in _notes(run)
        doc, r = _cli(bag, tmp_path / f'o_{name.replace("/", "_")}')
        assert r['power_out_source'] == 'effort'
        assert r['power_out_w'] == pytest.approx(r_ok['power_out_w'], rel=1e-9)
        assert r['efficiency'] == pytest.approx(r_ok['efficiency'], rel=1e-9)
        assert 'not rad/s' not in ' '.join(doc['warnings'])
        # live: the same windows, P_out from the efforts, nothing said per window
        live = _live(bag)
        assert len(live) == len(live_ok) > 0
        for a, b in zip(live, live_ok):
            assert a.power_out_w == pytest.approx(b.power_out_w, rel=1e-9)
            assert a.warnings == b.warnings


def test_a_gear_ratio_is_not_applied_to_the_joint_power(src, tmp_path):
    """A factor of no unit (a gear ratio, 3.2) is not silently applied: refused, the model's
    P_out, a note giving the factor measured (before: P_out 3.2x, accepted)."""
    from hexapod_energy.descriptors import VELOCITY_UNITS_NOTE
    from test_energy_review_zero_effort import _live

    ref = read_robot_bag(_consistent_joints(src / 'src', tmp_path / 'rad'), mass_kg=MASS)
    bag = _consistent_joints(src / 'src', tmp_path / 'gear', factor=3.2)
    run = read_robot_bag(bag, mass_kg=MASS)
    assert run.power_out_w == pytest.approx(ref.power_out_w * 3.2, rel=1e-6)
    assert VELOCITY_UNITS_NOTE in _notes(run) and '3.2 times' in _notes(run)
    doc, r = _cli(bag, tmp_path / 'o_gear')
    assert r['power_out_source'] == 'model' and r['power_out_w'] < ref.power_out_w
    text = ' '.join(doc['warnings'])
    assert 'not rad/s' in text and 'the efforts are not joint torques' not in text
    live = _live(bag)
    assert live and all(any(w.startswith(VELOCITY_UNITS_NOTE) for w in d.warnings)
                        for d in live)
    assert all(d.power_out_w < ref.power_out_w for d in live)
