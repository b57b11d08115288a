"""dynamixel_driver says what it did to the torque at exit (it was silent: Known gaps)."""

from __future__ import annotations

import pytest
from harness import ros_env
from rclpy.parameter import Parameter


@pytest.mark.timeout(60)
@pytest.mark.parametrize('action', ['torque_off', 'hold'])
def test_the_torque_at_shutdown_is_said(tmp_path, action) -> None:
    from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode
    from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

    names = ['L1_coxa', 'L1_femur', 'L1_tibia', 'R1_coxa']
    joints = tmp_path / 'joints.yaml'
    joints.write_text('joints:\n' + ''.join(f'  {n}: {{id: {i + 1}}}\n'
                                            for i, n in enumerate(names)))
    lines: list[str] = []
    with ServoBusEmulator.of_model('xl430', range(1, 5)) as emu, ros_env('dxl_exit') as env:
        node = DynamixelDriverNode(context=env.context, namespace=env.namespace,
                                   parameter_overrides=[
                                       Parameter('port', value=emu.port_name),
                                       Parameter('protocol', value=2),
                                       Parameter('joints_file', value=str(joints)),
                                       Parameter('shutdown_action', value=action),
                                       Parameter('timeout_margin_ms', value=20.0)])
        log = node.get_logger()
        log.info = lambda msg, **kw: lines.append(msg)
        log.warning = lambda msg, **kw: lines.append(msg)
        node.destroy_node()
    if action == 'torque_off':
        assert 'torque off on 4 servo(s)' in lines
    else:
        assert any('torque left on' in x for x in lines)
