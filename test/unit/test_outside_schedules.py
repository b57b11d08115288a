"""A robot bag that changes its walking schedule (a speed sweep recorded in one bag, a stop at
the end): each walking schedule is its own run, equal to the run recorded alone; windows across
a change and standing are left out. Before, every window was averaged into one run predicted
with the last schedule (a mix of 27 and 43 W against the 0.5 s schedule's 44 W), and a bag
ending standing failed with 'period_s must be finite and > 0'."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Writer

from hexapod_bench_drivers.bench_sim import BenchPlan, simulate_bench
from hexapod_bench_drivers.effects import parse_effects
from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.bags import typestore
from hexapod_energy.bag_io import read_robot_bag, read_robot_segments
from hexapod_energy.cli import main
from hexapod_energy.errors import BagContentError

MASS = 2.183


def concat(dst: Path, srcs: list[Path]) -> Path:
    """The bags one after the other: each next bag's stamps (header and bag time) shifted to
    start 10 ms after the previous one's last message."""
    store = typestore()
    with Writer(dst, version=8) as w:
        conns: dict[tuple[str, str], object] = {}
        shift = 0
        for src in srcs:
            with AnyReader([src], default_typestore=store) as r:
                times = [t for _, t, _ in r.messages()]
                off = shift - min(times)
                for c, t, raw in r.messages():
                    msg = r.deserialize(raw, c.msgtype)
                    h = getattr(msg, 'header', None)
                    if h is not None:
                        h.stamp.sec, h.stamp.nanosec = divmod(
                            h.stamp.sec * 10**9 + h.stamp.nanosec + off, 10**9)
                    key = (c.topic, c.msgtype)
                    if key not in conns:
                        conns[key] = w.add_connection(c.topic, c.msgtype, typestore=store)
                    w.write(conns[key], t + off, store.serialize_cdr(msg, c.msgtype))
                shift = max(times) + off + 10_000_000
    return dst


@pytest.fixture(scope='module')
def bags(tmp_path_factory):
    root = tmp_path_factory.mktemp('sched')
    parts = []
    for name, period, seconds in (('slow', 1.0, 8.0), ('fast', 0.5, 8.0), ('stand', 0.0, 3.0)):
        write_trace(simulate_robot(seconds, RobotConfig(period_s=period),
                                   effects=parse_effects([]), seed=1), root / name)
        parts.append(root / name)
    concat(root / 'sweep', parts)
    return root


def test_each_schedule_is_the_run_recorded_alone(bags):
    runs = read_robot_segments(bags / 'sweep', mass_kg=MASS)
    alone = [read_robot_bag(bags / n, mass_kg=MASS) for n in ('slow', 'fast')]
    assert [r.gait.period_s for r in runs] == [1.0, 0.5]
    for r, a in zip(runs, alone):
        assert r.windows == a.windows
        # the same samples; their stamps shifted (float rounding of the new times only)
        assert r.power_in_w == pytest.approx(a.power_in_w, rel=1e-6)
        assert r.speed_mps == pytest.approx(a.speed_mps, rel=1e-6)
    assert [r.extra['segment']['index'] for r in runs] == [0, 1]
    assert all(r.extra['segment']['of'] == 2 for r in runs)
    assert any('spanning a schedule change' in n for n in runs[0].extra['notes'])
    # the single-run reader takes the schedule with the most windows, and says so
    one = read_robot_bag(bags / 'sweep', mass_kg=MASS)
    assert one.gait.period_s == 0.5 and '2 walking schedules' in ' '.join(one.extra['notes'])
    assert read_robot_bag(bags / 'sweep', mass_kg=MASS, segment=0).gait.period_s == 1.0


def test_a_bag_only_standing_is_refused_by_name(bags):
    with pytest.raises(BagContentError, match='no whole gait cycle'):
        read_robot_segments(bags / 'stand', mass_kg=MASS)


