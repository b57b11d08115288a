"""Residual loop figures: per effect, held-out RMSE before/after and recovered vs simulated
parameter; time of the loop against the straightforward baseline (read the bags and compute
the Eq. 1 residual only), measured in the same run.

Run: ``.venv/bin/python bench/bench_resid.py`` (about a minute on one core).
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.effects import parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_energy import residuals as R
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag
from hexapod_energy.prediction import RobotSpec

CASES = [
    ([], None, None, None, (26, 26, 26)),
    (['kinematic_error=3'], 'kinematic_error', 'w_per_hz', 3.0, (26, 26, 26)),
    (['supply_resistance=0.3'], 'supply_resistance', 'resistance_ohm', 0.3, (26, 26, 26)),
    (['speed_friction=15'], 'speed_friction', 'c_n_s_per_m', 15.0, (26, 26, 26)),
    (['leg_anomaly=L2:2'], 'leg_anomaly', 'power_w', 2.0, (26, 26, 26)),
    (['thermal_drift=0.05'], 'thermal_drift', 'w_per_k', 0.05, (50, 26, 38)),
    (['kinematic_error=3', 'leg_anomaly=L2:2'], 'kinematic_error', 'w_per_hz', 3.0,
     (26, 26, 26)),
    (['basal_power=3'], 'basal_power', 'power_w', 3.0, (26, 26, 26)),
    (['time_offset=0.05'], 'time_offset', 'offset_s', 0.05, (26, 26, 26)),
]


def main() -> None:
    root = Path(tempfile.mkdtemp(prefix='bench_resid_'))
    plan = BenchPlan(loads_kg=(0.0, 0.187, 0.4, 0.6),
                     frequencies_hz=(0.0, 0.75, 1.25, 1.75, 2.25), walk_s=4.0)
    write_trace(simulate_bench(plan, seed=1), root / 'bench')
    model = R.fit_bench_model(bench_phase_samples(read_bench_bag(root / 'bench'))[0])
    tref = R._bench_temperature_c([root / 'bench'])
    spec = RobotSpec()
    print(f'{"effects":40s} {"added":38s} {"heldout before":>14s} {"after":>8s} '
          f'{"recovered":>10s} {"true":>6s} {"bias W":>7s} {"sample before":>13s} {"after":>6s}'
          f' {"runs out before":>15s} {"after":>6s}')
    t_loop = t_base = 0.0
    for effects, name, param, true, temps in CASES:
        bags = []
        for i, period in enumerate((1.0, 0.7, 0.5)):
            p = root / f'{"_".join(effects) or "clean"}_{i}'.replace(':', '').replace('=', '')
            cfg = RobotConfig(period_s=period, initial_temperature_c=temps[i])
            write_trace(simulate_robot(10.0, cfg, effects=parse_effects(effects), seed=10 + i),
                        p)
            bags.append(p)
        t0 = time.perf_counter()
        runs = [R.read_residual_run(p) for p in bags]
        for r in runs:
            R.predict_run_w(r, model, total_mass_kg=spec.mass_kg, leg_mass_kg=spec.leg_mass_kg)
        t_base += time.perf_counter() - t0
        t0 = time.perf_counter()
        runs = [R.read_residual_run(p) for p in bags]
        doc = R.energy_loop_from_runs(model, runs, None, temp_ref_c=tref)
        t_loop += time.perf_counter() - t0
        got = ''
        if name is not None:
            got = next(a for a in doc['added_params'] if a['name'] == name)['params'][param]
            got = f'{got:.4g}'
        h = doc['heldout']
        # leave-one-run-out (effects selected and fitted on the other runs; only when added)
        loro = doc.get('leave_one_run_out') or {}
        print(f'{" ".join(effects) or "(clean)":40s} {",".join(doc["effects_added"]) or "-":38s}'
              f' {h["rmse_before"]:14.3f} {h["rmse_after"]:8.3f} {got:>10s} '
              f'{"" if true is None else true:>6} {doc["baseline"]["bias"]:7.3f} '
              f'{doc["sample_view"]["heldout_rmse_before"]:13.3f} '
              f'{doc["sample_view"]["heldout_rmse_after"]:6.3f} '
              f'{loro.get("rmse_before", float("nan")):15.3f} '
              f'{loro.get("rmse_after", float("nan")):6.3f}')
    print(f'loop time {t_loop:.2f} s, baseline (read + Eq. 1 residual) {t_base:.2f} s, '
          f'ratio {t_loop / t_base:.2f}')


if __name__ == '__main__':
    main()
