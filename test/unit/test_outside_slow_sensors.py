"""Other labs' sensors: a slow battery monitor, a load cell that reports compression negative.

- A 1 Hz battery monitor (a fuel gauge) reporting current positive while discharging: the
  ``auto`` current sign used to wait for 20 samples, so a 12 s run gave no window at all
  ("no whole gait cycle with battery samples around it"). Three samples that agree now decide
  it; windows holding fewer than 4 battery samples carry a note (aliasing with the gait).
- A bench whose force sensor reports compression negative: the stance/swing split took the
  swing for the stance with no warning (stance power 2.18 W instead of 5.13 W on a simulated
  bench). The 0 Hz sessions against the walking ones under the same load decide the sign.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_energy_cli import _write_bench

from hexapod_common.bags import BagWriter, new_msg, stamp
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag, read_robot_bag
from hexapod_energy.descriptors import SLOW_BATTERY_NOTE


def _write_slow_battery_robot(path, *, period_s=0.5, duration_s=12.0, battery_hz=1.0,
                              power_w=30.0):
    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    with BagWriter(path) as w:
        every = int(round(100 / battery_hz))
        for k, t in enumerate(np.arange(0.0, duration_s, 0.01)):
            ns = int(round(t * 1e9))
            if k % every == 0:  # positive while discharging, as many fuel gauges report
                w.write('/battery_state', 'sensor_msgs/msg/BatteryState', new_msg(
                    'sensor_msgs/msg/BatteryState', header=stamp(ns), voltage=12.0,
                    current=power_w / 12.0), ns)
            w.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase', new_msg(
                'hexapod_interfaces/msg/GaitPhase', header=stamp(ns), gait='tripod',
                period=period_s, duty_factor=0.5, step_length=0.1, step_height=0.04,
                cycle_phase=(t / period_s) % 1.0, leg_names=list(legs),
                phase_offsets=[0.0, 0.5, 0.0, 0.5, 0.0, 0.5], in_stance=[True] * 6,
                supporting_legs=3), ns)


def test_one_hertz_battery_gives_windows_with_a_note(tmp_path):
    _write_slow_battery_robot(tmp_path / 'slow')
    run = read_robot_bag(tmp_path / 'slow', mass_kg=2.3, current_sign='auto')
    assert run.current_sign == 1.0                     # decided from 3 agreeing samples
    assert run.windows >= 18                            # 24 cycles, those after the 1st sample
    assert run.power_in_w == pytest.approx(30.0, rel=1e-9)
    assert any(n.startswith(SLOW_BATTERY_NOTE) for n in run.extra['notes'])
    # a 100 Hz monitor: no note
    _write_slow_battery_robot(tmp_path / 'fast', battery_hz=100.0)
    fast = read_robot_bag(tmp_path / 'fast', mass_kg=2.3, current_sign='auto')
    assert not any(n.startswith(SLOW_BATTERY_NOTE) for n in fast.extra['notes'])


@pytest.fixture(scope='module')
def bench(tmp_path_factory):
    root = tmp_path_factory.mktemp('bench')
    _write_bench(root / 'bench')
    return read_bench_bag(root / 'bench')


def _by_session(samples):
    return {s.session_id: s for s in samples}


@pytest.mark.parametrize('tare_n', [0.0, 12.0, -12.0])
def test_compression_negative_force_is_flipped(bench, tare_n):
    ref, ref_diag = bench_phase_samples(bench)
    assert ref_diag['force_sign'] == 1.0 and not ref_diag['notes']
    flipped = dataclasses.replace(bench, force_z_n=tare_n - bench.force_z_n)
    got, diag = bench_phase_samples(flipped)
    assert diag['force_sign'] == -1.0
    assert any('negative in compression' in n for n in diag['notes'])
    assert diag['force_offset_s'] == pytest.approx(ref_diag['force_offset_s'], abs=1e-9)
    a, b = _by_session(ref), _by_session(got)
    assert a.keys() == b.keys()
    for sid in a:
        assert b[sid].p_stance_w == pytest.approx(a[sid].p_stance_w, rel=1e-9, nan_ok=True)
        assert b[sid].p_swing_w == pytest.approx(a[sid].p_swing_w, rel=1e-9, nan_ok=True)
    # taken as recorded, the split is wrong: the walking sessions' stance power moves
    kept, _ = bench_phase_samples(flipped, force_sign='positive')
    k = _by_session(kept)
    walking = [sid for sid in a if a[sid].frequency_hz > 0]
    assert max(abs(k[sid].p_stance_w - a[sid].p_stance_w) for sid in walking) > 0.1
    # a tare on a correctly signed sensor changes nothing
    shifted, diag = bench_phase_samples(dataclasses.replace(bench,
                                                            force_z_n=bench.force_z_n + tare_n))
    assert diag['force_sign'] == 1.0


def test_force_sign_from_the_tip_without_a_static_session(bench):
    # no 0 Hz session to compare with: the tip decides (the force falls as the tip rises),
    # where the sign used to go unchecked (test_outside_bench_quirks.py)
    walking_only = dataclasses.replace(
        bench, sessions=[s for s in bench.sessions if s['frequency_hz'] > 0])
    _, diag = bench_phase_samples(walking_only)
    assert diag['force_sign'] == 1.0
    assert not any('force sign not checked' in n for n in diag['notes'])
    flipped = dataclasses.replace(walking_only, force_z_n=-walking_only.force_z_n)
    assert bench_phase_samples(flipped)[1]['force_sign'] == -1.0
    with pytest.raises(ValueError, match='force sign'):
        bench_phase_samples(bench, force_sign='up')


def test_leg_tip_in_millimetres_is_refused(bench):
    from hexapod_energy.errors import BagContentError

    mm = dataclasses.replace(bench, tip_z_m=1000.0 * bench.tip_z_m)
    with pytest.raises(BagContentError, match='millimetres'):
        bench_phase_samples(mm)
