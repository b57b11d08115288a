"""The simulators walk a leg file's leg (``hexapod-sim bench|robot --leg FILE``, the
simulator classes' ``leg=``), the file ``gait_scheduler -p leg_file`` and ``hexapod-analyze
energy --leg`` read.

The simulators walked AntBot's leg only (their ``dh`` argument kept AntBot's neutral tip, and
no command took a leg file): another leg's bench needed recorded bags. A PhantomX-like leg
(52/66/133 mm, 175 g; the leg of ``test_sequencer_leg_file``) is simulated on the bench and on
the robot; ``energy --bench --leg --robot`` predicts the simulated robot within the AntBot
end-to-end test's tolerance (``test_energy_e2e_sim``: RMSE < 5 %, worst run < 6 %), and the
simulator's joint loads along the commanded path are the Eq. 6 model's of ``energy --leg``.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from hexapod_bench_drivers.bench_sim import BenchConfig, BenchPlan, BenchSimulator
from hexapod_bench_drivers.effects import EffectSet
from hexapod_bench_drivers.robot_sim import RobotConfig, RobotSimulator, simulate_robot
from hexapod_bench_drivers.sim_bag import CONFIG_KEY, write_trace
from hexapod_bench_drivers.sim_cli import _infeasible, main
from hexapod_bench_drivers.sim_core import G_MPS2
from hexapod_energy.cli import main as energy_main
from hexapod_energy.leg_description import load_leg_description
from hexapod_gait.gait import carried_mass_per_leg_kg, make_gait
from hexapod_gait.leg_file import read_leg_file

PHANTOMX = """name: PhantomX-like
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.060, 0.070, 0.045]
neutral_tip_m: [0.14, 0.0, -0.10]
"""
LEG_KG = 0.175
#: AntBot's body (2.183 kg less six 0.166 kg legs) with six PhantomX-like legs
ROBOT_KG = 2.183 - 6 * (0.01498 + 0.1118 + 0.03923) + 6 * LEG_KG


@pytest.fixture(scope='module')
def leg_path(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp('leg') / 'phantomx.yaml'
    path.write_text(PHANTOMX, encoding='utf8')
    return path


@pytest.fixture(scope='module')
def leg(leg_path):
    return read_leg_file(leg_path)


def _config(bag: Path) -> dict:
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    return json.loads(meta['rosbag2_bagfile_information']['custom_data'][CONFIG_KEY])


def _commanded_power_out_w(sim: RobotSimulator, n: int = 600) -> float:
    """Whole-robot positive joint power [W] of the simulator's own leg model (links, masses,
    rod inertias: ``LegLoads.torques``, inverse dynamics) along its commanded joint paths,
    the stance tips carrying ``(m_c + m_leg) g`` as the simulator loads them."""
    gait = sim.gait
    t = np.arange(n) / n * gait.period_s
    q, qd, qdd, stance, _ = sim.gait_inputs(t)
    carried = carried_mass_per_leg_kg(sim.config.total_mass_kg, sim.loads.leg_mass_kg,
                                      stance.sum(axis=1))
    force = np.zeros(q.shape)
    force[..., 2] = np.where(stance, (carried[:, None] + sim.loads.leg_mass_kg) * G_MPS2, 0.0)
    tau = sim.loads.torques(q.reshape(-1, 3), qd.reshape(-1, 3), qdd.reshape(-1, 3),
                            force.reshape(-1, 3)).reshape(q.shape)
    return float(np.clip(tau * qd, 0.0, None).sum(axis=(1, 2)).mean())


def test_the_robot_walks_the_files_leg_and_its_eq6_power(leg, leg_path) -> None:
    """Links, masses and neutral tip are the file's; along the commanded path the simulated
    legs need exactly the joint power ``energy --leg`` models (Eq. 6). With the DH table
    alone (the ``dh`` argument, AntBot's neutral tip) they needed -7.8 % at 0.1 m/s and
    +3.5 % at 0.6 m/s."""
    from hexapod_bench_drivers.robot_sim import default_robot_mass_kg

    assert default_robot_mass_kg(6, LEG_KG) == pytest.approx(ROBOT_KG, abs=1e-9)
    model = load_leg_description(leg_path).output_power_model(ROBOT_KG)
    for v in (0.1, 0.3, 0.6):
        cfg = RobotConfig(speed_mps=v, robot_mass_kg=ROBOT_KG)
        sim = RobotSimulator(cfg, effects=EffectSet.none(), leg=leg)
        assert sim.loads.dh == leg.dh and sim.loads.leg_mass_kg == pytest.approx(LEG_KG)
        np.testing.assert_allclose(sim.kinematics.forward(sim.neutral_q),
                                   np.tile(leg.neutral_tip_m, (6, 1)), atol=1e-12)
        assert all(np.array_equal(tr.neutral_tip_m, leg.neutral_tip_m)
                   for tr in sim.trajectories)
        want = float(model.power_out_w(cfg.gait_pattern()))
        assert _commanded_power_out_w(sim) == pytest.approx(want, rel=1e-6), v
    # the servos' own output power, against P_in: the AntBot simulator's band
    # (test_sim_robot: 0.5 to 6 %) and the e2e test's for the model's (0.3 to 7 %)
    cfg = RobotConfig(speed_mps=0.3, robot_mass_kg=ROBOT_KG)
    tr = simulate_robot(3.0, cfg, effects=EffectSet.none(), leg=leg)
    keep = tr.t_s > 1.0
    p_in = tr.mean_power_in_w(keep)
    p_out = float(np.clip(tr.true_mechanical_power_w[keep], 0.0, None).sum(axis=1).mean())
    eq6 = float(model.power_out_w(cfg.gait_pattern()))
    print(f'\n0.3 m/s: P_in {p_in:.2f} W, servo P_out {p_out:.3f} W, Eq. 6 {eq6:.3f} W')
    assert 0.005 <= p_out / p_in <= 0.06 and 0.003 < eq6 / p_in < 0.07
    assert tr.config['leg_description']['a_m'] == list(leg.dh.a_m)


def test_the_bench_walks_the_files_leg(leg) -> None:
    sim = BenchSimulator(BenchConfig(), effects=EffectSet.none(), leg=leg)
    np.testing.assert_allclose(sim.kinematics.forward(sim.neutral_q)[0], leg.neutral_tip_m,
                               atol=1e-12)
    assert sim.loads.leg_mass_kg == pytest.approx(LEG_KG)
    tr = sim.run_plan(BenchPlan(loads_kg=(0.2,), frequencies_hz=(1.0,), walk_s=3.0,
                                max_cool_s=5.0))
    walking = tr.gait_name == 'tripod'
    stance = walking & tr.in_stance[:, 0] & (tr.ground_force_n > 0)
    # the stance tip carries the file's leg and the load
    assert np.median(tr.ground_force_n[stance]) == pytest.approx((LEG_KG + 0.2) * G_MPS2)
    # commands: the file's inverse kinematics from its neutral tip
    cmd_tip = sim.kinematics.forward(tr.command_position_rad[walking])
    assert np.ptp(cmd_tip[:, 2]) == pytest.approx(0.04, abs=1e-3)
    assert cmd_tip[:, 2].min() == pytest.approx(leg.neutral_tip_m[2], abs=1e-9)
    assert tr.config['leg_description']['name'] == 'PhantomX-like'


def test_cli_robot_leg_file(leg_path, tmp_path, capsys) -> None:
    assert main(['robot', '--out', str(tmp_path / 'six'), '--leg', str(leg_path),
                 '--speed', '0.3', '--duration', '0.5', '--no-progress']) == 0
    cfg = _config(tmp_path / 'six')
    assert cfg['robot_mass_kg'] == pytest.approx(ROBOT_KG)       # AntBot's body, 6 such legs
    assert cfg['leg_description']['a_m'] == [0.052, 0.066, 0.133]
    assert cfg['leg_description']['neutral_tip_m'] == [0.14, 0.0, -0.10]
    assert main(['robot', '--out', str(tmp_path / 'four'), '--leg', str(leg_path), '--legs',
                 '4', '--period', '0', '--duration', '0.2', '--no-progress']) == 0
    assert _config(tmp_path / 'four')['robot_mass_kg'] == pytest.approx(
        ROBOT_KG - 2 * LEG_KG)
    capsys.readouterr()
    # a step the file's leg cannot reach (AntBot's can): refused up front, no bag
    assert main(['robot', '--out', str(tmp_path / 'far'), '--leg', str(leg_path),
                 '--step-length', '0.3', '--period', '3', '--duration', '0.2',
                 '--no-progress']) == 2
    err = capsys.readouterr().err
    assert 'leave the leg workspace' in err and "'PhantomX-like'" in err
    assert not (tmp_path / 'far').exists()
    # the servo limits on the file's leg's joint path: a 160 mm step at 1.9 Hz, walkable by
    # AntBot's leg, needs a period >= 0.546 s on it (gait_scheduler -p leg_file refuses it)
    args = ['--step-length', '0.16', '--period', f'{1 / 1.9:.6f}', '--duration', '0.2',
            '--no-progress']
    assert main(['robot', '--out', str(tmp_path / 'antbot'), *args]) == 0
    capsys.readouterr()
    assert main(['robot', '--out', str(tmp_path / 'fast'), '--leg', str(leg_path),
                 *args]) == 2
    err = capsys.readouterr().err
    assert 'infeasible' in err and "on leg 'PhantomX-like'" in err
    gait = make_gait('tripod', period_s=1 / 1.9, step_length_m=0.16)
    assert _infeasible(gait) == [] and _infeasible(gait, leg=read_leg_file(leg_path))
    # a file that is no leg: refused naming it
    bad = tmp_path / 'bad.yaml'
    bad.write_text(PHANTOMX.replace('a_m:', 'a_mm:'))
    assert main(['robot', '--out', str(tmp_path / 'bad'), '--leg', str(bad),
                 '--no-progress']) == 2
    assert 'bad.yaml' in capsys.readouterr().err


def test_cli_bench_leg_file_and_place(leg_path, tmp_path, capsys) -> None:
    common = ['--loads', '0', '--frequencies', '1', '--duration', '0.5', '--max-cool', '5',
              '--no-progress']
    assert main(['bench', '--out', str(tmp_path / 'b'), '--leg', 'R1', '--leg',
                 str(leg_path), *common]) == 0
    cfg = _config(tmp_path / 'b')
    assert cfg['leg'] == 'R1' and cfg['leg_description']['name'] == 'PhantomX-like'
    assert main(['bench', '--out', str(tmp_path / 'c'), '--leg', str(leg_path), *common]) == 0
    assert _config(tmp_path / 'c')['leg'] == 'R2'
    assert main(['bench', '--out', str(tmp_path / 'd'), *common]) == 0
    assert _config(tmp_path / 'd')['leg_description']['name'] == 'AntBot'
    capsys.readouterr()
    assert main(['bench', '--out', str(tmp_path / 'e'), '--leg', str(leg_path), '--leg',
                 str(leg_path), *common]) == 2
    assert 'at most one' in capsys.readouterr().err
    assert main(['bench', '--out', str(tmp_path / 'f'), '--leg', str(leg_path),
                 '--step-length', '0.3', *common]) == 2
    assert 'leave the leg workspace' in capsys.readouterr().err


def test_energy_predicts_the_simulated_robot_with_the_same_leg(leg, leg_path,
                                                                tmp_path) -> None:
    """Bench (3 loads x 0-3 Hz, 3 s walks) and three tripod runs of the PhantomX-like leg:
    ``energy --bench --leg --robot`` within the AntBot e2e test's tolerance (there: 5 loads x
    8 frequencies, six runs, RMSE < 5 %, worst < 6 %); measured 0.63 % RMSE, worst 1.11 %."""
    plan = BenchPlan(loads_kg=(0.0, 0.3, 0.6), frequencies_hz=(0.0, 1.0, 2.0, 3.0), walk_s=3.0,
                     max_cool_s=5.0)
    write_trace(BenchSimulator(BenchConfig(), seed=3, leg=leg).run_plan(plan),
                tmp_path / 'bench')
    speeds = (0.2, 0.3, 0.45)
    robots = [str(tmp_path / f'robot_{v:.2f}') for v in speeds]
    for i, (v, path) in enumerate(zip(speeds, robots)):
        write_trace(simulate_robot(4.0, RobotConfig(speed_mps=v, robot_mass_kg=ROBOT_KG),
                                   seed=10 + i, leg=leg), path)
    out = tmp_path / 'o'
    assert energy_main(['--bench', str(tmp_path / 'bench'), '--robot', *robots, '--leg',
                        str(leg_path), '--power-out', 'model', '--out', str(out),
                        '--no-progress']) == 0
    doc = json.loads((out / 'energy.json').read_text())
    err = doc['prediction_error']
    for r in doc['robot_runs']:
        print(f"\nv {r['speed']:.2f} m/s: measured {r['measured_power_in_w']:.2f} W, "
              f"predicted {r['predicted_power_in_w']:.2f} W, P_out {r['power_out_w']:.3f} W",
              end='')
    print(f"\nRMSE {100 * err['relative_rmse']:.2f} %, worst "
          f"{100 * err['max_abs_relative']:.2f} %")
    assert err['runs'] == 3 and doc['leg']['name'] == 'PhantomX-like'
    assert all(r['mass_kg'] == pytest.approx(ROBOT_KG) for r in doc['robot_runs'])
    assert err['relative_rmse'] < 0.05 and err['max_abs_relative'] < 0.06
