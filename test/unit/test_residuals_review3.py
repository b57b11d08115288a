"""Residual loop, findings of a third outside review (blind injections): a realigned battery
stream is cut where it has no samples (not held)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.effects import parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy import residuals as R
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag

PERIODS_S = (1.0, 0.7, 0.5)
RUN_S = 10.0


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    path = tmp_path_factory.mktemp('bench') / 'bench'
    plan = BenchPlan(loads_kg=(0.0, 0.187, 0.4, 0.6),
                     frequencies_hz=(0.0, 0.75, 1.25, 1.75, 2.25), walk_s=4.0)
    write_trace(simulate_bench(plan, seed=1), path)
    samples, _ = bench_phase_samples(read_bench_bag(path))
    return {'model': R.fit_bench_model(samples), 'temp_ref_c': R._bench_temperature_c([path])}


def _bags(root: Path, effects: list[str]) -> list[Path]:
    root.mkdir(parents=True, exist_ok=True)
    out = []
    for i, period in enumerate(PERIODS_S):
        path = root / f'run{i}'
        write_trace(simulate_robot(RUN_S, RobotConfig(period_s=period),
                                   effects=parse_effects(effects), seed=10 + i), path)
        out.append(path)
    return out


@pytest.fixture(scope='module')
def basal_bags(tmp_path_factory):
    return _bags(tmp_path_factory.mktemp('basal'), ['basal_power=1'])


def _lagged(path: Path, lag_s: float) -> R.ResidualRun:
    """The run with its battery current delayed by ``lag_s`` (stamps and voltage kept, the
    first samples holding the first reading), as the review's rewrite of /battery_state."""
    r = R.read_residual_run(path)
    n = int(round(lag_s / float(np.median(np.diff(r.t_s)))))
    cur = np.empty_like(r.current_a)
    cur[n:], cur[:n] = r.current_a[:-n], r.current_a[0]
    r.current_a, r.power_w = cur, r.voltage_v * cur
    return r


def _loop(bench, runs, **kw) -> dict:
    return R.energy_loop_from_runs(bench['model'], runs, None, temp_ref_c=bench['temp_ref_c'],
                                   plots=False, **kw)


# --- 1: the realigned stream's ends ---------------------------------------------------------

def _synthetic_run(n: int = 200) -> R.ResidualRun:
    t = np.arange(n) * 0.01
    phase = t % 1.0
    stance = np.column_stack([phase < 0.5] * 3 + [phase >= 0.5] * 3)
    return R.ResidualRun(
        name='r', t_s=t, voltage_v=np.full(n, 12.0), current_a=t.copy(), power_w=12.0 * t,
        cycle_phase=phase, period_s=np.ones(n), duty_factor=np.full(n, 0.5),
        step_length_m=np.full(n, 0.1), in_stance=stance, supporting=np.full(n, 3),
        temp_sum_c=np.full(n, np.nan), servo_count=18, leg_names=tuple('ABCDEF'),
        phase_offsets=(0.0, 0.5, 0.0, 0.5, 0.0, 0.5), gait='tripod',
        predicted_w=np.full(n, 30.0), joint_t_s=t.copy(), joint_features=np.ones((n, 5)))


@pytest.mark.parametrize('offset_s', [0.15, -0.15])
def test_samples_shifted_beyond_the_battery_stream_are_dropped_not_held(offset_s):
    """np.interp held the last (first) battery sample over the run's last (first) 150 ms: the
    end window read +20 W / -27 W. Those samples are now cut from every per-sample array."""
    r = _synthetic_run()
    a = r.realigned(offset_s)
    assert a.t_s.size == r.t_s.size - 15
    for name in R.ResidualRun.PER_SAMPLE:
        x = getattr(a, name)
        if x is not None:
            assert len(x) == a.t_s.size, name
    # the power is the stream read at t + offset everywhere: no held (constant) stretch
    np.testing.assert_allclose(a.power_w, 12.0 * (a.t_s + offset_s), atol=1e-9)
    assert np.all(np.diff(a.power_w) > 0)
    assert a.lag_s == pytest.approx(-offset_s)
    assert a.joint_t_s is r.joint_t_s       # the joint stream is not on the battery stamps


def test_a_lag_beside_a_basal_power_both_found(bench, basal_bags):
    """150 ms current lag beside a real 1 W basal power (the review's b1lag case): the held
    tail inflated the windows' error (3.13 W) and basal_power was refused against it,
    'unexplained' instead. Now the lag is realigned, the error is the clean one's and the
    basal power is found."""
    doc = _loop(bench, [_lagged(p, 0.15) for p in basal_bags])
    assert doc['effects_added'][:1] == ['time_offset'], doc['summary']
    assert 'basal_power' in doc['effects_added'], doc['summary']
    p = next(a for a in doc['added_params'] if a['name'] == 'basal_power')['params']
    assert 0.75 <= p['power_w'] <= 1.15, doc['summary']
    assert doc['heldout']['rmse_before'] < 1.5, doc['heldout']
    assert doc['heldout']['rmse_after'] < 0.5, doc['heldout']
