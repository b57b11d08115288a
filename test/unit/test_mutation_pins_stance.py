"""Pins for stance extraction (slip_identification.stance) found missing by a mutation review:
each test fails on a one-line change that passed the suite."""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from slip_identification.stance import (
    SteadyClock,
    best_shift,
    longest_free_segment,
    single_tripod_stances,
    tripod_stance_windows,
)


def _square(t):
    """A two-speed target: slow (1 rad/s) for the first half of every 0.2 s cycle."""
    return np.where((np.asarray(t) % 0.2) < 0.1, 1.0, 5.0)


def test_shift_is_the_middle_of_the_shifts_the_samples_allow():
    """Samples 1 ms apart (at 0.4 ms past each ms) of a target delayed by 21.3 ms: every
    shift in (20.4, 21.4) ms reproduces them exactly (the cost is flat there). The middle,
    20.9 ms, is within half a sample spacing of any delay the data allow; the start of the
    flat minimum (what a mutant returned) is off by up to a whole spacing."""
    t = np.arange(0.0, 2.0, 1e-3) + 4e-4
    for lag, middle in ((0.0213, 0.0209), (0.0239, 0.0239), (0.0261, 0.0259)):
        tau = best_shift(t, _square(t - lag), _square)
        assert tau == pytest.approx(middle, abs=6e-5), lag
        assert abs(tau - lag) <= 0.5e-3 + 6e-5


def test_shift_is_never_negative():
    """The measured hip follows its command, it cannot lead it: the shift is searched in
    [0, max_shift_s] only. A measured speed that leads the target by 20 ms gives 0, not -20
    ms (allowing negative shifts moved every touchdown 20 ms early)."""
    t = np.arange(0.0, 2.0, 1e-3) + 4e-4
    tau = best_shift(t, _square(t + 0.02), _square)
    assert 0.0 <= tau <= 0.15
    assert tau == pytest.approx(0.0, abs=1e-3)


def test_a_touchdown_whose_lift_off_was_missed_is_not_paired_across_the_next_touchdown():
    """Touchdowns at 0 and 1 s, one lift-off at 1.5 s (the one after 0 s was missed): the
    stance is [1, 1.5]. Pairing 0 s with the next lift-off made a 1.5 s 'stance' spanning a
    whole swing and another stance."""
    got = tripod_stance_windows([0.0, 1.0], [1.5])
    assert_allclose(got, [[1.0, 1.5]])
    # a regular sequence pairs every touchdown
    assert_allclose(tripod_stance_windows([0.0, 1.0, 2.0], [0.4, 1.4, 2.4]),
                    [[0.0, 0.4], [1.0, 1.4], [2.0, 2.4]])


def test_the_longest_single_support_part_is_kept():
    """A stance [0, 1] with the other tripod down over [0.2, 0.3]: single support is
    [0, 0.2] and [0.3, 1]; the longest, [0.3, 1], is the stance fitted (the first free part
    kept a 0.2 s piece of a 0.7 s single support)."""
    assert longest_free_segment(0.0, 1.0, [[0.2, 0.3]]) == pytest.approx((0.3, 1.0))
    assert longest_free_segment(0.0, 1.0, [[0.7, 0.9]]) == pytest.approx((0.0, 0.7))
    w = {'left': np.array([[0.0, 1.0]]), 'right': np.array([[0.2, 0.3]])}
    left = [s for s in single_tripod_stances(w) if s.tripod == 'left']
    assert [(s.touchdown_s, s.liftoff_s) for s in left] == [pytest.approx((0.3, 1.0))]


def test_an_edge_is_not_snapped_onto_a_loosely_pinned_clock():
    """SteadyClock.snap moves a sampled edge onto the clock's own only where the clock pins it
    tighter (half-range <= CLOCK_EDGE_GAIN x the sampled edge's half-width). A clock whose
    touchdown is known within +-4 ms only, against a sampled edge good to +-5 ms: the sampled
    edge is kept. Snapping anyway replaced a 3 ms-off-centre edge by a guess no better."""
    loose = SteadyClock(t_ref_s=0.0, touchdown_vertices=np.array([[-0.004, 0.2], [0.004, 0.2]]),
                        liftoff_vertices=np.array([[0.1, 0.2]]), slow=1.0, fast=5.0)
    assert_allclose(loose.snap([0.003, 0.203], 'touchdown', 0.005), [0.003, 0.203])
    # pinned within +-1 ms: snapped onto the middle of the clock's range
    tight = SteadyClock(t_ref_s=0.0, touchdown_vertices=np.array([[-0.001, 0.2], [0.001, 0.2]]),
                        liftoff_vertices=np.array([[0.1, 0.2]]), slow=1.0, fast=5.0)
    assert_allclose(tight.snap([0.003, 0.203], 'touchdown', 0.005), [0.0, 0.2], atol=1e-12)
    # off by more than the sampled edge's half-width: the clock changed, kept
    assert_allclose(tight.snap([0.007], 'touchdown', 0.005), [0.007])


def test_shift_is_the_middle_of_a_flat_bottom_wider_than_the_refinement():
    """A measured speed switching as sharply as its target, sampled at 100 Hz: every shift
    from 14.1 to 23.9 ms fits exactly. The middle, 19.0 ms, is within half a sample of the
    true 23.9 ms lag; refining only around the first 1 ms grid point of the flat bottom gave
    15.0 ms (an outside review)."""
    t = np.arange(0.0, 2.0, 0.01) + 0.004
    shift = best_shift(t, _square(t - 0.0239), _square)
    assert shift == pytest.approx(0.019, abs=2e-4)
