"""A robot's leg from a file: DH table, link masses and stance pose (``neutral_tip_m``).

One file describes the leg to every part of the project: ``gait_scheduler -p leg_file:=FILE``
(inverse kinematics of the joint commands, the stand pose, the reach checks),
``energy_monitor -p leg_file:=FILE`` and ``hexapod-analyze energy --leg FILE`` (the Eq. 6
output-power model, :mod:`hexapod_energy.leg_description`). The format (YAML or JSON)::

    name: PhantomX MK-III           # optional
    a_m: [0.052, 0.066, 0.133]      # DH link lengths [m]
    alpha_rad: [1.5708, 0, 0]       # optional (this is the only analytic form)
    d_m: [0, 0, 0]                  # optional
    theta_offset_rad: [0, 0, 0]     # optional: theta_i = q_i + offset_i
    link_masses_kg: [0.02, 0.08, 0.06]
    joint_limits_rad: [[-2.6, 2.6], [-2.6, 2.6], [-2.6, 2.6]]   # optional
    neutral_tip_m: [0.13, 0.0, -0.10]   # stance midpoint in the leg base frame [m]

Every key is checked (unknown keys refused, lengths and signs named in the error); the default
gait's path (tripod, 100 mm steps, 40 mm high) must lie inside the leg's workspace from that
stance pose, else the file is refused saying which point leaves it.

An outside review's quadruped (50/100/140 mm links): ``gait_scheduler`` had no leg parameter,
so it commanded AntBot's inverse kinematics on it; the scheduled 80 mm step walked 86.7 mm
with a 47.4 mm lift, and the speed, CoT and specific resistance read 8 % off.

Core module: no rclpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .errors import InvalidGaitError, UnreachableError

__all__ = ['LEG_FILE_KEYS', 'LegFile', 'LegFileError', 'read_leg_file']

LEG_FILE_KEYS = frozenset({'name', 'a_m', 'alpha_rad', 'd_m', 'theta_offset_rad',
                           'link_masses_kg', 'joint_limits_rad', 'neutral_tip_m'})


class LegFileError(InvalidGaitError):
    """A leg file that cannot be read or describes no usable leg (the message names the
    file and the problem)."""


@dataclass(frozen=True)
class LegFile:
    """A leg read from a file: DH table (:class:`~hexapod_gait.kinematics.DHParameters`),
    stance midpoint of the tip in the leg base frame [m] and a name."""

    dh: Any
    neutral_tip_m: tuple[float, float, float]
    name: str

    def kinematics(self) -> Any:
        """The leg's :class:`~hexapod_gait.kinematics.LegKinematics`."""
        from .kinematics import LegKinematics

        return LegKinematics(self.dh)


def _triple(doc: dict[str, Any], key: str, path: Path, *, positive: bool = False,
            nonneg: bool = False) -> tuple[float, float, float]:
    value = doc[key]
    try:
        out = tuple(float(x) for x in value)
    except (TypeError, ValueError):
        raise LegFileError(f'leg file {path}: {key} must be 3 numbers, got {value!r}') \
            from None
    if len(out) != 3 or not all(math.isfinite(x) for x in out):
        raise LegFileError(f'leg file {path}: {key} must be 3 finite numbers, got {value!r}')
    if nonneg and any(x < 0 for x in out):
        raise LegFileError(f'leg file {path}: {key} must be >= 0, got {list(out)}')
    if positive and any(x <= 0 for x in out[1:]):
        raise LegFileError(f'leg file {path}: {key}: femur and tibia must be > 0, got '
                           f'{list(out)}')
    return out  # type: ignore[return-value]


def read_leg_file(path: str | Path) -> LegFile:
    """Read and check a leg file (module docs); raises :class:`LegFileError` naming the file
    and the problem."""
    from ruamel.yaml import YAML
    from ruamel.yaml.error import YAMLError

    from .config import check_reachable
    from .gait import make_gait
    from .kinematics import DHParameters, LegKinematics

    path = Path(path)
    try:
        doc = YAML(typ='safe').load(path.read_text(encoding='utf8'))
    except OSError as err:
        raise LegFileError(f'leg file {path}: {err.strerror or err}') from None
    except YAMLError as err:
        raise LegFileError(f'leg file {path} is not YAML/JSON: '
                           f'{str(err).splitlines()[0]}') from None
    if not isinstance(doc, dict):
        raise LegFileError(f'leg file {path}: expected a mapping of {sorted(LEG_FILE_KEYS)}')
    unknown = sorted(set(doc) - LEG_FILE_KEYS)
    if unknown:
        raise LegFileError(f'leg file {path}: unknown key(s) {unknown}; expected '
                           f'{sorted(LEG_FILE_KEYS)}')
    missing = [k for k in ('a_m', 'link_masses_kg', 'neutral_tip_m') if k not in doc]
    if missing:
        raise LegFileError(f'leg file {path}: missing {missing}')
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
            raise LegFileError(f'leg file {path}: joint_limits_rad must be 3 [lower, '
                               f'upper] pairs, got {doc["joint_limits_rad"]!r}') from None
    tip = _triple(doc, 'neutral_tip_m', path)
    try:
        dh = DHParameters(**kw)
        kin = LegKinematics(dh)
        check_reachable(make_gait('tripod'), kinematics=kin, neutral_tip_m=tip)
    except (InvalidGaitError, UnreachableError) as err:
        raise LegFileError(f'leg file {path}: {err}') from None
    return LegFile(dh, tip, str(doc.get('name') or path.stem))
