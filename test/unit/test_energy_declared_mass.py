"""The robot mass a simulated bag declares, and the simulator's static support check.

``hexapod-sim robot --legs 4`` simulates AntBot's body with 4 legs (1.851 kg) and records the
mass in the bag's metadata (``hexapod_sim.config`` ``robot_mass_kg``); ``hexapod-analyze
energy`` and ``residuals`` replaced it by AntBot's six-leg 2.183 kg (energy with a warning,
residuals silently): CoT, CoT/M and specific resistance 15 % low. They now read it; bags of
different masses are refused rather than divided by one robot's mass.

``hexapod-sim robot --gait wave`` at the default duty factor 0.5 lifts every leg of a side at
once: ``gait_scheduler`` refuses it and energy calls the run infeasible, but the simulator
walked it without a word.
"""

from __future__ import annotations

import json

import pytest

G = 9.81


def _sim(tmp_path, name, capsys, *args):
    from hexapod_bench_drivers.sim_cli import main as sim_main

    rc = sim_main(['robot', '--out', str(tmp_path / name), '--duration', '4', '--no-progress',
                   '--speed', '0.1', *args])
    err = capsys.readouterr().err
    return rc, err


def _energy(tmp_path, capsys, out, *args):
    from hexapod_energy.cli import main as energy_main

    rc = energy_main(['--out', str(tmp_path / out), '--no-progress', *args])
    err = capsys.readouterr().err
    doc = json.loads((tmp_path / out / 'energy.json').read_text()) \
        if (tmp_path / out / 'energy.json').exists() else None
    return rc, err, doc


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    from hexapod_bench_drivers.sim_cli import main as sim_main

    d = tmp_path_factory.mktemp('declared_mass')
    for name, legs in (('four', '4'), ('six', '6')):
        assert sim_main(['robot', '--out', str(d / name), '--duration', '4', '--no-progress',
                         '--speed', '0.1', '--legs', legs, '--gait', 'alternating'
                         if legs == '4' else 'tripod']) == 0
    return d


def test_energy_reads_the_bags_declared_mass(bags, tmp_path, capsys) -> None:
    rc, err, doc = _energy(tmp_path, capsys, 'e4', '--robot', str(bags / 'four'))
    assert rc == 0, err
    assert doc['robot_mass']['source'] == "bags' metadata"
    assert doc['robot_mass']['kg'] == pytest.approx(1.851, abs=1e-3)
    assert 'from the bags\' metadata' in err
    assert not any('robot mass not given' in w for w in doc.get('warnings', []))
    run = doc['robot_runs'][0]
    # specific resistance = P_in / (m g v) with the declared mass (no payload)
    assert run['specific_resistance'] == pytest.approx(
        run['measured_power_in_w'] / (1.851 * G * run['speed']), rel=2e-3)


def test_robot_mass_option_overrides_the_metadata(bags, tmp_path, capsys) -> None:
    rc, err, doc = _energy(tmp_path, capsys, 'e4m', '--robot', str(bags / 'four'),
                           '--robot-mass', '2.0')
    assert rc == 0, err
    assert doc['robot_mass'] == {'kg': 2.0, 'source': '--robot-mass'}
    run = doc['robot_runs'][0]
    assert run['specific_resistance'] == pytest.approx(
        run['measured_power_in_w'] / (2.0 * G * run['speed']), rel=2e-3)


def test_bags_of_different_masses_are_refused(bags, tmp_path, capsys) -> None:
    rc, err, _ = _energy(tmp_path, capsys, 'emix', '--robot', str(bags / 'four'),
                         str(bags / 'six'))
    assert rc == 2
    assert 'declare different robot masses' in err and 'four 1.851 kg' in err \
        and 'six 2.183 kg' in err and '--robot-mass' in err
    rc, err, doc = _energy(tmp_path, capsys, 'emix2', '--robot', str(bags / 'four'),
                           str(bags / 'six'), '--robot-mass', '2.183')
    assert rc == 0, err
    assert len(doc['robot_runs']) == 2


def test_declared_mass_of_bags_without_one(bags, tmp_path) -> None:
    """A bag without the key (a recorded live run) declares nothing; beside a declaring
    one it is taken to be that robot, and said."""
    import shutil

    import yaml

    from hexapod_energy.bag_io import declared_robot_mass

    plain = tmp_path / 'plain'
    shutil.copytree(bags / 'six', plain)
    meta_path = plain / 'metadata.yaml'
    meta = yaml.safe_load(meta_path.read_text())
    meta['rosbag2_bagfile_information']['custom_data'] = None
    meta_path.write_text(yaml.safe_dump(meta))
    assert declared_robot_mass([plain]) == (None, '')
    kg, note = declared_robot_mass([bags / 'four', plain])
    assert kg == pytest.approx(1.851, abs=1e-3)
    assert '1 bag(s) declare none (plain)' in note
    # an unreadable path declares nothing (its reading says why later)
    assert declared_robot_mass([tmp_path / 'missing']) == (None, '')


