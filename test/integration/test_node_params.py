"""Node conventions (hexapod_common.node_utils): which parameters a run-time change may touch,
finite numbers, and the one-line start-up error of the console scripts."""

from __future__ import annotations

import math
from dataclasses import dataclass

import pytest
import rclpy
from harness import ros_env
from rclpy.node import Node
from rclpy.parameter import Parameter

from hexapod_common.errors import ParameterError
from hexapod_common.node_utils import declare_params, param, run_node, validate_params


@dataclass(frozen=True)
class _Params:
    rate_hz: float = param(10.0, 'a timer period, read once')
    label: str = param('', 'read at every use', live=True)
    limit: float = param(1.0, 'a limit', validate=lambda v: None if v > 0 else 'must be > 0')
    off: float = param(math.nan, 'NaN = off', finite=False)
    box: list[float] = param([0.0, 1.0], 'two numbers')


class _Node(Node):
    def __init__(self, *, context, namespace, on_change=None, parameter_overrides=None):
        super().__init__('params_node', context=context, namespace=namespace,
                         parameter_overrides=parameter_overrides or [])
        self.changes = []
        declare_params(self, _Params, on_change=on_change)


def test_without_a_handler_only_live_parameters_change_at_run_time():
    with ros_env('np') as env:
        node = env.make(_Node)
        [rate] = node.set_parameters([Parameter('rate_hz', value=1.0)])
        assert not rate.successful and 'read-only' in rate.reason
        assert node.params.rate_hz == 10.0
        [label] = node.set_parameters([Parameter('label', value='x')])
        assert label.successful and node.params.label == 'x'


def test_with_a_handler_the_handler_gets_every_change():
    with ros_env('np') as env:
        changes = []
        node = env.make(_Node, on_change=lambda p: changes.append(p.rate_hz))
        [ok] = node.set_parameters([Parameter('rate_hz', value=2.0)])
        assert ok.successful and changes == [2.0] and node.params.rate_hz == 2.0


@pytest.mark.parametrize('name,value', [('limit', math.nan), ('limit', math.inf),
                                        ('box', [0.0, math.nan])])
def test_non_finite_numbers_are_refused(name, value):
    with pytest.raises(ParameterError, match=f"'{name}'.*finite"):
        validate_params(_Params, {name: value})
    assert math.isnan(validate_params(_Params, {'off': math.nan}).off)


def test_non_finite_numbers_are_refused_at_run_time():
    with ros_env('np') as env:
        node = env.make(_Node, on_change=lambda p: None)
        [res] = node.set_parameters([Parameter('limit', value=math.nan)])
        assert not res.successful and 'finite' in res.reason
        assert node.params.limit == 1.0


def test_a_wrong_type_at_start_up_is_a_parameter_error():
    with ros_env('np') as env, pytest.raises(ParameterError, match="'rate_hz'"):
        env.make(_Node, parameter_overrides=[Parameter('rate_hz', value='abc')])



@pytest.mark.timeout(60)
def test_a_whole_number_for_a_float_parameter_is_taken_as_a_float_at_start_up():
    # energy_monitor --ros-args -p mass:=2 (an INTEGER override of a DOUBLE parameter)
    from hexapod_energy.energy_node import EnergyMonitorNode

    with ros_env('np') as env:
        node = env.make(EnergyMonitorNode, parameter_overrides=[Parameter('mass', value=2)])
        assert node.params.mass == 2.0 and isinstance(node.params.mass, float)
        assert node.get_parameter('mass').type_ == Parameter.Type.DOUBLE
        other = env.make(_Node, parameter_overrides=[Parameter('rate_hz', value=5),
                                                     Parameter('box', value=[1, 2])])
        assert other.params.rate_hz == 5.0 and isinstance(other.params.rate_hz, float)
        assert other.params.box == [1.0, 2.0]
        assert all(isinstance(v, float) for v in other.params.box)
        assert other.get_parameter('box').type_ == Parameter.Type.DOUBLE_ARRAY


@pytest.mark.timeout(60)
@pytest.mark.parametrize('value', [True, 'abc'])
def test_a_bool_or_a_string_for_a_float_parameter_is_still_refused_at_start_up(value):
    with ros_env('np') as env, pytest.raises(ParameterError, match="'limit'.*DOUBLE"):
        env.make(_Node, parameter_overrides=[Parameter('limit', value=value)])


@pytest.mark.timeout(60)
def test_a_whole_number_for_a_float_parameter_is_taken_as_a_float_at_run_time():
    # ros2 param set /params_node limit 3: the SetParameters service with an INTEGER value
    from rcl_interfaces.srv import SetParameters

    with ros_env('np') as env:
        seen = []
        node = env.make(_Node, on_change=lambda p: seen.append(p.limit))
        client_node = env.add(rclpy.create_node('np_client', context=env.context,
                                                namespace=env.namespace))
        client = client_node.create_client(SetParameters,
                                           f'{node.get_fully_qualified_name()}/set_parameters')
        assert env.spin_until(client.service_is_ready, timeout_s=30.0)

        def call(name, value):
            fut = client.call_async(SetParameters.Request(
                parameters=[Parameter(name, value=value).to_parameter_msg()]))
            env.executor.spin_until_future_complete(fut, timeout_sec=30.0)
            assert fut.done()
            [result] = fut.result().results
            return result

        assert call('limit', 3).successful
        assert node.params.limit == 3.0 and isinstance(node.params.limit, float)
        assert seen == [3.0] and isinstance(seen[0], float)
        assert node.get_parameter('limit').type_ == Parameter.Type.DOUBLE
        assert call('box', [2, 5]).successful and node.params.box == [2.0, 5.0]
        for bad in (True, 'abc'):
            res = call('limit', bad)
            assert not res.successful and 'type' in res.reason.lower()
        assert node.params.limit == 3.0
        res = call('limit', -1)   # still validated after the conversion
        assert not res.successful and 'must be > 0' in res.reason


