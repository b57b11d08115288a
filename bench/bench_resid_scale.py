"""Residual windows of a long run: ``build_windows`` (windows grouped by one sort, each
window's means over its own samples) against the straightforward per-window implementation it
replaced (a mask over the whole run per window, and per column), measured in the same run on
the same synthetic runs; both tables are checked equal.

Run: ``.venv/bin/python bench/bench_resid_scale.py [minutes]`` (default 10 min of walking at
100 Hz: about 2,400 windows; the baseline takes most of the time).
"""

from __future__ import annotations

import math
import sys
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from hexapod_common.series import span_mean
from hexapod_energy import residuals as R
from hexapod_energy.effects_catalogue import WindowTable


def synthetic_run(minutes: float, *, rate_hz: float = 100.0, seed: int = 0) -> R.ResidualRun:
    """A tripod run of ``minutes`` at ``rate_hz`` with two speed changes and a standing part,
    noisy power, voltage and current, servo temperatures and predictions."""
    rng = np.random.default_rng(seed)
    n = int(minutes * 60.0 * rate_hz)
    t = np.arange(n) / rate_hz + 1e-4 * rng.standard_normal(n)
    t.sort()
    period = np.where(t < 0.4 * t[-1], 1.0, np.where(t < 0.8 * t[-1], 0.7, 0.0))
    phase = np.zeros(n)
    for i in range(1, n):
        phase[i] = (phase[i - 1] + (t[i] - t[i - 1]) / period[i]) % 1.0 if period[i] > 0 \
            else phase[i - 1]
    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    offsets = np.array([0.0, 0.5, 0.0, 0.5, 0.0, 0.5])
    in_stance = ((phase[:, None] - offsets[None, :]) % 1.0) < 0.5
    in_stance[period == 0] = True
    power = 30.0 + 5.0 * np.sin(2 * math.pi * phase) + rng.standard_normal(n)
    voltage = 11.1 - 0.05 * power / 11.1 + 0.01 * rng.standard_normal(n)
    current = power / voltage
    run = R.ResidualRun(
        name='synthetic', t_s=t, voltage_v=voltage, current_a=current, power_w=power,
        cycle_phase=phase, period_s=period, duty_factor=np.full(n, 0.5),
        step_length_m=np.full(n, 0.06), in_stance=in_stance, supporting=in_stance.sum(axis=1),
        temp_sum_c=18 * (30.0 + t / t[-1]), servo_count=18, leg_names=legs,
        phase_offsets=tuple(float(x) for x in offsets), gait='tripod')
    run.predicted_w = power + rng.standard_normal(n)
    return run


