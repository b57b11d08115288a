"""Benchmark: EduBot simulator speed (real-time factor) and bag writing.

Prints, per Table 1 gait, the real-time factor of ``simulate_edubot`` (numba-compiled step
loop, the default) and of the same step loop run as plain Python (the baseline), their ratio,
and the real-time factor of the whole batch path ``hexapod-sim edubot`` (simulate + write an
mcap bag). Run by hand: ``python bench/bench_edubot.py [--duration S]``.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from hexapod_bench_drivers import edubot_sim
from hexapod_bench_drivers.edubot_bag import write_run
from hexapod_bench_drivers.edubot_sim import EdubotParams, resolve_clock, simulate_edubot


def _time(fn, repeat: int = 3) -> float:
    best = float('inf')
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument('--duration', type=float, default=20.0, help='simulated seconds')
    args = parser.parse_args()
    dur = args.duration
    p = EdubotParams()
    # compile (or load the numba cache) and import the bag writer once, outside the timings
    with tempfile.TemporaryDirectory() as tmp:
        write_run(Path(tmp) / 'bag', simulate_edubot('pace', duration_s=1.0))
    print(f'EduBot simulator, {dur:g} s simulated per run, dt {p.dt_s * 1e3:g} ms')
    print(f'{"gait":8s} {"kernel RTF":>11s} {"python RTF":>11s} {"ratio":>7s} '
          f'{"sim+bag RTF":>12s}')
    for gait in ('running', 'jogging', 'pace', 'walk'):
        name, clock = resolve_clock(gait)
        n = int(round(dur / p.dt_s))
        gains = edubot_sim._gains(name, clock)
        t_fast = _time(lambda: edubot_sim._integrate(clock, gains, p, n, 0.0, 0.0, 1.0, 15.6))
        t_slow = _time(lambda: edubot_sim._integrate(clock, gains, p, n, 0.0, 0.0, 1.0, 15.6,
                                                     compiled=False), repeat=1)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            run = simulate_edubot(gait, duration_s=dur, seed=0)
            write_run(Path(tmp) / 'bag', run)
            t_bag = time.perf_counter() - t0
        print(f'{gait:8s} {dur / t_fast:10.0f}x {dur / t_slow:10.1f}x {t_slow / t_fast:6.0f}x '
              f'{dur / t_bag:11.1f}x')
    print('RTF = simulated seconds per wall-clock second (target for the batch: >= 20x)')


if __name__ == '__main__':
    main()
