"""Input power over a run's time (hexapod_energy.trend): a run that heats up, sags or wears
draws a different power at its end than at its start on one schedule; energy.json used to
average it into one P_in without a word (an hour's simulated AntBot walk: 35.0 W at the start,
37.5 W after 30 min, one mean 37.1 W against a 35.1 W prediction)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexapod_energy.trend import (TREND_MIN_SPAN_S, TREND_MIN_WINDOWS, power_in_trend,
                                  trend_note)


def _windows(n: int, period_s: float = 0.7, t0: float = 1.7e9):
    t_end = t0 + period_s * np.arange(1, n + 1)
    return t_end, np.full(n, period_s)


def test_a_heating_run_is_a_drift_and_said() -> None:
    rng = np.random.default_rng(0)
    t_end, w = _windows(400)
    tau = 120.0
    p = 35.0 + 2.0 * (1 - np.exp(-(t_end - t_end[0]) / tau)) + rng.normal(0, 0.1, 400)
    tr = power_in_trend(t_end, w, p)
    assert tr is not None and tr['drift']
    assert tr['windows'] == 400 and tr['span_s'] == pytest.approx(280.0)
    assert len(tr['bin_power_in_w']) == len(tr['bin_time_s']) == 10
    assert tr['first_w'] < tr['last_w'] and tr['change_w'] > 1.0
    assert np.all(np.diff(tr['bin_time_s']) > 0) and 0 < tr['bin_time_s'][0] < 28.0
    # the noise estimate is the windows' spread, not the trend's
    assert tr['change_sigma_w'] == pytest.approx(np.sqrt(2) * 1.2533 * 0.1 / np.sqrt(40),
                                                 rel=0.25)
    note = trend_note(tr)
    assert note and 'rose' in note and 'thermal_drift' in note and '+' in note


def test_a_falling_run_is_said_to_fall() -> None:
    t_end, w = _windows(100)
    p = np.linspace(40.0, 37.0, 100)
    tr = power_in_trend(t_end, w, p)
    assert tr['drift'] and tr['change_w'] < 0
    assert 'fell' in trend_note(tr)


@pytest.mark.parametrize('case', ['flat_noise', 'glitches', 'small_trend', 'ripple'])
def test_no_false_drift(case) -> None:
    """Noise, isolated glitches, a change under 2 % and a slow cycle-to-cycle ripple are
    not a drift."""
    rng = np.random.default_rng(1)
    t_end, w = _windows(300)
    p = 35.0 + rng.normal(0, 0.3, 300)
    if case == 'glitches':
        p[[0, 1, 150, 298, 299]] += 30.0   # first and last windows too
    elif case == 'small_trend':
        p = 35.0 + np.linspace(0, 0.5, 300) + rng.normal(0, 0.01, 300)
    elif case == 'ripple':
        p = 35.0 + 0.5 * np.sin(2 * np.pi * np.arange(300) / 7.0)
    tr = power_in_trend(t_end, w, p)
    assert tr is not None and not tr['drift'], tr
    assert trend_note(tr) is None


def test_short_runs_get_no_trend_and_bad_input_is_refused() -> None:
    t_end, w = _windows(TREND_MIN_WINDOWS - 1)
    assert power_in_trend(t_end, w, np.linspace(30, 40, t_end.size)) is None
    # enough windows, too short a time
    n = TREND_MIN_WINDOWS + 5
    t_end, w = _windows(n, period_s=0.5 * TREND_MIN_SPAN_S / n)
    assert power_in_trend(t_end, w, np.linspace(30, 40, n)) is None
    # non-finite windows are left out, not counted
    t_end, w = _windows(60)
    p = np.linspace(30, 31, 60)
    p[::2] = np.nan
    assert power_in_trend(t_end, w, p)['windows'] == 30
    # out-of-order windows are sorted
    t_end, w = _windows(60)
    p = np.linspace(30, 40, 60)
    order = np.random.default_rng(2).permutation(60)
    assert power_in_trend(t_end[order], w, p[order])['change_w'] > 8.0
    with pytest.raises(ValueError, match='differ in shape'):
        power_in_trend(t_end, w[:-1], p)


@pytest.mark.timeout(120)
def test_energy_json_holds_the_trend_and_plots_it(tmp_path) -> None:
    """End to end: a simulated AntBot walk of 40 s with the thermal_drift effect (0.05 W per
    kelvin per servo) rises about 3 % on one schedule: the run's power_in_trend says so, a
    note and a warning name it, the plot is written; the same walk without the effect (its
    windings warm by a fraction of a kelvin) is no drift."""
    from hexapod_bench_drivers.effects import EffectSet
    from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
    from hexapod_bench_drivers.sim_bag import write_trace
    from hexapod_energy.cli import main

    docs = {}
    for name, eff in (('hot', EffectSet.defaults().with_effect('thermal_drift', 0.05)),
                      ('clean', EffectSet.defaults())):
        write_trace(simulate_robot(40.0, RobotConfig(speed_mps=0.3), effects=eff, seed=4),
                    tmp_path / name)
        out = tmp_path / f'out_{name}'
        assert main(['--robot', str(tmp_path / name), '--robot-mass', '2.183', '--out',
                     str(out), '--no-progress']) == 0
        docs[name] = json.loads((out / 'energy.json').read_text())
        assert 'power_in_over_time.png' in docs[name]['plots']
        assert (out / 'power_in_over_time.png').stat().st_size > 10_000
    hot = docs['hot']['robot_runs'][0]
    assert hot['power_in_trend']['drift']
    assert 0.015 < hot['power_in_trend']['change_fraction'] < 0.06
    assert any('input power rose over the run' in n for n in hot['notes'])
    assert any('input power rose over the run' in w for w in docs['hot']['warnings'])
    clean = docs['clean']['robot_runs'][0]
    assert clean['power_in_trend'] is not None and not clean['power_in_trend']['drift']
    assert not any('input power rose' in w for w in docs['clean'].get('warnings', []))
