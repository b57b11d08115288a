"""Benchmark: Dynamixel driver on the emulated bus (real dynamixel_sdk over a pty).

Prints
1. DynamixelBus.poll() rate for 18 AX-18A (Protocol 1.0, one block READ per servo) and for
   4 and 18 XL430 (Protocol 2.0, one Sync Read), against a straightforward baseline measured
   in the same run: the SDK's stock PortHandler (busy-wait) reading the five present values
   with one READ each per servo.
2. The dynamixel_driver node publishing /joint_states for 18 AX-18A, rate_hz = 200: received
   messages per second that carry all 18 joints (the acceptance asks >= 100 Hz), with the
   emulator in a child process (as real servos: not sharing the driver's interpreter) and in
   a thread of the driver's process (sharing its GIL and core).

Run: .venv/bin/python bench/bench_dxl.py  (about 20 s)
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from dynamixel_sdk import PacketHandler, PortHandler

from hexapod_bench_drivers.control_tables import AX18A, XL430
from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator, emulator_process

DURATION_S = 3.0


def poll_rate(model: str, protocol: int, n: int, in_process: bool = True) -> float:
    from contextlib import ExitStack

    with ExitStack() as stack:
        if in_process:
            port = stack.enter_context(ServoBusEmulator.of_model(model, range(1, n + 1))).port_name
        else:
            port = stack.enter_context(emulator_process(model, range(1, n + 1)))
        bus = stack.enter_context(DynamixelBus(
            port, [JointConfig(f'j{i}', i) for i in range(1, n + 1)], protocol=protocol))
        bus.set_torque(True)
        cycles, ok = 0, True
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < DURATION_S:
            ok &= all(r.ok for r in bus.poll().readings)
            cycles += 1
        rate = cycles / (time.perf_counter() - t0)
        failures = sum(h.failed_cycles for h in bus.health())
    where = 'thread' if in_process else 'child process'
    print(f'  poll {n:2d} x {model}: {rate:7.1f} cycles/s  ({failures} failed servo-cycles, '
          f'emulator in {where})')
    return rate


def baseline_rate(model: str, protocol: int, n: int) -> float:
    """Stock PortHandler, one READ per present value per servo."""
    table = AX18A if protocol == 1 else XL430
    regs = [table.reg(name) for name in table.read_names]
    with ServoBusEmulator.of_model(model, range(1, n + 1)) as emu:
        port = PortHandler(emu.port_name)
        port.openPort()
        ph = PacketHandler(float(protocol))
        cycles = 0
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < DURATION_S:
            for sid in range(1, n + 1):
                for reg in regs:
                    ph.readTxRx(port, sid, reg.address, reg.size)
            cycles += 1
        rate = cycles / (time.perf_counter() - t0)
        port.closePort()
    print(f'  base {n:2d} x {model}: {rate:7.1f} cycles/s  (stock PortHandler, 5 READs/servo)')
    return rate


def node_rate(in_process: bool) -> float:
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from sensor_msgs.msg import JointState

    from hexapod_bench_drivers.dynamixel_node import DynamixelDriverNode

    from contextlib import ExitStack

    with ExitStack() as stack:
        if in_process:
            port = stack.enter_context(ServoBusEmulator.of_model('ax18a', range(1, 19))).port_name
        else:
            port = stack.enter_context(emulator_process('ax18a', range(1, 19)))
        tmp = stack.enter_context(tempfile.TemporaryDirectory())
        path = Path(tmp) / 'joints.yaml'
        path.write_text('joints:\n' + ''.join(f'  j{i}: {{id: {i}}}\n' for i in range(1, 19)))
        ctx = rclpy.Context()
        rclpy.init(context=ctx)
        node = DynamixelDriverNode(context=ctx, namespace='/bench_dxl', parameter_overrides=[
            Parameter('port', value=port), Parameter('joints_file', value=str(path)),
            Parameter('rate_hz', value=200.0)])
        sub_node = rclpy.create_node('bench_listener', context=ctx, namespace='/bench_dxl')
        stamps: list[float] = []
        sub_node.create_subscription(
            JointState, 'joint_states',
            lambda m: stamps.append(time.perf_counter()) if len(m.name) == 18 else None, 100)
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)
        ex.add_node(sub_node)
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < DURATION_S:
            ex.spin_once(timeout_sec=0.1)
        window = [s for s in stamps if s > t0 + 0.5]
        rate = (len(window) - 1) / (window[-1] - window[0]) if len(window) > 1 else 0.0
        ex.shutdown()
        node.destroy_node()
        sub_node.destroy_node()
        ctx.try_shutdown()
    where = 'emulator in-process thread' if in_process else 'emulator in a child process'
    print(f'  node 18 x ax18a: {rate:7.1f} /joint_states per s with all 18 joints '
          f'(rate_hz 200, {where}; acceptance >= 100)')
    return rate


def main() -> None:
    print('Dynamixel driver on the emulated bus')
    for model, protocol, n in (('ax18a', 1, 18), ('xl430', 2, 4), ('xl430', 2, 18)):
        ours = poll_rate(model, protocol, n)
        base = baseline_rate(model, protocol, n)
        print(f'  ratio {n} x {model}: {ours / base:5.1f}x the baseline')
    poll_rate('ax18a', 1, 18, in_process=False)
    node_rate(in_process=False)
    node_rate(in_process=True)


if __name__ == '__main__':
    main()
