"""Benchmark of the per-stance SLIP fit: batch throughput, online latency, ratio to baseline.

Prints stances per second of the fast fit (compiled Nelder-Mead per stance and start, the
default three starts, in parallel; and from the paper's start alone) on a
batch of synthetic running stances (120 Hz mocap + 0.2 mm noise, spline-resampled to 1 kHz),
the same for the straightforward baseline (scipy ``solve_ivp`` rtol 1e-10 + scipy Nelder-Mead,
stance by stance) measured in the same run on a subset, their ratio, the largest relative
difference of the SLIP-measure between the two, and the single-stance latency (online case).

Online: a simulated EduBot running run (mocap clock offset, noise, misalignment) is fed to
:class:`OnlineSlip` in arrival order; for each stance the publish latency is the data latency in
simulated time (newest mocap sample minus lift-off) plus the measured compute time of the step
that fitted it; the share within 20 ms is printed (acceptance: >= 95 %).

Usage: ``python bench/bench_slip.py [--distinct 60] [--copies 20] [--baseline 8]``
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from slip_identification import _kernels
from slip_identification.fit import SlipFitter, SlipPositionFitter
from slip_identification.synthetic import make_stances


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument('--distinct', type=int, default=60)
    ap.add_argument('--copies', type=int, default=20)
    ap.add_argument('--baseline', type=int, default=8)
    args = ap.parse_args()

    t = time.perf_counter()
    syn = make_stances(args.distinct, seed=42, sample_hz=120.0, noise_m=2e-4,
                       speed_mps=(0.6, 1.1))
    stances = [s.stance for s in syn]
    print(f'generated {len(stances)} distinct stances in {time.perf_counter() - t:.1f} s; '
          f'mean {np.mean([s.n_samples for s in stances]):.0f} samples at 1 kHz; '
          f'numba={_kernels.HAVE_NUMBA}')

    t = time.perf_counter()
    SlipFitter().fit(stances[:2])
    SlipFitter().fit(stances[:20])
    print(f'warm-up (compile or load cached kernels): {time.perf_counter() - t:.2f} s')

    batch = stances * args.copies
    t = time.perf_counter()
    fast = SlipFitter().fit(batch).results_
    dt_fast = time.perf_counter() - t
    rate_fast = len(batch) / dt_fast
    print(f'fast batch: {len(batch)} stances in {dt_fast:.2f} s = {rate_fast:.0f} stances/s '
          f'(with standard errors); converged {np.mean([r.converged for r in fast]):.3f}')

    t = time.perf_counter()
    SlipFitter(stderr=False).fit(batch)
    dt_ns = time.perf_counter() - t
    print(f'fast batch without standard errors: {len(batch) / dt_ns:.0f} stances/s')

    t = time.perf_counter()
    paper = SlipFitter(starts='paper').fit(batch).results_
    dt_p = time.perf_counter() - t
    lower = sum(a.nerr < b.nerr - 1e-6 for a, b in zip(fast, paper))
    print(f"fast batch from the paper's start alone: {len(batch) / dt_p:.0f} stances/s; the "
          f'three starts found a lower nerr on {lower} of {len(batch)}')

    lat = []
    for s in stances:
        t = time.perf_counter()
        SlipFitter().fit([s])
        lat.append(time.perf_counter() - t)
    lat_ms = 1e3 * np.array(lat)
    print(f'online single-stance fit latency: median {np.median(lat_ms):.2f} ms, '
          f'p95 {np.percentile(lat_ms, 95):.2f} ms, max {lat_ms.max():.2f} ms')

    sub = stances[: args.baseline]
    t = time.perf_counter()
    ref = SlipFitter(method='reference', stderr=False).fit(sub).results_
    dt_ref = time.perf_counter() - t
    rate_ref = len(sub) / dt_ref
    print(f'baseline solve_ivp + scipy Nelder-Mead: {len(sub)} stances in {dt_ref:.2f} s = '
          f'{rate_ref:.2f} stances/s')
    rel = [abs(a.nerr - b.nerr) / b.nerr for a, b in zip(fast[: len(sub)], ref)]
    print(f'SLIP-measure fast vs reference: max relative difference {max(rel):.2e}')
    print(f'RATIO fast / baseline throughput: {rate_fast / rate_ref:.0f}x')

    t = time.perf_counter()
    SlipPositionFitter().fit(stances)
    rate_pos = len(stances) / (time.perf_counter() - t)
    t = time.perf_counter()
    SlipPositionFitter(starts='paper').fit(stances)
    rate_pos1 = len(stances) / (time.perf_counter() - t)
    print(f'position estimator (initial state free): {rate_pos:.0f} stances/s from the '
          f'three starts, {rate_pos1:.0f} from the paper\'s start alone')
    online()


def online(duration_s: float = 6.0, seed: int = 3) -> None:
    """Publish latency of OnlineSlip on a simulated run (data latency + compute time)."""
    from hexapod_bench_drivers.edubot_sim import simulate_edubot

    from slip_identification.online import OnlineSlip
    from slip_identification.preprocess import Box

    run = simulate_edubot('running', duration_s=duration_s, seed=seed)
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    off = run.truth['clock_offset_s']
    ev = [(float(t), 0, i) for i, t in enumerate(run.t_s)]
    ev += [(float(t) - off, 1, i) for i, t in enumerate(run.mocap_t_s)]
    ev.sort()
    # first pass as a live slip_fitter starts: the kernels loaded by warm_up (the node calls
    # it at start), the rest cold; the second pass with every cache warm (the steady state)
    for rep, label in enumerate(('first pass after warm_up', 'second pass')):
        core = OnlineSlip(box=Box((-10.0,) * 3, (10.0,) * 3), mocap_offset_s=off)
        if rep == 0:
            print(f'online: warm_up at start {core.warm_up():.2f} s')
        compute_ms: list[float] = []
        nofit_ms: list[float] = []
        for _, kind, i in ev:
            if kind == 0:
                core.add_joint_state(float(run.t_s[i]), names, run.hip_velocity_rad_s[i])
                core.add_command(float(run.t_s[i]), names, run.target_velocity_rad_s[i])
                continue
            core.add_mocap(float(run.mocap_t_s[i]), run.mocap_position_m[i],
                           run.mocap_quat_xyzw[i])
            t = time.perf_counter()
            fits = core.step()
            dt_ms = 1e3 * (time.perf_counter() - t)
            if fits:
                compute_ms.extend([dt_ms] * len(fits))
            else:
                nofit_ms.append(dt_ms)
        data_ms = 1e3 * np.array(core.latency_s)
        comp = np.array(compute_ms)
        total = data_ms + comp
        print(f'online, {label}: {total.size} fits; step with a fit: compute median '
              f'{np.median(comp):.1f} ms, p95 {np.percentile(comp, 95):.1f} ms, first '
              f'{comp[0]:.1f} ms; step without: median {np.median(nofit_ms):.2f} ms, p95 '
              f'{np.percentile(nofit_ms, 95):.2f} ms')
        print(f'online publish latency, {label} (data {np.median(data_ms):.1f} ms median + '
              f'compute): median {np.median(total):.1f} ms, p95 {np.percentile(total, 95):.1f} '
              f'ms, max {total.max():.1f} ms; within 20 ms: {100 * np.mean(total <= 20.0):.0f} %')

if __name__ == '__main__':
    main()
