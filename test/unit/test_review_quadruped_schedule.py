"""Offline robot run: the schedule it reports (and its Eq. 6 P_out model) is the one its windows
walked, not a /gait/phase sample after them. A quadruped review (4 legs, alternating, 80 mm)
stopped its gait node with SIGTERM: the stand transition's first samples (step 79.91 mm, within
the schedule tolerance) became the run's schedule, so energy.json said step_length_m 0.0799,
and P_out 0.20932 W where every live window read 0.20958 W (-0.12 %)."""

from __future__ import annotations

import math

import pytest

from hexapod_bench_drivers.effects import parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.testbags import rewrite_bag
from hexapod_energy.bag_io import read_robot_bag

MASS = 2.183
STEP = 0.1
#: the settling stand transition's first samples: within the 1e-4 schedule tolerance
SETTLING = STEP - 8e-5


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('quad_sched')
    write_trace(simulate_robot(6.6, RobotConfig(period_s=1.0, step_length_m=STEP),
                               effects=parse_effects([]), seed=3), root / 'walk')
    last = {}

    def find_end(topic, msg):
        if topic == '/gait/phase':
            last['t'] = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9

    rewrite_bag(root / 'walk', root / 'copy', find_end, topics=['/gait/phase'])
    t_tail = last['t'] - 0.3   # after the last whole cycle (6.6 s: the 7th never ends)

    def tail(topic, msg):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        if topic == '/gait/phase' and t >= t_tail:
            msg.step_length = SETTLING

    rewrite_bag(root / 'walk', root / 'tail', tail, topics=['/gait/phase'])
    return root


def test_run_schedule_is_the_walked_one(bags):
    ref = read_robot_bag(bags / 'walk', mass_kg=MASS)
    run = read_robot_bag(bags / 'tail', mass_kg=MASS)
    assert run.windows == ref.windows
    assert math.isclose(ref.gait.step_length_m, STEP, rel_tol=0, abs_tol=1e-12)
    # before: SETTLING, the first samples of what came after the last window
    assert math.isclose(run.gait.step_length_m, STEP, rel_tol=0, abs_tol=1e-12)
    assert run.power_in_w == ref.power_in_w
