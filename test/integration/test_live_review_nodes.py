"""Live-graph review, node side: ``--help`` starts nothing, Ctrl-C under a publishing timer
exits 0, the energy monitor's masses, the simulated robot's joint/leg mismatches and mass."""

from __future__ import annotations

import dataclasses
import importlib
import json
from typing import Any

import pytest
import rclpy
from harness import ros_env
from rclpy.impl.implementation_singleton import rclpy_implementation
from rclpy.parameter import Parameter
from sensor_msgs.msg import JointState

from hexapod_common.node_utils import find_params_class, run_node, wants_help

#: (module, main function, node class) of every console-script node built on run_node
NODES = [
    ('hexapod_gait.gait_node', 'main', 'GaitSchedulerNode'),
    ('hexapod_energy.energy_node', 'main', 'EnergyMonitorNode'),
    ('hexapod_bench_drivers.sim_nodes', 'main_robot', 'SimRobotNode'),
    ('hexapod_bench_drivers.sim_nodes', 'main_bench', 'SimBenchNode'),
    ('hexapod_bench_drivers.dynamixel_node', 'main', 'DynamixelDriverNode'),
    ('hexapod_bench_drivers.power_node', 'main', 'PowerMonitorNode'),
    ('hexapod_bench_drivers.force_node', 'main', 'ForceSensorNode'),
    ('hexapod_bench_drivers.sequencer_node', 'main', 'BenchSequencerNode'),
    ('slip_identification.slip_node', 'main', 'SlipFitterNode'),
]


def _no_init(*args: Any, **kwargs: Any) -> None:
    raise AssertionError('--help must not initialise rclpy')


@pytest.mark.timeout(60)
@pytest.mark.parametrize('flag', ['--help', '-h'])
@pytest.mark.parametrize('module,func,cls', NODES)
def test_help_prints_the_parameters_and_starts_nothing(module: str, func: str, cls: str,
                                                       flag: str, capsys: Any,
                                                       monkeypatch: Any) -> None:
    """``gait_scheduler --help`` used to start walking (and publish /joint_commands)."""
    mod = importlib.import_module(module)
    monkeypatch.setattr(rclpy, 'init', _no_init)
    assert getattr(mod, func)([flag]) == 0
    out = capsys.readouterr().out
    params = find_params_class(getattr(mod, cls))
    assert params is not None
    assert out.startswith('usage: ')
    for fld in dataclasses.fields(params):
        assert f'  {fld.name} = ' in out, fld.name
        assert fld.metadata['description'].split()[0] in out


@pytest.mark.timeout(60)
def test_help_says_which_parameters_take_a_run_time_set(capsys: Any) -> None:
    """``--help`` did not say which parameters ``ros2 param set`` changes; its "settable" tags
    must be the declared descriptors' ``read_only`` negated, on every node."""
    from hexapod_common.errors import ParameterError
    from hexapod_common.node_utils import declare_params, writable_params

    checked = 0
    with ros_env() as env:
        for module, func, cls in NODES:
            mod = importlib.import_module(module)
            klass = getattr(mod, cls)
            params = find_params_class(klass)
            node = rclpy.create_node(f'help_{cls.lower()}', context=env.context)
            env.nodes.append(node)
            on_change = (lambda _p: None) if 'on_change' in _declare_call(klass) else None
            try:
                declare_params(node, params, on_change=on_change)
            except ParameterError:
                pass   # a required value (joints_file): every parameter is declared by then
            writable = {f.name for f in dataclasses.fields(params)
                        if not node.describe_parameter(f.name).read_only}
            assert writable_params(klass, params) == writable, cls
            getattr(mod, func)(['--help'])
            out = capsys.readouterr().out
            for fld in dataclasses.fields(params):
                line = next(ln for ln in out.splitlines() if ln.startswith(f'  {fld.name} = '))
                assert line.endswith(', settable)') == (fld.name in writable), line
            checked += 1
    assert checked == len(NODES)


def _declare_call(klass: type) -> str:
    import inspect
    import re

    for k in inspect.getmro(klass):
        try:
            src = inspect.getsource(k.__init__)
        except (OSError, TypeError):
            continue
        m = re.search(r'declare_params\(self[^)]*\)', src)
        if m:
            return m.group(0)
    return ''


def test_help_only_before_ros_args() -> None:
    assert wants_help(['--help']) and wants_help(['prog', '-h', '--ros-args'])
    assert not wants_help(['--ros-args', '-p', 'x:=1', '--help'])
    assert not wants_help([])


