"""Gait patterns, supporting legs L(t), leg kinematics, tip trajectories, Buehler clock; gait node.

Core modules (numpy/scipy only, no rclpy):

* :mod:`hexapod_gait.legs`: leg and joint names (DESIGN section 4).
* :mod:`hexapod_gait.gait`: ``GaitPattern``, ``make_gait``, exact ``L(t)``,
  ``carried_mass_per_leg_kg``.
* :mod:`hexapod_gait.feasibility`: ``ActuatorLimits`` (with ``LimitsReference``, the leg and
  step they were measured on), ``check_feasible``, ``max_speed_mps``, ``period_for_speed``.
* :mod:`hexapod_gait.step_limits`: the limits for a step geometry on a leg (the reference
  leg's bench step scaled by the joint paths), ``limits_for_step``, ``measured_on_leg``,
  ``check_feasible_for_step``.
* :mod:`hexapod_gait.kinematics`: ``DHParameters``, ``ANTBOT_LEG``, ``LegKinematics``.
* :mod:`hexapod_gait.trajectory`: ``tip_path``, ``LegTrajectory``.
* :mod:`hexapod_gait.buehler`: ``BuehlerClock``, ``BUEHLER_PRESETS``, ``TRIPOD_LEGS``.
* :mod:`hexapod_gait.scheduler`: ``GaitScheduler`` (phase-continuous transitions).
* :mod:`hexapod_gait.errors`: typed exceptions.

Node: :mod:`hexapod_gait.gait_node` (``gait_scheduler``).
"""
