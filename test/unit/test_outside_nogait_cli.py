"""``hexapod-analyze energy --robot BAG`` on another lab's bag without ``/gait/phase``: the
run is analysed on joint-derived cycles; the prediction needs ``--gait --duty-factor
--step-length``; the speed falls back to ``--robot-speed``; every fallback is in the run's
``notes``."""

from __future__ import annotations

import json

import numpy as np
import pytest
from test_energy_cli import _write_bench, _write_robot
from test_outside_nogait_bag import simulated_run, write_lab_bag

from hexapod_energy.cli import main


@pytest.fixture(scope='module', autouse=True)
def bags_read_once():
    """Every run here reads the same bench bag (about 0.9 s each, a dozen times) and most
    read a lab bag another run read already: each read with the same arguments and the same
    hexapod-analyze settings (remaps, joint map) reads the bag once, every run given its own
    copy of the result."""
    import copy
    import os

    from hexapod_energy import bag_io

    def once(real):
        done = {}

        def read(path, *args, **kw):
            env = tuple(sorted((k, v) for k, v in os.environ.items()
                               if k.startswith('HEXAPOD')))
            key = (str(path), repr(args), repr(sorted(kw.items())), env)
            if key not in done:
                done[key] = real(path, *args, **kw)
            return copy.deepcopy(done[key])
        return read

    with pytest.MonkeyPatch.context() as mp:
        for name in ('read_bench_bag', 'read_robot_segments'):
            mp.setattr(bag_io, name, once(getattr(bag_io, name)))
        yield


@pytest.fixture(scope='module')
def trace():
    """The simulated 10 s tripod run the lab bags are written from."""
    return simulated_run(duration_s=10.0)


@pytest.fixture(scope='module')
def bags(tmp_path_factory, trace):
    root = tmp_path_factory.mktemp('nogait_cli')
    _write_bench(root / 'bench')
    _write_robot(root / 'robot_gait', 0.5)
    write_lab_bag(root / 'lab_odom', trace)
    write_lab_bag(root / 'lab_bare', trace, odom=False)
    return root


def _run(root, out, *extra):
    code = main(['--bench', str(root / 'bench'), '--robot', *extra, '--out', str(out),
                 '--no-progress'])
    assert code == 0
    return json.loads((out / 'energy.json').read_text())


def test_gait_given_gives_a_prediction(bags, tmp_path):
    doc = _run(bags, tmp_path / 'o', str(bags / 'lab_odom'), str(bags / 'robot_gait'),
               '--gait', 'tripod', '--duty-factor', '0.5', '--step-length', '0.1')
    lab, ref = doc['robot_runs']
    assert lab['cycle_source'] == 'joints' and ref['cycle_source'] == 'gait_phase'
    assert lab['gait'] == 'tripod' and lab['leg_count'] == 6
    np.testing.assert_allclose(lab['period_s'], 2 / 3, rtol=0.01)
    assert lab['predicted_power_in_w'] > 0 and lab['speed_source'] == 'odometry'
    np.testing.assert_allclose(lab['speed'], 0.3, rtol=0.02)
    # the simulated AX servos report PWM load as effort (never negative work): 'auto' refuses
    # it and, the gait being given, uses the inverse-dynamics model, with a warning
    assert lab['power_out_source'] == 'model'
    assert lab['power_out_effort_w'] > 3 * lab['power_out_model_w'] > 0
    assert any('never do negative work' in w for w in doc['warnings'])
    assert doc['prediction_error']['runs'] == 2
    assert any('as given' in n for n in lab['notes'])


def test_without_gait_no_prediction_and_given_speed(bags, tmp_path):
    doc = _run(bags, tmp_path / 'o', str(bags / 'lab_bare'), str(bags / 'robot_gait'),
               '--robot-speed', '0.25')
    lab, ref = doc['robot_runs']
    assert lab['predicted_power_in_w'] is None and lab['residual_w'] is None
    assert lab['gait'] is None and lab['leg_count'] == 6
    assert lab['speed'] == 0.25 and lab['speed_source'] == 'given'
    assert lab['specific_resistance'] > 0
    # its efforts are the simulated AX servos' PWM load (never negative work): refused, and
    # without a gait there is no model to fall back on, so P_out and efficiency are unknown
    assert lab['efficiency'] is None and lab['power_out_effort_w'] > 0
    assert any('never do negative work' in w for w in doc['warnings'])
    assert doc['prediction_error']['runs'] == 1  # the run with a prediction only
    notes = ' '.join(lab['notes'])
    assert 'no Eq. 1 prediction' in notes and 'no /gait/phase' in notes
    assert ref['speed'] == pytest.approx(0.4)  # gait runs keep the schedule's speed