def _publishing_after_shutdown_factory(shutdown: bool) -> Any:
    """A node whose timer shuts the context down (as rclpy's SIGINT handler does, from its own
    thread) and then publishes, or (``shutdown=False``) fails with an RCLError of its own."""
    def factory() -> Any:
        node = rclpy.create_node('publish_after_shutdown')
        pub = node.create_publisher(JointState, 'joint_states', 10)

        def tick() -> None:
            if not shutdown:
                raise rclpy_implementation.RCLError('a real failure')
            rclpy.try_shutdown()
            pub.publish(JointState())   # RCLError: publisher's context is invalid
        node.create_timer(0.001, tick)
        return node
    return factory


@pytest.mark.timeout(60)
def test_publish_after_the_context_shut_down_is_a_clean_stop() -> None:
    """Ctrl-C crashed sim_robot (3 of 10 at 400 Hz) and gait_scheduler with a traceback and
    exit 1: ``RCLError: Failed to publish: publisher's context is invalid``."""
    assert run_node(_publishing_after_shutdown_factory(True), ['prog']) == 0
    assert not rclpy.ok()


@pytest.mark.timeout(60)
def test_ctrl_c_while_the_node_is_built_is_a_clean_stop(capsys: Any) -> None:
    """A slow start (energy_monitor builds its P_out model) interrupted by Ctrl-C was reported
    as ``error: RCLError: Failed to create publisher: rcl node's context is invalid``, exit 2."""
    def factory() -> Any:
        node = rclpy.create_node('built_after_shutdown')
        rclpy.try_shutdown()
        node.create_publisher(JointState, 'joint_states', 10)
        return node

    assert run_node(factory, ['prog']) == 0
    assert 'error' not in capsys.readouterr().err


@pytest.mark.timeout(60)
def test_an_rcl_error_with_the_context_up_is_still_raised() -> None:
    with pytest.raises(rclpy_implementation.RCLError, match='a real failure'):
        run_node(_publishing_after_shutdown_factory(False), ['prog'])
    assert not rclpy.ok()


# --- energy_monitor masses ------------------------------------------------------------------

def _energy(env: Any, **params: float) -> Any:
    """An energy monitor of ``env``'s context, not namespaced (``run_offline`` replays the
    bag's own topic names)."""
    from hexapod_energy.energy_node import EnergyMonitorNode

    node = EnergyMonitorNode(context=env.context, parameter_overrides=[
        Parameter('current_sign', value='ros'),
        *(Parameter(k, value=v) for k, v in params.items())])
    env.nodes.append(node)
    return node


@pytest.mark.timeout(60)
def test_energy_monitor_warns_when_the_mass_is_assumed() -> None:
    with ros_env('review_mass') as env:
        node = _energy(env)
        assert len(node.start_warnings) == 1
        assert "AntBot's 2.183 kg is assumed; give -p mass:=KG" in node.start_warnings[0]
        assert node.robot_mass_kg == pytest.approx(2.183)
        assert _energy(env, mass=2.183).start_warnings == []   # given, even if the same
        light = _energy(env, mass=1.6)
        assert light.start_warnings == [] and light.robot_mass_kg == pytest.approx(1.6)
        loaded = _energy(env, mass=2.5, robot_mass=2.183)       # a 0.317 kg payload
        assert loaded.start_warnings == [] and loaded.robot_mass_kg == pytest.approx(2.183)
        odd = _energy(env, mass=1.6, robot_mass=2.183)
        assert len(odd.start_warnings) == 1 and 'robot_mass 2.183 kg > mass 1.6' in \
            odd.start_warnings[0]


@pytest.mark.timeout(120)
def test_energy_monitor_p_out_model_equals_the_offline_command(tmp_path: Any) -> None:
    """``-p mass:=1.6`` used to give P_out for a 2.183 kg robot (robot_mass defaulted to
    AntBot's); now the figure of ``hexapod-analyze energy --robot-mass 1.6``."""
    from hexapod_common.replay import run_offline
    from hexapod_common.testbags import write_two_battery_robot_bag
    from hexapod_energy.cli import main as energy_main
    from hexapod_energy.leg_description import antbot_leg
    from hexapod_gait.gait import make_gait

    bag = tmp_path / 'bag'
    write_two_battery_robot_bag(bag, logic_w=0.0)
    with ros_env('review_pout') as env:
        node = _energy(env, mass=1.6)
        live = run_offline([node], str(bag))['/energy/descriptors']
    assert len(live) >= 10
    assert energy_main(['--robot', str(bag), '--robot-mass', '1.6', '--out',
                        str(tmp_path / 'out'), '--no-progress']) == 0
    [run] = json.loads((tmp_path / 'out' / 'energy.json').read_text())['robot_runs']
    assert run['power_out_source'] == 'model'
    for m in live:
        assert m.power_out == pytest.approx(run['power_out_w'], rel=1e-6)
    gait = make_gait('tripod', period_s=0.5, step_length_m=0.1)
    antbot = float(antbot_leg().output_power_model(2.183).power_out_w(gait))
    # not the 2.183 kg robot's any more (1.339 W against 1.377 W for this gait)
    assert live[0].power_out < 0.99 * antbot


