"""Command-line values that cannot work, refused up front by the tools (an outside review, A8-A11,
B2-B8, C8, C15): ``hexapod-sim``, ``hexapod-demo``, ``bag_replay`` and ``bag_recorder`` exit 2
with one line on stderr naming the option and the reason, before simulating, starting a graph
or creating anything; a failed simulation leaves no half-written bag; SIGTERM stops a waiting
replay (exit 143)."""

from __future__ import annotations

import json
import os
import select
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from hexapod_bench_drivers import bench_sim, edubot_bag, robot_sim, sim_bag
from hexapod_bench_drivers.edubot_sim import simulate_edubot
from hexapod_bench_drivers.sim_cli import main as sim_main

BIN = Path(sys.executable).parent


def _one_error_line(capsys, *words: str) -> str:
    """The single stderr line of a refusal; it holds every one of ``words``."""
    captured = capsys.readouterr()
    lines = [ln for ln in captured.err.splitlines() if ln.strip()]
    assert len(lines) == 1, captured.err
    assert 'Traceback' not in lines[0] and 'error' in lines[0]
    for word in words:
        assert word in lines[0], lines[0]
    return lines[0]


@pytest.fixture
def no_simulation(monkeypatch):
    """The cases refused up front: simulating at all is a failure."""
    def refuse(*args, **kwargs):
        raise AssertionError('simulated before the arguments were checked')
    monkeypatch.setattr(robot_sim.RobotSimulator, '__init__', refuse)
    monkeypatch.setattr(bench_sim.BenchSimulator, 'run_plan', refuse)
    monkeypatch.setattr(edubot_bag, 'simulate_edubot', refuse)


# --------------------------------------------------------------------------------------------
# hexapod-sim
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('command,args,words', [
    # 1. EduBot effects beyond the physical range (exit 0 with negative battery power and
    #    227 m/s backwards before)
    ('edubot', ['--effect', 'hip_torque=1e9'], ['--effect', 'hip_torque', '4.41 N m']),
    ('edubot', ['--effect', 'hip_torque=100'], ['--effect', 'hip_torque', 'out of range']),
    ('edubot', ['--effect', 'leg_damping=1e9'], ['--effect', 'leg_damping', '100 N s/m']),
    ('edubot', ['--effect', 'time_offset=1e9'], ['--effect', 'time_offset']),
    # 2. runs of fewer than 2 samples (an empty bag with exit 0, or a numpy message)
    ('robot', ['--duration', '1e-9'], ['--duration', 'fewer than 2']),
    ('robot', ['--duration', '2', '--rate', '0.01'], ['--rate', 'fewer than 2']),
    ('bench', ['--duration', '0.001'], ['--duration', 'fewer than 2']),
    ('edubot', ['--duration', '1e-6'], ['--duration', 'fewer than 2 samples']),
    # 3. payloads, loads and frequencies the hardware cannot carry or walk
    ('robot', ['--payload', '1e9'], ['--payload', "10 x the robot's mass"]),
    ('bench', ['--loads', '1e9', '--frequencies', '1'], ['--loads', '5 kg']),
    ('bench', ['--loads', '0', '--frequencies', '1e9'],
     ['--frequencies', '1e+09 Hz', '--allow-infeasible']),
    ('bench', ['--loads', '0', '--frequencies', '0,1,8'], ['--frequencies', '8 Hz']),
    # 4. sizes that ran out of memory (an OOM kill, MemoryError tracebacks)
    ('robot', ['--legs', '1000000000'], ['--legs', 'from 2 to 64']),
    ('robot', ['--legs', '3'], ['--legs', 'even']),
    ('robot', ['--duration', '1e9'], ['--duration', '24 h']),
    ('robot', ['--rate', '1e9'], ['--rate', '10000 Hz']),
    ('robot', ['--duration', '80000'], ['--duration', 'more than 2e+06']),
    ('bench', ['--duration', '10000'], ['--duration', 'sessions', 'more than 2e+06']),
    ('edubot', ['--duration', '1e9'], ['--duration', '24 h']),
    ('edubot', ['--duration', '1000'], ['--duration', 'more than 600 s']),
    ('edubot', ['--runs', '1000000000'], ['--runs', 'from 1 to 1000']),
    # 5. a clock offset that overflowed the stamps (struct.error and a partial bag)
    ('robot', ['--effect', 'time_offset=1e9'], ['--effect', 'time_offset', '100000 s']),
    ('robot', ['--effect', 'sensor_latency=1e9'], ['--effect', 'sensor_latency']),
    # 6. a negative seed: numpy's message without the option
    ('robot', ['--seed', '-1'], ['--seed', '>= 0']),
    ('bench', ['--seed', '-1'], ['--seed']),
    ('edubot', ['--seed', '-1'], ['--seed']),
])
def test_sim_refuses_values_that_cannot_work(command, args, words, tmp_path, capsys,
                                             no_simulation):
    out = tmp_path / 'bag'
    argv = [command, '--out', str(out), *args]
    if command != 'edubot':
        argv.append('--no-progress')
    assert sim_main(argv) == 2
    _one_error_line(capsys, f'hexapod-sim {command}', *words)
    assert os.listdir(tmp_path) == []


