"""One rule for motion-capture gaps: the pitch smoother and the output-error fit's window
pairs bridge what the SLIP track bridges (``preprocess.max_mocap_gap_s``: 30 ms, two missing
samples at 120 Hz, one at 60 Hz) and split at longer gaps only.

Before, each had its own rule: the pitch smoother split at a step over 1.5 sample intervals
(a piece shorter than its 9 samples stayed raw: 8 % of the pitch samples of a simulated 120 Hz
EduBot run with 10 % of its poses missing in pairs), and the output-error fit paired 0.1 s
windows only 1.5 sample intervals apart.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter

from slip_identification.geometry import _merge_groups, _smooth_segments

NOISE_RAD = 6e-4


def _pitch(rate_hz: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, a pitch-like truth (2.5 Hz stride, 2 degrees) and it with white noise."""
    t = np.arange(int(3 * rate_hz)) / rate_hz
    truth = 0.03 * np.sin(2 * np.pi * 2.5 * t) + 0.005 * np.sin(2 * np.pi * 5 * t + 1.0)
    return t, truth, truth + NOISE_RAD * np.random.default_rng(3).standard_normal(t.size)


def _holes(size: int, every: int, width: int) -> np.ndarray:
    """Mask of the samples kept: ``width`` missing every ``every`` samples."""
    keep = np.ones(size, dtype=bool)
    for a in range(every, size - every, every):
        keep[a:a + width] = False
    return keep


def _rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(x))))


@pytest.mark.parametrize('rate_hz,n,width,every', [(120.0, 9, 2, 8), (60.0, 5, 1, 5)])
def test_pitch_smoother_bridges_what_the_track_bridges(rate_hz, n, width, every) -> None:
    # pieces of 6 (120 Hz) and 4 (60 Hz) samples between the holes: shorter than the smoother,
    # so the old rule (split over 1.5 intervals) left nine in ten samples raw: RMS error 0.59
    # and 0.63 mrad against the clean run's 0.30 and 0.43 (now 0.35 and 0.49)
    t, truth, y = _pitch(rate_hz)
    clean = _smooth_segments(t, y, n)
    keep = _holes(t.size, every, width)
    got = _smooth_segments(t[keep], y[keep], n)
    assert np.count_nonzero(got == y[keep]) == 0          # every sample smoothed
    err_clean = _rms(clean - truth)
    err = _rms(got - truth[keep])
    assert err_clean < 0.75 * NOISE_RAD
    assert err < 1.25 * err_clean                         # was 1.5-2 times
    assert _rms(got - clean[keep]) < 0.45 * NOISE_RAD     # 0.20, 0.22 mrad (was 0.51, 0.45)


def test_pitch_smoother_splits_at_a_longer_gap_and_keeps_clean_data_as_it_was() -> None:
    t, _, y = _pitch(120.0)
    n = 9
    # clean (and jittered within 1.5 intervals) stamps: scipy's filter exactly, as before
    np.testing.assert_array_equal(_smooth_segments(t, y, n), savgol_filter(y, n, 2,
                                                                            mode='interp'))
    tj = t + np.random.default_rng(4).uniform(-1e-3, 1e-3, t.size)
    np.testing.assert_array_equal(_smooth_segments(tj, y, n), savgol_filter(y, n, 2,
                                                                             mode='interp'))
    # four missing samples (42 ms > 30 ms): two segments smoothed on their own
    keep = np.ones(t.size, dtype=bool)
    keep[150:154] = False
    got = _smooth_segments(t[keep], y[keep], n)
    np.testing.assert_array_equal(got[:150], savgol_filter(y[:150], n, 2, mode='interp'))
    np.testing.assert_array_equal(got[150:], savgol_filter(y[154:], n, 2, mode='interp'))


def test_output_error_windows_pair_across_a_bridged_gap_only() -> None:
    tm = np.arange(60) / 120.0
    masks = []
    for a in range(0, 48, 12):                      # four 0.1 s windows of 12 samples
        k = np.zeros(tm.size, dtype=bool)
        k[a:a + 12] = True
        masks.append(k)
    assert _merge_groups(tm, masks, 2) == [[0, 1], [2, 3]]
    # two samples missing where the first two windows meet (25 ms): still paired as clean
    two = masks[0].copy(), masks[1].copy()
    two[0][10:12] = False
    assert _merge_groups(tm, [two[0], two[1]] + masks[2:], 2) == [[0, 1], [2, 3]]
    # four missing (42 ms, the track splits there): not paired across it
    four = masks[0].copy(), masks[1].copy()
    four[0][10:12] = False
    four[1][12:14] = False
    assert _merge_groups(tm, [four[0], four[1]] + masks[2:], 2) == [[0], [1, 2], [3]]
