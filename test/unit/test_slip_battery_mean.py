"""The run's input power in `slip` is the time-weighted mean `energy` takes (trapezoid of V I
over the whole cycles, interpolated at their bounds), and a gap in /battery_state is said.

An outside review: `slip` took the plain mean of the battery samples in the cycles, which
weights the moments samples cluster at (up to 2.5 % with 10 or more samples a cycle), so the
same bag's SR differed between `slip` and `energy` when the samples came irregularly."""

from __future__ import annotations

import argparse
import json

import numpy as np
import pytest

from hexapod_common.series import span_mean
from hexapod_common.testbags import rewrite_bag
from hexapod_energy.cli import add_cli as add_energy_cli
from slip_identification.cli import add_cli as add_slip_cli
from slip_identification.energetics import battery_power_w

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')


def test_span_mean_is_exact_on_a_piecewise_linear_signal():
    t = np.array([0.0, 0.1, 0.15, 0.2, 1.0, 3.0])
    y = 2.0 + 5.0 * t
    # interpolated at bounds between samples; samples farther out change nothing
    assert span_mean(t, y, 0.12, 2.5) == pytest.approx(2.0 + 5.0 * (0.12 + 2.5) / 2, rel=1e-12)
    assert span_mean(t[:5], y[:5], 0.0, 1.0) == pytest.approx(4.5, rel=1e-12)
    with pytest.raises(ValueError, match='tb > ta'):
        span_mean(t, y, 1.0, 1.0)
    with pytest.raises(ValueError, match='as many stamps'):
        span_mean(t, y[:-1], 0.0, 1.0)


def test_clustered_samples_do_not_weight_the_moments_they_cluster_at():
    """A draw rising from 20 to 40 W over 10 s, sampled at 100 Hz for the first 2 s and 5 Hz
    after (a logger that flushes in bursts): 30 W. The plain mean read 23.7 W."""
    t = np.concatenate([np.arange(0.0, 2.0, 0.01), np.arange(2.0, 10.0 + 1e-9, 0.2)])
    volts = np.full(t.size, 12.0)
    amps = -(20.0 + 2.0 * t) / volts     # ROS convention: negative while discharging
    p, sign = battery_power_w(volts, amps, t_s=t, span_s=(0.0, 10.0))
    assert sign == 'ros' and p == pytest.approx(30.0, rel=1e-12)
    plain, _ = battery_power_w(volts, amps)
    assert abs(plain - 30.0) > 2.0       # what the plain mean gave
    # the sign is decided inside the span; stamps must match the samples
    with pytest.raises(Exception, match='differ in number'):
        battery_power_w(volts, amps, t_s=t[:-1])


def _run(add, argv):
    """The command ``argv`` through the subcommand ``add`` registers; its exit code. (The
    ``slip`` runs here go without figures, --no-plots: the tests read slip.json only.)"""
    parser = argparse.ArgumentParser()
    add(parser.add_subparsers(dest='command', required=True))
    args = parser.parse_args(argv)
    return args.func(args)


def _thinned(bag, dst, keep):
    """The bag with /battery_state messages kept where ``keep(t_s)`` is true."""
    def edit(topic, msg):
        if topic != '/battery_state':
            return None
        return bool(keep(msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec))
    return rewrite_bag(bag, dst, edit)


@pytest.fixture(scope='module')
def jog_bag(tmp_path_factory):
    return edubot_sim.write_edubot_bag(tmp_path_factory.mktemp('jog') / 'jog', 'jogging',
                                       duration_s=6.0, seed=3)


def test_slip_and_energy_give_one_sr_on_irregular_battery_samples(jog_bag, tmp_path):
    """Battery samples every 10 ms for 0.3 s, then every 40 ms for 0.2 s (a monitor whose
    reports bunch up): the same whole cycles, the same power. The plain mean read the slip
    run's SR 0.8 % off energy's (1.727 for 1.741)."""
    def keep(t):
        k = int(round(t * 100))
        return (k % 50) < 30 or k % 4 == 0
    bag = _thinned(jog_bag, tmp_path / 'irregular', keep)
    assert _run(add_slip_cli, ['slip', str(bag), '--out', str(tmp_path / 'slip'),
                               '--jobs', '1', '--no-plots']) == 0
    assert _run(add_energy_cli, ['energy', '--robot', str(bag), '--robot-mass', '3.31',
                                 '--out', str(tmp_path / 'energy'), '--no-progress']) == 0
    run = json.loads((tmp_path / 'slip' / 'slip.json').read_text())['runs'][0]
    robot = json.loads((tmp_path / 'energy' / 'energy.json').read_text())['robot_runs'][0]
    assert run['frame']['energetics']['whole_cycles'] >= 2
    assert run['sr'] == pytest.approx(robot['specific_resistance'], rel=2e-3)


def test_a_battery_gap_inside_the_cycles_is_said(jog_bag, tmp_path):
    bag = _thinned(jog_bag, tmp_path / 'gap', lambda t: not 2.0 <= t < 3.0)
    assert _run(add_slip_cli, ['slip', str(bag), '--out', str(tmp_path / 'slip'),
                               '--jobs', '1', '--no-plots']) == 0
    doc = json.loads((tmp_path / 'slip' / 'slip.json').read_text())
    notes = ' '.join(doc['runs'][0]['notes'])
    assert 'gap(s) in /battery_state' in notes and 'the longest 1.01 s' in notes


def test_the_robot_mass_assumed_is_said(jog_bag, tmp_path, capsys, monkeypatch):
    """``slip`` without --mass took EduBot's 3.31 kg without a word (SR, P and the Table 3
    comparison scale with it: an outside review). Now a warning in slip.json and on the
    terminal; with --mass none.

    Both runs analyse the bag with the same options (--mass 3.31 is the mass assumed): the
    bag is analysed once, each run given its own copy (the warnings are the command's)."""
    import copy

    import slip_identification.cli as slip_cli

    real, done = slip_cli.analyze_bag, {}

    def analyze_once(path, options):
        key = (path, json.dumps(options, sort_keys=True, default=repr))
        if key not in done:
            done[key] = real(path, options)
        return copy.deepcopy(done[key])

    monkeypatch.setattr(slip_cli, 'analyze_bag', analyze_once)
    assert _run(add_slip_cli, ['slip', str(jog_bag), '--out', str(tmp_path / 'a'),
                               '--no-plots']) == 0
    doc = json.loads((tmp_path / 'a' / 'slip.json').read_text())
    assert doc['mass_kg'] == pytest.approx(3.31)
    assert any('robot mass not given' in w for w in doc['warnings'])
    assert 'slip: warning: robot mass not given' in capsys.readouterr().err
    assert _run(add_slip_cli, ['slip', str(jog_bag), '--out', str(tmp_path / 'b'),
                               '--mass', '3.31', '--no-plots']) == 0
    assert json.loads((tmp_path / 'b' / 'slip.json').read_text())['warnings'] == []
