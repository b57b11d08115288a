"""Live-graph review, core side: joint/leg mismatches reported, robots lighter than their legs
refused (no ROS here; the nodes are in test/integration/test_live_review_nodes.py)."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_bench_drivers.robot_sim import RobotConfig, RobotSimulator, robot_mass_problem
from hexapod_bench_drivers.sim_live import LiveRobot, NameMismatch
from hexapod_gait.kinematics import ANTBOT_LEG
from hexapod_gait.legs import joint_names

LEG_KG = float(sum(ANTBOT_LEG.link_masses_kg))


def _joints(legs: tuple[str, ...]) -> tuple[str, ...]:
    return tuple(j for leg in legs for j in joint_names(leg))


def test_eight_leg_commands_to_a_six_leg_robot_are_reported_once_per_set() -> None:
    robot = LiveRobot()
    check = NameMismatch('/joint_commands', robot.joint_names, robot.describe(), 'joints')
    eight = _joints(('L1', 'L2', 'L3', 'L4', 'R1', 'R2', 'R3', 'R4'))
    level, text = check.check(eight)
    assert level == 'warning'
    for name in ('L4_coxa', 'L4_tibia', 'R4_femur'):
        assert name in text
    assert '6 legs' in text and 'L1_coxa' in text
    assert check.check(eight) is None                     # the same set: said once
    assert check.check(robot.joint_names) is None         # all ours: nothing to say
    assert check.check(_joints(('L1', 'L4')))[0] == 'warning'   # another set: said


def test_commands_matching_no_joint_are_an_error() -> None:
    robot = LiveRobot()
    check = NameMismatch('/joint_commands', robot.joint_names, robot.describe(), 'joints')
    hips = tuple(f'{leg}_hip' for leg in ('L1', 'L2', 'L3', 'R1', 'R2', 'R3'))
    level, text = check.check(hips)
    assert level == 'error' and 'L1_hip' in text and 'none of its 6 joints' in text
    assert check.check(hips) is None
    # the robot holds its pose: _Commands.update used none of them
    q0 = robot.commands.q.copy()
    used = robot.commands.update(1.0, hips, np.ones(6), np.zeros(6))
    assert used == 0 and np.array_equal(robot.commands.q, q0)


def test_unknown_gait_legs_are_reported_and_skipped() -> None:
    robot = LiveRobot()
    check = NameMismatch('/gait/phase', robot.sim.leg_names, robot.describe(), 'legs')
    legs = ('L1', 'L2', 'L3', 'L4', 'R1', 'R2', 'R3', 'R4')
    robot.set_gait(legs, np.zeros(8, dtype=bool), 0.3, 0.5)
    assert not robot.in_stance.any()
    level, text = check.check(legs)
    assert level == 'warning' and 'L4, R4' in text and 'legs not on this robot' in text


def test_bench_leg_only_reports_commands_without_its_joints() -> None:
    check = NameMismatch('/joint_commands', joint_names('R2'), 'bench leg R2', 'joints',
                         extra_ok=True)
    assert check.check(_joints(('L1', 'L2', 'L3', 'R1', 'R2', 'R3'))) is None
    level, text = check.check(_joints(('L1', 'R1')))
    assert level == 'error' and 'bench leg R2' in text and 'R2_coxa' in text


def test_many_distinct_sets_are_capped() -> None:
    check = NameMismatch('/joint_commands', ('a',), 'x', 'joints', max_sets=3)
    notes = [check.check(('a', f'b{i}')) for i in range(10)]
    assert sum(n is not None for n in notes) == 3


def test_robot_lighter_than_its_legs_is_refused() -> None:
    assert robot_mass_problem(2.183, 6, LEG_KG) is None
    reason = robot_mass_problem(1.0, 8, LEG_KG)
    assert reason is not None and '8 legs' in reason and 'outweigh' in reason
    assert robot_mass_problem(6 * LEG_KG, 6, LEG_KG) is not None   # a body of 0 kg
    with pytest.raises(ValueError, match='outweigh'):
        RobotSimulator(RobotConfig(leg_count=8, robot_mass_kg=1.0))
    RobotSimulator(RobotConfig(leg_count=8, robot_mass_kg=1.5))    # 8 x 0.166 = 1.33 kg


@pytest.mark.parametrize('kw,match', [
    ({'robot_mass_kg': 0.0}, 'robot_mass_kg'),
    ({'robot_mass_kg': float('nan')}, 'robot_mass_kg'),
    ({'payload_kg': -0.5}, 'payload_kg'),
    ({'leg_count': 5}, 'leg_count'),
    ({'leg_count': 0}, 'leg_count'),
])
def test_robot_config_refuses_impossible_values(kw: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        RobotConfig(**kw)
