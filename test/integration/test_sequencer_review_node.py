"""bench_sequencer with a real gait_scheduler after the outside review: a signal, an overheating
servo or a silent driver abort the plan safely (stand, then torque off, ``aborted``, exit 1);
the session gait is set atomically and a refused one aborts (FINDINGS S1-S5, S8)."""

from __future__ import annotations

import json

import pytest
import rclpy
from harness import Collector, ctrl_c, ros_env
from hexapod_common.bags import iter_messages, open_reader
from hexapod_interfaces.msg import BenchSession, GaitPhase, ServoStatus
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from std_srvs.srv import SetBool

from hexapod_gait.gait_node import GaitSchedulerNode

from hexapod_bench_drivers.sequencer import OVERHEATING_FLAG
from hexapod_bench_drivers.sequencer_node import BenchSequencerNode, abort_on_signals

LATCHED = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
SID = 'load0.000kg_f1.00Hz_b0.50_s0.100m'


class Bench:
    """Fake servo driver: servo_status (temperature, error flags) and a set_torque service
    that notes the gait node's step length at each call."""

    def __init__(self, env, gait):
        self.temp, self.flags, self.status_on, self.calls = 26.0, 0, True, []
        self.node = env.add(rclpy.create_node('fake_bench', context=env.context,
                                              namespace=env.namespace))
        self.pub = self.node.create_publisher(ServoStatus, 'servo_status', 10)
        self.node.create_service(SetBool, 'set_torque', self._torque)
        self.node.create_timer(0.02, self._tick)
        self.gait = gait

    def _torque(self, request, response):
        sched = self.gait.scheduler
        step = sched.state(self.gait._now_s()).gait.step_length_m if sched else None
        self.calls.append((request.data, step))
        response.success = True
        return response

    def _tick(self):
        if self.status_on:
            self.pub.publish(ServoStatus(name=['a', 'b', 'c'], temperature=[self.temp] * 3,
                                         error=[self.flags] * 3))


def _start(env, tmp_path, plan='loads_kg: [0.0]\nfrequencies_hz: [1.0]\nwalk_duration_s: 30.0\n',
           gait_kw=None, **seq_kw):
    (tmp_path / 'plan.yaml').write_text(plan)
    gait = env.make(GaitSchedulerNode, parameter_overrides=[
        Parameter(k, value=v) for k, v in {'rate': 50.0, 'step_length': 0.0,
                                           'step_height': 0.0, **(gait_kw or {})}.items()])
    bench = Bench(env, gait)
    kw = {'plan_file': str(tmp_path / 'plan.yaml'), 'state_file': str(tmp_path / 'state.json'),
          'output_dir': str(tmp_path / 'bags'), 'auto_load_change': True, 'rate_hz': 20.0,
          'gait_node': 'gait_scheduler', 'torque_service': 'set_torque',
          # the topics this test graph publishes: a recorded topic never received by the end
          # of `starting` aborts the plan now (outside integration review D4)
          'record_topics': ['servo_status', 'joint_commands', 'gait/phase', 'bench/session'],
          **seq_kw}
    node = env.make(BenchSequencerNode,
                    parameter_overrides=[Parameter(k, value=v) for k, v in kw.items()])
    sessions = Collector(env, BenchSession, 'bench/session', LATCHED)
    return gait, bench, node, sessions


def _walk(env, gait, sessions):
    assert env.spin_until(lambda: any(m.state == 'walking' for m in sessions.messages), 20)
    assert env.spin_until(lambda: gait.scheduler.state(gait._now_s()).gait.step_length_m
                          == pytest.approx(0.1), 20)


def _check_safe_abort(env, tmp_path, gait, bench, node, sessions):
    assert env.spin_until(node.finished.done, 20)
    assert node.finished.result() == 1
    assert env.spin_until(lambda: sessions.messages[-1].state == 'aborted', 10)
    # torque went off once after the walk, once the gait node had stood the leg (step 0),
    # never mid-step (the first call is the torque off of idle, before any walk)
    assert [c[0] for c in bench.calls][-2:] == [True, False]
    assert [c[0] for c in bench.calls].count(False) <= 2
    assert bench.calls[-1][1] == 0.0
    assert gait.params.step_length == 0.0 and gait.params.step_height == 0.0
    assert not (tmp_path / 'bags' / SID).exists()           # the partial bag is moved aside
    assert (tmp_path / 'bags' / f'{SID}.interrupted-1').exists()
    assert not (tmp_path / 'state.json').exists()           # nothing counted


@pytest.mark.timeout(90)
def test_sigint_aborts_the_plan_safely(tmp_path):
    with ros_env('seqrev') as env:
        gait, bench, node, sessions = _start(env, tmp_path)
        _walk(env, gait, sessions)
        ctrl_c(abort_on_signals, node)
        assert node.seq.abort_reason == 'SIGINT received'
        _check_safe_abort(env, tmp_path, gait, bench, node, sessions)


