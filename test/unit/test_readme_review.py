"""New-user README review (2026-11-26): a bench bag or a RHex-class robot's bag given to the
servo hexapod's energy analyses, and a RHex's P_out."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.edubot_bag import write_edubot_bag
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy import residuals as R
from hexapod_energy.cli import main as energy_main
from hexapod_energy.errors import BagContentError


@pytest.fixture(scope='module')
def bags(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp('readme_review')
    plan = BenchPlan(loads_kg=(0.0, 0.2, 0.4), frequencies_hz=(0.0, 0.75, 1.5, 2.25), walk_s=3.0)
    write_trace(simulate_bench(plan, seed=1), root / 'bench')
    write_edubot_bag(root / 'edubot', 'running', duration_s=4.0, seed=3)
    return {'bench': root / 'bench', 'edubot': root / 'edubot'}


def test_residuals_refuse_a_bench_bag_as_a_robot_run(bags) -> None:
    """It was read as a standing robot and 'missed speed_friction' (exit 0)."""
    with pytest.raises(BagContentError, match='single-leg bench bag.*give it with --bench'):
        R.read_residual_run(bags['bench'])


def test_residuals_refuse_a_buehler_clock_run(bags) -> None:
    """An EduBot run against the servo bench 'missed supply_resistance' with a 106 A
    electronics current (exit 0)."""
    with pytest.raises(R.ResidualDataError, match='Buehler clock.*residuals --slip'):
        R.run_energy_loop([bags['bench']], [bags['edubot']], None)


def test_energy_on_a_rhex_run_gives_effort_p_out_and_no_servo_prediction(bags, tmp_path):
    """The hip torques (net / positive joint power 0.91) were refused as 'AX-series PWM load'
    and the AntBot leg's Eq. 6 model gave P_out 0 W and efficiency 0; the run was predicted at
    62.8 W by the servo bench for 34.5 W measured (82 % 'prediction error')."""
    out = tmp_path / 'out'
    assert energy_main(['--bench', str(bags['bench']), '--robot', str(bags['edubot']),
                        '--robot-mass', '3.31', '--out', str(out), '--no-progress']) == 0
    doc = json.loads((out / 'energy.json').read_text())
    [run] = doc['robot_runs']
    assert run['gait'] == 'buehler' and run['predicted_power_in_w'] is None
    assert run['power_out_source'] == 'effort' and run['power_out_w'] > 5.0
    assert 0.1 < run['efficiency'] < 0.6
    assert any('Buehler clock' in n for n in run['notes'])
    assert not any('PWM' in w for w in doc.get('warnings', []))


def test_the_driver_params_file_finds_its_joint_map_from_anywhere(tmp_path, monkeypatch):
    """``dynamixel_driver --ros-args --params-file hexapod_bench_drivers/config/
    dynamixel_driver.yaml`` from the repository root stopped with 'joint map
    hexapod_ax18a_joints.yaml: cannot read': the name is resolved in the package's config/."""
    import yaml

    from hexapod_bench_drivers.dynamixel_bus import JointMapError, load_joint_map

    cfg = Path(__file__).resolve().parents[2] / 'hexapod_bench_drivers' / 'config'
    params = yaml.safe_load((cfg / 'dynamixel_driver.yaml').read_text())
    name = params['dynamixel_driver']['ros__parameters']['joints_file']
    monkeypatch.chdir(tmp_path)
    assert len(load_joint_map(name)) == 18
    (tmp_path / name).write_text('joints: {L1_coxa: {id: 7}}\n')   # a local file wins
    assert [j.servo_id for j in load_joint_map(name)] == [7]
    with pytest.raises(JointMapError, match='nosuch.yaml'):
        load_joint_map('nosuch.yaml')


def test_energy_clears_its_old_plots_from_a_reused_folder(bags, tmp_path):
    """An earlier --sweep's four-quadrant plots stayed in a re-used --out folder and
    report.html showed them beside the new energy.json; other files are left alone."""
    out = tmp_path / 'out'
    out.mkdir()
    for name in ('four_quadrant_duty_factor.png', 'four_quadrant_duty_factor.svg',
                 'power_map.png', 'notes.txt'):
        (out / name).write_text('old')
    assert energy_main(['--robot', str(bags['edubot']), '--robot-mass', '3.31', '--out',
                        str(out), '--no-progress']) == 0
    assert not (out / 'four_quadrant_duty_factor.png').exists()
    assert not (out / 'four_quadrant_duty_factor.svg').exists()
    assert not (out / 'power_map.png').exists()
    assert (out / 'notes.txt').read_text() == 'old'


def test_a_topic_mapping_that_matches_nothing_is_warned_about(bags, tmp_path, capsys):
    """``--namespace /antbot`` or ``--remap /lab/power:=...`` with a typo was silent."""
    from hexapod_common.analyze_cli import main as analyze_main

    args = ['energy', '--robot', str(bags['edubot']), '--robot-mass', '3.31', '--out',
            str(tmp_path / 'o'), '--no-progress']
    assert analyze_main(['--remap', '/lab/power:=/battery_state', '--namespace', '/antbot',
                         '--mocap-tf', 'world:base_link', *args]) == 0
    err = capsys.readouterr().err
    assert '--remap /lab/power:=/battery_state: no given bag has /lab/power' in err
    assert '--namespace /antbot: no topic of the given bags starts with /antbot/' in err
    assert '--mocap-tf world:base_link: no given bag has /tf' in err
    assert analyze_main(['--remap', '/mocap/body:=/mocap/body', *args]) == 0
    assert 'warning: --remap' not in capsys.readouterr().err


def test_a_refused_energy_run_leaves_no_empty_out_folder(bags, tmp_path, capsys):
    out = tmp_path / 'never'
    assert energy_main(['--robot', str(bags['bench']), '--out', str(out),
                        '--no-progress']) == 2
    assert 'single-leg bench bag' in capsys.readouterr().err
    assert not out.exists()


def test_a_global_option_after_the_command_name_says_where_it_goes(capsys):
    from hexapod_common.analyze_cli import main as analyze_main

    with pytest.raises(SystemExit) as exc:
        analyze_main(['energy', '--robot', 'r', '--remap', '/a:=/b', '--out', 'o'])
    assert exc.value.code == 2
    assert '--remap goes before the command name' in capsys.readouterr().err
