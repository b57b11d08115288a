"""bench_sequencer node, backend sim: a 3-load x 3-frequency plan on the embedded bench simulator
in accelerated time, killed in the middle and restarted; per-session bags for the analysis."""

from __future__ import annotations

import json

import pytest
from harness import Collector, ros_env
from hexapod_common.conversions import stamp_to_s
from hexapod_interfaces.msg import BenchSession, ServoStatus
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from hexapod_bench_drivers.sequencer_node import SIM_EPOCH_S, BenchSequencerNode

LATCHED = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
PLAN = ('loads_kg: [0.0, 0.095, 0.141]\nfrequencies_hz: [1.0, 2.0, 3.0]\n'
        'walk_duration_s: 2.0\n')


@pytest.mark.timeout(120)
def test_sim_backend_runs_the_plan_killed_and_resumed(tmp_path):
    from hexapod_energy.bag_io import bench_phase_samples, read_bench_bag

    plan = tmp_path / 'plan.yaml'
    plan.write_text(PLAN)
    overrides = [Parameter('plan_file', value=str(plan)),
                 Parameter('state_file', value=str(tmp_path / 'state.json')),
                 Parameter('output_dir', value=str(tmp_path / 'bags')),
                 Parameter('backend', value='sim'), Parameter('rate_hz', value=500.0),
                 Parameter('sim_initial_temperature_c', value=30.0)]
    with ros_env('seqsim') as env:
        node = env.make(BenchSequencerNode, parameter_overrides=overrides)
        sessions1 = Collector(env, BenchSession, 'bench/session', LATCHED)
        status = Collector(env, ServoStatus, 'servo_status')
        # Killed while walking the fifth session.
        assert env.spin_until(lambda: len(node.seq.completed) == 4
                              and node.last_command.state == 'walking', 60)
        done1 = node.seq.completed
        env.executor.remove_node(node)
        env.nodes.remove(node)
        node.destroy_node()
        assert env.spin_until(lambda: any(m.state == 'walking' for m in sessions1.messages)
                              and status.messages, 10)
    states = [m.state for m in sessions1.messages]
    assert states[:3] == ['idle', 'cooling', 'walking']      # hot start: the gate held
    first_walk = next(m for m in sessions1.messages if m.state == 'walking')
    # Stamped in simulated time: cooling 30 -> 27.5 degC took minutes, in well under a second.
    assert 250.0 < stamp_to_s(first_walk.header.stamp) - SIM_EPOCH_S < 600.0
    assert all(max(m.temperature) >= 27.0 for m in status.messages[:5])

    with ros_env('seqsim') as env:
        node = env.make(BenchSequencerNode, parameter_overrides=overrides)
        assert node.seq.skipped == done1
        sessions2 = Collector(env, BenchSession, 'bench/session', LATCHED)
        assert env.spin_until(lambda: sessions2.messages
                              and sessions2.messages[-1].state == 'done', 90)
        # the plan is over: the node resolves ``finished`` (run_node then exits with 0)
        assert env.spin_until(lambda: node.finished.done(), 10)
        assert node.finished.result() == 0
    all_ids = json.loads((tmp_path / 'state.json').read_text())['completed']
    assert len(all_ids) == 9 and all_ids[:4] == done1
    walked2 = [m.session_id for m in sessions2.messages if m.state == 'walking']
    assert walked2 == all_ids[4:]                 # the finished ones are not walked again
    walks = {m.session_id: m for m in sessions1.messages + sessions2.messages
             if m.state == 'walking'}
    assert sorted((m.load_mass, m.frequency) for m in walks.values()) == sorted(
        (m, f) for m in (0.0, 0.095, 0.141) for f in (1.0, 2.0, 3.0))
    for sid in all_ids:
        samples, diag = bench_phase_samples(read_bench_bag(tmp_path / 'bags' / sid))
        assert len(samples) == 1 and samples[0].session_id == sid
        assert samples[0].load_kg == pytest.approx(walks[sid].load_mass)
        assert samples[0].p_stance_w > 0.5