def build_windows_baseline(runs: Sequence[R.ResidualRun], *, temp_ref_c: float | None = None,
                           settle_s: float = 1.0) -> WindowTable:
    """The per-window implementation replaced (verbatim but for the module prefix): for every
    window a mask over the run, and every column masked and interpolated over the whole run."""
    cols: dict[str, list[Any]] = {k: [] for k in (
        'run', 't_s', 'duration_s', 'measured_w', 'predicted_w', 'step_frequency_hz',
        'speed_mps', 'current_sq_a2', 'temp_excess_k', 'stance_fraction')}
    extra: dict[str, list[float]] = {'supply_dv_v': [], 'supply_sat_v2': [],
                                     'saturated_drives': [], 'elapsed_energy_j': [],
                                     'temp_excess_mean_k': [], 'winding_excess_w': [],
                                     'duty_factor': [], 'step_length_m': []}
    with_slope = all(r.mass_slope_w_per_kg is not None for r in runs)
    if with_slope:
        extra['mass_slope_w_per_kg'] = []
    slope, se, v_lag = R._lagged_slope(runs)
    sat_counts = R.saturated_drive_count(runs)
    for ri, r in enumerate(runs):
        assert r.predicted_w is not None
        per = r.period_s
        jump = np.abs(np.diff(per)) > 0.02 * np.maximum(np.abs(per[1:]), 1e-9)
        jump |= (np.diff(r.duty_factor) != 0) | (np.diff(r.step_length_m) != 0)
        changed = np.flatnonzero(jump) + 1
        starts = np.concatenate([[r.t_s[0]], r.t_s[changed]])
        k = np.searchsorted(starts, r.t_s, side='right') - 1
        keep = r.t_s >= starts[k] + settle_s
        t = r.t_s[keep]
        walking = r.period_s[keep] > 0
        half = np.floor(r.cycle_phase[keep] * 2.0)
        wraps = np.concatenate([[0], np.cumsum((np.diff(half) != 0) |
                                               (np.diff(k[keep]) != 0))])
        label = np.where(walking, wraps, np.floor((t - t[0]) / 0.5) + 1e6) + k[keep] * 1e9
        _, inv, counts = np.unique(label, return_inverse=True, return_counts=True)
        dt = float(np.median(np.diff(t))) if t.size > 1 else 1.0
        span = np.where(walking, 0.5 * r.period_s[keep], 0.5)
        expected = np.maximum(span / max(dt, 1e-9), 1.0)
        full = counts[inv] >= 0.6 * np.minimum(expected, np.max(counts))
        ref = temp_ref_c if temp_ref_c is not None else \
            float(r.temp_sum_c[0] / max(r.servo_count, 1))
        texcess = r.temp_sum_c - r.servo_count * ref
        per = np.where(r.period_s > 0, r.period_s, np.inf)
        freq = np.where(r.period_s > 0, 1.0 / per, 0.0)
        speed = np.where(r.period_s > 0, r.step_length_m / (r.duty_factor * per), 0.0)
        v_s = R.source_voltage_v(r, max(slope, 0.0), v_lag)
        sub = {
            'measured_w': r.power_w, 'predicted_w': r.predicted_w, 'step_frequency_hz': freq,
            'speed_mps': speed, 'current_sq_a2': r.current_a ** 2, 'temp_excess_k': texcess,
        }
        dt_mean = texcess / max(r.servo_count, 1)
        sub_extra = {'supply_dv_v': r.voltage_v - v_s,
                     'temp_excess_mean_k': dt_mean,
                     'winding_excess_w': dt_mean * r.predicted_w,
                     'supply_sat_v2': sat_counts[ri] * (r.voltage_v ** 2 - v_s ** 2),
                     'saturated_drives': sat_counts[ri],
                     'duty_factor': r.duty_factor, 'step_length_m': r.step_length_m,
                     'elapsed_energy_j': np.concatenate([[0.0], np.cumsum(
                         0.5 * (r.power_w[1:] + r.power_w[:-1]) * np.diff(r.t_s))])}
        if with_slope:
            sub_extra['mass_slope_w_per_kg'] = r.mass_slope_w_per_kg
        hu = np.full(t.size, np.nan)
        if np.any(walking):
            ph = r.cycle_phase[keep]
            wrap = np.concatenate([[0.0], np.cumsum(np.diff(ph) < -0.5)])
            hu = 2.0 * (ph + wrap)
            seg = k[keep]       # no exact span across a schedule change (as build_windows)
            border = np.flatnonzero(np.diff(seg) != 0)
            hu[border] = np.nan
            hu[border + 1] = np.nan
        for w in np.unique(inv[full]):
            m = inv == w
            m &= full
            tw = t[m]
            if tw.size < 3:
                continue
            idx = np.flatnonzero(m)
            span = R._half_cycle_span(t, hu, idx) if walking[idx[0]] else None
            cols['run'].append(ri)
            if span is None:
                cols['t_s'].append(float(tw.mean()))
                cols['duration_s'].append(float(tw[-1] - tw[0]))
                for k, arr in sub.items():
                    cols[k].append(float(np.mean(arr[keep][m])))
                for k, arr in sub_extra.items():
                    extra[k].append(float(np.mean(arr[keep][m])))
            else:
                ta, tb = span
                cols['t_s'].append(0.5 * (ta + tb))
                cols['duration_s'].append(tb - ta)
                for k, arr in sub.items():
                    cols[k].append(span_mean(t, np.asarray(arr)[keep], ta, tb))
                for k, arr in sub_extra.items():
                    extra[k].append(span_mean(t, np.broadcast_to(arr, r.t_s.shape)[keep],
                                                 ta, tb))
            cols['stance_fraction'].append(r.in_stance[keep][m].mean(axis=0))
    if not cols['run']:
        raise R.ResidualDataError('robot bags give no complete half-cycle window after the '
                                  f'first {settle_s} s; record longer runs')
    arrays = {k: np.array(v) for k, v in cols.items()}
    arrays['run'] = arrays['run'].astype(int)
    return WindowTable(**arrays, leg_names=runs[0].leg_names, supply_slope_ohm=slope,
                       supply_slope_stderr_ohm=se,
                       extra={**{k: np.array(v) for k, v in extra.items()},
                              'windows_per_cycle': tuple(2 for _ in runs)})


def max_difference(a: WindowTable, b: WindowTable) -> float:
    """Largest absolute difference between two window tables (inf if their shapes or NaNs
    differ)."""
    worst = 0.0
    pairs = [(getattr(a, f), getattr(b, f)) for f in (
        'run', 't_s', 'duration_s', 'measured_w', 'predicted_w', 'step_frequency_hz',
        'speed_mps', 'current_sq_a2', 'temp_excess_k', 'stance_fraction')]
    if set(a.extra) != set(b.extra):
        return math.inf
    pairs += [(a.extra[k], b.extra[k]) for k in a.extra]
    for x, y in pairs:
        x, y = np.asarray(x, float), np.asarray(y, float)
        if x.shape != y.shape or not np.array_equal(np.isnan(x), np.isnan(y)):
            return math.inf
        both = ~np.isnan(x)
        if np.any(both):
            worst = max(worst, float(np.max(np.abs(x[both] - y[both]))))
    return worst


def main() -> None:
    minutes = float(sys.argv[1]) if len(sys.argv) > 1 else 10.0
    runs = [synthetic_run(minutes)]
    t0 = time.perf_counter()
    new = R.build_windows(runs)
    t_new = time.perf_counter() - t0
    t0 = time.perf_counter()
    old = build_windows_baseline(runs)
    t_old = time.perf_counter() - t0
    n = new.t_s.size
    print(f'{minutes:g} min at 100 Hz: {n} windows; build_windows {t_new:.3f} s '
          f'({n / t_new:,.0f} windows/s); per-window baseline {t_old:.2f} s '
          f'({n / t_old:,.0f} windows/s, {t_old / t_new:.0f}x); '
          f'largest difference {max_difference(new, old):.1e}')


if __name__ == '__main__':
    main()
