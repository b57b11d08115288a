"""Outside integration review (/tmp/review_integ FINDINGS D3): a serial device that vanishes
while pyserial flushes its input (``reset_input_buffer`` -> ``termios.tcflush``) raises
``termios.error``, which is not an OSError. It escaped the port-loss handling of the SCPI power
backend (a 30-line traceback killed ``power_monitor``), of the force sensor's reopen and of the
Dynamixel bus; now it is one PowerPortLost / a reopen with backoff / PortLostError.
The bench sequencer core's side of D1, D4 and D5 is tested at the end."""

from __future__ import annotations

import math
import termios

import pytest

from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig, PortLostError
from hexapod_bench_drivers.force_backend import ForceReading, SerialForceSource
from hexapod_bench_drivers.power_backends import PowerPortLost, ScpiSupplyBackend
from hexapod_bench_drivers.sequencer import BenchSequencer, load_plan
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator

pytestmark = pytest.mark.timeout(60)

EIO = termios.error(5, 'Input/output error')


class Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


class VanishingPort:
    """A serial.Serial stand-in: unplugged, its input flush raises termios.error (what
    pyserial's reset_input_buffer does on a vanished tty), reads raise OSError EIO."""

    plugged = True
    flush_fails = False          # the flush fails even when plugged (a device re-enumerating)
    opens = 0

    def __init__(self, port: str, **kw: object) -> None:
        if not VanishingPort.plugged:
            raise OSError(2, f'could not open port {port}: No such file or directory')
        VanishingPort.opens += 1
        self.queue: list[bytes] = []

    def reset_input_buffer(self) -> None:
        if not VanishingPort.plugged or VanishingPort.flush_fails:
            raise EIO

    def write(self, data: bytes) -> int:
        q = data.decode().strip()
        self.queue.append({'MEAS:VOLT?': b'12.0\n', 'MEAS:CURR?': b'0.5\n'}.get(q, b'X,Y\n'))
        return len(data)

    def readline(self) -> bytes:
        return self.queue.pop(0)

    @property
    def in_waiting(self) -> int:
        if not VanishingPort.plugged:
            raise OSError(5, 'Input/output error')
        return sum(len(q) for q in self.queue)

    def read(self, n: int) -> bytes:
        out = b''.join(self.queue)
        self.queue = []
        return out

    def close(self) -> None:
        pass


@pytest.fixture(autouse=True)
def _plugged():
    VanishingPort.plugged, VanishingPort.flush_fails, VanishingPort.opens = True, False, 0
    yield


def test_scpi_flush_on_a_vanished_device_is_port_lost_then_reopened():
    clock = Clock()
    scpi = ScpiSupplyBackend('/dev/ttyUSB9', serial_factory=VanishingPort, clock=clock)
    assert scpi.read().current_a == 0.5
    VanishingPort.plugged = False          # the first thing a query does is the flush
    with pytest.raises(PowerPortLost, match=r'port failed .*Input/output error'):
        scpi.read()
    assert scpi.lost and scpi.ser is None
    with pytest.raises(PowerPortLost, match='port lost'):
        scpi.read()                        # within the backoff: no open attempt
    VanishingPort.plugged = True
    clock.t += 0.6
    s = scpi.read()                        # reopened (resynchronised first)
    assert (s.voltage_v, s.current_a) == (12.0, 0.5)
    assert scpi.lost is None and scpi.reconnects == 1 and VanishingPort.opens == 2


def test_force_reopen_whose_flush_fails_backs_off_instead_of_raising():
    clock = Clock()
    src = SerialForceSource('/dev/ttyACM9', serial_factory=VanishingPort, clock=clock)
    src.ser.queue.append(b'10,5\n')
    assert src.poll() == [ForceReading(0.01, 5)]
    VanishingPort.plugged = False
    assert src.poll() == [] and src.lost
    # The device node is back but not ready: the open succeeds, its flush raises termios.error.
    VanishingPort.plugged, VanishingPort.flush_fails = True, True
    clock.t += 0.6
    assert src.poll() == [] and src.failed_opens == 1 and src.ser is None
    VanishingPort.flush_fails = False
    clock.t += 1.1
    assert src.poll() == [] and src.lost is None and src.reconnects == 1
    src.ser.queue.append(b'20,7\n')
    assert src.poll() == [ForceReading(0.02, 7)]


@pytest.mark.parametrize('model,protocol', [('ax18a', 1), ('xl430', 2)])
def test_dxl_flush_on_a_vanished_adapter_is_port_lost(model, protocol):
    """clearPort() (reset_input_buffer) runs before every SDK transaction: a termios.error
    there escaped _port_guard, which caught OSError only."""
    emu = ServoBusEmulator.of_model(model, [1, 2]).start()
    bus = DynamixelBus(emu.port_name, [JointConfig('j1', 1), JointConfig('j2', 2)],
                       protocol=protocol, timeout_margin_ms=40.0).open()
    try:
        assert bus.poll().readings[0].ok
        ser = bus.port.ser

        def vanished() -> None:
            raise EIO
        ser.reset_input_buffer = vanished
        with pytest.raises(PortLostError, match=rf'port {emu.port_name} lost: error: .*'
                                                'Input/output error'):
            bus.poll()
        assert not bus.is_open and emu.port_name in bus.port_lost
        assert bus.set_torque(False) == {'j1': False, 'j2': False}   # skipped, no raise
        with pytest.raises(PortLostError):
            bus.poll()
    finally:
        emu.stop()
        bus.close()


# --------------------------------------------------------------------------------------------
# Bench sequencer core (no ROS): D1 (no torque service), D5 (stand the gait node cannot
# deliver, owner of a silent stream), D4 (a recorded topic never received).