def _run_sim_sequencer(tmp_path, plan_text: str, namespace: str, *extra: str):
    """The bench_sequencer console script on the sim backend with ``plan_text`` (``extra``:
    more ``-p`` arguments); its result."""
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    plan = tmp_path / 'plan.yaml'
    plan.write_text(plan_text)
    exe = shutil.which('bench_sequencer') or str(Path(sys.executable).parent / 'bench_sequencer')
    return subprocess.run(
        [exe, '--ros-args', '-r', f'__ns:={namespace}', '-p', f'plan_file:={plan}',
         '-p', f'state_file:={tmp_path / "state.json"}', '-p', f'output_dir:={tmp_path / "bags"}',
         '-p', 'backend:=sim', '-p', 'rate_hz:=500.0', '-p', 'sim_initial_temperature_c:=26.0',
         *extra],
        capture_output=True, text=True, timeout=100)


@pytest.mark.timeout(120)
def test_bench_sequencer_executable_exits_when_the_plan_is_done(tmp_path):
    """The console script (run_node) returns 0 once the plan is done instead of spinning on."""
    proc = _run_sim_sequencer(
        tmp_path, 'loads_kg: [0.0]\nfrequencies_hz: [2.0]\nwalk_duration_s: 1.0\n', '/seqexit')
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert 'plan done: 1 sessions completed' in proc.stderr + proc.stdout
    assert json.loads((tmp_path / 'state.json').read_text())['completed']


@pytest.mark.timeout(120)
def test_a_basal_0_hz_session_is_planned_and_recorded(tmp_path):
    """The plan refused frequencies_hz 0 ('> 0 expected'), so a real bench run by the sequencer
    could not record the paper's basal session, which the single-leg method needs (new-user
    review: no plan example in the README). A 0 Hz session now stands at its load."""
    from hexapod_energy.bag_io import read_bench_bag

    proc = _run_sim_sequencer(
        tmp_path, 'loads_kg: [0.2]\nfrequencies_hz: [0.0, 2.0]\nwalk_duration_s: 1.0\n',
        '/seqbasal')
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert 'plan done: 2 sessions completed' in proc.stderr + proc.stdout
    bags = sorted((tmp_path / 'bags').iterdir())
    basal = [b for b in bags if '_f0.00Hz' in b.name]
    assert len(basal) == 1
    data = read_bench_bag(basal[0])
    assert data.sessions and {round(float(s['frequency_hz']), 3) for s in data.sessions
                              if s.get('state', 'walking') == 'walking'} == {0.0}
    assert data.battery_t_s.size >= 40     # 1 s of the 50 Hz power monitor


@pytest.mark.timeout(120)
def test_backend_sim_walks_the_leg_file(tmp_path):
    """With ``-p leg_file`` the sim backend warned that its sessions walked AntBot's leg (the
    plan was checked on the file's); the simulated bench now walks the file's leg, said at
    start-up, and its bags record it."""
    import yaml

    from hexapod_bench_drivers.sim_bag import CONFIG_KEY

    leg = tmp_path / 'phantomx.yaml'
    leg.write_text('name: PhantomX-like\na_m: [0.052, 0.066, 0.133]\n'
                   'link_masses_kg: [0.060, 0.070, 0.045]\nneutral_tip_m: [0.14, 0.0, -0.10]\n')
    proc = _run_sim_sequencer(
        tmp_path, 'loads_kg: [0.0]\nfrequencies_hz: [2.0]\nwalk_duration_s: 1.0\n',
        '/seqleg', '-p', f'leg_file:={leg}')
    out = proc.stderr + proc.stdout
    assert proc.returncode == 0, out[-2000:]
    assert "AntBot's leg" not in out
    assert "the simulated bench walks 'PhantomX-like'" in out
    [bag] = sorted((tmp_path / 'bags').iterdir())
    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())
    config = json.loads(meta['rosbag2_bagfile_information']['custom_data'][CONFIG_KEY])
    assert config['leg_description']['a_m'] == [0.052, 0.066, 0.133]
