"""Dynamixel servos, power monitor, force sensor, bench sequencer, servo-bus emulator and physics simulators."""
