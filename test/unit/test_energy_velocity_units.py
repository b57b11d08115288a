"""Joint velocities in other units than rad/s (a known gap): the factor between
``JointState.velocity`` and the derivative of the positions is fitted per joint and pooled; a
unit recognised (deg/s, rpm, rev/s; with positions in degrees, their swings say so) is
converted, P_out from the efforts as with rad/s, said once; a factor of no unit (a gear ratio)
is refused with the factor measured. Before, deg/s velocities fell back to the model's P_out,
rpm and rev/s ones and a gear ratio were taken as joint power (8.5x, 0.16x, 3.2x), and positions
in degrees with deg/s velocities read P_out 57x."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
from hexapod_energy.descriptors import (
    POSITION_DEGREES_NOTE,
    VELOCITY_CONVERTED_NOTE,
    VELOCITY_UNITS_NOTE,
    DescriptorAccumulator,
    VelocityScale,
    joint_units,
    velocity_scale,
)

LEGS = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
NAMES = tuple(f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia'))
DEG = 180.0 / math.pi


def _pairs(factor, *, joints=6, n=60, seed=0, noise=0.05):
    """Moving samples (velocity, position derivative) of ``joints`` joints whose velocity is
    ``factor`` times the derivative, with relative noise."""
    rng = np.random.default_rng(seed)
    out = {}
    for k in range(joints):
        f = factor[k] if isinstance(factor, (list, tuple)) else factor
        rate = 1.5 * np.sin(np.linspace(0.1, 6.0, n) + k)
        rate = rate[np.abs(rate) > 0.1]
        v = f * rate * (1 + noise * rng.standard_normal(rate.size))
        out[f'j{k}'] = list(zip(v.tolist(), rate.tolist()))
    return out


def _said_factor(note):
    return float(re.search(r'JointState.velocity is ([0-9.]+) times', note).group(1))


@pytest.mark.parametrize('factor, unit', [(180 / math.pi, 'deg/s'), (30 / math.pi, 'rpm'),
                                          (0.5 / math.pi, 'rev/s')])
def test_a_unit_is_recognised_and_converted(factor, unit):
    scale = velocity_scale(_pairs(0.93 * factor))   # a driver's velocity a little low
    assert scale.factor == pytest.approx(0.93 * factor, rel=0.03)
    u = joint_units(scale)
    assert (u.velocity_unit, u.velocity_factor, u.refused) == (unit, factor, False)
    assert u.note.startswith(VELOCITY_CONVERTED_NOTE) and f'velocities are {unit}' in u.note
    assert _said_factor(u.note) == pytest.approx(0.93 * factor, rel=0.03)   # as measured


def test_rad_per_second_says_nothing():
    u = joint_units(velocity_scale(_pairs(1.0)))
    assert (u.velocity_factor, u.position_factor, u.refused, u.note) == (1.0, 1.0, False, '')


def test_a_gear_ratio_is_refused_with_its_factor():
    u = joint_units(velocity_scale(_pairs(3.2)))
    assert u.refused and u.velocity_factor == 1.0
    assert u.note.startswith(VELOCITY_UNITS_NOTE)
    assert _said_factor(u.note) == pytest.approx(3.2, rel=0.03)
    assert 'no unit recognised' in u.note


def test_positions_in_degrees():
    # rad/s velocities, degree positions: the ratio says it; P_out stands
    u = joint_units(velocity_scale(_pairs(1 / DEG)))
    assert not u.refused and u.velocity_factor == 1.0 and u.position_factor == DEG
    assert u.note.startswith(POSITION_DEGREES_NOTE)
    # deg/s velocities with degree positions: factor 1, the swings say degrees
    same = velocity_scale(_pairs(1.0))
    assert joint_units(same).note == ''
    u = joint_units(same, degree_swings=40, largest_swing=47.0)
    assert (u.velocity_unit, u.velocity_factor, u.position_factor) == ('deg/s', DEG, DEG)
    assert u.note.startswith(VELOCITY_CONVERTED_NOTE) and 'degrees' in u.note
    # rpm velocities with degree positions (9.55 / 57.3 = 0.167, near rev/s's 0.159)
    u = joint_units(velocity_scale(_pairs(30 / math.pi / DEG)), degree_swings=40,
                    largest_swing=47.0)
    assert u.velocity_unit == 'rpm'
    # degree positions without velocities: position-difference power converted
    u = joint_units(VelocityScale(), degree_swings=40, largest_swing=47.0)
    assert u.position_factor == DEG and u.note.startswith(POSITION_DEGREES_NOTE)


def test_velocities_unrelated_to_the_positions_say_nothing():
    rng = np.random.default_rng(1)
    pairs = {f'j{k}': list(zip(rng.standard_normal(80).tolist(),
                               (rng.standard_normal(80) + 0.2).tolist())) for k in range(6)}
    u = joint_units(velocity_scale(pairs))
    assert not u.refused and u.note == '' and u.velocity_factor == 1.0
    # too few samples: nothing either
    assert math.isnan(velocity_scale(_pairs(DEG, joints=1, n=30)).factor)


def test_a_joint_whose_velocity_does_not_follow_its_position_is_left_out():
    pairs = _pairs(DEG)
    rng = np.random.default_rng(2)
    pairs['passive'] = list(zip(rng.standard_normal(80).tolist(),
                                (rng.standard_normal(80) + 0.2).tolist()))
    scale = velocity_scale(pairs)
    assert 'passive' not in dict(scale.joint_factors) and len(scale.joint_factors) == 6
    assert joint_units(scale).velocity_unit == 'deg/s'


def test_joints_in_other_units_are_refused():
    u = joint_units(velocity_scale(_pairs([1.0, 1.0, 1.0, DEG, DEG, 1.0])))
    assert u.refused and u.note.startswith(VELOCITY_UNITS_NOTE) and 'one unit' in u.note


# -- the accumulator (energy_monitor's core, and the offline readers') -------------------------

def _run(vel_factor=1.0, pos_factor=1.0, *, duration_s=6.0, velocities=True, glitch=False,
         continuous=False):
    """A walking robot's stream: 18 joints at 100 Hz (positions x ``pos_factor``, velocities
    x ``vel_factor``; efforts doing negative work too), /gait/phase at 100 Hz, period 1 s,
    battery at 50 Hz; power_out_source auto without a model (refused: NaN)."""
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros', power_out_source='auto')
    out = []
    off = np.arange(len(NAMES)) / 7.0
    amp = np.tile([0.4, 0.3, 0.25], len(LEGS))
    for k in range(int(duration_s * 100) + 1):
        t = 10.0 + 0.01 * k
        w = 2 * np.pi * (t + off)
        if continuous:   # a leg turning on (a Buehler clock), positions unwrapped in rad
            q, v = 2 * np.pi * t + off, np.full(len(NAMES), 2 * np.pi)
        else:
            q, v = amp * np.sin(w), amp * 2 * np.pi * np.cos(w)
        if glitch and k == 250:
            q = q.copy()
            q[4] += 40.0   # one encoder glitch
        tau = 0.3 + 0.5 * np.sin(w + 0.7)
        out += acc.add_gait_phase(GaitPhaseSample(
            t_s=t, gait='tripod', period_s=1.0, duty_factor=0.5, step_length_m=0.06,
            step_height_m=0.03, sweep_angle_rad=0.0, leg_offset_rad=0.0,
            cycle_phase=(t - 10.0) % 1.0, leg_names=LEGS,
            phase_offsets=np.array([0, .5, 0, .5, 0, .5]), in_stance=np.ones(6, bool),
            supporting_legs=3))
        out += acc.add_joint_state(JointStateSample(
            t_s=t + 0.002, names=NAMES, position=q * pos_factor,
            velocity=v * vel_factor if velocities else np.array([]), effort=tau))
        if k % 2 == 0:
            out += acc.add_battery(BatterySample(t_s=t + 0.001, voltage_v=12.0,
                                                 current_a=-2.0, temperature_c=25.0))
    return acc, out


@pytest.fixture(scope='module')
def reference():
    acc, out = _run()
    assert len(out) >= 4 and all(math.isfinite(d.power_out_w) for d in out)
    assert not any('not rad' in n or 'converted' in n for n in acc.notes_)
    return out


@pytest.mark.parametrize('vel, pos, unit', [
    (180 / math.pi, 1.0, 'deg/s'), (30 / math.pi, 1.0, 'rpm'), (0.5 / math.pi, 1.0, 'rev/s'),
    (180 / math.pi, 180 / math.pi, 'deg/s'), (30 / math.pi, 180 / math.pi, 'rpm')])
def test_windows_take_the_converted_joint_power(reference, vel, pos, unit):
    acc, out = _run(vel, pos)
    assert len(out) == len(reference)
    for a, b in zip(out, reference):
        assert a.power_out_w == pytest.approx(b.power_out_w, rel=1e-9)
        assert a.joint_power_net_w == pytest.approx(b.joint_power_net_w, rel=1e-9, abs=1e-12)
        assert a.power_out_source == 'effort' and a.warnings == b.warnings
    said = [n for n in acc.notes_ if n.startswith(VELOCITY_CONVERTED_NOTE)]
    assert len(said) == 1 and f'velocities are {unit}' in said[0]   # once, not per window
    assert acc.joint_units_().velocity_unit == unit


def test_degree_positions_with_rad_per_second_keep_the_joint_power(reference):
    acc, out = _run(1.0, DEG)
    assert [d.power_out_w for d in out] == pytest.approx([d.power_out_w for d in reference],
                                                         rel=1e-9)
    assert sum(n.startswith(POSITION_DEGREES_NOTE) for n in acc.notes_) == 1


def test_degree_positions_without_velocities_convert_the_position_power():
    _, rad = _run(velocities=False)
    acc, deg = _run(pos_factor=DEG, velocities=False)
    assert len(rad) == len(deg) > 0
    assert [d.power_out_w for d in deg] == pytest.approx([d.power_out_w for d in rad],
                                                         rel=1e-9)
    assert acc.joint_units_().position_factor == DEG


def test_a_gear_ratio_is_refused_per_window():
    acc, out = _run(3.2)
    assert out and all(math.isnan(d.power_out_w) and d.power_out_source == 'none'
                       for d in out)
    assert all(any(w.startswith(VELOCITY_UNITS_NOTE) and 'times the derivative' in w
                   for w in d.warnings) for d in out)
    assert not any(n.startswith(VELOCITY_CONVERTED_NOTE) for n in acc.notes_)


def test_no_degrees_from_a_turning_leg_or_a_glitch():
    acc, _ = _run(continuous=True)
    assert acc.degree_swings_ == 0 and acc.joint_units_().position_factor == 1.0
    acc, _ = _run(glitch=True)
    assert acc.degree_swings_ <= 2 and acc.joint_units_().position_factor == 1.0
