"""build_windows is linear in the run's length and equals the per-window implementation it
replaced (kept as the baseline of bench/bench_resid_scale.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from hexapod_energy import residuals as R

_BENCH = Path(__file__).resolve().parents[2] / 'bench' / 'bench_resid_scale.py'


def _bench_module():
    spec = importlib.util.spec_from_file_location('bench_resid_scale', _BENCH)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_windows_equal_the_per_window_baseline():
    bench = _bench_module()
    runs = [bench.synthetic_run(1.5, seed=3), bench.synthetic_run(1.0, seed=4)]
    new = R.build_windows(runs, temp_ref_c=29.0)
    old = bench.build_windows_baseline(runs, temp_ref_c=29.0)
    assert new.t_s.size > 300
    # the thermal drift's reference extras are newer than the baseline (an outside review,
    # F1): the window sums of the servo temperatures follow temp_excess_k exactly
    ref = {k: new.extra.pop(k) for k in ('temp_sum_c', 'servo_count', 'temp_coldest_c',
                                         'temp_bench_c')}
    # so are the step geometry's phase-duration factors and the in-run battery voltage
    # (outside review G): 1 without a model's factors, the window means of |V|
    newer = {k: new.extra.pop(k) for k in ('stance_scale', 'swing_scale', 'voltage_v',
                                           'extra_stance_legs')}
    assert np.all(newer['stance_scale'] == 1.0) and np.all(newer['swing_scale'] == 1.0)
    assert np.all(newer['voltage_v'] > 0)
    # and the legs in stance beyond three (stance_preload): never negative, at most L - 3
    assert np.all(newer['extra_stance_legs'] >= 0)
    assert np.all(newer['extra_stance_legs'] <= runs[0].in_stance.shape[1] - 3)
    assert bench.max_difference(new, old) <= 1e-12
    assert ref['temp_bench_c'] == 29.0
    np.testing.assert_allclose(ref['temp_sum_c'] - ref['servo_count'] * 29.0,
                               new.temp_excess_k, atol=1e-9)