def test_without_any_speed_source_nulls(bags, tmp_path):
    doc = _run(bags, tmp_path / 'o', str(bags / 'lab_bare'))
    lab = doc['robot_runs'][0]
    assert lab['speed'] is None and lab['specific_resistance'] is None
    assert lab['cost_of_transport'] is None and lab['measured_power_in_w'] > 0
    assert 'prediction_error' not in doc
    assert any('speed unknown' in n for n in lab['notes'])


def test_partial_gait_options_refused(bags, tmp_path, capsys):
    code = main(['--bench', str(bags / 'bench'), '--robot', str(bags / 'lab_bare'),
                 '--gait', 'tripod', '--out', str(tmp_path / 'o'), '--no-progress'])
    assert code == 2 and '--duty-factor' in capsys.readouterr().err


def test_joint_names_outside_the_contract_need_legs(bags, trace, tmp_path, capsys):
    """PhantomX-style names (``j_c1_lf``, ``j_thigh_lf``...) say nothing the contract can read
    about the leg count: with ``--gait`` the run is refused naming ``--legs``; with
    ``--legs 6`` it gets the same prediction as the contract-named twin (``lab_odom``, the
    same run with the contract's names; the bench is the module's)."""
    import dataclasses

    side = {'L': 'l', 'R': 'r'}
    where = {'1': 'f', '2': 'm', '3': 'r'}
    part = {'coxa': 'c1', 'femur': 'thigh', 'tibia': 'tibia'}
    names = tuple(f'j_{part[n.split("_")[1]]}_{side[n[0]]}{where[n[1]]}'
                  for n in trace.joint_names)
    write_lab_bag(tmp_path / 'phantomx', dataclasses.replace(trace, joint_names=names))
    gait = ['--gait', 'tripod', '--duty-factor', '0.5', '--step-length', '0.1']
    code = main(['--bench', str(bags / 'bench'), '--robot', str(tmp_path / 'phantomx'),
                 *gait, '--out', str(tmp_path / 'o'), '--no-progress'])
    err = capsys.readouterr().err
    assert code == 2 and '--legs' in err and 'j_c1_lf' in err
    doc = _run(bags, tmp_path / 'p', str(tmp_path / 'phantomx'),
               str(bags / 'lab_odom'), *gait, '--legs', '6')
    lab, ref = doc['robot_runs']
    assert lab['leg_count'] == ref['leg_count'] == 6
    np.testing.assert_allclose(lab['predicted_power_in_w'], ref['predicted_power_in_w'],
                               rtol=1e-9)
    assert any('given by --legs' in n for n in lab['notes'])
    # without --gait the names are not needed: measured descriptors, leg count unknown
    doc = _run(bags, tmp_path / 'q', str(tmp_path / 'phantomx'))
    assert doc['robot_runs'][0]['leg_count'] is None
    assert doc['robot_runs'][0]['measured_power_in_w'] > 0
    # or the names are mapped to the contract's (hexapod-analyze --joint-map): legs from names
    from hexapod_common.analyze_cli import main as analyze_main

    jmap = [f'{a}:={b}' for a, b in zip(names, trace.joint_names)]
    rc = analyze_main(['--joint-map', *jmap, 'energy', '--bench', str(bags / 'bench'),
                       '--robot', str(tmp_path / 'phantomx'), *gait, '--out',
                       str(tmp_path / 'r'), '--no-progress'])
    assert rc == 0
    mapped = json.loads((tmp_path / 'r' / 'energy.json').read_text())['robot_runs'][0]
    assert mapped['leg_count'] == 6
    np.testing.assert_allclose(mapped['predicted_power_in_w'], ref['predicted_power_in_w'],
                               rtol=1e-9)


