"""A robot that does not follow its walking schedule (an outside review of other robots): the
simulator's joint_commands remapped away, the legs stood still while /gait/phase walked, and
live and offline read 0.15 m/s, specific resistance 2.85 for 6.93 walking, silently; a
simulator that took the commands 2.2 s late put 7.5 W windows at 0.15 m/s into its run (P_in
-14 %). Now such windows carry a warning, have no speed or model P_out, and are left out
(offline) or not published (live). Also: a schedule whose legs are named outside the
contract gave the live monitor no window at all (every battery sample dropped): P_out
unknown, the windows kept, as offline."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
from hexapod_common.testbags import rewrite_bag, write_foreign_robot_bag
from hexapod_energy.descriptors import (STILL_JOINTS_NOTE, DescriptorAccumulator,
                                        model_power_out)

T0, PERIOD = 1000.0, 1.0
LEGS = ('L1', 'R1', 'L2', 'R2', 'L3', 'R3')
NAMES = tuple(f'{leg}_{j}' for leg in LEGS for j in ('coxa', 'femur', 'tibia'))


def _gait(t: float, legs=LEGS, step: float = 0.1) -> GaitPhaseSample:
    return GaitPhaseSample(t_s=t, gait='tripod', period_s=PERIOD, duty_factor=0.5,
                           step_length_m=step, step_height_m=0.03 if step else 0.0,
                           cycle_phase=((t - T0) / PERIOD) % 1.0, leg_names=legs,
                           phase_offsets=(0.0, 0.5) * (len(legs) // 2),
                           in_stance=(True,) * len(legs), supporting_legs=len(legs) // 2,
                           sweep_angle_rad=0.0, leg_offset_rad=0.0)


def _run(moving: bool, *, legs=LEGS, velocities: bool = True, still_until: float = -math.inf,
         model=None, positions: bool = True, joint_every: int = 1, cycles: int = 1,
         steps: int = 600) -> list:
    acc = DescriptorAccumulator(mass_kg=2.183, current_sign='ros', power_out_model=model,
                                power_out_source='auto' if model else 'effort', cycles=cycles)
    out = []
    for k in range(steps):
        t = T0 + 0.01 * k
        ph = 2 * math.pi * (t - T0) / PERIOD
        move = moving and t >= still_until
        pos = np.array([0.3 * math.sin(ph + 0.2 * n) if move and positions else 0.1 * n
                        for n in range(len(NAMES))])
        vel = np.array([0.3 * 2 * math.pi * math.cos(ph + 0.2 * n) if move else 0.0
                        for n in range(len(NAMES))])
        out += acc.add_gait_phase(_gait(t, legs)) or []
        if k % joint_every == 0:
            out += acc.add_joint_state(JointStateSample(
                t_s=t + 2e-4, names=NAMES, position=pos,
                velocity=vel if velocities else np.zeros(0), effort=np.zeros(0))) or []
        out += acc.add_battery(BatterySample(t_s=t + 1e-4, voltage_v=12.0,
                                             current_a=-(2.0 if move else 0.7),
                                             temperature_c=25.0)) or []
    return out


def _still(d) -> bool:
    return any(w.startswith(STILL_JOINTS_NOTE) for w in d.warnings)


def test_a_robot_standing_while_the_schedule_walks_has_no_speed():
    still = _run(False)
    assert len(still) >= 3
    assert all(_still(d) for d in still)
    assert all(math.isnan(d.speed_mps) and d.speed_source == 'none' for d in still)
    assert all(math.isnan(d.specific_resistance) for d in still)
    walking = _run(True)
    assert walking and not any(_still(d) for d in walking)
    assert all(d.speed_mps == pytest.approx(0.2) for d in walking)


def test_only_the_windows_before_the_robot_followed_are_flagged():
    out = _run(True, still_until=T0 + 2.0)
    flagged = [d.t_end_s for d in out if _still(d)]
    assert flagged and max(flagged) <= T0 + 2.0 + 1e-6
    assert any(not _still(d) for d in out)


def test_a_driver_that_fills_no_positions_but_velocities_is_moving():
    """Positions left constant by a driver, velocities real: not a still robot."""
    acc_out = _run(True, positions=False)
    assert not any(_still(d) for d in acc_out)


@pytest.mark.parametrize('every', [100, 90, 25])
def test_joint_states_sampled_once_a_cycle_cannot_show_a_still_robot(every):
    """A review: joint states at 1 Hz without velocities on a 1 s gait read a range of 0
    in every window, and every window of a walking run was left out."""
    out = _run(True, velocities=False, joint_every=every)
    assert out and not any(_still(d) for d in out)


def test_one_sample_a_cycle_over_windows_of_several_cycles_is_not_judged():
    """A review: with -p cycles:=8 and joint states once a cycle, walking windows were
    still flagged (8 samples, all at one phase)."""
    out = _run(True, velocities=False, joint_every=100, cycles=8, steps=3000)
    assert out and not any(_still(d) for d in out)


@pytest.mark.parametrize('every', [9, 10])
def test_a_still_robot_is_seen_at_an_ax_bus_rate(every):
    """A review: at an AX-18A bus's 11 Hz (89 ms cycles) a fixed minimum of 8 samples per
    window missed a still robot on 1 s (and 0.5 s) cycles."""
    out = _run(False, velocities=False, joint_every=every)
    assert out and all(_still(d) for d in out)


def test_the_model_p_out_of_a_still_window_is_unknown():
    from hexapod_energy.leg_description import antbot_leg

    model = model_power_out(antbot_leg().output_power_model(2.183), robot_mass_kg=2.183)
    still = _run(False, velocities=False, model=model)
    assert still and all(math.isnan(d.power_out_w) for d in still)


def test_legs_outside_the_contract_keep_their_windows_with_p_out_unknown():
    from hexapod_energy.leg_description import antbot_leg

    model = model_power_out(antbot_leg().output_power_model(2.183), robot_mass_kg=2.183)
    legs = ('FL', 'FR', 'ML', 'MR', 'HL', 'HR')
    out = _run(True, legs=legs, velocities=False, model=model)
    assert len(out) >= 3
    assert all(d.power_in_w == pytest.approx(24.0) for d in out)
    assert all(math.isnan(d.power_out_w) for d in out)
    assert all(any('no P_out model for this schedule' in w for w in d.warnings) for d in out)


def test_offline_leaves_the_still_windows_out_and_refuses_a_bag_of_them(tmp_path):
    from hexapod_energy.errors import BagContentError
    from hexapod_energy.bag_io import read_robot_bag

    write_foreign_robot_bag(tmp_path / 'base', legs=6, duration_s=12.0, storage='mcap')
    t_first: list[float] = []

    def freeze(until_s: float):
        def edit(topic, msg):
            if topic != '/joint_states':
                return None
            t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
            if not t_first:
                t_first.append(t)
            if t - t_first[0] < until_s:
                msg.position = np.zeros(len(msg.name))
                msg.velocity = np.zeros(len(msg.name))
            return None
        return edit

    t_first.clear()
    part = rewrite_bag(tmp_path / 'base', tmp_path / 'late', freeze(4.0))
    clean = read_robot_bag(tmp_path / 'base', mass_kg=2.0)
    late = read_robot_bag(part, mass_kg=2.0)
    assert late.windows < clean.windows
    assert any('left out' in n and STILL_JOINTS_NOTE in n for n in late.extra['notes'])
    assert not any(STILL_JOINTS_NOTE in n for n in clean.extra['notes'])
    t_first.clear()
    frozen = rewrite_bag(tmp_path / 'base', tmp_path / 'frozen', freeze(1e9))
    with pytest.raises(BagContentError, match='did not move'):
        read_robot_bag(frozen, mass_kg=2.0)


def test_a_gait_node_walking_fewer_legs_than_the_robot_is_warned():
    """Six legs of joints, a four-leg schedule: L3 and R3 stood, silently."""
    acc = DescriptorAccumulator(mass_kg=2.183, current_sign='ros', power_out_source='effort')
    out = []
    four = ('L1', 'R1', 'L2', 'R2')
    for k in range(400):
        t = T0 + 0.01 * k
        ph = 2 * math.pi * (t - T0) / PERIOD
        out += acc.add_gait_phase(_gait(t, four)) or []
        out += acc.add_joint_state(JointStateSample(
            t_s=t + 2e-4, names=NAMES, position=np.array([0.3 * math.sin(ph + n)
                                                          for n in range(18)]),
            velocity=np.ones(18), effort=np.full(18, 0.1))) or []
        out += acc.add_battery(BatterySample(t_s=t + 1e-4, voltage_v=12.0, current_a=-2.0,
                                             temperature_c=25.0)) or []
    assert out
    assert all(any('legs L3, R3 have joints' in w for w in d.warnings) for d in out)
    six = _run(True)
    assert not any('have joints on /joint_states' in w for d in six for w in d.warnings)


def test_a_gait_schedulers_stand_is_a_standing_run_not_a_buehler_clock(tmp_path):
    """An outside review: gait_scheduler's stand (the walking period kept, step length and
    height 0) was read by ``energy`` as a Buehler clock ("rotating legs"); it is a robot
    standing, predicted from the bench's 0 Hz sessions when a bench is given."""
    import json

    from hexapod_common.testbags import rewrite_bag, write_foreign_robot_bag
    from hexapod_energy.cli import main

    write_foreign_robot_bag(tmp_path / 'walk', legs=6, duration_s=12.0)

    def stand(topic, msg):
        if topic == '/gait/phase':
            msg.step_length = 0.0
            msg.step_height = 0.0
        return None

    rewrite_bag(tmp_path / 'walk', tmp_path / 'stand', stand)
    assert main(['--robot', str(tmp_path / 'stand'), '--robot-mass', '2.183',
                 '--out', str(tmp_path / 'o'), '--no-progress']) == 0
    [run] = json.loads((tmp_path / 'o' / 'energy.json').read_text())['robot_runs']
    notes = ' '.join(run['notes'])
    assert 'the robot stands' in notes
    assert 'Buehler clock' not in notes
