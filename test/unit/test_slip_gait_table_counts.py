"""slip.json ``gaits[]``: the stance counts are counts (JSON integers), not floats.

An outside review's client read ``gaits.<gait>.stances``, ``constant_force_stances`` and
``two_minima_stances`` as documented counts and got ``15.0``, ``0.0`` and ``8.0`` (floats),
while ``runs[].stances`` and residuals.json's ``stances.count`` are integers.
"""

from __future__ import annotations

import json

from slip_identification.energetics import gait_table

COUNT_KEYS = ('stances', 'constant_force_stances', 'two_minima_stances')


def _rows() -> list[dict[str, float | str]]:
    rows: list[dict[str, float | str]] = []
    for k in range(5):
        rows.append({'gait': 'walk', 'nerr': 0.1 + 0.01 * k, 'power_w': 18.0,
                     'speed_mps': 0.18, 'sr': 3.1, 'force_swing': 0.5 + 0.3 * k,
                     'other_nerr_ratio': 1.05 if k < 2 else 2.0,
                     'nerr_noise_floor': 0.05, 'stiffness': 400.0, 'rest_length': 0.2})
    return rows


def test_gait_table_counts_are_integers() -> None:
    table = gait_table(_rows())
    entry = table['walk']
    assert entry['stances'] == 5
    assert entry['constant_force_stances'] == 2     # force_swing 0.5, 0.8 under 1
    assert entry['two_minima_stances'] == 2
    for key in COUNT_KEYS:
        assert type(entry[key]) is int, (key, entry[key])
    # as a client reads it back from slip.json
    back = json.loads(json.dumps(table))['walk']
    for key in COUNT_KEYS:
        assert isinstance(back[key], int), (key, back[key])


def test_gait_table_statistics_stay_floats() -> None:
    entry = gait_table(_rows())['walk']
    for key in ('nerr_mean', 'nerr_std', 'power_w_mean', 'sr_mean', 'stiffness_median',
                'nerr_noise_floor_median'):
        assert isinstance(entry[key], float), key