def _failing_factory(exc):
    def factory():
        raise exc
    return factory


@pytest.mark.parametrize('exc', [ParameterError("parameter 'mass' = -1.0 refused"),
                                 FileNotFoundError('/nonexistent.yaml'),
                                 ValueError('hip_x must have 3 values')])
def test_run_node_start_up_error_is_one_line_and_exit_2(exc, capsys, monkeypatch):
    monkeypatch.delenv('HEXAPOD_DEBUG', raising=False)
    assert run_node(_failing_factory(exc), ['prog']) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'Traceback' not in err[0]
    assert str(exc) in err[0] and 'error' in err[0]
    assert not rclpy.ok()   # the context was shut down


@pytest.mark.parametrize('argv, says', [
    (['prog', '-p', 'speed:=0.3'], 'go after --ros-args'),
    (['prog', '--speed', '0.3', '--ros-args', '-p', 'x:=1'], 'unrecognized argument(s) --speed'),
    (['prog', '--ros-args', '--params-file', '/nonexistent.yaml'], "Couldn't parse params"),
    (['prog', '--ros-args', '-r', '__ns:=robot1'], 'ROS arguments were refused'),
])
def test_run_node_refuses_stray_and_bad_ros_arguments(argv, says, capsys, monkeypatch):
    """'-p speed:=0.3' without --ros-args was ignored and the robot walked the defaults; a
    params file missing or a remap malformed gave a traceback and exit 1 (an outside
    review): one line, exit 2, no node built."""
    monkeypatch.delenv('HEXAPOD_DEBUG', raising=False)
    built = []
    assert run_node(lambda: built.append(1), argv) == 2
    err = capsys.readouterr().err
    assert says in err and 'Traceback' not in err and not built
    assert not rclpy.ok()


def test_run_node_debug_shows_the_traceback(monkeypatch):
    monkeypatch.setenv('HEXAPOD_DEBUG', '1')
    with pytest.raises(ValueError, match='bad'):
        run_node(_failing_factory(ValueError('bad')), ['prog'])
    assert not rclpy.ok()


@pytest.mark.parametrize('module,args,expected', [
    ('hexapod_energy.energy_node', ['mass:=abc'], "'mass'"),
    ('hexapod_energy.energy_node', ['mass:=.inf'], "'mass'"),
    ('hexapod_energy.energy_node', ['leg_file:=/nonexistent.yaml'], '/nonexistent.yaml'),
    ('slip_identification.slip_node', ['model:=bogus'], 'bogus'),
    ('slip_identification.slip_node', ['ground:=0.0', 'hip_x:=[1.0]'], "'hip_x'"),
    ('slip_identification.slip_node', ['hip_x:=[1.0]'], "'hip_x'"),
    ('slip_identification.slip_node', ['box:=[1.0]'], "'box'"),
    ('slip_identification.slip_node', ['mocap_offset:=.inf'], "'mocap_offset'"),
])
@pytest.mark.timeout(60)
def test_console_scripts_refuse_bad_start_up_values_in_one_line(module, args, expected, capsys,
                                                                monkeypatch):
    import importlib

    monkeypatch.delenv('HEXAPOD_DEBUG', raising=False)
    main = importlib.import_module(module).main
    argv = ['node', '--ros-args'] + [x for a in args for x in ('-p', a)]
    assert main(argv) == 2
    err = [ln for ln in capsys.readouterr().err.splitlines() if ln.strip()]
    assert len(err) == 1, err
    assert expected in err[0] and 'Traceback' not in err[0]


def test_a_start_up_parameter_the_node_does_not_declare_is_warned_of():
    """``-p mas:=3.0`` ran on the default mass and ``-p sped:=0.9`` walked at the default
    speed without a word (an outside review): now a warning naming the closest parameter."""
    with ros_env('np') as env:
        node = env.make(_Node, parameter_overrides=[Parameter('rat_hz', value=1.0),
                                                    Parameter('limit', value=2.0),
                                                    Parameter('zzz', value=1),
                                                    Parameter('lab', value=1)])
        assert node.params.limit == 2.0
        assert set(node.unknown_parameters_) == {'rat_hz', 'zzz', 'lab'}
        assert "did you mean 'rate_hz'" in node.unknown_parameters_['rat_hz']
        assert '--help' in node.unknown_parameters_['zzz']
        # a name far from any of this node's (another node's, from a shared /** file) is no
        # typo: no wrong hint (review D: 'port' read "did you mean 'preset'?")
        assert 'did you mean' not in node.unknown_parameters_['lab']
