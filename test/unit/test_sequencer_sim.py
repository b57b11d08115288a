"""Bench sequencer on the bench simulator in accelerated time: 3 loads x 3 frequencies with the
temperature gate on the servo thermal model, crash/resume, and per-session bags that
``hexapod-analyze energy --bench`` reads."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchConfig
from hexapod_bench_drivers.sequencer import load_plan
from hexapod_bench_drivers.sequencer_sim import SimulatedBench, SimulatedBenchRun

PLAN = {'loads_kg': [0.0, 0.095, 0.141], 'frequencies_hz': [1.0, 2.0, 3.0],
        'walk_duration_s': 3.0, 'temperature_gate_c': 26.0, 'temperature_tolerance_c': 1.0}
HOT_START_C = 30.0          # servos warm from an earlier run: the gate must hold the first walk


def _bench() -> SimulatedBench:
    return SimulatedBench(BenchConfig(initial_temperature_c=HOT_START_C,
                                      ambient_temperature_c=25.5), seed=3)


@pytest.fixture(scope='module')
def full_run(tmp_path_factory):
    root = tmp_path_factory.mktemp('seqsim')
    run = SimulatedBenchRun(load_plan(PLAN), _bench(), state_file=root / 'state.json',
                            output_dir=root / 'bags')
    last = run.run(max_sim_s=20_000.0)
    return root, run, last


def _ids(run, kind):
    return [e.session_id for e in run.events if e.kind == kind]


def test_plan_runs_to_completion_and_the_gate_holds(full_run):
    root, run, last = full_run
    sessions = [s.session_id for s in run.plan.sessions]
    assert last.state == 'done'
    assert _ids(run, 'finished') == sessions
    assert _ids(run, 'walk') == sessions
    assert json.loads((root / 'state.json').read_text())['completed'] == sessions
    walks = [e for e in run.events if e.kind == 'walk']
    # Every measured walk started with every servo inside 26 +- 1 degC.
    assert all(25.0 <= min(e.temperatures_c) and max(e.temperatures_c) <= 27.0 for e in walks)
    # Hot start: torque off (cooling) until the servos were back in the gate; with a winding
    # time constant of 480 s, 30 -> 27.5 degC takes about 480 ln(4.5/2) = 390 s.
    first_states = [e.detail for e in run.events if e.kind == 'state'][:3]
    assert first_states == ['idle', 'cooling', 'walking']
    assert 250.0 < walks[0].t_s < 600.0
    # Walking heats the servos out of the gate, and each session waits to cool again.
    bags = [e for e in run.events if e.kind == 'bag']
    assert max(max(e.temperatures_c) for e in bags) > 27.0
    finished = [e for e in run.events if e.kind == 'finished']
    assert all(f.t_s - b.t_s > 0.0 for f, b in zip(finished, bags))
    assert max(f.t_s - b.t_s for f, b in zip(finished, bags)) > 20.0


def test_each_session_bag_reads_as_a_bench_session(full_run):
    from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag

    root, run, _ = full_run
    stance = {}
    for spec in run.plan.sessions:
        data = read_bench_bag(root / 'bags' / spec.session_id)
        assert [s['state'] for s in data.sessions] == ['walking']
        assert data.sessions[0]['load_kg'] == pytest.approx(spec.load_kg)
        assert data.sessions[0]['frequency_hz'] == pytest.approx(spec.frequency_hz)
        # Recorded walk: whole session at 100 Hz, minus the stop setting stand.
        assert 195 <= len(data.battery_t_s) <= 305
        samples, diag = bench_phase_samples(data)
        assert diag['current_sign'] == -1.0 and len(samples) == 1
        s = samples[0]
        assert s.frequency_hz == spec.frequency_hz
        stance[spec.load_kg, spec.frequency_hz] = s.p_stance_w
    # Physics through the chain: stance power grows with the load and with the frequency.
    for f in PLAN['frequencies_hz']:
        assert stance[0.0, f] < stance[0.095, f] < stance[0.141, f]
    for m in PLAN['loads_kg']:
        assert stance[m, 1.0] < stance[m, 2.0] < stance[m, 3.0]


def test_hexapod_analyze_energy_reads_the_bags(full_run, tmp_path):
    from hexapod_energy.cli import main

    root, run, _ = full_run
    bags = [str(root / 'bags' / s.session_id) for s in run.plan.sessions]
    assert main(['--bench', *bags, '--out', str(tmp_path / 'out')]) == 0
    doc = json.loads((tmp_path / 'out' / 'energy.json').read_text())
    fitted = doc['bench']['fit']['sessions']
    assert sorted(s['session_id'] for s in fitted) == sorted(s.session_id
                                                           for s in run.plan.sessions)
    assert all(np.isfinite(s['p_stance_w']) and s['p_stance_w'] > 0 for s in fitted)


def test_killed_and_restarted_resumes_without_repeating(tmp_path):
    plan = load_plan(PLAN)
    sessions = [s.session_id for s in plan.sessions]
    state, bags = tmp_path / 'state.json', tmp_path / 'bags'
    bench = _bench()                       # the physical bench outlives the sequencer process
    first = SimulatedBenchRun(plan, bench, state_file=state, output_dir=bags)
    # Killed while cooling after the 5th walk: its bag is written, the session is unfinished.
    crashed = first.run(stop=lambda cmd: len(_ids(first, 'bag')) == 5)
    assert crashed.state == 'cooling'
    done1 = _ids(first, 'finished')
    assert done1 == sessions[:4]
    # A fresh simulator after the restart takes the stage load from the state file.
    fresh = SimulatedBenchRun(plan, _bench(), state_file=state)
    assert fresh.bench.load_kg == plan.sessions[4].load_kg == 0.095
    second = SimulatedBenchRun(plan, bench, state_file=state, output_dir=bags)
    assert second.seq.skipped == done1
    assert second.run().state == 'done'
    done2 = _ids(second, 'finished')
    assert done1 + done2 == sessions
    assert _ids(second, 'walk') == sessions[4:]        # only the unfinished one is walked again
    assert json.loads(state.read_text())['completed'] == sessions
    assert sorted(p.name for p in bags.iterdir()) == sorted(
        [*sessions, sessions[4] + '.interrupted-1'])
    # A third start has nothing left to do.
    third = SimulatedBenchRun(plan, bench, state_file=state, output_dir=bags)
    assert third.run().state == 'done' and not _ids(third, 'walk')


def test_cold_bench_is_heated_by_walking_before_recording(tmp_path):
    plan = load_plan({**PLAN, 'loads_kg': [0.095], 'frequencies_hz': [3.0]})
    bench = SimulatedBench(BenchConfig(initial_temperature_c=23.0, ambient_temperature_c=23.0))
    run = SimulatedBenchRun(plan, bench, output_dir=tmp_path)
    assert run.run(max_sim_s=5000.0).state == 'done'
    states = [e.detail for e in run.events if e.kind == 'state']
    assert states[:3] == ['idle', 'heating', 'walking']
    walk = next(e for e in run.events if e.kind == 'walk')
    assert min(walk.temperatures_c) >= 25.0 and walk.t_s > 10.0
