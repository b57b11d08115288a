"""dynamixel_driver and /joint_commands names its joint map does not have: said once, not
dropped in silence. A quadruped review (4 legs, joint map L1/L2/R1/R2) ran the gait node at
its default leg_count 6: the L3/R3 commands were dropped without a word (and a typo in a
joint map, e.g. L1_femor, leaves that joint uncommanded the same way)."""

from __future__ import annotations

from hexapod_bench_drivers.dynamixel_bus import DynamixelBus, JointConfig
from hexapod_bench_drivers.servo_bus_emulator import ServoBusEmulator


def test_unknown_command_names_are_said_once():
    joints = [JointConfig('L1_coxa', 1), JointConfig('L1_femor', 2)]
    with ServoBusEmulator.of_model('XM430-W350', [1, 2]) as emu, \
            DynamixelBus(emu.port_name, joints, protocol=2).open() as bus:
        bus.take_notes()
        goals = {'L1_coxa': 0.1, 'L1_femur': 0.2, 'L3_coxa': 0.0}
        assert bus.write_goals(goals) == 1
        notes = bus.take_notes()
        said = [n for n in notes if 'L3_coxa' in n]
        assert len(said) == 1, notes
        assert 'L1_femur' in said[0] and 'L1_femor' in said[0]
        for _ in range(5):
            bus.write_goals(goals)
        assert not [n for n in bus.take_notes() if 'L3_coxa' in n]
        bus.write_goals({'R3_tibia': 0.0})    # another unknown name: said again
        assert [n for n in bus.take_notes() if 'R3_tibia' in n]