@pytest.mark.timeout(60)
def test_energy_monitor_warns_on_an_infeasible_schedule() -> None:
    """The live monitor computed a tripod at 4.5 Hz without a word (the offline command warned
    on its bag): each infeasible schedule is now noted once, under the ``limits`` parameter."""
    from hexapod_interfaces.msg import GaitPhase

    def phase(t: float, period: float) -> GaitPhase:
        msg = GaitPhase()
        msg.header.stamp.sec, msg.header.stamp.nanosec = 1 + int(t), int(1e9 * (t % 1.0))
        msg.gait, msg.period, msg.duty_factor = 'tripod', period, 0.5
        msg.step_length, msg.step_height, msg.cycle_phase = 0.1, 0.04, (t / period) % 1.0
        msg.leg_names = ['L1', 'L2', 'L3', 'R1', 'R2', 'R3']
        msg.phase_offsets = [0.0, 0.5, 0.0, 0.5, 0.0, 0.5]
        msg.in_stance = [True, False, True, False, True, False]
        msg.supporting_legs = 3
        return msg

    with ros_env('review_feasible') as env:
        node = _energy(env, mass=2.183)
        for k in range(20):
            node._on_gait(phase(0.01 * k, 0.2222))
        assert len(node.core.infeasible_) == 1
        assert any('4.5 Hz > maximum 3 Hz' in n for n in node.core.notes_)
        loose = _energy(env, mass=2.183, limits=[0.1, 0.1, 5.0])
        for k in range(20):
            loose._on_gait(phase(0.01 * k, 0.2222))
        assert loose.core.infeasible_ == []
        slow = _energy(env, mass=2.183)
        slow._on_gait(phase(0.0, 1.0))
        assert slow.core.infeasible_ == []


# --- sim_robot ------------------------------------------------------------------------------

def _commands(names: list[str]) -> JointState:
    msg = JointState()
    msg.header.stamp.sec = 1
    msg.name = names
    msg.position = [0.1] * len(names)
    msg.velocity = [0.0] * len(names)
    return msg


@pytest.mark.timeout(60)
def test_sim_robot_reports_joints_it_does_not_have() -> None:
    from hexapod_bench_drivers.sim_nodes import SimRobotNode
    from hexapod_gait.legs import joint_names

    with ros_env('review_joints') as env:
        sim = env.make(SimRobotNode)
        pub_node = env.add(rclpy.create_node('cmd_pub', context=env.context,
                                             namespace=env.namespace))
        pub = pub_node.create_publisher(JointState, 'joint_commands', 10)
        eight = [j for leg in ('L1', 'L2', 'L3', 'L4', 'R1', 'R2', 'R3', 'R4')
                 for j in joint_names(leg)]
        hips = [f'{leg}_hip' for leg in ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')]
        for names, n in ((eight, 1), (hips, 2)):
            assert env.spin_until(lambda: pub.publish(_commands(names)) or
                                  len(sim.name_notes) >= n, timeout_s=20.0)
        # the same sets again say nothing new; a third set (after them, in order) is said
        for names in (eight, hips, eight):
            pub.publish(_commands(names))
        other = ['L1_coxa', 'X9_coxa']
        assert env.spin_until(lambda: pub.publish(_commands(other)) or
                              len(sim.name_notes) >= 3, timeout_s=20.0)
        assert [level for level, _ in sim.name_notes] == ['warning', 'error', 'warning']
        warning, error, third = (text for _, text in sim.name_notes)
        assert 'L4_coxa' in warning and 'R4_tibia' in warning and '6 legs' in warning
        assert 'L1_hip' in error and 'none of its 6 joints' in error
        assert 'X9_coxa' in third and 'L1_coxa,' not in third.split('(ours')[0]


@pytest.mark.timeout(60)
def test_sim_robot_lighter_than_its_legs_is_refused_in_one_line(capsys: Any,
                                                                monkeypatch: Any) -> None:
    from hexapod_bench_drivers.sim_nodes import main_robot

    monkeypatch.delenv('HEXAPOD_DEBUG', raising=False)
    assert main_robot(['sim_robot', '--ros-args', '-p', 'leg_count:=8',
                       '-p', 'robot_mass:=1.0']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'Traceback' not in err[0]
    assert 'robot_mass' in err[0] and 'leg_count' in err[0] and 'outweigh' in err[0]
    assert not rclpy.ok()
