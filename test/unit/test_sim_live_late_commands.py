"""The live simulators say when ``/joint_commands`` come late (a busy host).

Under a load average of 8 on two cores the demo's live robot read 94-98 W for its 35 W: the
gait node's commands came over 0.1 s apart, the simulated servos held the old target and then
stepped to the new one. Only a "battery samples missing" warning was logged; ``sim_robot``
and ``sim_bench`` now count such commands (``_Commands.late``) and warn on the 1st, 10th,
100th ... (``hexapod_common.clocks.count_milestone``).
"""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_bench_drivers.sim_live import (LATE_COMMAND_JUMP_RAD, LATE_COMMAND_MAX_GAP_S,
                                            MAX_CARRY_S, _Commands)
from hexapod_common.clocks import count_milestone

NAMES = ('L1_coxa', 'L1_femur', 'L1_tibia')


def _commands() -> _Commands:
    return _Commands(NAMES, np.zeros(3))


def _walk(c: _Commands, t0: float, t1: float, dt: float = 0.01) -> float:
    """Commands every ``dt`` along a 1 Hz, 0.3 rad swing of the joints; the last stamp."""
    t = t0
    while t <= t1 + 1e-9:
        q = 0.3 * np.sin(2 * np.pi * t) * np.ones(3)
        c.update(t, NAMES, q, 0.6 * np.pi * np.cos(2 * np.pi * t) * np.ones(3))
        t += dt
    return t - dt


def test_commands_on_time_are_not_late() -> None:
    c = _commands()
    _walk(c, 0.0, 3.0)
    assert c.late == 0


def test_a_gap_with_a_jump_is_late_and_says_how_much() -> None:
    c = _commands()
    last = _walk(c, 0.0, 1.0)
    _walk(c, last + 0.3, 2.0)        # 0.3 s without commands, then the schedule moved on
    assert c.late == 1
    assert c.late_gap_s == pytest.approx(0.3, abs=1e-6)
    assert c.late_jump_rad > LATE_COMMAND_JUMP_RAD


def test_standing_restarts_and_short_gaps_are_not_late() -> None:
    c = _commands()
    still = np.full(3, 0.2)
    c.update(0.0, NAMES, still, np.zeros(3))
    c.update(0.5, NAMES, still, np.zeros(3))          # a standing gait node at 2 Hz
    assert c.late == 0
    c.update(0.5 + LATE_COMMAND_MAX_GAP_S + 1.0, NAMES, still + 0.5, np.zeros(3))  # restart
    assert c.late == 0
    t = 0.5 + 2 * LATE_COMMAND_MAX_GAP_S + 2.0   # another restart
    c.update(t, NAMES, still, np.zeros(3))
    c.update(t + 0.9 * MAX_CARRY_S, NAMES, still + 0.3, np.zeros(3))  # carried forward
    assert c.late == 0
    # joints not ours do not count as a jump
    c.update(t + 1.0, ('R1_coxa',), np.array([1.0]), np.zeros(1))
    assert c.late == 0


def test_count_milestone_logs_1_10_100_1000_then_every_10000() -> None:
    assert [n for n in range(0, 30001) if count_milestone(n)] == \
        [1, 10, 100, 1000, 10000, 20000, 30000]
