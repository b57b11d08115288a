"""Bags recorded under other topic names are read through a topic remapping (open_reader,
HEXAPOD_BAG_REMAP, ``hexapod-analyze --namespace/--remap``)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from hexapod_bench_drivers.robot_sim import RobotConfig, simulate_robot
from hexapod_bench_drivers.sim_bag import write_trace
from hexapod_common.analyze_cli import main as analyze_main
from hexapod_common.bags import (
    REMAP_ENV,
    BagWriter,
    iter_messages,
    new_msg,
    open_reader,
    parse_remap,
    stamp,
)
from hexapod_common.errors import BagReadError


def _bag(path: Path, topics: list[str]) -> Path:
    with BagWriter(path) as w:
        for k in range(5):
            for topic in topics:
                msg = new_msg('sensor_msgs/msg/BatteryState', header=stamp(k * 10_000_000),
                              voltage=12.0 + k, current=-1.0)
                w.write(topic, 'sensor_msgs/msg/BatteryState', msg, k * 10_000_000)
    return path


def test_namespace_and_remap_rename_connections(tmp_path: Path) -> None:
    bag = _bag(tmp_path / 'b', ['/antbot/battery_state', '/lab/power', '/joint_states'])
    with open_reader(bag, namespace='/antbot', remap={'/lab/power': '/power_in'}) as r:
        assert sorted(c.topic for c in r.connections) == ['/battery_state', '/joint_states',
                                                          '/power_in']
        got = [(m.topic, r.deserialize(m.data, m.msgtype).voltage)
               for m in iter_messages(r, ['/battery_state'])]
    assert got == [('/battery_state', 12.0 + k) for k in range(5)]
    with open_reader(bag) as r:                       # no remapping: recorded names
        assert '/antbot/battery_state' in {c.topic for c in r.connections}


def test_ambiguous_or_bad_remap_is_refused(tmp_path: Path) -> None:
    bag = _bag(tmp_path / 'b', ['/a/battery_state', '/b/battery_state'])
    with pytest.raises(BagReadError, match='ambiguous'):
        open_reader(bag, remap={'/a/battery_state': '/battery_state',
                                '/b/battery_state': '/battery_state'})
    with pytest.raises(ValueError, match='FROM:=TO'):
        parse_remap(['/joint_states'])
    assert parse_remap(['robot/js:=joint_states']) == {'/robot/js': '/joint_states'}


def test_environment_remap_applies_to_every_reader(tmp_path: Path, monkeypatch) -> None:
    bag = _bag(tmp_path / 'b', ['/r2/battery_state'])
    monkeypatch.setenv(REMAP_ENV, json.dumps({'remap': {}, 'namespace': 'r2'}))
    with open_reader(bag) as r:
        assert [c.topic for c in r.connections] == ['/battery_state']
    monkeypatch.setenv(REMAP_ENV, '{not json')
    with pytest.raises(BagReadError, match=REMAP_ENV):
        open_reader(bag)


def test_analyze_energy_on_a_namespaced_robot_bag(tmp_path: Path, monkeypatch) -> None:
    """Another lab's bag: every topic under /antbot; the energy analysis reads it with
    --namespace and gives the same numbers as the same run under the contract names."""
    from hexapod_bench_drivers.bench_sim import BenchConfig, BenchPlan, BenchSimulator
    from hexapod_energy.bag_io import read_robot_bag

    monkeypatch.setenv(REMAP_ENV, '')     # empty = no remapping; restored after the test
    write_trace(simulate_robot(3.0, RobotConfig(speed_mps=0.3), seed=1), tmp_path / 'robot')
    plan = BenchPlan(loads_kg=(0.0, 0.2, 0.4), frequencies_hz=(0.0, 1.0, 2.0, 3.0), walk_s=2.0,
                     max_cool_s=1.0)
    write_trace(BenchSimulator(BenchConfig(), seed=3).run_plan(plan), tmp_path / 'bench')
    ns_bag = tmp_path / 'robot_ns'
    with open_reader(tmp_path / 'robot') as r, BagWriter(ns_bag) as w:
        for m in iter_messages(r):
            w.write('/antbot' + m.topic, m.msgtype, m.data, m.stamp_ns)
    plain = read_robot_bag(tmp_path / 'robot', mass_kg=2.3)
    with pytest.raises(Exception, match='/battery_state'):       # the missing topic is named
        read_robot_bag(ns_bag, mass_kg=2.3)
    monkeypatch.setenv(REMAP_ENV, json.dumps({'remap': {}, 'namespace': '/antbot'}))
    renamed = read_robot_bag(ns_bag, mass_kg=2.3)
    monkeypatch.setenv(REMAP_ENV, '')
    assert renamed.windows == plain.windows
    assert renamed.power_in_w == pytest.approx(plain.power_in_w, rel=1e-12)
    assert renamed.speed_mps == pytest.approx(plain.speed_mps, rel=1e-12)

    # the command line: --namespace before the command name, for every bag of the run
    rc = analyze_main(['--namespace', '/antbot', 'energy', '--bench', str(tmp_path / 'bench'),
                       '--robot', str(ns_bag), '--out', str(tmp_path / 'out'), '--no-progress'])
    assert rc == 0
    assert os.environ[REMAP_ENV] == ''               # main() leaves the environment as it was
    doc = json.loads((tmp_path / 'out' / 'energy.json').read_text())
    assert doc['robot_runs'][0]['measured_power_in_w'] == pytest.approx(plain.power_in_w,
                                                                         rel=1e-12)
    with pytest.raises(SystemExit):
        analyze_main(['--remap', 'no-separator', 'energy', '--bench', 'x', '--out', 'y'])

    # the README's form: several FROM:=TO items right before the command name (a greedy
    # nargs='+' used to swallow the command and its bags: "invalid choice")
    ren_bag = tmp_path / 'robot_ren'
    with open_reader(tmp_path / 'robot') as r, BagWriter(ren_bag) as w:
        for m in iter_messages(r):
            w.write({'/battery_state': '/lab/power', '/gait/phase': '/lab/gait'}.get(
                m.topic, m.topic), m.msgtype, m.data, m.stamp_ns)
    rc = analyze_main(['--remap', '/lab/power:=/battery_state', '/lab/gait:=/gait/phase',
                       'energy', '--robot', str(ren_bag), '--out', str(tmp_path / 'out2'),
                       '--no-progress'])
    assert rc == 0
    doc = json.loads((tmp_path / 'out2' / 'energy.json').read_text())
    assert doc['robot_runs'][0]['measured_power_in_w'] == pytest.approx(plain.power_in_w,
                                                                         rel=1e-12)


def test_spelled_out_mapping_options() -> None:
    from hexapod_common.analyze_cli import _spell_out_mappings

    assert _spell_out_mappings(['--remap', 'a:=b', 'c:=d', 'energy', '--robot', 'x:=y']) == [
        '--remap', 'a:=b', '--remap', 'c:=d', 'energy', '--robot', 'x:=y']
    assert _spell_out_mappings(['--joint-map', 'h0:=L1_hip', '--namespace', 'n', 'slip']) == [
        '--joint-map', 'h0:=L1_hip', '--namespace', 'n', 'slip']
    assert _spell_out_mappings(['--remap', 'bad', 'energy']) == ['--remap', 'bad', 'energy']


def test_joint_map_renames_joint_states(monkeypatch) -> None:
    """``HEXAPOD_JOINT_MAP`` (``hexapod-analyze --joint-map``): recorded joint names read as the
    contract's; unlisted names pass; malformed maps are refused by name."""
    from hexapod_common.conversions import (
        JOINT_MAP_ENV,
        joint_map,
        joint_state_from_msg,
        parse_joint_map,
    )

    msg = new_msg('sensor_msgs/msg/JointState', header=stamp(0), name=['hip_0', 'hip_1', 'x'],
                  position=[0.1, 0.2, 0.3], velocity=[], effort=[])
    monkeypatch.delenv(JOINT_MAP_ENV, raising=False)
    assert joint_state_from_msg(msg).names == ('hip_0', 'hip_1', 'x') and joint_map() == {}
    monkeypatch.setenv(JOINT_MAP_ENV, json.dumps({'hip_0': 'L1_hip', 'hip_1': 'L2_hip'}))
    sample = joint_state_from_msg(msg)
    assert sample.names == ('L1_hip', 'L2_hip', 'x')
    assert list(sample.position) == [0.1, 0.2, 0.3]
    for bad in (['hip_0'], ['a:=L1_hip', 'b:=L1_hip'], ['a:=x', 'a:=y'], [':=L1_hip']):
        with pytest.raises(ValueError):
            parse_joint_map(bad)
    monkeypatch.setenv(JOINT_MAP_ENV, '[1, 2]')
    with pytest.raises(ValueError, match=JOINT_MAP_ENV):
        joint_state_from_msg(msg)
    with pytest.raises(SystemExit):
        analyze_main(['--joint-map', 'a:=L1_hip', 'b:=L1_hip', 'slip', 'x', '--out', 'y'])