def test_bench_allow_infeasible_simulates_far_beyond_the_limits_with_a_warning(
        tmp_path, capsys, no_simulation):
    # the paper's plan goes to 3.3 Hz, past the AX-18A's limits: a test rig walks it without
    # a word; 8 Hz (phases under half the limits) only when asked for, with a warning
    with pytest.raises(AssertionError, match='simulated'):
        sim_main(['bench', '--out', str(tmp_path / 'a'), '--loads', '0', '--frequencies',
                  '1,3.3', '--no-progress'])
    assert 'warning' not in capsys.readouterr().err
    with pytest.raises(AssertionError, match='simulated'):
        sim_main(['bench', '--out', str(tmp_path / 'b'), '--loads', '0', '--frequencies',
                  '1,8', '--allow-infeasible', '--no-progress'])
    err = capsys.readouterr().err
    assert 'warning' in err and '8 Hz' in err and '--allow-infeasible' in err
    assert '1 Hz' not in err


def test_edubot_summary_line_is_strict_json(tmp_path, capsys, monkeypatch):
    """A stalled run (no speed) printed ``"specific_resistance": Infinity``: not JSON."""
    def stalled(gait, **kwargs):
        run = simulate_edubot(gait, **kwargs)
        run.truth['summary'] = {'power_w': 150.0, 'speed_m_s': 0.0,
                                'specific_resistance': float('inf')}
        return run
    monkeypatch.setattr(edubot_bag, 'simulate_edubot', stalled)
    assert sim_main(['edubot', '--out', str(tmp_path / 'e'), '--duration', '0.3']) == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]

    def refuse(constant):
        raise ValueError(f'not strict JSON: {constant}')
    doc = json.loads(line, parse_constant=refuse)
    assert doc['specific_resistance'] is None and doc['power_w'] == 150.0


@pytest.mark.parametrize('error', [ValueError('disk says no'), RuntimeError('a bug')])
def test_a_failed_run_leaves_no_bag_behind(error, tmp_path, capsys, monkeypatch):
    """time_offset=1e9 died in the bag writer and left metadata.yaml and an 8 kB .mcap."""
    def half_written(trace, out, **kwargs):
        Path(out).mkdir(parents=True)
        (Path(out) / 'half.mcap').write_bytes(b'x' * 8192)
        raise error
    monkeypatch.setattr(sim_bag, 'write_trace', half_written)
    out = tmp_path / 'a' / 'bag'
    argv = ['robot', '--out', str(out), '--duration', '0.05', '--no-progress']
    if isinstance(error, ValueError):
        assert sim_main(argv) == 2
        _one_error_line(capsys, 'disk says no')
    else:
        with pytest.raises(RuntimeError, match='a bug'):   # a bug: traceback, exit 1
            sim_main(argv)
    assert os.listdir(tmp_path) == []


