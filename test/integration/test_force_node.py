"""force_sensor node on a pty peer: calibrated force.z with the leg tip, malformed lines skipped."""

from __future__ import annotations

import os
import tty

import pytest
from geometry_msgs.msg import PointStamped, WrenchStamped
from harness import Collector, ros_env
from numpy.testing import assert_allclose
from rclpy.parameter import Parameter

from hexapod_bench_drivers.force_node import ForceSensorNode


@pytest.mark.timeout(60)
def test_force_node_calibration_tip_and_malformed():
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        with ros_env('force') as env:
            node = env.make(ForceSensorNode, parameter_overrides=[
                Parameter('serial_port', value=os.ttyname(slave)),
                Parameter('calibration', value=[0.5, 0.001, 10.0, -2.0])])
            forces = Collector(env, WrenchStamped, 'bench/ground_force')
            os.write(master, b'# tare done\n10,1000\ngarbage\n20,1\xff00\n30,2000\n')
            forces.wait_for(env, 2)
            assert_allclose([m.wrench.force.z for m in forces.messages], [1.5, 2.5])
            assert node.malformed_lines == 2
            # With the leg tip at (0.02, 0.15) m: + 10 * 0.02 - 2 * 0.15 = -0.1 N.
            tip_pub = node.create_publisher(PointStamped, 'bench/leg_tip', 10)
            tip = PointStamped()
            tip.point.x, tip.point.y = 0.02, 0.15
            assert env.spin_until(lambda: (tip_pub.publish(tip), node.tip_xy)[1] == (0.02, 0.15),
                                  10.0)
            os.write(master, b'40,1000\n')
            forces.wait_for(env, 3)
            assert_allclose(forces.messages[2].wrench.force.z, 1.4)
            assert forces.messages[2].header.frame_id == 'treadmill'
    finally:
        os.close(master)
        os.close(slave)
