"""Gait patterns, supporting legs L(t), leg kinematics, tip trajectories, Buehler clock; gait node."""
