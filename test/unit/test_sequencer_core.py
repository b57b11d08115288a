"""Bench sequencer core: 3 loads x 3 frequencies on a thermal stand-in, temperature gate, resume."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexapod_bench_drivers.sequencer import BenchSequencer, PlanError, load_plan

PLAN = {'loads_kg': [0.0, 0.095, 0.141], 'frequencies_hz': [0.5, 1.0, 2.0],
        'walk_duration_s': 60.0, 'temperature_gate_c': 26.0, 'temperature_tolerance_c': 1.0}


class ThermalBench:
    """Three servos: first-order winding temperature, heating while walking, cooling off."""

    def __init__(self, ambient_c=25.5, start_c=(25.8, 26.1, 26.3)):
        self.temp = np.array(start_c, dtype=float)
        self.ambient_c = ambient_c
        self.load_kg = 0.0

    def step(self, dt_s, walk, torque, frequency_hz):
        target = self.ambient_c + (6.0 * (1 + self.load_kg * 5) * frequency_hz if walk else
                                   (1.0 if torque else 0.0))
        self.temp += (target - self.temp) * (1 - np.exp(-dt_s / 120.0))
        return list(self.temp)


def run(seq, bench, t0=0.0, stop_after_walk_start=None, dt_s=1.0, max_t_s=200_000.0):
    """Drive the sequencer in accelerated time; returns (t, events)."""
    t = t0
    temps = list(bench.temp)
    events = []
    walk_starts = 0
    prev = None
    while t < max_t_s:
        cmd = seq.update(t, temps)
        if cmd.load_request_kg is not None:
            bench.load_kg = cmd.load_request_kg       # automatic load change in simulation
            seq.confirm_load(cmd.load_request_kg)
        if cmd.finished_session:
            events.append(('finished', cmd.finished_session, t))
        if cmd.state == 'walking' and prev != 'walking':
            events.append(('walk', cmd.session.session_id, t, max(temps), min(temps)))
            walk_starts += 1
            if stop_after_walk_start is not None and walk_starts == stop_after_walk_start:
                return t, events                       # 'crash' in the middle of a session
        if cmd.state == 'done':
            return t, events
        prev = cmd.state
        freq = cmd.session.frequency_hz if cmd.session else 0.0
        temps = bench.step(dt_s, cmd.walk, cmd.torque, freq)
        t += dt_s
    raise AssertionError('plan did not finish')


def test_plan_order_and_validation(tmp_path):
    plan = load_plan(PLAN)
    assert len(plan.sessions) == 9
    assert [s.load_kg for s in plan.sessions] == [0.0] * 3 + [0.095] * 3 + [0.141] * 3
    assert [s.frequency_hz for s in plan.sessions[:3]] == [0.5, 1.0, 2.0]
    path = tmp_path / 'plan.yaml'
    path.write_text('loads_kg: [0.1]\nfrequencies_hz: [1.0]\nduty_factors: [0.6]\n')
    assert load_plan(path).sessions[0].duty_factor == 0.6
    with pytest.raises(PlanError, match="'frequencies_hz' is required"):
        load_plan({'loads_kg': [0.1]})
    with pytest.raises(PlanError, match=r'duty_factors must be in \(0, 1\)'):
        load_plan({**PLAN, 'duty_factors': [1.5]})


def test_full_plan_runs_to_completion_with_gate(tmp_path):
    seq = BenchSequencer(load_plan(PLAN), state_file=tmp_path / 'state.json')
    bench = ThermalBench()
    t, events = run(seq, bench)
    finished = [e[1] for e in events if e[0] == 'finished']
    assert finished == [s.session_id for s in seq.plan.sessions]
    # Every walk started with all servos inside 26 +- 1 degC.
    walks = [e for e in events if e[0] == 'walk']
    assert len(walks) == 9
    assert all(25.0 <= lo and hi <= 27.0 for *_, hi, lo in walks)
    # The gate held: after a hot session, the next walk waited for cooling (far beyond 60 s).
    gaps = np.diff([e[2] for e in walks])
    assert np.all(gaps > 60.0) and gaps.max() > 200.0
    assert json.loads((tmp_path / 'state.json').read_text())['completed'] == finished


def test_cold_servos_are_heated_before_walking():
    seq = BenchSequencer(load_plan({**PLAN, 'loads_kg': [0.0], 'frequencies_hz': [1.0]}),
                         initial_load_kg=0.0)
    bench = ThermalBench(ambient_c=22.0, start_c=(22.0, 22.5, 23.0))
    assert seq.update(0.0, list(bench.temp)).state == 'heating'
    _, events = run(seq, bench)
    walk = next(e for e in events if e[0] == 'walk')
    assert walk[4] >= 25.0 and walk[2] > 0


def test_nan_temperature_blocks_the_gate():
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0)
    cmd = seq.update(0.0, [26.0, float('nan'), 26.0])
    assert cmd.state == 'cooling' and not cmd.torque
    assert seq.update(1.0, [26.0, 26.0, 26.0]).state == 'walking'


def test_crash_and_resume_repeats_no_finished_session(tmp_path):
    state = tmp_path / 'state.json'
    plan = load_plan(PLAN)
    bench = ThermalBench()
    first = BenchSequencer(plan, state_file=state)
    t, ev1 = run(first, bench, stop_after_walk_start=5)    # killed while walking session 5
    done1 = [e[1] for e in ev1 if e[0] == 'finished']
    assert len(done1) == 4
    del first                                              # nothing else is saved on a crash
    second = BenchSequencer(plan, state_file=state)
    assert second.skipped == done1
    assert second.current.session_id == plan.sessions[4].session_id
    _, ev2 = run(second, bench, t0=t)
    done2 = [e[1] for e in ev2 if e[0] == 'finished']
    assert done1 + done2 == [s.session_id for s in plan.sessions]
    assert not set(done1) & set(done2)
    # The interrupted session is walked again from its start; finished ones never.
    walked2 = [e[1] for e in ev2 if e[0] == 'walk']
    assert walked2 == [s.session_id for s in plan.sessions[4:]]


def test_corrupt_state_file_is_a_clear_error(tmp_path):
    state = tmp_path / 'state.json'
    state.write_text('{not json')
    with pytest.raises(PlanError, match='unreadable'):
        BenchSequencer(load_plan(PLAN), state_file=state)