def test_joint_map_names_that_match_nothing_or_collide_are_warned(tmp_path: Path,
                                                                  capsys) -> None:
    """``--joint-map a:=L1_hip`` (no joint ``a`` recorded) and ``L1_hip:=L2_hip`` (the bag has
    an ``L2_hip`` already: two joints would share the name) ran without a word."""
    bag = tmp_path / 'j'
    with BagWriter(bag) as w:
        for k in range(3):
            msg = new_msg('sensor_msgs/msg/JointState', header=stamp(k * 10_000_000),
                          name=['L1_hip', 'L2_hip'], position=[0.0, 0.0],
                          velocity=[0.0, 0.0], effort=[0.0, 0.0])
            w.write('/joint_states', 'sensor_msgs/msg/JointState', msg, k * 10_000_000)
    analyze_main(['--joint-map', 'a:=L3_hip', '--joint-map', 'L1_hip:=L2_hip', 'slip',
                  str(bag), '--out', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert '--joint-map a:=L3_hip: no given bag records a joint a' in err
    assert '--joint-map L1_hip:=L2_hip: the bags record a joint L2_hip already' in err
    analyze_main(['--joint-map', 'L1_hip:=R1_hip', 'slip', str(bag), '--out',
                  str(tmp_path / 'o2')])
    assert '--joint-map' not in capsys.readouterr().err
