"""energy_monitor's messages name the topics as remapped.

README Known gaps until 2026-11-28: a node started with `-r battery_state:=/lab/power` warned
about "battery_state" (the contract's name, from the core), a topic it was not reading. The
node's logger now writes the names its subscriptions resolved to; rclpy's per-call-site
filters (once, one severity per call site) still see the node's own lines.
"""

from __future__ import annotations

import pytest
import rclpy
from harness import RosEnv, unique_namespace
from rclpy.executors import SingleThreadedExecutor
from sensor_msgs.msg import BatteryState

from hexapod_common.renaming_logger import RenamingLogger, topic_renames
from hexapod_energy.energy_node import EnergyMonitorNode


def test_renames_whole_names_only():
    class Sub:
        def __init__(self, name):
            self.topic_name = name
    renames = topic_renames({'battery_state': Sub('/lab/power'), 'gait/phase': Sub('/gait/phase'),
                             'joint_states': Sub('/antbot/joint_states')})
    assert renames == {'battery_state': '/lab/power', 'joint_states': '/antbot/joint_states'}
    log = RenamingLogger(rclpy.logging.get_logger('renaming_test'), renames)
    assert log.rename('no /battery_state for 5 s; battery_state in milli-units') == \
        'no /lab/power for 5 s; /lab/power in milli-units'
    # already resolved names, longer names and other topics are left alone
    assert log.rename('/antbot/joint_states and /joint_states_raw, /gait/phase') == \
        '/antbot/joint_states and /joint_states_raw, /gait/phase'


def test_call_site_filters_still_see_the_callers_lines():
    log = RenamingLogger(rclpy.logging.get_logger('renaming_sites'), {'odom': '/lab/odom'})
    said = [log.warning('odom once', once=True) for _ in range(3)]
    assert said == [True, False, False]
    # another line of the caller is another call site (through an unregistered wrapper both
    # were the wrapper's one line, and this second message was dropped)
    assert log.warning('odom once, elsewhere', once=True)
    log.info('a second call site')          # another severity at another line: no ValueError
    log.error('a third call site')


@pytest.mark.timeout(60)
def test_a_remapped_battery_topic_is_named_in_the_warnings():
    context = rclpy.Context()
    rclpy.init(context=context, args=['--ros-args', '-r', 'battery_state:=/lab/power'])
    executor = SingleThreadedExecutor(context=context)
    env = RosEnv(context, executor, unique_namespace('remap'))
    try:
        node = env.make(EnergyMonitorNode)
        lines = []
        inner = node.get_logger()._logger
        original = inner.warning
        inner.warning = lambda msg, **kw: lines.append(msg) or original(msg, **kw)
        probe = env.add(rclpy.create_node('probe', context=context, namespace=env.namespace))
        pub = probe.create_publisher(BatteryState, '/lab/power', 10)
        msg = BatteryState()
        msg.voltage, msg.current = 11800.0, -2500.0       # milli-units
        msg.header.stamp = node.get_clock().now().to_msg()

        def said():
            pub.publish(msg)
            return any('milli-units' in m for m in lines)
        assert env.spin_until(said, 30.0), lines
        line = next(m for m in lines if 'milli-units' in m)
        assert line.startswith('/lab/power voltage and current in milli-units'), line
    finally:
        for n in env.nodes:
            executor.remove_node(n)
            n.destroy_node()
        executor.shutdown()
        context.try_shutdown()