def test_the_step_height_of_a_run_without_gait_phase(bags, tmp_path):
    """A review: a bag without /gait/phase had no way to give its lift, so a 60 mm lift was
    predicted at 40 mm in silence (-15 %). --step-height gives it (default the bench's,
    said in the run's notes) and robot_runs[] records it."""
    gait = ['--gait', 'tripod', '--duty-factor', '0.5', '--step-length', '0.1']
    doc = _run(bags, tmp_path / 'a', str(bags / 'lab_odom'), *gait)
    doc60 = _run(bags, tmp_path / 'b', str(bags / 'lab_odom'), *gait, '--step-height', '0.06')
    lab, lab60 = doc['robot_runs'][0], doc60['robot_runs'][0]
    assert lab['step_height_m'] == pytest.approx(0.04) and lab60['step_height_m'] == 0.06
    assert any("step height 0.04 m (the bench's)" in n for n in lab['notes'])
    assert lab60['predicted_power_in_w'] > 1.05 * lab['predicted_power_in_w']


def test_legs_against_the_joint_names_and_unreachable_steps_are_refused(bags, tmp_path,
                                                                         capsys):
    """An outside review: ``--legs 4`` on a bag whose contract joint names give 6 legs read
    it as a 4-leg robot (24.1 W predicted for 35.1 W), and ``--step-length 5`` was predicted
    like the bench's 0.1 m step; both exit 2 now, naming the flag."""
    base = ['--bench', str(bags / 'bench'), '--robot', str(bags / 'lab_odom'),
            '--out', str(tmp_path / 'o'), '--no-progress', '--gait', 'tripod',
            '--duty-factor', '0.5']
    assert main(base + ['--step-length', '0.1', '--legs', '4']) == 2
    assert '--legs 4, but the joint names' in capsys.readouterr().err
    assert main(base + ['--step-length', '5']) == 2
    assert "--step-length 5 m / --step-height 0.04 m: out of the leg's reach" in \
        capsys.readouterr().err


def test_a_model_output_above_the_input_is_not_an_efficiency(bags, tmp_path, monkeypatch):
    """A 1000 kg payload (or robot) made the Eq. 6 model's P_out exceed the measured P_in:
    efficiency 1.004 and a negative cost of transport, without a word (a payload over 10
    times the robot is refused now). P_out is unknown (null efficiency and costs), with a
    warning naming the mass. (``--robot-mass`` above 200 kg is refused as grams since an
    outside review; the limit is raised here to reach the guard, as a robot bag's declared
    mass still can.)"""
    from hexapod_energy import cli as energy_cli

    monkeypatch.setattr(energy_cli, 'ROBOT_MASS_MAX_KG', 1e4)
    doc = _run(bags, tmp_path / 'o', str(bags / 'robot_gait'), '--robot-mass', '3000')
    run = doc['robot_runs'][0]
    assert run['power_out_source'] == 'none'
    assert run['power_out_w'] is None and run['efficiency'] is None
    assert run['specific_cost_of_transport'] is None
    assert any('efficiency >= 1 is impossible' in w for w in doc['warnings'])


def test_tripod_given_for_four_legs_is_said_to_be_the_alternating_gait(tmp_path):
    """``--gait tripod`` on a 4-leg bag was silently walked as ``alternating`` while the note
    said "as given" (an outside review of other robots)."""
    write_lab_bag(tmp_path / 'quad', simulated_run(legs=4, gait='alternating', duration_s=10.0))
    code = main(['--robot', str(tmp_path / 'quad'), '--gait', 'tripod', '--duty-factor', '0.5',
                 '--step-length', '0.1', '--robot-mass', '1.851',
                 '--out', str(tmp_path / 'o'), '--no-progress'])
    assert code == 0
    run = json.loads((tmp_path / 'o' / 'energy.json').read_text())['robot_runs'][0]
    assert run['gait'] == 'alternating' and run['leg_count'] == 4
    assert any('--gait tripod on 4 legs: taken as the alternating gait' in n
               for n in run['notes'])