PLAN = {'loads_kg': [0.0], 'frequencies_hz': [1.0, 2.0], 'walk_duration_s': 5.0}
GATE = [26.0, 26.0, 26.0]
HOT = [28.0, 28.0, 28.0]


def _walking(**kw):
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, **kw)
    cmd = seq.update(0.0, GATE)
    assert cmd.state == 'walking' and cmd.walk
    return seq


def test_gait_node_gone_holds_the_torque_at_once_and_says_support_the_stage():
    """D5: the gait node died mid-walk. Before: the stand was waited for stand_timeout_s, then
    torque off under a leg frozen mid-swing; now no wait, the torque is kept on, the plan is
    aborted and the operator told to support the stage."""
    seq = _walking(stand_timeout_s=10.0)
    seq.abort('no gait/phase for 5 s')
    cmd = seq.update(1.0, GATE, standing=False,
                     stand_unavailable='gait node /gait_scheduler unavailable')
    assert cmd.state == 'aborted' and cmd.hold and cmd.torque and not cmd.walk
    assert 'NOT stood' in seq.hold_reason and 'support the stage' in seq.hold_reason
    assert 'torque kept ON' in seq.hold_reason and '/gait_scheduler' in seq.hold_reason
    assert seq.abort_reason == 'no gait/phase for 5 s'           # the first cause is kept
    for t in (2.0, 50.0):                                        # held for good
        cmd = seq.update(t, GATE, standing=None)
        assert cmd.hold and cmd.torque


def test_stand_not_reported_by_the_gait_node_holds_the_torque_and_aborts():
    """D5: after a session the gait node does not report the stand within stand_timeout_s.
    Before: "torque off anyway"; now the torque is kept on and the plan aborted."""
    seq = _walking(stand_timeout_s=3.0)
    assert seq.update(5.0, HOT, standing=False).torque          # the stand begins
    assert seq.update(7.0, HOT, standing=False).torque
    cmd = seq.update(8.0, HOT, standing=False)
    assert cmd.state == 'aborted' and cmd.hold and cmd.torque
    assert seq.abort_reason == seq.hold_reason
    assert 'within stand_timeout_s = 3 s' in seq.hold_reason and seq.completed == []


def test_no_torque_service_the_stand_message_does_not_claim_torque_off():
    """D1: with no torque service the unknown stand ended with "torque off anyway"."""
    seq = _walking(stand_timeout_s=3.0, torque_controlled=False)
    seq.update(5.0, HOT)
    cmd = seq.update(8.0, HOT)
    assert not cmd.torque and not cmd.hold
    assert 'torque off' not in seq.stand_warning
    assert 'does not control the torque' in seq.stand_warning


def test_unknown_stand_with_torque_service_still_turns_it_off():
    seq = _walking(stand_timeout_s=3.0)
    seq.update(5.0, HOT)
    cmd = seq.update(8.0, HOT)
    assert not cmd.torque and not cmd.hold and 'torque off now' in seq.stand_warning


@pytest.mark.parametrize('topic, owner', [
    ('servo_status', 'servo driver'), ('joint_states', 'servo driver'),
    ('battery_state', 'power monitor'), ('bench/ground_force', 'force sensor'),
    ('bench/leg_tip', 'motion capture'), ('gait/phase', 'gait node'),
    ('joint_commands', 'gait node'),
])
def test_a_silent_stream_names_its_owner(topic, owner):
    """D5: every silent stream said "check the driver"."""
    seq = _walking(stream_timeout_s=1.0)
    ages = {'servo_status': 0.1, topic: 2.0}
    cmd = seq.update(2.0, GATE, stream_ages_s=ages)
    assert cmd.state == 'aborted' and f'no {topic} for 2.00 s' in seq.abort_reason
    assert owner in seq.abort_reason and 'check the driver' not in seq.abort_reason


def test_a_recorded_topic_never_received_aborts_at_the_end_of_starting():
    """D4: a recorded topic never received (a best-effort mocap bridge, or none) let every
    session count; now ``starting`` waits for it, at most stand_timeout_s, then aborts."""
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, stand_timeout_s=1.0,
                         stream_timeout_s=2.0)
    cmd = seq.update(0.0, GATE, unseen_topics=['bench/leg_tip'])
    assert cmd.state == 'starting' and cmd.walk and not cmd.record
    assert seq.update(1.0, GATE, unseen_topics=['bench/leg_tip']).state == 'starting'
    cmd = seq.update(2.0, GATE, unseen_topics=['bench/leg_tip'])
    assert cmd.state == 'aborted' and not cmd.record and seq.completed == []
    assert "['bench/leg_tip']" in seq.abort_reason and 'motion capture' in seq.abort_reason
    # seen in time: the walk is recorded as before
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, stand_timeout_s=1.0,
                         stream_timeout_s=2.0)
    assert seq.update(0.0, GATE, unseen_topics=['bench/leg_tip']).state == 'starting'
    cmd = seq.update(1.0, GATE)
    assert cmd.state == 'walking' and cmd.record


def test_servo_status_gone_silent_while_cooling_aborts_the_plan():
    """D6: a driver gone while the plan cooled left it waiting for the gate for ever, without a
    word (the watchdog ran while walking only). Never seen (inf): waiting for the driver."""
    seq = BenchSequencer(load_plan(PLAN), initial_load_kg=0.0, stream_timeout_s=1.0)
    assert seq.update(0.0, HOT, stream_ages_s={'servo_status': math.inf}).state == 'cooling'
    assert seq.update(1.0, HOT, stream_ages_s={'servo_status': 0.5}).state == 'cooling'
    cmd = seq.update(2.0, [], stream_ages_s={'servo_status': 1.5})
    assert cmd.state == 'aborted' and not cmd.torque
    assert 'while cooling' in seq.abort_reason and 'servo driver' in seq.abort_reason
