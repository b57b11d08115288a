"""A run's power, speed and specific resistance in ``slip.json`` are over whole gait cycles, as
``hexapod-analyze energy`` computes them (an outside review: the motion capture's tracked span
alone cut a jogging run's first cycle, SR 1.780 in slip.json against 1.697 in energy.json)."""

from __future__ import annotations

import argparse
import json

import pytest

from hexapod_energy.cli import add_cli as add_energy_cli
from slip_identification.cli import add_cli as add_slip_cli

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def _run(add_cli, argv):
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(argv)
    return args.func(args)


def test_slip_and_energy_give_one_specific_resistance(tmp_path):
    bag = edubot_sim.write_edubot_bag(tmp_path / 'jog', 'jogging', duration_s=6.0, seed=3)
    assert _run(add_slip_cli, ['slip', str(bag), '--out', str(tmp_path / 'slip'),
                               '--jobs', '1']) == 0
    assert _run(add_energy_cli, ['energy', '--robot', str(bag), '--robot-mass', '3.31',
                                 '--out', str(tmp_path / 'energy'), '--no-progress']) == 0
    run = json.loads((tmp_path / 'slip' / 'slip.json').read_text())['runs'][0]
    robot = json.loads((tmp_path / 'energy' / 'energy.json').read_text())['robot_runs'][0]
    span = run['frame']['energetics']
    assert span['whole_cycles'] >= 2 and span['end_s'] > span['start_s']
    # the same whole cycles' power and speed: one specific resistance
    assert run['sr'] == pytest.approx(robot['specific_resistance'], rel=3e-3)
    assert run['speed_mps'] == pytest.approx(robot['speed'], rel=3e-3)
