"""Bench sequencer core after the outside review: stand before torque off, aborts on faults
while walking, strict plan checks (FINDINGS S1, S2, S5, S7, S8)."""

from __future__ import annotations

import json
import math

import pytest

from hexapod_bench_drivers.sequencer import (
    OVERHEATING_FLAG,
    BenchSequencer,
    PlanError,
    load_plan,
)

PLAN = {'loads_kg': [0.0], 'frequencies_hz': [1.0, 2.0], 'walk_duration_s': 5.0}
GATE = [26.0, 26.0, 26.0]


def _walking(tmp_path=None, **kw):
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0,
                         state_file=None if tmp_path is None else tmp_path / 'state.json', **kw)
    cmd = seq.update(0.0, GATE)
    assert cmd.state == 'walking' and cmd.walk and cmd.record
    return seq


# --- S8 / item 3: stand before torque off ------------------------------------------------------
def test_torque_stays_on_while_the_leg_stands_after_a_walk():
    seq = _walking()
    hot = [28.0] * 3                                       # walk over, servos out of the gate
    cmd = seq.update(5.0, hot, standing=False)
    assert cmd.state == 'cooling' and not cmd.walk
    assert cmd.torque and cmd.standing                     # never torque off with the stand
    assert seq.update(6.0, hot, standing=False).torque     # not standing yet: still powered
    cmd = seq.update(7.0, hot, standing=True)
    assert cmd.state == 'cooling' and not cmd.torque and not cmd.standing


def test_stand_is_bounded_by_stand_timeout():
    seq = _walking(stand_timeout_s=3.0)
    hot = [28.0] * 3
    assert seq.update(5.0, hot).torque                     # standing unknown: wait
    assert seq.update(7.0, hot).torque
    cmd = seq.update(8.0, hot)
    assert not cmd.torque and 'stand_timeout_s = 3 s' in seq.stand_warning


def test_plan_end_stands_before_torque_off(tmp_path):
    seq = BenchSequencer(load_plan({**PLAN, 'frequencies_hz': [1.0]}), initial_load_kg=0.0)
    seq.update(0.0, GATE)
    cmd = seq.update(5.0, GATE, standing=False)            # in the gate: session done at once
    assert cmd.finished_session and cmd.state == 'done' and cmd.torque
    assert seq.update(5.1, GATE, standing=True).torque is False


# --- S2 / item 1: abort --------------------------------------------------------------------------
def test_abort_while_walking_stands_then_torque_off_and_counts_nothing(tmp_path):
    seq = _walking(tmp_path)
    cmd = seq.abort('SIGINT received')
    assert cmd.state == 'aborted' and cmd.torque and not cmd.walk
    cmd = seq.update(1.0, GATE, standing=False)
    assert cmd.state == 'aborted' and cmd.torque and not cmd.record
    cmd = seq.update(1.5, GATE, standing=True)
    assert cmd.state == 'aborted' and not cmd.torque
    assert seq.update(100.0, GATE).state == 'aborted'      # stays aborted
    assert seq.completed == [] and seq.abort_reason == 'SIGINT received'
    assert not (tmp_path / 'state.json').exists()


# --- S1, S5 / item 2: faults while walking ------------------------------------------------------
def test_overheating_flag_aborts_the_walk():
    seq = _walking()
    cmd = seq.update(2.0, [27.0] * 3, error_flags=[0, OVERHEATING_FLAG, 0])
    assert cmd.state == 'aborted' and not cmd.walk and cmd.torque   # stand first
    assert 'overheating' in seq.abort_reason and '0x04' in seq.abort_reason
    assert seq.completed == []


def test_temperature_above_the_limit_aborts_the_walk():
    seq = _walking()
    assert seq.update(1.0, [30.0] * 3).state == 'walking'           # warm: fine
    cmd = seq.update(2.0, [40.0, 46.0, 40.0])
    assert cmd.state == 'aborted'
    assert 'temperature_limit_c 45' in seq.abort_reason


@pytest.mark.parametrize('topic', ['servo_status', 'battery_state'])
def test_a_silent_stream_aborts_the_walk_and_the_session_is_not_counted(tmp_path, topic):
    seq = _walking(tmp_path, stream_timeout_s=0.5)
    ages = {'servo_status': 0.1, 'battery_state': 0.1}
    assert seq.update(1.0, GATE, stream_ages_s=ages).state == 'walking'
    cmd = seq.update(2.0, GATE, stream_ages_s={**ages, topic: 0.8})
    assert cmd.state == 'aborted' and f'no {topic} for 0.80 s' in seq.abort_reason
    for t in (3.0, 4.0, 10.0):
        seq.update(t, GATE, standing=True)
    assert seq.completed == [] and not (tmp_path / 'state.json').exists()