def test_energy_reports_one_run_per_schedule(bags, tmp_path):
    bench = tmp_path / 'bench'
    write_trace(simulate_bench(BenchPlan(loads_kg=(0.0, 0.3, 0.6),
                                         frequencies_hz=(0.0, 0.75, 1.25, 1.75, 2.25),
                                         walk_s=3.0), seed=2), bench)
    assert main(['--bench', str(bench), '--robot', str(bags / 'sweep'),
                 '--out', str(tmp_path / 'out'), '--no-progress']) == 0
    doc = json.loads((tmp_path / 'out' / 'energy.json').read_text())
    runs = doc['robot_runs']
    assert [r['period_s'] for r in runs] == [1.0, 0.5]
    assert [r['segment']['index'] for r in runs] == [0, 1]
    assert doc['prediction_error']['runs'] == 2
    for r in runs:
        assert abs(r['residual_w']) < 0.05 * r['measured_power_in_w']


def test_without_gait_phase_each_step_period_is_a_run(bags, tmp_path):
    """The same sweep recorded by a lab with its own gait code (no /gait/phase): the
    joint-derived step period changes from 1 s to 0.5 s; each period is its own run, with the
    power of the run recorded alone (within 1 %: joint-derived window edges)."""
    store = typestore()
    src, dst = bags / 'sweep', tmp_path / 'nogait'
    with AnyReader([src], default_typestore=store) as r, Writer(dst, version=8) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in r.connections if c.topic != '/gait/phase'}
        for c, t, raw in r.messages():
            if c.id in conns:
                w.write(conns[c.id], t, raw)
    runs = read_robot_segments(dst, mass_kg=MASS)
    assert [round(r.extra['period_s'], 2) for r in runs] == [1.0, 0.5]
    alone = [read_robot_bag(bags / n, mass_kg=MASS) for n in ('slow', 'fast')]
    for r, a in zip(runs, alone):
        assert r.power_in_w == pytest.approx(a.power_in_w, rel=0.01)
        assert r.extra['segment']['of'] == 2


def test_slip_labels_each_stance_with_the_gait_at_its_touchdown(tmp_path):
    """A RHex bag that switches gait (running, then walk): the reader keeps every change of
    /gait/phase and a stance takes the gait in force at its touchdown."""
    from hexapod_bench_drivers.edubot_bag import write_run
    from hexapod_bench_drivers.edubot_sim import simulate_edubot
    from slip_identification.cli import read_run

    parts = []
    for gait in ('running', 'walk'):
        write_run(tmp_path / gait, simulate_edubot(gait, duration_s=2.0, seed=1))
        parts.append(tmp_path / gait)
    run = read_run(concat(tmp_path / 'switch', parts))
    assert [g for _, g in run.gait_changes] == ['running', 'walk']
    t_switch = run.gait_changes[1][0]
    assert run.gait == 'running'
    assert run.gait_at(t_switch - 0.5) == 'running' and run.gait_at(t_switch + 0.5) == 'walk'
    single = read_run(parts[0])
    assert [g for _, g in single.gait_changes] == ['running']


def test_a_period_recomputed_every_tick_is_one_schedule(bags, tmp_path):
    """A gait node that recomputes its period from the speed every tick publishes values that
    differ in the last digits: still one schedule, the same run as the clean bag."""
    store = typestore()
    src, dst = bags / 'slow', tmp_path / 'jitter'
    with AnyReader([src], default_typestore=store) as r, Writer(dst, version=8) as w:
        conns = {c.id: w.add_connection(c.topic, c.msgtype, typestore=store)
                 for c in r.connections}
        for k, (c, t, raw) in enumerate(r.messages()):
            if c.topic == '/gait/phase':
                msg = r.deserialize(raw, c.msgtype)
                msg.period *= 1.0 + (1e-6 if k % 2 else -1e-6)
                raw = store.serialize_cdr(msg, c.msgtype)
            w.write(conns[c.id], t, raw)
    [run] = read_robot_segments(dst, mass_kg=MASS)
    clean = read_robot_bag(src, mass_kg=MASS)
    assert run.windows == clean.windows
    assert run.power_in_w == pytest.approx(clean.power_in_w, rel=1e-9)
