"""bench_sequencer after the outside integration review (/tmp/review_integ FINDINGS D1, D4-D6):
an empty gait_node / torque_service is warned about and no message claims a torque off; a
driver gone says the torque service is unavailable; a dead gait node is not waited for, the
torque is kept on and the operator told to support the stage; a best-effort publisher is
recorded; a recorded topic never received aborts instead of counting the session."""

from __future__ import annotations

import json
import sys

import pytest
import rclpy
from geometry_msgs.msg import PointStamped, WrenchStamped
from harness import Collector, ros_env
from hexapod_common.bags import iter_messages, open_reader
from hexapod_interfaces.msg import BenchSession, ServoStatus
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from rclpy.serialization import deserialize_message
from std_srvs.srv import SetBool

from hexapod_gait.gait_node import GaitSchedulerNode

from hexapod_bench_drivers.sequencer_node import BenchSequencerNode

LATCHED = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)
SID = 'load0.000kg_f1.00Hz_b0.50_s0.100m'
PLAN = 'loads_kg: [0.0]\nfrequencies_hz: [1.0]\nwalk_duration_s: {}\n'
MINIMAL = ['servo_status', 'joint_commands', 'gait/phase', 'bench/session']


@pytest.fixture
def logs(monkeypatch):
    """Every message logged at info, warning or error level (by any node of this process),
    printed to stderr instead of rcutils (which refuses one call site for several levels)."""
    out: dict[str, list[str]] = {'info': [], 'warning': [], 'error': []}
    for level in out:
        def wrapper(self, msg, *a, _level=level, **kw):
            out[_level].append(str(msg))
            print(f'[{_level.upper()}] [{self.name}]: {msg}', file=sys.stderr)
            return True
        monkeypatch.setattr(RcutilsLogger, level, wrapper)
    return out


class Driver:
    """Fake servo driver: servo_status in the gate and a set_torque service (calls noted)."""

    def __init__(self, env):
        self.env, self.calls, self.temp = env, [], 26.0
        self.node = env.add(rclpy.create_node('fake_driver', context=env.context,
                                              namespace=env.namespace))
        self.pub = self.node.create_publisher(ServoStatus, 'servo_status', 10)
        self.node.create_service(SetBool, 'set_torque', self._torque)
        self.timer = self.node.create_timer(0.02, lambda: self.pub.publish(
            ServoStatus(name=['a', 'b', 'c'], temperature=[self.temp] * 3, error=[0] * 3)))

    def _torque(self, request, response):
        self.calls.append(request.data)
        response.success = True
        return response


def _kill(env, node):
    """The node's process is gone: its topics and services vanish."""
    env.nodes.remove(node)
    env.executor.remove_node(node)
    node.destroy_node()


def _start(env, tmp_path, duration=30.0, gait=True, driver=True, **seq_kw):
    (tmp_path / 'plan.yaml').write_text(PLAN.format(duration))
    g = env.make(GaitSchedulerNode, parameter_overrides=[
        Parameter(k, value=v) for k, v in {'rate': 50.0, 'step_length': 0.0,
                                           'step_height': 0.0}.items()]) if gait else None
    d = Driver(env) if driver else None
    kw = {'plan_file': str(tmp_path / 'plan.yaml'), 'state_file': str(tmp_path / 'state.json'),
          'output_dir': str(tmp_path / 'bags'), 'auto_load_change': True, 'rate_hz': 20.0,
          'gait_node': 'gait_scheduler' if gait else '',
          'torque_service': 'set_torque' if driver else '', 'record_topics': MINIMAL,
          **seq_kw}
    node = env.make(BenchSequencerNode,
                    parameter_overrides=[Parameter(k, value=v) for k, v in kw.items()])
    sessions = Collector(env, BenchSession, 'bench/session', LATCHED)
    return g, d, node, sessions


def _walking(env, sessions):
    assert env.spin_until(lambda: any(m.state == 'walking' for m in sessions.messages), 20)