# --- S7 / item 5: plan checks ----------------------------------------------------------------
@pytest.mark.parametrize('change, match', [
    ({'loads_kg': [math.nan]}, "'loads_kg': expected finite numbers"),
    ({'loads_kg': [-0.1]}, 'loads_kg >= 0'),
    ({'walk_duration_s': math.nan}, "'walk_duration_s': expected a finite number"),
    ({'walk_duration_s': -1.0}, 'walk_duration_s > 0'),
    ({'frequencies_hz': [math.inf]}, "'frequencies_hz': expected finite numbers"),
    ({'frequencies_hz': [-1.0]}, 'frequencies_hz >= 0'),
    ({'frequencies_hz': [10.0]}, 'step frequency 10 Hz > maximum 3 Hz'),
    ({'frequencies_hz': [3.0], 'duty_factors': [0.8]}, 'swing lasts 0.06667 s'),
    ({'step_lengths_m': [0.5]}, 'leave the leg workspace'),
    ({'step_lengths_m': [-0.1]}, 'step_lengths_m > 0'),
    ({'step_height_m': -0.05}, 'step_height_m >= 0'),
    ({'temperature_gate_c': math.nan}, "'temperature_gate_c': expected a finite number"),
    ({'temperature_tolerance_c': -1.0}, 'temperature_tolerance_c must be > 0'),
    ({'temperature_limit_c': 26.5}, 'temperature_limit_c .* must be above'),
    ({'walk_duraton_s': 5.0}, r"unknown keys \['walk_duraton_s'\]"),
    ({'loads_kg': [0.1, 0.1004]}, 'two sessions have the id'),
    ({'frequencies_hz': [1.0, 1.0]}, 'two sessions have the id'),
])
def test_bad_plans_are_refused_with_the_reason(change, match):
    with pytest.raises(PlanError, match=match):
        load_plan({**PLAN, **change})


def test_a_good_plan_with_a_basal_session_still_loads(tmp_path):
    plan = load_plan({**PLAN, 'frequencies_hz': [0.0, 0.5, 3.0], 'temperature_limit_c': 40})
    assert [s.frequency_hz for s in plan.sessions] == [0.0, 0.5, 3.0]
    assert plan.temperature_limit_c == 40.0
    path = tmp_path / 'plan.yaml'
    path.write_text(json.dumps({**PLAN, 'duty_factors': [0.5, 0.6]}))
    assert len(load_plan(path).sessions) == 4


# --- S6 / item 7: the recording holds only the steady session gait ------------------------------
def test_recording_starts_once_the_gait_is_steady():
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, stand_timeout_s=5.0)
    cmd = seq.update(0.0, GATE, gait_ready=False)
    assert cmd.state == 'starting' and cmd.walk and cmd.torque and not cmd.record
    assert seq.update(2.0, GATE, gait_ready=False).state == 'starting'
    cmd = seq.update(3.0, GATE, gait_ready=True)
    assert cmd.state == 'walking' and cmd.record
    assert seq.update(7.9, GATE, gait_ready=True).state == 'walking'   # 5 s from t = 3 s
    assert seq.update(8.0, [28.0] * 3, gait_ready=True).state == 'cooling'


def test_a_gait_that_never_settles_aborts_the_plan():
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, stand_timeout_s=5.0)
    seq.update(0.0, GATE, gait_ready=False)
    cmd = seq.update(5.0, GATE, gait_ready=False)
    assert cmd.state == 'aborted' and cmd.torque and not cmd.record      # stands first
    assert 'did not settle at the session gait' in seq.abort_reason


def test_the_next_session_waits_for_its_own_gait_without_cooling():
    """A session that follows another without cooling (always after a basal one): the
    readiness passed in was the finished session's, so the next one's recording began on
    its ramp up (0.95 s of a 4 s bag, a second review). Now it starts in 'starting'."""
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, stand_timeout_s=5.0)
    seq.update(0.0, GATE, gait_ready=True)
    first = seq.current.session_id
    cmd = seq.update(5.0, GATE, gait_ready=True)      # the first walk ends, in the gate
    assert seq.current is not None and seq.current.session_id != first
    assert cmd.state == 'starting' and not cmd.record
    cmd = seq.update(5.1, GATE, gait_ready=True)
    assert cmd.state == 'walking' and cmd.record


def test_a_slow_battery_monitor_does_not_abort_the_walk(tmp_path):
    """A 1 Hz fuel gauge with jitter (1.03 s between samples) aborted a normal plan under the
    1 s default (a second review); the default is 5 s."""
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0)
    assert seq.fault([25.0] * 3, (), {'battery_state': 1.03, 'servo_status': 0.05}) is None
    why = seq.fault([25.0] * 3, (), {'battery_state': 5.2})
    assert why and 'stream_timeout_s = 5 s' in why
