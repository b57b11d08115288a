"""One rule for motion-capture gaps: the pitch smoother, the contact and joint-offset windows
and the output-error fit's window pairs bridge what the SLIP track bridges
(``preprocess.max_mocap_gap_s``: 30 ms, two missing samples at 120 Hz, one at 60 Hz) and
split at longer gaps only.

Before, each had its own rule: the pitch smoother split at a step over 1.5 sample intervals
(a piece shorter than its 9 samples stayed raw: 8 % of the pitch samples of a simulated 120 Hz
EduBot run with 10 % of its poses missing in pairs), the contact and joint-offset fits dropped
a window with a step over 2.5 intervals (two missing samples at 120 Hz: 25 ms), and the
output-error fit paired 0.1 s windows only 1.5 intervals apart.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter

from slip_identification.contact import refine_contact_edges
from slip_identification.geometry import _merge_groups, _smooth_segments
from slip_identification.proprio_edges import _joint_cost

edubot_sim = pytest.importorskip('hexapod_bench_drivers.edubot_sim')

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


@pytest.fixture(scope='module')
def running_120hz():
    """A noise-free simulated running run's COM height at 120 Hz and its stances."""
    run = edubot_sim.simulate_edubot('running', duration_s=3.0, seed=1,
                                     effects={'mocap_noise': 0.0})
    t = np.arange(0.5, 2.95, 1 / 120.0)
    z = np.interp(t, run.fine_t_s, run.fine_state[:, 2])
    c = np.concatenate([np.array(run.truth['tripod_contact'][tp]) for tp in ('left', 'right')])
    c = c[np.argsort(c[:, 0])]
    c = c[(c[:, 0] > 1.6) & (c[:, 1] < 2.8)]
    return t, z, c


def test_contact_edges_refined_across_two_missing_samples(running_120hz) -> None:
    t, z, c = running_120hz
    start = c + np.random.default_rng(0).uniform(-0.01, 0.01, c.shape)
    clean, rms0 = refine_contact_edges(t, z, start)
    assert np.all(np.isfinite(rms0))
    # two samples (25 ms step) missing in the middle of every stance
    keep = np.ones(t.size, dtype=bool)
    for a, b in c:
        i = int(np.searchsorted(t, 0.5 * (a + b)))
        keep[i:i + 2] = False
    got, rms = refine_contact_edges(t[keep], z[keep], start)
    assert np.all(np.isfinite(rms))                 # was NaN: every stance kept its start
    assert np.max(np.abs(got - clean)) < 1e-3
    # three missing (33 ms): over the rule, the stance keeps its initial edges
    for a, b in c:
        i = int(np.searchsorted(t, 0.5 * (a + b)))
        keep[i + 2] = False
    got, rms = refine_contact_edges(t[keep], z[keep], start)
    assert np.all(np.isnan(rms))
    np.testing.assert_array_equal(got, start)


def test_joint_offset_keeps_the_stances_across_two_missing_samples(running_120hz) -> None:
    t, z, c = running_120hz
    td = c[:, 0]
    grid = np.arange(-0.003, 0.0031, 5e-4)
    lo_grid = np.arange(0.05, 0.1205, 1e-3)
    kw = dict(pre_s=0.03, post_frac=0.8, lo_grid_s=lo_grid, degree=3)
    cost0, used0 = _joint_cost(t, z, td, grid, 0.0, **kw)
    assert used0 >= 4
    keep = np.ones(t.size, dtype=bool)
    for a, b in c:
        i = int(np.searchsorted(t, 0.5 * (a + b)))
        keep[i:i + 2] = False
    cost, used = _joint_cost(t[keep], z[keep], td, grid, 0.0, **kw)
    assert used == used0                            # was 0
    # the same minimum (the true touchdowns: offset 0) within a grid step
    assert abs(grid[np.argmin(cost)] - grid[np.argmin(cost0)]) <= 5e-4


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