def test_one_resolution_of_the_robot_mass(bags, tmp_path) -> None:
    """``energy`` and ``residuals`` take the mass from one rule (they had a copy each):
    given, else declared, else AntBot's, the one constant every module uses."""
    from hexapod_bench_drivers.robot_sim import RobotConfig
    from hexapod_energy import cli, energy_node, residuals
    from hexapod_energy.bag_io import resolve_robot_mass
    from hexapod_gait.kinematics import ANTBOT_MASS_KG

    given = resolve_robot_mass(3.0, [bags / 'four'])
    assert (given.kg, given.source, given.note, given.assumed) == (3.0, '--robot-mass', '',
                                                                   False)
    declared = resolve_robot_mass(None, [bags / 'four'])
    assert declared.kg == pytest.approx(1.851, abs=1e-3) and not declared.assumed
    assert declared.source == "bags' metadata" and 'robot_mass_kg' in declared.note
    for bag_list in ([], [tmp_path / 'missing']):
        assumed = resolve_robot_mass(None, bag_list)
        assert (assumed.kg, assumed.source, assumed.assumed) == (ANTBOT_MASS_KG,
                                                                 'assumed (AntBot)', True)
    assert ANTBOT_MASS_KG == 2.183 == RobotConfig.robot_mass_kg
    assert cli.ANTBOT_MASS_KG is energy_node.ANTBOT_MASS_KG is ANTBOT_MASS_KG
    assert residuals.run_energy_loop.__kwdefaults__['robot_mass_kg'] == ANTBOT_MASS_KG


def test_residuals_read_the_declared_mass(bags, tmp_path, capsys) -> None:
    from hexapod_energy.residuals_cli import main as residuals_main

    rc = residuals_main(['--bench', str(bags / 'six'), '--robot', str(bags / 'four'),
                         '--out', str(tmp_path / 'r'), '--no-progress', '--no-plots'])
    err = capsys.readouterr().err
    assert "robot mass 1.851 kg (payload excluded) from the bags' metadata" in err
    # the six-leg robot bag is no bench: refused (exit 2), after the mass was read
    assert rc == 2


def test_sim_refuses_a_side_in_swing_unless_allowed(tmp_path, capsys) -> None:
    rc, err = _sim(tmp_path, 'w4', capsys, '--legs', '4', '--gait', 'wave')
    assert rc == 2 and not (tmp_path / 'w4').exists()
    assert 'lifts every leg of side L/R at once' in err and '>= 0.75' in err \
        and '--allow-infeasible' in err
    rc, err = _sim(tmp_path, 'w6', capsys, '--gait', 'wave')
    assert rc == 2 and 'the wave walks at 1 - 1/n = 0.8333 on 6 legs' in err
    rc, err = _sim(tmp_path, 'w6ok', capsys, '--gait', 'wave', '--duty-factor', '0.8333')
    assert rc == 0, err
    rc, err = _sim(tmp_path, 'w4a', capsys, '--legs', '4', '--gait', 'wave',
                   '--allow-infeasible')
    assert rc == 0 and 'simulating an infeasible' in err and 'side L/R' in err


def test_energy_json_keeps_its_options_and_the_report_its_source(bags, tmp_path,
                                                                  capsys) -> None:
    """A review: report.html named the package versions alone (all 0.1.0) and nothing of
    the analysis' options; energy.json now keeps them and the report names the commit."""
    import subprocess
    from pathlib import Path

    from hexapod_common.report import _source_commit, write_report

    rc, err, doc = _energy(tmp_path, capsys, 'eo', '--robot', str(bags / 'four'),
                           '--current-sign', 'ros')
    assert rc == 0, err
    assert doc['options']['robot'] == [str(bags / 'four')]
    assert doc['options']['current_sign'] == 'ros' and doc['options']['robot_mass'] \
        == pytest.approx(1.851, abs=1e-3)
    html = write_report(tmp_path / 'eo').read_text()
    assert 'options' in html and 'robot_mass' in html
    here = Path(__file__).resolve().parent
    git = subprocess.run(['git', '-C', str(here), 'rev-parse', '--short', 'HEAD'],
                         capture_output=True, text=True)
    if git.returncode == 0:   # a git checkout (CI's clone): the report names its commit
        assert _source_commit().startswith(git.stdout.strip())
        assert f'source commit {git.stdout.strip()}' in html
