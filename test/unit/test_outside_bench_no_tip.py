"""A single-leg bench without motion capture of the leg tip (another lab's bench: a force
plate and the servos' joint angles, no /bench/leg_tip): the tip height comes from the
/joint_states angles by forward kinematics of the leg, and the phase powers equal those of the
same bench recorded with its tip tracked. Before, such a bag was refused for lacking the topic.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.bags import BagWriter, iter_messages, open_reader
from hexapod_common.testbags import rewrite_bag
from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag
from hexapod_energy.cli import main
from hexapod_energy.errors import BagContentError


def _without(src: Path, dst: Path, topic: str) -> Path:
    with open_reader(src) as r, BagWriter(dst) as w:
        for m in iter_messages(r):
            if m.topic != topic:
                w.write(m.topic, m.msgtype, r.deserialize(m.data, m.msgtype), m.stamp_ns)
    return dst


@pytest.fixture(scope='module')
def benches(tmp_path_factory) -> tuple[Path, Path]:
    root = tmp_path_factory.mktemp('notip')
    plan = BenchPlan(loads_kg=(0.0, 0.3), frequencies_hz=(0.0, 0.75, 1.5, 2.25), walk_s=4.0)
    write_trace(simulate_bench(plan, seed=2), root / 'tracked')
    return root / 'tracked', _without(root / 'tracked', root / 'untracked', '/bench/leg_tip')


def test_tip_from_joint_angles_gives_the_tracked_phase_powers(benches):
    tracked, untracked = benches
    # the contact split (the paper's), where the tip height labels the phases
    a, _ = bench_phase_samples(read_bench_bag(tracked), phase_split='contact')
    data = read_bench_bag(untracked)
    b, diag = bench_phase_samples(data, phase_split='contact')
    assert any('forward kinematics of the AntBot leg' in n and '_coxa' in n
               for n in diag['notes']), diag['notes']
    assert len(a) == len(b) == 8
    for x, y in zip(a, b):
        assert (x.load_kg, x.t_stance_s) == (y.load_kg, y.t_stance_s)
        np.testing.assert_allclose([y.p_stance_w, y.p_swing_w], [x.p_stance_w, x.p_swing_w],
                                   rtol=0.01)
    # the joint-derived height swings by the gait's lift (40 mm), as the tracked tip does
    span = np.subtract(*np.percentile(data.tip_z_m, [95, 5]))
    assert 0.025 < span < 0.06


def test_energy_cli_reads_the_untracked_bench(benches, tmp_path):
    _, untracked = benches
    assert main(['--bench', str(untracked), '--out', str(tmp_path), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'energy.json').read_text())
    assert doc['bench']['fit']['chosen']
    assert any('forward kinematics' in n for n in doc['bench']['diagnostics'][0]['notes'])


def test_joints_of_several_legs_are_refused_by_name(benches, tmp_path):
    _, untracked = benches

    def two_legs(topic, msg):
        if topic == '/joint_states':
            msg.name = list(msg.name) + ['L1_coxa', 'L1_femur', 'L1_tibia']
            for field in ('position', 'velocity', 'effort'):
                arr = np.asarray(getattr(msg, field))
                if arr.size:
                    setattr(msg, field, np.concatenate([arr, np.zeros(3)]))

    bag = rewrite_bag(untracked, tmp_path / 'two_legs', two_legs)
    with pytest.raises(BagContentError, match=r"several legs \['L1', 'R2'\]"):
        read_bench_bag(bag)
    # neither the tip nor the joints: refused naming the missing topic
    bare = _without(untracked, tmp_path / 'bare', '/joint_states')
    with pytest.raises(BagContentError, match=r"lacks topic\(s\) \['/bench/leg_tip'\]"):
        read_bench_bag(bare)


def test_phase_split_modes(benches, tmp_path):
    """'auto' labels by the commanded schedule where /gait/phase is recorded (diagnostics say
    which), 'contact' by force and tip; 'schedule' without /gait/phase is refused by name, and
    a bag without it falls back to the contact split under 'auto'."""
    from hexapod_energy.bag_io import BenchData

    tracked, _ = benches
    data = read_bench_bag(tracked)
    assert data.schedule_t_s.size > 1000 and data.schedule_stance.any()
    _, d_auto = bench_phase_samples(data)
    _, d_contact = bench_phase_samples(data, phase_split='contact')
    assert (d_auto['phase_split'], d_contact['phase_split']) == ('schedule', 'contact')
    no_gait = _without(tracked, tmp_path / 'no_gait', '/gait/phase')
    bare = read_bench_bag(no_gait)
    assert isinstance(bare, BenchData) and bare.schedule_t_s.size == 0
    assert bench_phase_samples(bare)[1]['phase_split'] == 'contact'
    with pytest.raises(BagContentError, match='phase split schedule needs'):
        bench_phase_samples(bare, phase_split='schedule')
    with pytest.raises(ValueError, match='phase split must be one of'):
        bench_phase_samples(data, phase_split='force')
