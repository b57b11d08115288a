"""An aborted plan on the simulated bench (``bench_sequencer -p backend:=sim``, Ctrl-C): the
partial bag of the session that was walking is moved aside to ``<session_id>.interrupted-N``,
as the external backend does, not left under the session's own name where ``hexapod-analyze
energy --bench`` would read a few seconds of a walk as a whole session."""

from __future__ import annotations

from hexapod_bench_drivers.bench_sim import BenchConfig
from hexapod_bench_drivers.sequencer import load_plan
from hexapod_bench_drivers.sequencer_sim import SimulatedBench, SimulatedBenchRun

PLAN = {'loads_kg': [0.0], 'frequencies_hz': [1.0, 2.0], 'walk_duration_s': 10.0,
        'temperature_gate_c': 26.0, 'temperature_tolerance_c': 1.0}


def test_abort_mid_walk_moves_the_partial_bag_aside(tmp_path):
    bench = SimulatedBench(BenchConfig(initial_temperature_c=26.0, ambient_temperature_c=25.5),
                           seed=1)
    run = SimulatedBenchRun(load_plan(PLAN), bench, state_file=tmp_path / 'state.json',
                            output_dir=tmp_path / 'bags')
    walking = 0
    for _ in range(10_000):
        cmd = run.step()
        if cmd.state == 'walking' and cmd.record:
            walking += 1
            if walking == 4:             # 2 s into a 10 s walk
                break
    assert walking == 4
    sid = cmd.session.session_id
    run.seq.abort('SIGINT')
    last = run.run(max_sim_s=100.0)
    assert last.state == 'aborted'
    bags = tmp_path / 'bags'
    assert not (bags / sid).exists(), 'the partial bag is left under the session id'
    assert (bags / f'{sid}.interrupted-1' / 'metadata.yaml').is_file()
    assert sid not in run.seq.completed
    assert [e.session_id for e in run.events if e.kind == 'bag'] == []
    assert [e.session_id for e in run.events if e.kind == 'interrupted'] == [sid]
