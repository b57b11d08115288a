"""``hexapod-sim``: a bad ``--out`` or number is refused in one line, exit 2, before simulating."""

from __future__ import annotations

import os

import pytest

from hexapod_bench_drivers import bench_sim, robot_sim
from hexapod_bench_drivers.sim_cli import main as cli_main

COMMANDS = ['robot', 'bench', 'edubot']


@pytest.fixture(autouse=True)
def _no_simulation(monkeypatch):
    """Every case here is refused up front: simulating at all is a failure."""
    def refuse(*args, **kwargs):
        raise AssertionError('simulated before the arguments were checked')
    monkeypatch.setattr(robot_sim.RobotSimulator, 'run', refuse)
    monkeypatch.setattr(bench_sim.BenchSimulator, 'run_plan', refuse)


def _one_error_line(capsys) -> str:
    captured = capsys.readouterr()
    lines = [ln for ln in captured.err.splitlines() if ln.strip()]
    assert len(lines) == 1, captured.err
    assert 'Traceback' not in lines[0] and 'error' in lines[0]
    assert captured.out == ''
    return lines[0]


@pytest.mark.parametrize('command', COMMANDS)
def test_an_existing_out_is_refused_by_name(command, tmp_path, capsys):
    out = tmp_path / 'bag'
    out.mkdir()
    (out / 'keep.txt').write_text('x')
    assert cli_main([command, '--out', str(out)]) == 2
    line = _one_error_line(capsys)
    assert str(out) in line and 'exists' in line
    assert (out / 'keep.txt').read_text() == 'x'


@pytest.mark.parametrize('command', COMMANDS)
def test_an_out_whose_parent_cannot_hold_a_folder_is_refused(command, tmp_path, capsys):
    if not os.path.isdir('/proc/self'):
        pytest.skip('needs Linux /proc')
    assert cli_main([command, '--out', '/proc/nope']) == 2
    assert '/proc/nope' in _one_error_line(capsys)
    assert not os.path.exists('/proc/nope')


@pytest.mark.parametrize('command', COMMANDS)
def test_an_out_under_a_file_is_refused(command, tmp_path, capsys):
    (tmp_path / 'file').write_text('x')
    out = tmp_path / 'file' / 'sub' / 'bag'
    assert cli_main([command, '--out', str(out)]) == 2
    assert 'not a folder' in _one_error_line(capsys)


def test_a_missing_parent_is_fine_and_nothing_is_left_behind(tmp_path, capsys):
    # the parent folders are created by the bag writer; the up-front check creates nothing
    out = tmp_path / 'a' / 'b' / 'bag'
    with pytest.raises(AssertionError, match='simulated'):
        cli_main(['robot', '--out', str(out), '--no-progress'])
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize('command,args,option', [
    ('robot', ['--speed', '-1'], '--speed'),
    ('robot', ['--speed', '0'], '--speed'),
    ('robot', ['--duration', '-1'], '--duration'),
    ('robot', ['--duration', 'nan'], '--duration'),
    ('robot', ['--rate', '0'], '--rate'),
    ('robot', ['--period', '-1'], '--period'),
    ('robot', ['--payload', '-0.5'], '--payload'),
    ('robot', ['--duty-factor', '1.5'], '--duty-factor'),
    ('robot', ['--step-height', 'inf'], '--step-height'),
    ('bench', ['--duration', '0'], '--duration'),
    ('bench', ['--max-cool', '-5'], '--max-cool'),
    ('bench', ['--loads', '0,-1'], '--loads'),
    ('bench', ['--frequencies', '1,nan'], '--frequencies'),
    ('bench', ['--rate', '-100'], '--rate'),
    ('edubot', ['--duration', '-1'], '--duration'),
])
def test_invalid_numbers_are_refused_in_one_line(command, args, option, tmp_path, capsys):
    out = tmp_path / 'bag'
    assert cli_main([command, '--out', str(out)] + args) == 2
    line = _one_error_line(capsys)
    assert option in line and f'hexapod-sim {command}' in line
    assert not out.exists()


@pytest.mark.parametrize('option, value', [('--ambient-c', '200'), ('--initial-temperature',
                                                                    '-1e3')])
def test_temperatures_out_of_range_are_refused(option, value, tmp_path, capsys):
    assert cli_main(['robot', '--out', str(tmp_path / 'b'), option, value]) == 2
    assert option in _one_error_line(capsys)


def test_a_warm_start_reaches_the_simulator(tmp_path, monkeypatch):
    """--ambient-c and --initial-temperature (a warm start, for thermal-drift studies: an
    outside review could not reproduce the benchmark's warm-start cases from the command
    line) set the robot's RobotConfig."""
    seen = {}

    def run(self, *args, **kwargs):
        seen['cfg'] = self.config
        raise SystemExit(0)
    monkeypatch.setattr(robot_sim.RobotSimulator, 'run', run)
    with pytest.raises(SystemExit):
        cli_main(['robot', '--out', str(tmp_path / 'b'), '--ambient-c', '20',
                  '--initial-temperature', '45', '--no-progress'])
    assert (seen['cfg'].ambient_temperature_c, seen['cfg'].initial_temperature_c) == (20, 45)
