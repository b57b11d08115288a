"""Gait benchmarks: figures against the paper and speed against a straightforward baseline.

Run: ``.venv/bin/python bench/bench_gait.py`` (a few seconds). Prints
1. maximum speeds under AntBot limits vs Brodoline et al. (Fig. 3A/3C, text);
2. exact L(t) profile vs sampling L(t) on a grid (time, error of the mean);
3. analytic vectorised inverse kinematics vs numerical IK (scipy least_squares) per point;
4. scheduler command tick (18 joints) steady and during a transition vs per-leg LegTrajectory.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.optimize import least_squares

from hexapod_gait.feasibility import max_speed_mps
from hexapod_gait.gait import make_gait
from hexapod_gait.kinematics import LegKinematics
from hexapod_gait.scheduler import GaitScheduler
from hexapod_gait.trajectory import LegTrajectory


def timeit(fn, repeat: int) -> float:
    t0 = time.perf_counter()
    for _ in range(repeat):
        fn()
    return (time.perf_counter() - t0) / repeat


def main() -> None:
    print('1. maximum speed [m/s], AntBot limits (swing 0.16 s, stance 0.15 s, 3 Hz)')
    for beta, step, paper in ((0.5, 0.10, 0.60), (0.6, 0.10, 0.42), (0.7, 0.10, 0.27),
                              (0.83, 0.10, 0.13), (0.5, 0.14, 0.84)):
        v = max_speed_mps(beta, step)
        print(f'   beta {beta:4.2f} step {step * 1e3:3.0f} mm: {v:.4f} (paper {paper:.2f}, '
              f'diff {v - paper:+.4f})')

    print('2. mean supporting legs, exact profile vs 10k-point sampling')
    rng = np.random.default_rng(0)
    gaits = [make_gait('custom', leg_count=6, duty_factor=b, phase_offsets=th)
             for b, th in zip(rng.uniform(0.1, 0.9, 200), rng.uniform(0, 1, (200, 6)))]
    t_exact = timeit(lambda: [g.mean_supporting_legs() for g in gaits], 3) / len(gaits)
    grid = np.linspace(0, 1, 10000, endpoint=False)
    t_sample = timeit(lambda: [g.supporting_legs(grid).mean() for g in gaits], 3) / len(gaits)
    err_exact = max(abs(g.mean_supporting_legs() - 6 * g.duty_factor) for g in gaits)
    err_sample = max(abs(g.supporting_legs(grid).mean() - 6 * g.duty_factor) for g in gaits)
    print(f'   exact: {t_exact * 1e6:7.1f} us/gait, max error {err_exact:.1e}')
    print(f'   sampled: {t_sample * 1e6:7.1f} us/gait, max error {err_sample:.1e}')
    print(f'   ratio sampled/exact time {t_sample / t_exact:.1f}x')

    print('3. inverse kinematics, analytic (vectorised) vs scipy least_squares')
    kin = LegKinematics()
    q = np.column_stack([rng.uniform(-1, 1, 2000), rng.uniform(-1, 1, 2000),
                         rng.uniform(-2.5, -0.3, 2000)])
    q = q[np.hypot(*kin.forward(q)[:, :2].T) > 0.08]  # tip in front of the coxa (R > 0)
    p = kin.forward(q)
    t_an = timeit(lambda: kin.inverse(p), 5) / len(p)
    err_an = np.abs(kin.inverse(p) - q).max()
    n_num = 100

    def numeric():
        out = []
        for target in p[:n_num]:
            sol = least_squares(lambda x: kin.forward(x)[0] - target, x0=[0.0, 0.3, -1.5],
                                xtol=1e-14, ftol=1e-14, gtol=1e-14)
            out.append(sol.x)
        return np.array(out)
    t0 = time.perf_counter()
    qn = numeric()
    t_num = (time.perf_counter() - t0) / n_num
    err_num = np.abs(qn - q[:n_num]).max()
    print(f'   analytic: {t_an * 1e6:7.2f} us/point, max |dq| {err_an:.1e} rad')
    print(f'   numeric: {t_num * 1e6:7.1f} us/point, max |dq| {err_num:.1e} rad '
          f'(branch not controlled)')
    print(f'   ratio numeric/analytic time {t_num / t_an:.0f}x')

    print('4. one 100 Hz command tick (6 legs, 18 joints)')
    g = make_gait('tripod', period_s=1.0)
    sched = GaitScheduler(g, 0.0)
    trajs = [LegTrajectory(g, i) for i in range(6)]
    ts = iter(np.arange(0, 1e4, 0.01))
    t_sched = timeit(lambda: sched.joint_targets(next(ts)), 300)
    t_legs = timeit(lambda: [tr.joints(next(ts)) for tr in trajs], 300)
    sched_tr = GaitScheduler(g, 0.0)
    sched_tr.set_gait(make_gait('wave', duty_factor=5 / 6, period_s=1.0), 0.0)
    sched_tr.transition_cycles = 1e6
    sched_tr.set_gait(make_gait('wave', duty_factor=5 / 6, period_s=1.0), 0.0)
    ts2 = iter(np.arange(0, 1e3, 0.01))
    t_trans = timeit(lambda: sched_tr.joint_targets(next(ts2)), 300)
    print(f'   scheduler steady: {t_sched * 1e6:7.1f} us; during transition: '
          f'{t_trans * 1e6:7.1f} us; 6 x LegTrajectory.joints: {t_legs * 1e6:7.1f} us')
    print(f'   ratio per-leg/scheduler {t_legs / t_sched:.1f}x; '
          f'CPU share at 100 Hz: {t_sched * 100 * 100:.1f}% steady, '
          f'{t_trans * 100 * 100:.1f}% in transition')


if __name__ == '__main__':
    main()
