"""``hexapod-analyze residuals --leg FILE``: the energy loop predicts a robot of another leg.

An outside review (a PhantomX-like robot, 0.175 kg legs): ``energy --leg`` predicted the
robot's runs with its own leg mass, but ``residuals`` had no ``--leg`` and carried AntBot's
0.166 kg legs in Eq. 1 silently (26.99 W predicted where energy said 26.83 W, the difference
left in the residual for the effects to explain). Small synthetic bags with a known power
model: P_stance = 2 + 6 m + 0.5 f, P_swing = 0.8 + 0.3 m + 1.5 f [W] (f = 1 / T_phase)."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer

from energy_bench_bags import _Msgs as BenchMsgs
from hexapod_energy.residuals_cli import add_cli

G = 9.81
BETA, STEP, HEIGHT = 0.5, 0.10, 0.04
LEG_MASSES = (0.060, 0.070, 0.045)
M_LEG = sum(LEG_MASSES)
MASS = 1.6
LEG_YAML = """name: PhantomX-like
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.060, 0.070, 0.045]
neutral_tip_m: [0.14, 0.0, -0.10]
"""
TYPES = {'/battery_state': 'sensor_msgs/msg/BatteryState',
         '/gait/phase': 'hexapod_interfaces/msg/GaitPhase',
         '/bench/ground_force': 'geometry_msgs/msg/WrenchStamped',
         '/bench/leg_tip': 'geometry_msgs/msg/PointStamped',
         '/bench/session': 'hexapod_interfaces/msg/BenchSession'}
TRIPOD = {'L1': 0.0, 'L2': 0.5, 'L3': 0.0, 'R1': 0.5, 'R2': 0.0, 'R3': 0.5}


def p_stance(f: float, m: float) -> float:
    return 2.0 + 6.0 * m + 0.5 * f


def p_swing(f: float, m: float) -> float:
    return 0.8 + 0.3 * m + 1.5 * f


class _Msgs(BenchMsgs):
    """energy_bench_bags' messages (header, battery, wrench, point) plus this file's
    gait phase, bench session and bag writer."""

    def gait(self, t: float, period: float, cyc: float, legs: dict[str, float]):
        stance = [((cyc - o) % 1.0) < BETA for o in legs.values()] if period else \
            [True] * len(legs)
        return self.T['hexapod_interfaces/msg/GaitPhase'](
            header=self.header(t), gait='tripod' if period else 'stand', period=float(period),
            duty_factor=BETA, step_length=STEP if period else 0.0,
            step_height=HEIGHT if period else 0.0, sweep_angle=0.0, leg_offset=0.0,
            cycle_phase=float(cyc), leg_names=list(legs),
            phase_offsets=np.asarray(list(legs.values()), float),
            in_stance=np.asarray(stance, bool), supporting_legs=int(sum(stance)))

    def session(self, t: float, sid: str, state: str, load: float, freq: float):
        return self.T['hexapod_interfaces/msg/BenchSession'](
            header=self.header(t), session_id=sid, state=state, load_mass=float(load),
            frequency=float(freq), duty_factor=BETA, step_length=STEP, step_height=HEIGHT)

    def write(self, path: Path, rec: list) -> None:
        rec.sort(key=lambda r: r[0])
        used = sorted({r[1] for r in rec})
        with Writer(path, version=9, storage_plugin=StoragePlugin.MCAP) as w:
            conns = {tp: w.add_connection(tp, TYPES[tp], typestore=self.store) for tp in used}
            for t, tp, msg in rec:
                w.write(conns[tp], int(round((t + 0.0005) * 1e9)),
                        self.store.serialize_cdr(msg, TYPES[tp]))


def _grid(t0: float, t1: float, hz: float) -> np.ndarray:
    return t0 + (np.arange(int(math.floor((t1 - t0) * hz))) + 0.5) / hz


def write_bench(path: Path) -> None:
    msgs, rec, t = _Msgs(), [], 1000.0
    for load in (0.0, 0.2, 0.5):
        for freq in (0.0, 0.5, 1.0, 1.5, 2.0, 2.5):
            sid, period = f'm{load:g}_f{freq:g}', (1.0 / freq if freq else 0.0)
            w0, w1 = t + 0.5, t + 0.5 + (4.0 if freq else 2.0)
            for tt in _grid(t, w1 + 0.3, 100.0):
                state = 'walking' if w0 <= tt < w1 else ('heating' if tt < w0 else 'cooling')
                rec.append((tt, '/bench/session', msgs.session(tt, sid, state, load, freq)))
            for tt in _grid(w0, w1, 200.0):
                cyc = ((tt - w0) / period) % 1.0 if period else 0.0
                if not period:
                    p = 1.0 + 4.0 * load
                elif cyc < BETA:
                    p = p_stance(1.0 / (BETA * period), load)
                else:
                    p = p_swing(1.0 / ((1.0 - BETA) * period), load)
                rec.append((tt, '/battery_state', msgs.battery(tt, p)))
            for tt in _grid(w0, w1, 100.0):
                cyc = ((tt - w0) / period) % 1.0 if period else 0.0
                down = not period or cyc < BETA
                rec.append((tt, '/gait/phase', msgs.gait(tt, period, cyc, {'R2': 0.0})))
                rec.append((tt, '/bench/ground_force',
                            msgs.wrench(tt, (M_LEG + load) * G if down else 0.0)))
                z = 0.0 if down else HEIGHT * math.sin(math.pi * (cyc - BETA) / (1 - BETA))
                rec.append((tt, '/bench/leg_tip', msgs.point(tt, z)))
            t = w1 + 0.3
    msgs.write(path, rec)


def robot_truth_w(period: float) -> float:
    """Eq. 1 of the truth for a tripod at beta 0.5 (3 legs down throughout)."""
    m_c = (MASS - 3 * M_LEG) / 3
    f = 1.0 / (BETA * period)
    return 3 * p_stance(f, m_c) + 3 * p_swing(f, 0.0)


def write_robot(path: Path, period: float, run_s: float = 9.0) -> None:
    msgs, rec, t0 = _Msgs(), [], 1000.0
    p = robot_truth_w(period)
    for tt in _grid(t0, t0 + run_s, 200.0):
        rec.append((tt, '/battery_state', msgs.battery(tt, p)))
    for tt in _grid(t0, t0 + run_s, 100.0):
        rec.append((tt, '/gait/phase', msgs.gait(tt, period, ((tt - t0) / period) % 1.0,
                                                 TRIPOD)))
    msgs.write(path, rec)


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('resid_leg')
    write_bench(root / 'bench')
    robots = []
    for period in (1.0, 0.6):
        write_robot(root / f'robot_{period:g}', period)
        robots.append(root / f'robot_{period:g}')
    leg = root / 'leg.yaml'
    leg.write_text(LEG_YAML, encoding='utf8')
    return root, leg, robots


def _run(argv: list[str]) -> dict:
    parser = argparse.ArgumentParser()
    add_cli(parser.add_subparsers())
    args = parser.parse_args(['residuals', *argv])
    assert args.func(args) in (0, None)
    return json.loads((Path(args.out) / 'residuals.json').read_text(encoding='utf8'))


def test_residuals_predicts_with_the_given_leg(bags):
    root, leg, robots = bags
    common = ['--bench', str(root / 'bench'), '--robot', *map(str, robots),
              '--robot-mass', str(MASS), '--no-plots', '--no-progress']
    doc = _run([*common, '--leg', str(leg), '--out', str(root / 'out')])
    antbot = _run([*common, '--out', str(root / 'out_antbot')])
    assert doc['leg']['name'] == 'PhantomX-like'
    assert doc['leg']['link_masses_kg'] == list(LEG_MASSES)
    assert antbot['leg']['name'] == 'AntBot'
    # Eq. 1 on 3 stance legs: 3 dP_stance/dm (m_c(own leg) - m_c(AntBot's leg)) = -0.16 W
    m_ant = 0.01498 + 0.1118 + 0.03923
    shift = 3 * 6.0 * ((MASS - 3 * M_LEG) / 3 - (MASS - 3 * m_ant) / 3)
    for run, ref, period in zip(doc['per_run'], antbot['per_run'], (1.0, 0.6)):
        assert run['predicted_w'] - ref['predicted_w'] == pytest.approx(shift, abs=0.02)
        # the bench fit itself is within 0.3 % of the truth (AntBot's legs: +0.5 %)
        assert run['predicted_w'] == pytest.approx(robot_truth_w(period), rel=0.003)