@pytest.mark.timeout(90)
def test_overheating_while_walking_aborts_the_plan_safely(tmp_path):
    with ros_env('seqrev') as env:
        gait, bench, node, sessions = _start(env, tmp_path)
        _walk(env, gait, sessions)
        bench.temp, bench.flags = 40.0, OVERHEATING_FLAG
        _check_safe_abort(env, tmp_path, gait, bench, node, sessions)
        assert 'overheating' in node.seq.abort_reason


@pytest.mark.timeout(90)
def test_silent_servo_status_while_walking_aborts_the_plan(tmp_path):
    with ros_env('seqrev') as env:
        gait, bench, node, sessions = _start(env, tmp_path, stream_timeout_s=0.3)
        _walk(env, gait, sessions)
        bench.status_on = False
        _check_safe_abort(env, tmp_path, gait, bench, node, sessions)
        assert 'no servo_status for' in node.seq.abort_reason


@pytest.mark.timeout(90)
@pytest.mark.parametrize('gait_kw, what, why', [
    # the wave at the plan's duty factor 0.5 lifts a whole side: the gait node refuses it
    ({'gait': 'wave', 'duty_factor': 5 / 6}, 'the session gait', 'lifts every leg of side'),
    # speed mode ignores the period (FINDINGS G5): the gait node refuses it now
    ({'speed': 0.3}, 'the stand', 'ignored while speed'),
])
def test_a_refused_gait_aborts_and_is_not_recorded(tmp_path, gait_kw, what, why):
    with ros_env('seqrev') as env:
        gait, bench, node, sessions = _start(env, tmp_path, gait_kw=gait_kw)
        assert env.spin_until(node.finished.done, 30)
        assert node.finished.result() == 1
        assert env.spin_until(lambda: sessions.messages[-1].state == 'aborted', 10)
        assert f'refused {what}' in node.seq.abort_reason and why in node.seq.abort_reason
        assert not (tmp_path / 'bags' / SID).exists()
        assert not (tmp_path / 'state.json').exists()
        assert gait.params.step_length == 0.0          # the leg never walked the refused gait


@pytest.mark.timeout(90)
def test_session_gait_is_applied_atomically(tmp_path):
    # From T = 2 s, beta 0.8 to T = 0.4 s, beta 0.5: one parameter at a time, the period
    # (0.4 s with beta 0.8: a 0.08 s swing) would be refused (FINDINGS S4).
    plan = ('loads_kg: [0.0]\nfrequencies_hz: [2.5]\nduty_factors: [0.5]\n'
            'walk_duration_s: 1.0\n')
    with ros_env('seqrev') as env:
        gait, bench, node, sessions = _start(env, tmp_path, plan,
                                             gait_kw={'period': 2.0, 'duty_factor': 0.8})
        assert env.spin_until(lambda: any(m.state == 'walking' for m in sessions.messages), 20)
        assert env.spin_until(lambda: gait.params.period == 0.4, 20)
        assert gait.params.duty_factor == 0.5 and node.seq.state != 'aborted'
        assert env.spin_until(node.finished.done, 30)
        assert node.finished.result() == 0
        sid = 'load0.000kg_f2.50Hz_b0.50_s0.100m'
        assert json.loads((tmp_path / 'state.json').read_text())['completed'] == [sid]
    # The recording started once the gait node had settled at the session gait (FINDINGS S6):
    # every /gait/phase in the bag is the session's gait, none of the ramp from standing.
    with open_reader(tmp_path / 'bags' / sid) as reader:
        phases = [deserialize_message(m.data, GaitPhase)
                  for m in iter_messages(reader, ['/gait/phase'])]
    assert len(phases) > 10
    assert {(m.period, m.duty_factor, m.step_length, m.step_height) for m in phases} == \
        {(0.4, 0.5, 0.1, 0.04)}


@pytest.mark.timeout(90)
def test_a_recorded_topic_gone_silent_while_walking_aborts_the_plan(tmp_path):
    # /bench/ground_force stops (a load cell unplugged) mid-session: the bag would lack the
    # force the phase split needs; it was watched only through the bag's topic count.
    from geometry_msgs.msg import WrenchStamped

    with ros_env('seqrev') as env:
        gait, bench, node, sessions = _start(
            env, tmp_path, stream_timeout_s=0.3,
            record_topics=['servo_status', 'gait/phase', 'bench/session', 'bench/ground_force'])
        force = env.add(rclpy.create_node('fake_force', context=env.context,
                                          namespace=env.namespace))
        pub = force.create_publisher(WrenchStamped, 'bench/ground_force', 10)
        force_on = [True]
        force.create_timer(0.02, lambda: force_on[0] and pub.publish(WrenchStamped()))
        _walk(env, gait, sessions)
        assert env.spin_until(lambda: 'bench/ground_force' in node._seen_ns, 10)
        assert node.seq.state != 'aborted'
        force_on[0] = False
        _check_safe_abort(env, tmp_path, gait, bench, node, sessions)
        assert 'no bench/ground_force for' in node.seq.abort_reason
