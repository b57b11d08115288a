"""`hexapod-analyze report DIR`: the energy runs as a table (one row per run or walking
schedule, extrapolated predictions starred), warnings listed, plots inline."""

from __future__ import annotations

import json

import pytest

from hexapod_common.report import write_report


def test_energy_runs_table_and_warnings(tmp_path):
    run = {'bag': '/data/sweep', 'gait': 'tripod', 'period_s': 1.0, 'speed': 0.2,
           'measured_power_in_w': 27.28, 'predicted_power_in_w': 27.93, 'power_out_w': 0.355,
           'efficiency': 0.013, 'specific_cost_of_transport': 61.7,
           'specific_resistance': 6.37, 'prediction_outside_bench': [],
           'segment': {'index': 0, 'of': 2}}
    slow = dict(run, period_s=3.0, segment={'index': 1, 'of': 2}, efficiency=None,
                prediction_outside_bench=["stance 1.5 s outside the bench's 0.167-1 s"])
    (tmp_path / 'energy.json').write_text(json.dumps({
        'robot_runs': [run, slow], 'prediction_error': {'rmse_w': 0.7},
        'warnings': ['/data/sweep: the Eq. 1 prediction extrapolates <the bench>']}))
    page = write_report(tmp_path).read_text()
    assert '<th>P_in [W]</th>' in page and '<td>sweep [1/2]</td>' in page
    assert '<td>27.28</td><td>27.93</td>' in page and '<td>1.30</td>' in page
    assert "title=\"stance 1.5 s outside the bench&#x27;s 0.167-1 s\">27.93*</td>" in page
    assert '<td>-</td>' in page                                   # efficiency unknown
    assert '<li>/data/sweep: the Eq. 1 prediction extrapolates &lt;the bench&gt;</li>' in page


def test_empty_folder_is_refused(tmp_path):
    with pytest.raises(FileNotFoundError, match='no \\*.json results'):
        write_report(tmp_path)
