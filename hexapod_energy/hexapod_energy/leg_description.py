"""Another robot's leg for the output-power model (Eq. 6): DH table, link masses, stance pose.

The Eq. 6 model computes the joint torques of one leg along the gait's tip path (inverse
kinematics, then Pinocchio's inverse dynamics). By default that leg is AntBot's (DESIGN §7);
a PhantomX or any 3-DOF leg with a coxa joint about the vertical and femur and tibia joints
parallel (standard DH ``alpha = (pi/2, 0, 0)``, ``d2 = d3 = 0``) is described in a YAML (or
JSON) file and given with ``hexapod-analyze energy --leg FILE`` (``energy_monitor -p
leg_file``). The file's format and checks are :mod:`hexapod_gait.leg_file`'s, which
``gait_scheduler -p leg_file`` reads too: one file describes the leg everywhere.

Core module: no rclpy.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from hexapod_energy.dynamics import LegSpec
from hexapod_energy.errors import InvalidInputError

__all__ = ['LegDescription', 'antbot_leg', 'load_leg_description']

@dataclass(frozen=True)
class LegDescription:
    """A leg for the output-power model: DH table (``hexapod_gait`` DHParameters) and stance
    midpoint of the tip in the leg base frame [m]."""

    dh: Any
    neutral_tip_m: tuple[float, float, float]
    name: str = 'AntBot'

    @property
    def spec(self) -> LegSpec:
        """The dynamics' leg (:class:`~hexapod_energy.dynamics.LegSpec`)."""
        return LegSpec.from_dh(self.dh)

    def output_power_model(self, robot_mass_kg: float, **kw: Any) -> Any:
        """An :class:`~hexapod_energy.prediction.OutputPowerModel` of a robot of this mass
        whose legs are this one (kinematics, trajectory and dynamics alike)."""
        from hexapod_gait.kinematics import LegKinematics
        from hexapod_gait.trajectory import LegTrajectory

        from hexapod_energy.prediction import OutputPowerModel, RobotSpec

        return OutputPowerModel(
            robot=RobotSpec(mass_kg=robot_mass_kg, leg=self.spec),
            kinematics=LegKinematics(self.dh),
            trajectory_factory=partial(LegTrajectory, neutral_tip_m=self.neutral_tip_m), **kw)

    def path_kwargs(self) -> dict[str, Any]:
        """``kinematics`` and ``trajectory_factory`` of this leg for
        :func:`hexapod_energy.prediction.phase_path`."""
        from hexapod_gait.kinematics import LegKinematics
        from hexapod_gait.trajectory import LegTrajectory

        return {'kinematics': LegKinematics(self.dh),
                'trajectory_factory': partial(LegTrajectory, neutral_tip_m=self.neutral_tip_m)}

    def summary(self) -> dict[str, Any]:
        """JSON-able description (``energy.json`` ``leg``)."""
        return {'name': self.name, 'a_m': list(self.dh.a_m),
                'alpha_rad': list(self.dh.alpha_rad), 'd_m': list(self.dh.d_m),
                'theta_offset_rad': list(self.dh.theta_offset_rad),
                'link_masses_kg': list(self.dh.link_masses_kg),
                'neutral_tip_m': list(self.neutral_tip_m)}


def antbot_leg() -> LegDescription:
    """AntBot's leg (DESIGN §7), the default."""
    from hexapod_gait.kinematics import ANTBOT_LEG
    from hexapod_gait.trajectory import ANTBOT_NEUTRAL_TIP_M

    return LegDescription(ANTBOT_LEG, tuple(ANTBOT_NEUTRAL_TIP_M), 'AntBot')  # type: ignore[arg-type]


def load_leg_description(path: str | Path) -> LegDescription:
    """Read and check a leg file (module docs; :func:`hexapod_gait.leg_file.read_leg_file`,
    which ``gait_scheduler`` reads too); raises :class:`InvalidInputError` naming the file and
    the problem."""
    from hexapod_gait.leg_file import LegFileError, read_leg_file

    try:
        leg = read_leg_file(path)
    except LegFileError as err:
        raise InvalidInputError(str(err)) from None
    return LegDescription(leg.dh, leg.neutral_tip_m, leg.name)
