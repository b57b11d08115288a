"""Preprocessing (offset, world frame, sagittal state) and stance extraction on known data."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from hexapod_gait.buehler import BUEHLER_PRESETS
from slip_identification.errors import SlipDataError
from slip_identification.preprocess import (
    Box,
    check_straight,
    estimate_offset,
    fit_world_frame,
    permissible_mask,
    sagittal_state,
)
from slip_identification.stance import (
    best_shift,
    edges_from_target,
    open_stance_windows,
    single_tripod_stances,
    tripod_stance_windows,
)


def _rot(yaw: float, tilt: float) -> np.ndarray:
    cz, sz = math.cos(yaw), math.sin(yaw)
    cx, sx = math.cos(tilt), math.sin(tilt)
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    return rz @ rx


def test_offset_between_100hz_and_120hz_streams():
    rng = np.random.default_rng(0)
    f = 6.05  # stepping frequency [Hz]
    ta = np.arange(0, 6, 0.01)
    a = np.sin(2 * np.pi * f * ta) + 0.3 * np.sin(2 * np.pi * 2 * f * ta + 0.4)
    offset = 0.0237
    tb = np.arange(0.003, 6, 1 / 120)
    b = np.sin(2 * np.pi * f * (tb - offset)) + 0.3 * np.sin(2 * np.pi * 2 * f * (tb - offset)
                                                           + 0.4)
    b += rng.normal(0, 0.02, tb.size)
    assert estimate_offset(ta, a, tb, b, max_offset_s=0.06) == pytest.approx(offset, abs=1e-3)


def test_world_frame_recovers_misalignment_and_height():
    t = np.arange(0, 2.0, 1 / 120)
    x = 0.8 * t - 0.8
    z = 0.15 + 0.01 * np.sin(2 * np.pi * 6 * t)
    y = 0.003 * np.sin(2 * np.pi * 0.7 * t)
    p_world = np.column_stack([x, y, z])
    rot = _rot(math.radians(30.0), math.radians(3.0))
    shift = rot @ np.array([0.2, -0.1, 0.0])  # mocap origin on the floor
    p_mocap = p_world @ rot.T + shift
    box = Box((-0.7, -1.0, -0.5), (1.2, 1.0, 0.5))
    inside = permissible_mask(p_mocap, box)
    up = rot @ np.array([0.001, -0.001, 1.0])  # mean body z axis (small attitude bias)
    frame = fit_world_frame(p_mocap[inside], up_mocap=up)
    assert math.degrees(frame.tilt_rad) == pytest.approx(3.0, abs=0.5)
    assert math.degrees(frame.yaw_rad) == pytest.approx(30.0, abs=0.5)
    pw = frame.to_world(p_mocap[inside])
    assert_allclose(pw[:, 2].mean(), 0.15, atol=2e-3)
    assert pw[0, 0] == pytest.approx(0.0, abs=1e-9)  # origin where the COM enters the box
    assert np.all(np.diff(pw[:, 0]) > 0)  # x along the direction of travel
    assert check_straight(pw) < 0.01
    with pytest.raises(SlipDataError, match='not straight'):
        check_straight(pw + np.column_stack([0 * x[inside], 0.2 * x[inside], 0 * x[inside]]))


def test_sagittal_state_splits_at_gaps():
    t = np.arange(0, 1.0, 1 / 120)
    p = np.column_stack([0.5 * t, 0 * t, 0.15 + 0.01 * np.sin(2 * np.pi * 3 * t)])
    keep = (t < 0.4) | (t > 0.5)
    track = sagittal_state(t[keep], p[keep])
    mid = (track.t_s > 0.41) & (track.t_s < 0.49)
    assert np.all(track.segment[mid] == -1)
    ok = (track.t_s > 0.05) & (track.t_s < 0.35)
    assert_allclose(track.state[ok, 1], 0.5, atol=1e-6)
    assert_allclose(track.state[ok, 3], 0.01 * 2 * np.pi * 3 * np.cos(2 * np.pi * 3 * track.t_s[ok]),
                    atol=2e-3)
    *_, whole = track.window(0.3, 0.6)
    assert whole is False


def test_stance_extraction_recovers_shift_and_edges():
    clock = BUEHLER_PRESETS['jogging']
    t = np.arange(0.0, 4.0, 0.01)  # 100 Hz proprioception
    lag = 0.023
    # measured hip speed: the target delayed, low-pass filtered (a PD-tracked hip)
    fine = np.arange(-0.5, 4.0, 1e-4)
    target_fine = clock.target_speed(fine - lag, 'left')
    alpha = 1e-4 / 0.004
    filt = np.empty_like(target_fine)
    acc = target_fine[0]
    for i, v in enumerate(target_fine):
        acc += alpha * (v - acc)
        filt[i] = acc
    measured = np.interp(t, fine, filt)
    tau = best_shift(t, measured, lambda tt: clock.target_speed(tt, 'left'))
    assert tau == pytest.approx(lag + 0.004, abs=3e-3)  # delay + filter time constant
    shifted = clock.target_speed(np.arange(0.5, 3.5, 1e-3) - lag, 'left')
    td, lo = edges_from_target(np.arange(0.5, 3.5, 1e-3), shifted)
    windows = clock.stance_windows(0.5 - lag, 3.5 - lag, 'left') + lag
    got = tripod_stance_windows(td, lo)
    assert_allclose(got, windows[: len(got)], atol=1.5e-3)


def test_single_tripod_parts_of_overlapping_stances():
    w = {'left': np.array([[0.0, 0.7]]), 'right': np.array([[-0.5, 0.2], [0.5, 1.2]])}
    st = single_tripod_stances(w)
    left = [s for s in st if s.tripod == 'left']
    assert len(left) == 1
    assert (left[0].touchdown_s, left[0].liftoff_s) == pytest.approx((0.2, 0.5))


def test_a_stance_cut_by_the_end_of_the_data_still_ends_the_other_tripods_single_support():
    """A walk (duty factor above 0.5) at the end of the data (the online buffer's newest
    sample): the right tripod touched down at 0.5 s and has not lifted off. Whole windows only,
    the left stance [0, 0.7] counted as single support up to its lift-off (the online fitter
    published that, and later [0.2, 0.5] again); the open stance ends it at 0.5. Likewise a
    stance cut by the start of the data (the right tripod's lift-off at 0.2)."""
    td = {'left': np.array([0.0]), 'right': np.array([0.5])}
    lo = {'left': np.array([0.7]), 'right': np.array([0.2])}
    whole = {tp: tripod_stance_windows(td[tp], lo[tp]) for tp in td}
    opened = {tp: open_stance_windows(td[tp], lo[tp]) for tp in td}
    assert whole['right'].shape == (0, 2)
    assert_allclose(opened['right'], [[-np.inf, 0.2], [0.5, np.inf]])
    assert opened['left'].shape == (0, 2)
    st = single_tripod_stances(whole, open_windows=opened)
    assert [(s.tripod, s.touchdown_s, s.liftoff_s) for s in st] == [('left', 0.2, 0.5)]
    # what it was: the whole left stance
    assert [(s.touchdown_s, s.liftoff_s) for s in single_tripod_stances(whole)] == [(0.0, 0.7)]
    # one kind of edge only, or none
    assert_allclose(open_stance_windows([0.3], []), [[0.3, np.inf]])
    assert_allclose(open_stance_windows([], [0.3]), [[-np.inf, 0.3]])
    assert open_stance_windows([], []).shape == (0, 2)
    assert open_stance_windows([0.1, 0.5], [0.3, 0.7]).shape == (0, 2)


def test_clock_edges_from_100hz_commands_below_the_sample_spacing():
    """An outside review: the paper's clock edges sat halfway between the two 100 Hz command
    samples around each switch (up to 5 ms off; stance 160 or 170 ms for the clock's 162.5).
    A steady clock's edges now come from every cycle's brackets together (a vernier): within
    1 ms of the clock's own; a clock that changes speed keeps the sampled target."""
    from slip_identification.stance import steady_clock

    clock = BUEHLER_PRESETS['jogging']
    tc = np.arange(0.0, 12.0, 0.01)
    v = clock.target_speed(tc, 'left')
    fitted = steady_clock(tc, v)
    assert fitted is not None
    true = clock.stance_windows(0.0, 12.0, 'left')
    mid_td, mid_lo = edges_from_target(tc, v)
    for mid, col, kind in ((mid_td, 0, 'touchdown'), (mid_lo, 1, 'liftoff')):
        mid = mid[(mid > 0.5) & (mid < 11.5)]
        ref = true[:, col]
        old = np.array([np.min(np.abs(ref - g)) for g in mid])
        assert np.max(old) > 2e-3                                    # the old way
        new = fitted.snap(mid, kind, 0.005 + 1e-6)
        err = np.array([np.min(np.abs(ref - g)) for g in new])
        assert np.mean(new != mid) > 0.9 and np.max(err[new != mid]) < 1e-3, err
        assert np.median(err) < 0.3 * np.median(old)
    fine = np.arange(0.5, 11.5, 1e-3)
    assert np.mean(fitted.target(fine) != clock.target_speed(fine, 'left')) < 0.01
    # a clock that slows down halfway: no single period, None
    v2 = np.where(tc < 2.5, v, clock.target_speed(2.5 + 0.8 * (tc - 2.5), 'left'))
    assert steady_clock(tc, v2) is None


def test_clock_refinement_is_bounded_on_long_runs_and_safe_when_the_clock_changes():
    """A review of the vernier: one polygon over a whole run grew with the cube of its edges
    (a 300 s bag asked for 11 GiB), and a clock whose period changed by 0.5 % halfway was
    snapped onto one fitted clock (edges up to 7.3 ms off, the midpoints 4.9). Blocks of
    CLOCK_BLOCK_CYCLES cycles bound both."""
    import tracemalloc

    from slip_identification.stance import refine_clock_edges

    clock = BUEHLER_PRESETS['running']
    tc = np.arange(0.0, 300.0, 0.01)
    v = clock.target_speed(tc, 'left')
    td, lo = edges_from_target(tc, v)
    tracemalloc.start()
    new_td, _ = refine_clock_edges(tc, v, td, lo)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 50e6 and np.mean(new_td != td) > 0.5
    for f in (1.002, 1.005, 1.01):
        warp = np.where(tc[:1000] < 5.0, tc[:1000], 5.0 + f * (tc[:1000] - 5.0))
        vc = clock.target_speed(warp, 'left')
        fine = np.arange(0.0, 10.5, 1e-5)
        true_td, _ = edges_from_target(fine, clock.target_speed(
            np.where(fine < 5.0, fine, 5.0 + f * (fine - 5.0)), 'left'))
        mid, mlo = edges_from_target(tc[:1000], vc)
        got, _ = refine_clock_edges(tc[:1000], vc, mid, mlo)
        err = lambda e: max(np.min(np.abs(true_td - x)) for x in e[(e > 0.3) & (e < 9.7)])
        assert err(got) <= err(mid) + 1e-4, f
