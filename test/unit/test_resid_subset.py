"""WindowTable.subset cuts every per-window array, those in ``extra`` included (the supply
model's per-window voltage deficit and saturation terms), and keeps run-level entries."""

from __future__ import annotations

import numpy as np

from hexapod_energy.effects_catalogue import WindowTable


def test_subset_cuts_per_window_extras() -> None:
    n = 5
    ar = np.arange(n, dtype=float)
    table = WindowTable(run=np.zeros(n, int), t_s=ar, duration_s=ar + 1, measured_w=ar,
                        predicted_w=ar, step_frequency_hz=ar, speed_mps=ar, current_sq_a2=ar,
                        temp_excess_k=ar, stance_fraction=np.ones((n, 6)), leg_names=('L1',),
                        extra={'supply_dv_v': 10 * ar, 'source_v': np.array([12.0, 11.9]),
                               'label': 'x'})
    mask = np.array([True, False, True, False, True])
    sub = table.subset(mask)
    np.testing.assert_array_equal(sub.extra['supply_dv_v'], [0.0, 20.0, 40.0])
    np.testing.assert_array_equal(sub.extra['source_v'], [12.0, 11.9])
    assert sub.extra['label'] == 'x' and sub.stance_fraction.shape == (3, 6)