# --- D1 ------------------------------------------------------------------------------------------
@pytest.mark.timeout(60)
def test_empty_gait_node_and_torque_service_are_warned_and_torque_off_never_claimed(
        tmp_path, logs):
    """The README's line left both empty: no word at start, and at the end "the leg did not
    report standing ...: torque off anyway" although no torque call existed."""
    with ros_env('integseq') as env:
        _, _, node, sessions = _start(env, tmp_path, duration=0.3, gait=False, driver=False,
                                      record_topics=['servo_status', 'bench/session'],
                                      stand_timeout_s=0.3)
        Driver(env)                                    # servo_status only: no torque service
        assert any("gait_node is empty: the plan's gaits will NOT be commanded" in w
                   for w in logs['warning'])
        assert any("torque_service is empty: the servos' torque is NOT controlled" in w
                   for w in logs['warning'])
        assert env.spin_until(node.finished.done, 30)
        assert node.finished.result() == 0
    said = logs['warning'] + logs['info'] + logs['error']
    stand = [w for w in said if 'stand_timeout_s' in w]
    assert stand and all('torque off' not in w for w in stand)
    assert any('does not control the torque' in w for w in stand)
    assert any('torque off not applied: no torque_service' in m for m in logs['info'])
    assert any('the sequencer did not turn the torque off' in w for w in logs['warning'])


# --- D6 ------------------------------------------------------------------------------------------
@pytest.mark.timeout(60)
def test_driver_gone_says_torque_service_unavailable(tmp_path, logs):
    """USB2Dynamixel unplugged: the driver exits, the sequencer aborted "0 sessions completed"
    with no word that the torque could not be turned off (and "check the driver" for any
    stream)."""
    with ros_env('integseq') as env:
        gait, driver, node, sessions = _start(env, tmp_path, stream_timeout_s=0.3)
        _walking(env, sessions)
        _kill(env, driver.node)
        assert env.spin_until(node.finished.done, 20)
        assert node.finished.result() == 1
        assert 'no servo_status for' in node.seq.abort_reason
        assert 'the servo driver (dynamixel_driver)' in node.seq.abort_reason
        assert False not in driver.calls[1:]          # the torque off never reached it
    said = [e for e in logs['error'] if 'unavailable' in e]
    assert len(said) == 1 and (f'torque service {env.namespace}/set_torque unavailable: the '
                               'servos may still hold torque') in said[0]


@pytest.mark.timeout(60)
def test_driver_gone_while_cooling_aborts_instead_of_waiting_for_ever(tmp_path, logs):
    """D6: the driver died while the plan waited (torque off) for the temperature gate: no
    servo_status, the gate never met, the plan waited for ever without a word."""
    with ros_env('integseq') as env:
        gait, driver, node, sessions = _start(env, tmp_path, stream_timeout_s=0.3)
        driver.temp = 40.0                                 # too hot: cooling, torque off
        assert env.spin_until(lambda: any(m.state == 'cooling' for m in sessions.messages), 20)
        assert env.spin_until(lambda: False in driver.calls, 10)
        _kill(env, driver.node)
        assert env.spin_until(node.finished.done, 10)
        assert node.finished.result() == 1
        assert 'no servo_status for' in node.seq.abort_reason
        assert 'while cooling' in node.seq.abort_reason


# --- D5 ------------------------------------------------------------------------------------------
@pytest.mark.timeout(60)
def test_gait_node_gone_keeps_the_torque_and_does_not_wait_for_its_stand(tmp_path, logs):
    """Ctrl-C of gait_scheduler mid-walk: "no gait/phase ... check the driver", then the full
    stand_timeout_s waited for a stand a dead node cannot deliver, then torque off under a leg
    frozen mid-swing. Now: the gait node is named, no wait, torque kept on, "support the
    stage"."""
    with ros_env('integseq') as env:
        gait, driver, node, sessions = _start(env, tmp_path, stream_timeout_s=0.3,
                                              stand_timeout_s=30.0)
        _walking(env, sessions)
        _kill(env, gait)
        # well within stand_timeout_s = 30 s (the abort itself comes after 0.3 s)
        assert env.spin_until(node.finished.done, 10)
        assert node.finished.result() == 1
        assert 'the gait node (gait_scheduler)' in node.seq.abort_reason
        assert 'check the driver' not in node.seq.abort_reason
        assert driver.calls and driver.calls[-1] is True     # torque held, never cut
        assert node.last_command.hold and node.last_command.torque
        assert not (tmp_path / 'bags' / SID).exists()        # partial bag moved aside
        assert (tmp_path / 'bags' / f'{SID}.interrupted-1').exists()
    held = [e for e in logs['error'] if 'NOT stood' in e]
    assert len(held) == 1
    assert 'gait_scheduler unavailable' in held[0] and 'support the stage' in held[0]
    assert 'torque kept ON' in held[0] and "'{data: false}'" in held[0]


