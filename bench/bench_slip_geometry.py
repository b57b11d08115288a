"""Benchmark: geometric stance edges, ground height and stream offset (geometry.py) on
simulated EduBot runs, against the proprioceptive baseline measured in the same run.

Per gait (running, jogging, pace, walk) and seed: the offset error [ms] and ground-height error
[mm] of the geometric fit (searched from 0 +- 60 ms, no prior offset; the ground's slope
fitted too; ``--refine``: the output-error refinement, the default, or ``none``), the share
of single-support stances (from the steady state on) whose touchdown and lift-off are both
within 5 ms of the simulator's truth, and the fit time; the baseline is the contact estimator
(effort onsets against body-height breaks), the paper's clock edges with the touchdown
refined to the effort onset (at the true offset), and the ground at the mocap origin (no
ground estimate). Prints the median absolute errors of both and their ratio.

Usage: ``python bench/bench_slip_geometry.py [--duration 4.5] [--seeds 1 2 3]
[--refine output|none] [--numpy-cost]`` (``--numpy-cost``: the fit's cost in numpy, as before
it was compiled, for the time per run against the compiled one)
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from hexapod_bench_drivers.edubot_sim import simulate_edubot_batch
from slip_identification.errors import SlipDataError
from slip_identification.geometry import (
    REFINE_MODES,
    LegGeometry,
    body_pitch_rad,
    fit_ground_offset,
    leg_contacts,
    single_support,
)
from slip_identification.pipeline import TRIPODS, _up_from_quats, analyze_run, run_data_from_sim
from slip_identification.preprocess import Box, fit_world_frame
from slip_identification.steady import steady_start_s

BOX = Box((-10.0, -10.0, -10.0), (10.0, 10.0, 10.0))


def _edge_share(windows: list[tuple[str, float, float]], truth: dict) -> float:
    ok = []
    for tripod, a, b in windows:
        tr = np.array(truth['single_support'][tripod])
        j = int(np.argmin(np.abs(tr[:, 0] - a)))
        ok.append(abs(a - tr[j, 0]) <= 5e-3 and abs(b - tr[j, 1]) <= 5e-3)
    return float(np.mean(ok)) if ok else float('nan')


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('--duration', type=float, default=4.5)
    ap.add_argument('--seeds', type=int, nargs='+', default=[1, 2, 3])
    ap.add_argument('--refine', choices=REFINE_MODES, default='output',
                    help='refinement of the ground and offset fit (geometry.py)')
    ap.add_argument('--numpy-cost', action='store_true',
                    help="the fit's cost and leg gaps in numpy instead of the compiled kernels "
                         '(geometry.COMPILED_COST)')
    args = ap.parse_args()
    if args.numpy_cost:
        from slip_identification import geometry
        geometry.COMPILED_COST = False
    rows = []
    for gait in ('running', 'jogging', 'pace', 'walk'):
        for run in simulate_edubot_batch(gait, duration_s=args.duration, seeds=args.seeds):
            off = run.truth['clock_offset_s']
            frame = fit_world_frame(run.mocap_position_m,
                                    up_mocap=_up_from_quats(run.mocap_quat_xyzw))
            pw = frame.to_world(run.mocap_position_m)
            ground = float(np.mean(pw[:, 2] - np.interp(run.mocap_t_s - off, run.fine_t_s,
                                                         run.fine_state[:, 2])))
            pitch = body_pitch_rad(frame.rotation, run.mocap_quat_xyzw)
            names = tuple(f'{leg}_hip' for leg in run.leg_names)
            geo_args = (LegGeometry.from_params(run.params), names, run.t_s,
                        run.hip_position_rad, run.hip_velocity_rad_s, run.mocap_t_s, pw[:, 2],
                        pitch)
            t0 = time.perf_counter()
            fit = fit_ground_offset(*geo_args, initial_offset_s=0.0, offset_range_s=0.06,
                                    x_m=pw[:, 0], refine=args.refine)
            contacts, unknown = leg_contacts(*geo_args, offset_s=fit.offset_s,
                                             ground_m=fit.ground_m, fit=fit, x_m=pw[:, 0])
            ss = single_support(contacts, TRIPODS, unknown)
            t_geo = time.perf_counter() - t0
            # steady state only (both estimators): the paper's runs
            t_steady = steady_start_s(run.mocap_t_s, pitch, run.clock.period_s) - off
            geo_edges = [(tp, a, b) for tp, iv in ss.items() for a, b in iv if a >= t_steady]
            # baseline, same run
            rd = run_data_from_sim(run)
            t0 = time.perf_counter()
            try:
                base_off = analyze_run(rd, box=BOX, offset_s='contact',
                                       position_fit=False).offset_s - off
            except SlipDataError:
                base_off = float('nan')
            t_base = time.perf_counter() - t0
            eff = analyze_run(rd, box=BOX, offset_s=off, position_fit=False, edges='effort')
            base_edges = [(f.tripod, f.touchdown_s, f.liftoff_s) for f in eff.fits
                          if f.touchdown_s >= t_steady]
            row = {
                'gait': gait, 'seed': run.seed,
                'geo_offset_ms': 1e3 * (fit.offset_s - off),
                'geo_ground_mm': 1e3 * (fit.ground_m - ground),
                'geo_edges': _edge_share(geo_edges, run.truth), 'geo_s': t_geo,
                'base_offset_ms': 1e3 * base_off, 'base_ground_mm': -1e3 * ground,
                'base_edges': _edge_share(base_edges, run.truth), 'base_s': t_base,
            }
            rows.append(row)
            print(f"{gait:8s} seed {run.seed}: geometry offset {row['geo_offset_ms']:+6.2f} ms, "
                  f"ground {row['geo_ground_mm']:+5.2f} mm, edges {row['geo_edges']:4.0%}, "
                  f"{t_geo:.2f} s | baseline offset {row['base_offset_ms']:+6.1f} ms, ground "
                  f"{row['base_ground_mm']:+5.1f} mm, edges {row['base_edges']:4.0%}, "
                  f'{t_base:.2f} s', flush=True)
    for key, unit in (('offset_ms', 'ms'), ('ground_mm', 'mm')):
        g = np.nanmedian(np.abs([r[f'geo_{key}'] for r in rows]))
        b = np.nanmedian(np.abs([r[f'base_{key}'] for r in rows]))
        print(f'median |{key}|: geometry {g:.2f} {unit}, baseline {b:.2f} {unit}; '
              f'RATIO baseline / geometry {b / g:.1f}x')
    g = np.nanmean([r['geo_edges'] for r in rows])
    b = np.nanmean([r['base_edges'] for r in rows])
    print(f'stances with both edges within 5 ms: geometry {g:.0%}, baseline {b:.0%}')
    print(f"time per run: geometry {np.mean([r['geo_s'] for r in rows]):.2f} s, baseline "
          f"(contact offset + pipeline) {np.mean([r['base_s'] for r in rows]):.2f} s")


if __name__ == '__main__':
    main()
