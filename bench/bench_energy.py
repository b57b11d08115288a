"""Benchmarks of hexapod_energy: the 50 x 50 output power map (Fig. 7D) and the whole sweep set
(Fig. 3A-D), each against a straightforward baseline measured in the same run.

Baselines: the power map by one Pinocchio RNEA + Jacobian per (speed, payload, sample) instead of
one RNEA pass per phase sample reused through the 1/T^2 scaling; the sweeps as the same curves
evaluated one speed at a time.  Run: ``python bench/bench_energy.py``.
"""

from __future__ import annotations

import time

import numpy as np

from hexapod_energy.dynamics import mean_mechanical_power_w
from hexapod_energy.prediction import OutputPowerModel, carried_mass_profile_kg
from hexapod_energy.sweeps import STANDARD_SWEEPS, run_standard_sweeps
from hexapod_gait.gait import make_gait


class Phase:
    """Analytic single-leg phase powers (stands in for a bench fit)."""

    def p_stance_w(self, t, m):
        f = 1 / np.asarray(t)
        return 1.9 + 0.45 * f + 0.05 * f**2 + 2.0 * np.asarray(m) * (1 + 0.2 * f)

    def p_swing_w(self, t, m):
        f = 1 / np.asarray(t)
        return 1.9 + 0.5 * f + 0.06 * f**2 + 0 * np.asarray(m)


def baseline_map(opm: OutputPowerModel, gait, speeds, payloads) -> np.ndarray:
    """Direct RNEA with explicit tip force for every (speed, payload) on one leg x 6 (tripod)."""
    from hexapod_energy.prediction import phase_path

    phase, q, d1, d2, _ = phase_path(gait, n_samples=opm.n_samples)
    out = np.zeros((len(speeds), len(payloads)))
    for i, v in enumerate(speeds):
        period = gait.step_length_m / (gait.duty_factor * v)
        for j, m in enumerate(payloads):
            carried = carried_mass_profile_kg(gait, phase, total_mass_kg=2.183 + m,
                                              leg_mass_kg=opm.robot.leg_mass_kg)
            force = np.zeros((len(q), 3))
            # Eq. 4: the stance tip carries the leg's own weight too
            force[:, 2] = (carried[0] + opm.robot.leg_mass_kg * (carried[0] > 0)) * 9.81
            tau = opm.dynamics.inverse_dynamics(q, d1 / period, d2 / period**2, force)
            out[i, j] = gait.leg_count * mean_mechanical_power_w(tau * d1 / period)
    return out


def main() -> None:
    gait = make_gait('tripod', duty_factor=0.5, step_length_m=0.1)
    speeds = np.linspace(0.1, 0.6, 50)
    payloads = np.linspace(0.0, 0.5, 50)

    t0 = time.perf_counter()
    opm = OutputPowerModel()
    pm = opm.power_map_w(gait, speeds, payloads)
    cold = time.perf_counter() - t0
    reps = 5
    t0 = time.perf_counter()
    for _ in range(reps):
        pm = opm.power_map_w(gait, speeds, payloads)
    warm = (time.perf_counter() - t0) / reps

    sub_s, sub_p = speeds[::10], payloads[::10]  # 5 x 5 baseline, scaled to 50 x 50
    t0 = time.perf_counter()
    base = baseline_map(opm, gait, sub_s, sub_p)
    base_t = (time.perf_counter() - t0) * (50 * 50) / (len(sub_s) * len(sub_p))
    err = np.max(np.abs(base - pm[::10, ::10]) / np.abs(base))
    print(f'power map 50x50: {cold:.3f} s cold (model + leg path + RNEA), {warm:.3f} s warm; '
          f'baseline per-point RNEA {base_t:.2f} s (extrapolated from 5x5); '
          f'speed-up x{base_t / warm:.0f}; max relative difference {err:.1e}')
    print(f'  P_out at 0.1 m/s, 0 g: {pm[0, 0]:.3f} W; at 0.6 m/s, 0 g: {pm[-1, 0]:.3f} W; '
          f'at 0.6 m/s, 500 g: {pm[-1, -1]:.3f} W')

    n_curves = sum(len(v) for v in STANDARD_SWEEPS.values())
    t0 = time.perf_counter()
    curves = run_standard_sweeps(Phase(), OutputPowerModel(), n_speeds=40)
    sweep_t = time.perf_counter() - t0
    opm2 = OutputPowerModel()
    t0 = time.perf_counter()
    for name, specs in STANDARD_SWEEPS.items():
        for spec in specs[:1]:
            c = curves[name][0]
            g = make_gait(spec.gait, leg_count=spec.leg_count, duty_factor=spec.duty_factor,
                          step_length_m=spec.step_length_m)
            for v in c.speeds_mps:
                opm2.power_out_w(g.with_changes(period_s=spec.step_length_m /
                                                (spec.duty_factor * v)),
                                 payload_kg=np.array(c.payloads_kg))
    loop_t = (time.perf_counter() - t0) * n_curves / len(STANDARD_SWEEPS)
    print(f'sweep set ({n_curves} curves x 40 speeds x 6 payloads): {sweep_t:.3f} s; '
          f'speed-by-speed baseline {loop_t:.3f} s (P_out only, extrapolated); '
          f'ratio x{loop_t / sweep_t:.1f}')
    # the analytic Phase() has no bench step geometry: the limits are AntBot's on the 100 mm
    # path for every step; `energy --sweep` scales them by each step's tip path (140 mm:
    # 0.63 m/s, not the 0.84 printed here)
    print('  v_max below: AntBot\'s limits unscaled by step length (analytic phase model, no '
          'bench geometry; energy --sweep scales them per step)')
    for name, cs in curves.items():
        print('  ' + name + ': ' + '; '.join(
            f"{c.spec.label}: v_max {c.speeds_mps[-1]:.2f} m/s, min eta {c.min_efficiency:.3f}"
            for c in cs))


if __name__ == '__main__':
    main()
