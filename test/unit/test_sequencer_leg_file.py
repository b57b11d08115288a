"""bench_sequencer checks its plan on the bench leg (``-p leg_file``, the gait node's leg).

An outside review (another robot's leg): the plan's gaits were checked on AntBot's leg only,
so a 260 mm step at 1.04 Hz that ``gait_scheduler -p leg_file`` walks on a longer leg was
refused as one "the gait node would refuse", and a 160 mm step at 1.9 Hz that the gait node
refuses on a PhantomX-like leg (its joint path needs a period >= 0.546 s) was accepted."""

from __future__ import annotations

import pytest

from hexapod_bench_drivers.sequencer import PlanError, load_plan
from hexapod_gait.leg_file import read_leg_file

BIG = """name: BigLeg
a_m: [0.05, 0.12, 0.20]
link_masses_kg: [0.06, 0.12, 0.08]
neutral_tip_m: [0.20, 0.0, -0.14]
"""
PHANTOMX = """name: PhantomX-like
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.060, 0.070, 0.045]
neutral_tip_m: [0.14, 0.0, -0.10]
"""


def plan(step_m: float, freq_hz: float) -> dict:
    return {'loads_kg': [0.0], 'frequencies_hz': [0.0, freq_hz], 'duty_factors': [0.5],
            'step_lengths_m': [step_m], 'step_height_m': 0.04, 'walk_duration_s': 10.0,
            'temperature_gate_c': 26.0, 'temperature_tolerance_c': 1.0}


def leg(tmp_path, text: str):
    path = tmp_path / 'leg.yaml'
    path.write_text(text, encoding='utf8')
    return read_leg_file(path)


def test_plan_the_longer_leg_walks_is_accepted(tmp_path):
    with pytest.raises(PlanError, match='would refuse'):
        load_plan(plan(0.26, 1 / 0.96))               # AntBot's leg: refused
    assert load_plan(plan(0.26, 1 / 0.96), leg=leg(tmp_path, BIG)).sessions


def test_plan_the_shorter_leg_cannot_walk_is_refused(tmp_path):
    assert load_plan(plan(0.16, 1.9)).sessions        # AntBot's leg: walkable
    with pytest.raises(PlanError, match='160 mm step needs'):
        load_plan(plan(0.16, 1.9), leg=leg(tmp_path, PHANTOMX))


def test_the_simulated_bench_walks_the_leg_file(tmp_path):
    """backend sim walked AntBot's leg whatever the leg file (a warning said so); the
    simulated bench now walks the file's leg: its bags record it and its stance tip carries
    the file's leg and the load."""
    import json

    import numpy as np
    import yaml

    from hexapod_bench_drivers.bench_sim import BenchConfig
    from hexapod_bench_drivers.sequencer_sim import SimulatedBench, SimulatedBenchRun
    from hexapod_bench_drivers.sim_bag import CONFIG_KEY
    from hexapod_energy.bag_io import read_bench_bag

    px = leg(tmp_path, PHANTOMX)
    spec = {**plan(0.10, 2.0), 'loads_kg': [0.2], 'frequencies_hz': [2.0],
            'walk_duration_s': 1.0}
    bench = SimulatedBench(BenchConfig(), seed=1, leg=px)
    np.testing.assert_allclose(bench.sim.kinematics.forward(bench.sim.neutral_q)[0],
                               px.neutral_tip_m, atol=1e-12)
    run = SimulatedBenchRun(load_plan(spec, leg=px), bench, output_dir=tmp_path / 'bags')
    assert run.run(max_sim_s=5000.0).state == 'done'
    [bag] = sorted((tmp_path / 'bags').iterdir())
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    config = json.loads(meta['rosbag2_bagfile_information']['custom_data'][CONFIG_KEY])
    assert config['leg_description']['name'] == 'PhantomX-like'
    assert config['leg_description']['a_m'] == [0.052, 0.066, 0.133]
    force = read_bench_bag(bag).force_z_n
    assert np.median(force[force > 1.0]) == pytest.approx((0.175 + 0.2) * 9.81, rel=0.01)
