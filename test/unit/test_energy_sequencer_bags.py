"""`energy --bench` on `bench_sequencer`'s bags (one bag per session, each with its
/bench/session): analysed as one bench, as a bag recording every session is.

An outside review of the README's commands: each such bag was analysed alone, so the checks
that need several sessions, the force sign (0 Hz against walking sessions of one load) and the
power clock's lag over the walking frequencies, never ran on a sequencer's bench ("force sign
not checked" on each 0 Hz bag). They are now merged as `--bench-sessions` bags are; bags that
overlap in time (not one bench's recording) are still analysed one by one, said.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import pytest

from hexapod_energy.cli import add_cli

PLAN = {'loads_kg': [0.0, 0.3], 'frequencies_hz': [0.0, 1.0, 2.0, 3.0],
        'walk_duration_s': 5.0, 'temperature_gate_c': 26.0, 'temperature_tolerance_c': 1.0}


@pytest.fixture(scope='module')
def sequencer_bags(tmp_path_factory):
    from hexapod_bench_drivers.bench_sim import BenchConfig
    from hexapod_bench_drivers.sequencer import load_plan
    from hexapod_bench_drivers.sequencer_sim import SimulatedBench, SimulatedBenchRun

    root = tmp_path_factory.mktemp('sequencer')
    bench = SimulatedBench(BenchConfig(initial_temperature_c=26.0, ambient_temperature_c=25.5),
                           seed=1)
    run = SimulatedBenchRun(load_plan(PLAN), bench, state_file=root / 'state.json',
                            output_dir=root / 'bags')
    assert run.run(max_sim_s=3000.0).state == 'done'
    bags = sorted((root / 'bags').iterdir())
    assert len(bags) == 8
    return bags


def _energy(bags, out: Path) -> dict:
    parser = argparse.ArgumentParser()
    add_cli(parser.add_subparsers(dest='command', required=True))
    args = parser.parse_args(['energy', '--bench', *map(str, bags), '--out', str(out),
                              '--no-progress'])
    assert args.func(args) == 0
    return json.loads((out / 'energy.json').read_text())


def test_one_bag_per_session_is_one_bench(sequencer_bags, tmp_path):
    doc = _energy(sequencer_bags, tmp_path / 'merged')
    diags = doc['bench']['diagnostics']
    # before: 8 diagnostics, one per bag, the 0 Hz bags' force sign unchecked
    assert len(diags) == 1 and diags[0]['sessions'] == 8
    assert diags[0]['force_sign'] == 1.0
    assert not any('not checked' in n for n in diags[0]['notes']), diags[0]['notes']
    assert doc['bench']['fit'] is not None and len(doc['bench']['fit']['basal_power_w']) == 2


def test_a_subset_of_the_sessions_is_one_bench_too(sequencer_bags, tmp_path):
    walking = [b for b in sequencer_bags if '_f0.00Hz' not in b.name]
    doc = _energy(walking[:5] + sequencer_bags[:1], tmp_path / 'some')
    assert len(doc['bench']['diagnostics']) == 1
