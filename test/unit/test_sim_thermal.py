"""Thermal drift (Brodoline et al. Fig. 4C): 10 min at 3 Hz with 500 g raise P_in by 0.7-2.1 W."""

from __future__ import annotations

import pytest

from hexapod_bench_drivers.bench_sim import BenchConfig, BenchPlan, simulate_bench
from hexapod_bench_drivers.effects import EffectSet


@pytest.mark.timeout(300)
def test_ten_minutes_at_3_hz_with_500_g_raises_power_per_leg() -> None:
    # 50 Hz samples with 5 ms servo sub-steps: 1 % power accuracy, five times cheaper.
    tr = simulate_bench(BenchPlan(loads_kg=(0.5,), frequencies_hz=(3.0,), walk_s=600.0,
                                  max_cool_s=10.0),
                        BenchConfig(rate_hz=50.0, max_substep_s=5e-3), effects=EffectSet.none())
    start = [r for r in tr.sessions if r.state == 'walking'][0].t_s
    p = -tr.battery_voltage_v * tr.battery_current_a
    first = (tr.t_s > start + 2.0) & (tr.t_s < start + 12.0)
    last = (tr.t_s > start + 590.0) & (tr.t_s <= start + 600.0)
    rise_w = p[last].mean() - p[first].mean()
    assert 0.7 <= rise_w <= 2.1          # paper: about 1.4 W per leg
    hot = tr.true_temperature_c[last].mean(axis=0)
    assert hot.min() > 40.0 and hot.max() < 75.0     # hot but under the shutdown limit
    assert (tr.servo_error[last] == 0).all()
