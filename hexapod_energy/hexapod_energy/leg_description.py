"""Another robot's leg for the output-power model (Eq. 6): DH table, link masses, stance pose.

The Eq. 6 model computes the joint torques of one leg along the gait's tip path (inverse
kinematics, then Pinocchio's inverse dynamics). By default that leg is AntBot's (DESIGN §7);
a PhantomX or any 3-DOF leg with a coxa joint about the vertical and femur and tibia joints
parallel (standard DH ``alpha = (pi/2, 0, 0)``, ``d2 = d3 = 0``) is described in a YAML (or
JSON) file and given with ``hexapod-analyze energy --leg FILE``::

    name: PhantomX MK-III           # optional, shown in energy.json
    a_m: [0.052, 0.066, 0.133]      # DH link lengths [m]
    alpha_rad: [1.5708, 0, 0]       # optional (this is the only analytic form)
    d_m: [0, 0, 0]                  # optional
    theta_offset_rad: [0, 0, 0]     # optional: theta_i = q_i + offset_i
    link_masses_kg: [0.02, 0.08, 0.06]
    joint_limits_rad: [[-2.6, 2.6], [-2.6, 2.6], [-2.6, 2.6]]   # optional
    neutral_tip_m: [0.13, 0.0, -0.10]   # stance midpoint in the leg base frame [m]

Every key is checked (unknown keys refused, lengths and signs named in the error); the gait's
default path (tripod, 100 mm steps, 40 mm high) must lie inside the leg's workspace from that
stance pose, else the file is refused saying which point leaves it.

Core module: no rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

from hexapod_energy.dynamics import LegSpec
from hexapod_energy.errors import InvalidInputError

__all__ = ['LegDescription', 'antbot_leg', 'load_leg_description']

_KEYS = {'name', 'a_m', 'alpha_rad', 'd_m', 'theta_offset_rad', 'link_masses_kg',
         'joint_limits_rad', 'neutral_tip_m'}


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


def _triple(doc: dict[str, Any], key: str, path: Path, *, positive: bool = False,
            nonneg: bool = False) -> tuple[float, float, float]:
    value = doc[key]
    try:
        out = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise InvalidInputError(f'leg file {path}: {key} must be 3 numbers, got {value!r}') \
            from None
    if len(out) != 3 or not all(math.isfinite(x) for x in out):
        raise InvalidInputError(f'leg file {path}: {key} must be 3 finite numbers, got {value!r}')
    if nonneg and any(x < 0 for x in out):
        raise InvalidInputError(f'leg file {path}: {key} must be >= 0, got {list(out)}')
    if positive and any(x <= 0 for x in out[1:]):
        raise InvalidInputError(f'leg file {path}: {key}: femur and tibia must be > 0, got '
                                f'{list(out)}')
    return out  # type: ignore[return-value]


def load_leg_description(path: str | Path) -> LegDescription:
    """Read and check a leg file (module docs); raises :class:`InvalidInputError` naming the
    file and the problem."""
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    from hexapod_gait.config import check_reachable
    from hexapod_gait.errors import InvalidGaitError, UnreachableError
    from hexapod_gait.gait import make_gait
    from hexapod_gait.kinematics import DHParameters, LegKinematics

    path = Path(path)
    try:
        doc = YAML(typ='safe').load(path.read_text(encoding='utf8'))
    except OSError as err:
        raise InvalidInputError(f'leg file {path}: {err.strerror or err}') from None
    except YAMLError as err:
        raise InvalidInputError(f'leg file {path} is not YAML/JSON: '
                                f'{str(err).splitlines()[0]}') from None
    if not isinstance(doc, dict):
        raise InvalidInputError(f'leg file {path}: expected a mapping of {sorted(_KEYS)}')
    unknown = sorted(set(doc) - _KEYS)
    if unknown:
        raise InvalidInputError(f'leg file {path}: unknown key(s) {unknown}; expected '
                                f'{sorted(_KEYS)}')
    missing = [k for k in ('a_m', 'link_masses_kg', 'neutral_tip_m') if k not in doc]
    if missing:
        raise InvalidInputError(f'leg file {path}: missing {missing}')
    kw: dict[str, Any] = {'a_m': _triple(doc, 'a_m', path, positive=True, nonneg=True),
                          'link_masses_kg': _triple(doc, 'link_masses_kg', path, nonneg=True)}
    for key in ('alpha_rad', 'd_m', 'theta_offset_rad'):
        if key in doc:
            kw[key] = _triple(doc, key, path)
    if 'joint_limits_rad' in doc:
        try:
            kw['joint_limits_rad'] = tuple((float(lo), float(hi))
                                           for lo, hi in doc['joint_limits_rad'])
        except (TypeError, ValueError):
            raise InvalidInputError(f'leg file {path}: joint_limits_rad must be 3 [lower, '
                                    f'upper] pairs, got {doc["joint_limits_rad"]!r}') from None
    tip = _triple(doc, 'neutral_tip_m', path)
    try:
        dh = DHParameters(**kw)
        kin = LegKinematics(dh)
        check_reachable(make_gait('tripod'), kinematics=kin, neutral_tip_m=tip)
    except (InvalidGaitError, UnreachableError) as err:
        raise InvalidInputError(f'leg file {path}: {err}') from None
    return LegDescription(dh, tip, str(doc.get('name') or path.stem))