# --------------------------------------------------------------------------------------------
# hexapod-demo
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('args,words', [
    (['--speed', '0'], ['--speed', '> 0']),         # walked at 0.2 m/s while saying 0.0
    (['--speed', 'nan'], ['--speed']),              # ParameterError traceback, exit 1
    (['--speed=-1'], ['--speed']),
    (['--speed', '1e9'], ['--speed', 'infeasible', 'maximum speed is 0.6 m/s']),
    (['--speed', '0.01'], ['--speed', '--live-seconds', '2 cycles']),
    (['--live-seconds', '1e9'], ['--live-seconds', '600 s']),   # hung
    (['--live-seconds', '0'], ['--live-seconds']),              # exit 1 after the graph ran
    (['--live-seconds', 'nan'], ['--live-seconds']),
    (['--live-seconds=-5'], ['--live-seconds']),
    (['--hidden-effect', 'bogus=1'], ['--hidden-effect', 'bogus']),
    (['--hidden-effect', 'time_offset=1e9'], ['--hidden-effect', 'time_offset']),
])
def test_demo_refuses_options_before_the_graph_starts(args, words, tmp_path, capsys,
                                                      monkeypatch):
    from hexapod_common import demo

    def refuse(*a, **k):
        raise AssertionError('the live graph started before the options were checked')
    monkeypatch.setattr(demo, 'run_live', refuse)
    out = tmp_path / 'demo'
    assert demo.main(['--out', str(out), '--quick', *args]) == 2
    _one_error_line(capsys, 'hexapod-demo', *words)
    assert not out.exists()


def test_demo_refuses_an_out_that_is_a_file(tmp_path, capsys, monkeypatch):
    from hexapod_common import demo

    monkeypatch.setattr(demo, 'run_live', lambda *a, **k: pytest.fail('graph started'))
    (tmp_path / 'f').write_text('x')
    assert demo.main(['--out', str(tmp_path / 'f')]) == 2
    _one_error_line(capsys, '--out', 'is a file')


# --------------------------------------------------------------------------------------------
# bag_recorder
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('args,words', [
    (['--flush-period', 'nan'], ['--flush-period']),   # said parameter 'flush_period'
    (['--flush-period', '0'], ['--flush-period']),     # silently ignored
    (['--flush-period=-1'], ['--flush-period']),
])
def test_recorder_refuses_a_bad_flush_period_by_its_flag(args, words, tmp_path, capsys):
    from hexapod_common.recorder_node import main as recorder

    assert recorder(['-o', str(tmp_path / 'r'), *args]) == 2
    assert 'flush_period' not in _one_error_line(capsys, 'bag_recorder', *words)
    assert os.listdir(tmp_path) == []


def test_recorder_says_a_regular_file_is_a_file(tmp_path, capsys):
    from hexapod_common.recorder_node import main as recorder

    (tmp_path / 'afile').write_text('keep')
    assert recorder(['-o', str(tmp_path / 'afile')]) == 2
    line = _one_error_line(capsys, '-o', 'is a file', 'refusing to overwrite')
    assert 'existing bag' not in line
    assert (tmp_path / 'afile').read_text() == 'keep'


@pytest.mark.parametrize('where', ['under_a_file', 'proc'])
def test_recorder_refuses_an_output_it_cannot_create(where, tmp_path, capsys):
    """A folder that cannot be written gave a PermissionError traceback (exit 1)."""
    from hexapod_common.recorder_node import main as recorder

    if where == 'proc':
        if not os.path.isdir('/proc/self'):
            pytest.skip('needs Linux /proc')
        out = '/proc/nope/r'
    else:
        (tmp_path / 'afile').write_text('x')
        out = str(tmp_path / 'afile' / 'r')
    assert recorder(['-o', out]) == 2
    _one_error_line(capsys, 'bag_recorder', '-o', out)
    assert not os.path.exists(out)


# --------------------------------------------------------------------------------------------
# bag_replay
# --------------------------------------------------------------------------------------------
@pytest.mark.parametrize('rate', ['1e-6', '0.0005'])
def test_replay_refuses_a_rate_that_would_take_days(rate, tmp_path, capsys):
    from hexapod_common.replay_node import main as replay

    assert replay([str(tmp_path / 'bag'), '--rate', rate]) == 2
    _one_error_line(capsys, 'bag_replay', '--rate', '0.001')