# --- D4 ------------------------------------------------------------------------------------------
@pytest.mark.timeout(60)
def test_best_effort_publishers_are_recorded_once(tmp_path, logs):
    """A mocap bridge publishing with SensorDataQoS was never recorded (reliable subscription)
    and the session still counted. A topic with a reliable and a best-effort publisher is
    recorded from both, each message once."""
    with ros_env('integseq') as env:
        pubs = env.add(rclpy.create_node('fake_mocap', context=env.context,
                                         namespace=env.namespace))
        tip = pubs.create_publisher(PointStamped, 'bench/leg_tip', qos_profile_sensor_data)
        force_rel = pubs.create_publisher(WrenchStamped, 'bench/ground_force', 10)
        force_be = pubs.create_publisher(WrenchStamped, 'bench/ground_force',
                                         qos_profile_sensor_data)
        k = [0]

        def publish():
            k[0] += 1
            tip.publish(PointStamped(header=_header(k[0])))
            force_rel.publish(WrenchStamped(header=_header(k[0], 'rel')))
            force_be.publish(WrenchStamped(header=_header(k[0], 'be')))
        pubs.create_timer(0.01, publish)
        gait, driver, node, sessions = _start(
            env, tmp_path, duration=1.0,
            record_topics=MINIMAL + ['bench/leg_tip', 'bench/ground_force'])
        assert env.spin_until(node.finished.done, 40)
        assert node.finished.result() == 0
        assert json.loads((tmp_path / 'state.json').read_text())['completed'] == [SID]
        assert not any('unavailable' in e for e in logs['error'])   # not at start-up either
    with open_reader(tmp_path / 'bags' / SID) as reader:
        tips = [deserialize_message(m.data, PointStamped)
                for m in iter_messages(reader, ['/bench/leg_tip'])]
    with open_reader(tmp_path / 'bags' / SID) as reader:
        forces = [deserialize_message(m.data, WrenchStamped)
                  for m in iter_messages(reader, ['/bench/ground_force'])]
    assert len(tips) > 20
    ids = [m.header.stamp.sec for m in tips]
    assert len(set(ids)) == len(ids)                           # no duplicates
    by = {'rel': [], 'be': []}
    for m in forces:
        by[m.header.frame_id].append(m.header.stamp.sec)
    assert len(by['rel']) > 20 and len(by['be']) > 20
    assert all(len(set(v)) == len(v) for v in by.values())


def _header(k, frame='mocap'):
    from std_msgs.msg import Header

    h = Header(frame_id=frame)
    h.stamp.sec = k
    return h


@pytest.mark.timeout(60)
def test_a_recorded_topic_never_received_aborts_instead_of_counting(tmp_path, logs):
    """A recorded topic that nothing delivers (no publisher, or one the subscription cannot
    hear) let each session count with a warning; now the plan aborts at the end of
    `starting`, naming the topic and its owner, and nothing is counted."""
    with ros_env('integseq') as env:
        gait, driver, node, sessions = _start(env, tmp_path, duration=1.0,
                                              stand_timeout_s=3.0, stream_timeout_s=1.0,
                                              record_topics=MINIMAL + ['bench/leg_tip'])
        assert env.spin_until(node.finished.done, 30)
        assert node.finished.result() == 1
        assert not any(m.state == 'walking' for m in sessions.messages)
        assert "['bench/leg_tip']" in node.seq.abort_reason
        assert 'the motion capture' in node.seq.abort_reason
        assert not (tmp_path / 'state.json').exists()
        assert not (tmp_path / 'bags' / SID).exists()
        assert driver.calls[-1] is False                  # the leg stood, torque off
        assert gait.params.step_length == 0.0


@pytest.mark.timeout(60)
def test_a_stand_request_to_a_gait_node_that_dies_is_not_waited_for(tmp_path, logs):
    """servo_status goes silent mid-walk: the plan aborts and asks the gait node to stand the
    leg; the gait node dies before it answers. The request will never be answered: the plan
    ended only after stand_timeout_s (30 s here; a CI run on a loaded machine met this order
    of events). Now a call whose server is gone is not waited for."""
    with ros_env('integseq') as env:
        gait, driver, node, sessions = _start(env, tmp_path, stream_timeout_s=0.3,
                                              stand_timeout_s=30.0)
        _walking(env, sessions)
        driver.timer.cancel()                          # no servo_status from now on

        def stand_asked():
            return bool(node.seq.abort_reason) and any(
                cl is node.gait_client and not call.done() for cl, call in node._calls)

        # one callback at a time, so that the gait node is killed right after the request went
        # out, before its service callback can run
        for _ in range(4000):
            env.executor.spin_once(timeout_sec=0.05)
            if stand_asked():
                break
        assert stand_asked()
        _kill(env, gait)                               # before it answers
        assert env.spin_until(node.finished.done, 10)  # not stand_timeout_s = 30 s
        assert node.finished.result() == 1
        assert 'no servo_status for' in node.seq.abort_reason
