"""An outside review: a PhantomX-class lab (52/66/133 mm, 0.175 kg legs) ran the live graph
(``sim_robot``, ``gait_scheduler``, ``energy_monitor``, ``bag_recorder``, all ``-p
leg_file``) and ``hexapod-analyze energy --leg`` on the bag.

- The robot mass nobody gave: ``sim_robot -p leg_file`` and ``hexapod-sim robot --leg`` walk
  AntBot's body with the file's legs (2.237 kg), but ``hexapod-analyze energy --leg`` (and
  ``residuals --leg``) on a bag that declares no mass (``bag_recorder``'s) assumed AntBot's
  2.183 kg: the Eq. 6 P_out 0.522 W for the 0.526 W of the robot walked at 0.2 m/s, CoT/M
  72.9 for 71.2 J/(m kg), with exit 0. One rule now (``kinematics.default_robot_mass_kg``).
- ``gait_scheduler``'s stand keeps its period (step length and height 0): the live
  ``energy_monitor`` read it as a Buehler clock (P_out NaN, a note about rotating legs), while
  ``energy`` reads the same stand as P_out 0 W.
"""

from __future__ import annotations

import numpy as np

LEG_YAML = """name: review PX leg
a_m: [0.052, 0.066, 0.133]
link_masses_kg: [0.030, 0.065, 0.080]
neutral_tip_m: [0.125, 0.0, -0.095]
"""
LEG_KG = 0.175
#: AntBot's body (2.183 kg less six 0.166 kg legs) with six of this leg
ROBOT_KG = 2.183 - 6 * (0.01498 + 0.1118 + 0.03923) + 6 * LEG_KG


def _stand(period_s: float = 1.0):
    from hexapod_common.conversions import GaitPhaseSample

    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    return GaitPhaseSample(t_s=1.0, gait='tripod', period_s=period_s, duty_factor=0.5,
                           step_length_m=0.0, step_height_m=0.0, sweep_angle_rad=0.0,
                           leg_offset_rad=0.0, cycle_phase=0.3, leg_names=legs,
                           phase_offsets=np.array([0, .5, 0, .5, 0, .5]),
                           in_stance=np.ones(6, bool), supporting_legs=6)


def test_a_stand_that_keeps_its_period_is_not_a_buehler_clock() -> None:
    from hexapod_energy.descriptors import is_clock_schedule, model_power_out
    from hexapod_energy.leg_description import antbot_leg

    stand = _stand(1.0)
    assert not is_clock_schedule(stand)
    assert not is_clock_schedule(_stand(0.0))
    model = model_power_out(antbot_leg().output_power_model(2.183), robot_mass_kg=2.183)
    assert model(stand, 2.183) == 0.0
    # a Buehler clock stays one
    from dataclasses import replace
    assert is_clock_schedule(replace(stand, gait='buehler', sweep_angle_rad=1.0))