@pytest.mark.timeout(60)
def test_replay_waiting_for_a_slow_message_reports_and_stops_on_sigterm(tmp_path, capsys):
    """``--rate 1e-6`` hung silently and ignored SIGTERM (SIGKILL needed). At the slowest rate
    allowed the next message of a 100 Hz bag is 10 s away: a progress line comes while it
    waits, and SIGTERM stops it at once with exit 143."""
    bag = tmp_path / 'bag'
    assert sim_main(['robot', '--out', str(bag), '--duration', '0.1', '--no-progress']) == 0
    capsys.readouterr()
    proc = subprocess.Popen([str(BIN / 'bag_replay'), str(bag), '--rate', '0.001',
                             '--progress-every', '0.1'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            env=dict(os.environ, PYTHONUNBUFFERED='1'))
    try:
        deadline = time.monotonic() + 30
        first = ''
        while not first and time.monotonic() < deadline and proc.poll() is None:
            ready, _, _ = select.select([proc.stderr], [], [], 0.5)
            if ready:
                line = proc.stderr.readline()
                # not rcl's warnings (ROS_LOCALHOST_ONLY is deprecated)
                first = line if 'bag_replay' in line or not line else ''
        assert 'next message is due in' in first, first
        proc.send_signal(signal.SIGTERM)
        out, err = proc.communicate(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 143, err
    assert 'Traceback' not in err
    assert 'stopped (SIGTERM)' in err.strip().splitlines()[-1]


@pytest.mark.timeout(90)
@pytest.mark.parametrize('signum, background', [(signal.SIGINT, True), (signal.SIGINT, False),
                                                (signal.SIGTERM, True)],
                         ids=['sigint-background', 'sigint-terminal', 'sigterm-background'])
def test_replay_stops_on_a_signal_in_the_middle_of_a_replay(tmp_path, signum, background):
    """``bag_replay`` started in the background of a script (SIGINT ignored at its start, as a
    shell does for ``cmd &``) and sent ``kill -INT`` exited 1 with a traceback, "publisher's
    context is invalid" (an outside review, 4 of 4 tries): rclpy's handler shut the context
    down under the replay. SIGINT now exits 130, in the background or not, and SIGTERM 143,
    each with one line saying how many messages went out, while messages are being sent at
    real time (SIGINT once said nothing)."""
    from hexapod_common.testbags import write_mixed_bag

    bag = tmp_path / 'bag'
    write_mixed_bag(bag, 3000, rate_hz=100.0)      # 10 s of bag, a message every 3.3 ms

    def ignore_sigint() -> None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)

    proc = subprocess.Popen([str(BIN / 'bag_replay'), str(bag), '--rate', '1',
                             '--progress-every', '0.1'], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=ignore_sigint if background else None,
                            env=dict(os.environ, PYTHONUNBUFFERED='1'))
    try:
        deadline = time.monotonic() + 30
        lines: list[str] = []
        # two progress lines: publishing at real time, well past its start
        while len(lines) < 2 and time.monotonic() < deadline and proc.poll() is None:
            ready, _, _ = select.select([proc.stderr], [], [], 0.5)
            if ready:
                line = proc.stderr.readline()
                if 'messages sent' in line:
                    lines.append(line)
        assert len(lines) == 2 and proc.poll() is None, lines
        proc.send_signal(signum)
        out, err = proc.communicate(timeout=20)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert 'Traceback' not in err, err
    assert 'replayed' not in out, out
    rest = [ln for ln in err.splitlines() if ln.strip() and 'messages sent' not in ln
            and '[rcl]' not in ln]
    name, code = ('SIGINT', 130) if signum == signal.SIGINT else ('SIGTERM', 143)
    assert proc.returncode == code, err
    assert len(rest) == 1 and f'bag_replay: stopped ({name}) after ' in rest[0], err
    sent = int(rest[0].split(' after ')[1].split()[0])
    assert 0 < sent < 3000, rest


def test_replay_names_a_bag_given_after_topics(tmp_path, capsys):
    """``bag_replay --topics /x BAG`` read 'the following arguments are required: bag' (the
    list takes every word after it): a review. Now it says the bag goes first."""
    from hexapod_common.replay_node import parse_args

    (tmp_path / 'bag').mkdir()
    with pytest.raises(SystemExit) as stop:
        parse_args(['--topics', '/x', str(tmp_path / 'bag')])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and 'the bag goes before --topics' in err
    with pytest.raises(SystemExit):
        parse_args(['--topics', '/x'])
    assert 'the following arguments are required: bag' in capsys.readouterr().err
    assert parse_args([str(tmp_path / 'bag'), '--topics', '/x']).topics == ['/x']


def test_analyze_names_a_command_option_given_before_the_command(capsys):
    """``hexapod-analyze --out o energy ...`` read "invalid choice: 'o'" (a review)."""
    from hexapod_common.analyze_cli import main as analyze

    with pytest.raises(SystemExit) as stop:
        analyze(['--out', 'o', 'energy', '--robot', 'r'])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and '--out is an option of the command' in err
