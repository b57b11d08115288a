"""hexapod-demo end to end (quick settings): live == replayed, analysis and report written."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest


@pytest.mark.timeout(420)
def test_demo_runs_end_to_end(tmp_path):
    out = tmp_path / 'demo'
    exe = Path(sys.executable).parent / 'hexapod-demo'
    proc = subprocess.run([str(exe), '--out', str(out), '--quick', '--live-seconds', '4'],
                          capture_output=True, text=True, timeout=400,
                          env=dict(os.environ, MPLBACKEND='Agg'))
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert 'Traceback' not in proc.stderr
    summary = json.loads((out / 'demo.json').read_text())
    live = summary['live']
    assert live['windows'] >= 2 and live['replayed'] >= live['windows']
    assert live['max_abs_difference'] <= 1e-9
    assert all(p > 5.0 for p in live['power_in_w'])
    batch = summary['batch']
    assert batch['prediction_error']['rmse_w'] > 0
    assert isinstance(batch['residuals'], dict), batch['residuals']
    # the hidden supply resistance is found alone (no stand-in effect added after it)
    assert batch['residuals']['effects_added'] == ['supply_resistance']
    # the same run without /gait/phase: cycles from the joints, the same input power
    lab = batch['other_lab']
    assert lab['cycle_source'] == 'joints'
    assert lab['period_s'] == pytest.approx(lab['reference_period_s'], rel=0.01)
    assert lab['power_in_w'] == pytest.approx(lab['reference_power_in_w'], rel=0.01)
    assert (out / 'report.html').stat().st_size > 10_000
    # the paper's figures are in the demo and its report (they were in neither): the four
    # four-quadrant sweeps, the power map and a recommendation at 0.26 m/s
    sweeps = batch['sweeps']
    assert set(sweeps['lowest_cot_per_mass']) == {'duty_factor', 'step_length', 'gait_type',
                                                  'leg_count'}
    assert sweeps['recommendation']['speed_mps'] == 0.26
    report = (out / 'report.html').read_text()
    for name in ('four_quadrant_duty_factor', 'four_quadrant_leg_count', 'power_map'):
        assert (out / 'energy' / f'{name}.png').is_file() and f'{name}.png' in report
    assert 'lowest CoT/M' in proc.stdout and 'recommendation at 0.26 m/s' in proc.stdout
    assert (out / 'residuals' / 'residuals.json').is_file()
    # SLIP step: quick settings simulate running and walk; the hidden 25 ms clock offset and
    # the ground height are found, and walking has the larger SLIP-measure (Table 3)
    slip = summary['slip']
    assert set(slip['gaits']) == {'running', 'walk'}
    for run in slip['runs']:
        assert abs(run['offset_s'] - run['true_offset_s']) < 0.005
        assert abs(run['ground_m'] - run['true_ground_m']) < 0.002
    assert slip['gaits']['walk']['nerr_mean'] > slip['gaits']['running']['nerr_mean']
    assert (out / 'slip' / 'slip.json').is_file()
