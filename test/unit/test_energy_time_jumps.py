"""DescriptorAccumulator under a clock that goes back (looped bag, sim-time reset), with a
cycle source that stops, and with battery samples only: same windows per loop, bounded
buffers, one note per event."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.conversions import BatterySample, GaitPhaseSample, JointStateSample
from hexapod_energy.descriptors import DescriptorAccumulator

PERIOD_S = 0.5


def gait(t: float, t0: float = 0.0) -> GaitPhaseSample:
    return GaitPhaseSample(t, 'tripod', PERIOD_S, 0.5, 0.1, 0.04, 0.0, 0.0,
                           ((t - t0) / PERIOD_S) % 1.0, ('L1',), np.zeros(1),
                           np.ones(1, bool), 3)


def battery(t: float, t0: float = 0.0) -> BatterySample:
    p = 20.0 + 5.0 * np.sin(2 * np.pi * (t - t0) / PERIOD_S) + 2.0 * (t - t0)
    return BatterySample(t, 12.0, -p / 12.0, 25.0)


def joints(t: float) -> JointStateSample:
    return JointStateSample(t, ('a',), np.array([0.1 * t]), np.array([0.1]), np.array([2.0]))


def loop(acc: DescriptorAccumulator, t0: float, duration_s: float = 3.0,
         jitter: bool = False) -> list:
    """One pass of a bag starting at ``t0``: gait, battery and joints at 100 Hz."""
    out = []
    for k in range(int(round(duration_s / 0.01))):
        t = t0 + 0.01 * k
        # a few ms out of order between streams (recorders, two drivers)
        tb = t - 0.004 if jitter and k % 3 == 0 else t + 1e-4
        out += acc.add_gait_phase(gait(t, t0))
        out += acc.add_battery(battery(tb, t0))
        out += acc.add_joint_state(joints(t))
    return out


@pytest.mark.parametrize('sign', ['ros', 'auto'])
def test_each_loop_of_a_looped_bag_gives_the_same_windows(sign):
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign=sign)
    first = loop(acc, 100.0)
    assert len(first) == 4
    for n in range(1, 4):
        again = loop(acc, 100.0)
        assert [d.t_end_s for d in again] == [d.t_end_s for d in first]
        assert [d.power_in_w for d in again] == pytest.approx([d.power_in_w for d in first],
                                                              rel=1e-12)
        assert len(acc.time_jumps_) == n
    assert acc.time_jumps_[0][1:] == pytest.approx((102.99, 100.0))
    # one note per jump, naming it
    jumps = [n for n in acc.notes_ if 'time jumped back' in n]
    assert len(jumps) == 3 and '2.990 s' in jumps[0] and '102.990 s -> 100.000 s' in jumps[0]
    assert len(acc._battery) < 100


def test_a_sim_time_reset_restarts_from_the_new_time():
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros')
    before = loop(acc, 100.0)
    after = loop(acc, 0.5)
    assert len(after) == len(before) == 4
    assert after[0].t_end_s == pytest.approx(0.5 + before[0].t_end_s - 100.0)
    assert after[0].power_in_w == pytest.approx(before[0].power_in_w, rel=1e-9)


def test_streams_that_jump_one_after_the_other():
    """Battery loops first; gait and joints of the old pass still arrive for 50 ms: those are
    dropped, not mixed into the new pass, and the windows match the first pass."""
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros')
    first = loop(acc, 100.0)
    out = []
    for k in range(5):
        out += acc.add_battery(battery(100.0 + 0.01 * k + 1e-4, 100.0))
        t_old = 103.0 + 0.01 * k
        out += acc.add_gait_phase(gait(t_old, 100.0))
        out += acc.add_joint_state(joints(t_old))
    assert acc.stale_samples_ == 10 and len(acc.time_jumps_) == 1
    for k in range(5, 300):
        t = 100.0 + 0.01 * k
        out += acc.add_gait_phase(gait(t, 100.0))
        out += acc.add_battery(battery(t + 1e-4, 100.0))
        out += acc.add_joint_state(joints(t))
    assert len(acc.time_jumps_) == 1   # the later streams' jumps are the same event
    assert [d.t_end_s for d in out] == [d.t_end_s for d in first]
    assert [d.power_in_w for d in out] == pytest.approx([d.power_in_w for d in first])


def test_stamps_a_few_ms_out_of_order_are_not_a_jump():
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros')
    out = loop(acc, 100.0, jitter=True)
    assert len(out) == 4 and not acc.time_jumps_ and not acc.notes_


def test_buffers_stay_bounded_when_the_gait_stream_stops():
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros', max_window_s=10.0)
    assert len(loop(acc, 0.0, 2.0)) == 2
    sizes = []
    for k in range(200, 20_000):         # 198 s of battery and joints, no /gait/phase
        t = 0.01 * k
        acc.add_battery(battery(t))
        acc.add_joint_state(joints(t))
        sizes.append((len(acc._battery), len(acc._joint)))
    assert max(max(s) for s in sizes) <= 1.5 * 10.0 * 100 + 2
    quiet = [n for n in acc.notes_ if 'no /gait/phase' in n]
    assert len(quiet) == 1 and 'for 5.0 s' in quiet[0]
    assert acc.dropped_windows_ == 1
    # the gait comes back: windows again, none across the pause (a wrap is not interpolated
    # across the 198 s silence: the first window starts at the first wrap after it)
    out = loop(acc, 200.0, 2.0)
    assert len(out) == 2 and all(d.window_s == pytest.approx(PERIOD_S) for d in out)
    assert out[0].t_end_s - out[0].window_s > 200.0
    assert acc.schedule_breaks_ and 'silent' in acc.schedule_breaks_[-1][1]
    assert len([n for n in acc.notes_ if 'no /gait/phase' in n]) == 1


def test_battery_only_before_the_gait_starts_is_bounded():
    acc = DescriptorAccumulator(mass_kg=2.0, current_sign='ros', max_window_s=10.0)
    for k in range(60_000):              # 10 min of battery at 100 Hz
        acc.add_battery(battery(0.01 * k))
    # nothing before the first gait sample can be in a window: quiet_s (5 s) of it is kept
    assert len(acc._battery) <= 1.5 * 5.0 * 100 + 2
    assert any('no /gait/phase' in n for n in acc.notes_)
    out = loop(acc, 600.0, 2.0)
    assert len(out) == 2
