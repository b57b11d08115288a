"""Named effects of the simulated hardware: documented switches with physical parameters.

Each effect is off unless asked for (``--effect NAME=VALUE``), except ``sensor_noise`` which is on
by default (value 1 = the noise of the real sensors; 0 turns it off). Every run records the
effective set in the bag's metadata (custom data key ``hexapod_sim.effects``, JSON), never in a
topic the analysis reads. Each parameter is chosen so that an analysis can recover it from the
data it is given (``/battery_state``, ``/servo_status``, ``/joint_states``, ``/gait/phase``):

=================== ======== ==================================================================
name                unit     exact physical meaning (the regressor an analysis would use)
=================== ======== ==================================================================
basal_power         W        constant extra input power at the supply, drawn whenever powered:
                             ``P_in += value``.
thermal_drift       W/K      every powered servo draws ``value * (T_i - T_ambient)`` extra, with
                             ``T_i`` its winding temperature (reported on ``/servo_status``):
                             ``P_in += value * sum_i (T_i - T_amb)``. On top of the copper
                             resistance rise (+0.393 %/K) that is always modelled.
kinematic_error     W/Hz     tracking-error cost while walking: ``P_in += value * f_step``
                             (``f_step = 1 / period`` from ``/gait/phase``), zero at standstill;
                             the joints' goals also overshoot the commanded motion by
                             ``0.0025 * value * f_step`` of its excursion from the neutral
                             pose (a visible symptom, whose own physical cost is small).
supply_resistance   ohm      series resistance between the ideal source and the monitor and
                             robot (cable, connector, battery): the monitored voltage is
                             ``V = V_source - value * I``; the servos run at that voltage.
speed_friction      N s/m    viscous friction of the ground (robot) or treadmill (bench) on the
                             stance tips: a horizontal force ``value * v`` against the motion of
                             the supporting tips, shared by the stance legs. Mechanical power
                             ``value * v^2``; the electrical cost is larger by the drive losses.
leg_anomaly         leg:W    one leg draws extra power while it is in stance (a stiff or
                             rubbing joint loaded by the body): ``LEG:W`` such as ``L2:1.5``;
                             ``P_in += W * in_stance(LEG)``.
stance_preload      N        robot only: legs fighting each other in an over-constrained
                             stance. With ``L > 3`` legs on the ground a position-controlled
                             robot's small kinematic mismatches (leg zero offsets, uneven
                             ground, body flex) make its stance legs push against each other:
                             vertical tip forces ``f`` of norm ``value * sqrt(L - 3)`` are
                             added to the weight's, internal (``sum f = 0`` and no roll or
                             pitch moment on a nominal footprint: each of the ``L - 3``
                             redundant supports carries ``value``), through each stance leg's
                             Jacobian, so the servos pay for them (copper and gear losses of
                             the servo model, no flat watts). Regressor: ``max(L - 3, 0)``.
time_offset         s        clock offset of the power monitor: ``/battery_state`` stamps are
                             ``t_true + value`` (the other streams keep the true time).
sensor_noise        x        scale of the sensors' white noise (1 = default, on): battery
                             current 8 mA and voltage 4 mV, force 0.05 N, leg tip 0.3 mm, joint
                             velocity 0.02 rad/s (positions are always quantised to the AX's
                             0.29 degree ticks, temperatures to 1 degC).
sensor_latency      s        transport delay of the servo bus: ``/joint_states`` and
                             ``/servo_status`` are stamped ``value`` seconds after the instant
                             they describe.
=================== ======== ==================================================================

The EduBot effects ``leg_damping`` and ``hip_torque`` belong to ``edubot_sim`` (its own helper);
this registry knows their names so that ``--effect`` validation accepts them for ``edubot``.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    'EFFECTS',
    'EffectError',
    'EffectSet',
    'EffectSpec',
    'METADATA_KEY',
    'effect_table_markdown',
    'parse_effects',
]

#: Custom-data key in the bag's metadata under which the effect set is stored (JSON).
METADATA_KEY = 'hexapod_sim.effects'


class EffectError(ValueError):
    """An unknown effect name or a value that does not parse (names the effect and the form)."""


@dataclass(frozen=True)
class EffectSpec:
    """One named effect: unit, default, and whether it is on without being asked."""

    name: str
    unit: str
    default: Any
    default_on: bool
    description: str
    kind: str = 'float'                  # 'float' or 'leg_watts'
    simulators: frozenset[str] = field(default_factory=lambda: frozenset({'bench', 'robot'}))


_SPECS = (
    EffectSpec('basal_power', 'W', 0.0, False,
               'constant extra input power at the supply'),
    EffectSpec('thermal_drift', 'W/K', 0.0, False,
               'extra power per servo per kelvin of winding temperature above ambient'),
    EffectSpec('kinematic_error', 'W/Hz', 0.0, False,
               'tracking-error power per hertz of step frequency while walking'),
    EffectSpec('supply_resistance', 'ohm', 0.0, False,
               'series resistance source -> monitor/robot: V = V_source - R I'),
    EffectSpec('speed_friction', 'N s/m', 0.0, False,
               'viscous ground/treadmill friction on the stance tips (F = c v)'),
    EffectSpec('leg_anomaly', 'leg:W', None, False,
               'one leg draws W extra while in stance (LEG:W, e.g. L2:1.5)', kind='leg_watts'),
    EffectSpec('stance_preload', 'N', 0.0, False,
               'legs fighting each other: an internal vertical preload per stance leg beyond '
               'three (no net force or moment), paid by the servos',
               simulators=frozenset({'robot'})),
    EffectSpec('time_offset', 's', 0.0, False,
               'clock offset of /battery_state stamps'),
    EffectSpec('sensor_noise', 'x', 1.0, True,
               'scale of the sensor white noise (1 = real sensors, 0 = none)'),
    EffectSpec('sensor_latency', 's', 0.0, False,
               'servo-bus delay of /joint_states and /servo_status stamps'),
    EffectSpec('leg_damping', 'N s/m', 0.0, False,
               'EduBot: viscous damping in the compliant legs (edubot_sim)',
               simulators=frozenset({'edubot'})),
    EffectSpec('hip_torque', 'N m', 0.0, False,
               'EduBot: extra hip torque offset (edubot_sim)', simulators=frozenset({'edubot'})),
)

#: The registry, by name.
EFFECTS: Mapping[str, EffectSpec] = {spec.name: spec for spec in _SPECS}


#: Largest magnitude of an effect's value, and why: a stamp moved by more than this is no clock
#: offset or transport delay of one recording (1e9 s overflowed the int32 stamp seconds and left a
#: half-written bag behind).
_MAX_ABS: dict[str, tuple[float, str]] = {
    'time_offset': (1e5, 'about a day: a larger offset is no clock offset of one recording'),
    'sensor_latency': (1e5, 'about a day: a larger delay is no transport delay'),
}


def _parse_value(spec: EffectSpec, text: str) -> Any:
    if spec.kind == 'leg_watts':
        leg, sep, watts = text.partition(':')
        try:
            value = float(watts)
        except ValueError:
            value = math.nan
        if not sep or not leg.strip() or not math.isfinite(value):
            raise EffectError(f'effect {spec.name}={text!r}: expected LEG:WATTS such as L2:1.5')
        return (leg.strip(), value)
    try:
        value = float(text)
    except ValueError:
        raise EffectError(f'effect {spec.name}={text!r}: expected a number in {spec.unit}') \
            from None
    if not math.isfinite(value):
        raise EffectError(f'effect {spec.name}={text!r}: expected a finite number')
    if spec.name in ('supply_resistance', 'speed_friction', 'sensor_noise', 'sensor_latency',
                     'stance_preload') and value < 0.0:
        raise EffectError(f'effect {spec.name}={text!r}: expected a value >= 0 {spec.unit}')
    if spec.name in _MAX_ABS and abs(value) > _MAX_ABS[spec.name][0]:
        limit, why = _MAX_ABS[spec.name]
        raise EffectError(f'effect {spec.name}={text!r}: expected |value| <= {limit:g} '
                          f'{spec.unit} ({why})')
    return value


@dataclass(frozen=True)
class EffectSet:
    """The effects of one run: name -> value for every effect that is on.

    Use :meth:`value` to read one (the neutral value when off).
    """

    active: Mapping[str, Any] = field(default_factory=dict)

    def is_on(self, name: str) -> bool:
        """Whether ``name`` is on in this run."""
        self._check(name)
        return name in self.active

    def value(self, name: str) -> Any:
        """The effect's value, or its neutral value (0, None, or 0 for noise) when off."""
        spec = self._check(name)
        if name in self.active:
            return self.active[name]
        return None if spec.kind == 'leg_watts' else 0.0

    def with_effect(self, name: str, value: Any) -> EffectSet:
        """Copy with one effect set (``value`` as parsed, or text to parse)."""
        spec = self._check(name)
        if isinstance(value, str):
            value = _parse_value(spec, value)
        active = dict(self.active)
        active[name] = value
        return EffectSet(active)

    def without(self, name: str) -> EffectSet:
        """Copy with one effect off."""
        self._check(name)
        return EffectSet({k: v for k, v in self.active.items() if k != name})

    def to_json(self) -> str:
        """JSON of the active effects with units, for the bag's metadata."""
        return json.dumps({name: {'value': list(v) if isinstance(v, tuple) else v,
                                  'unit': EFFECTS[name].unit}
                           for name, v in sorted(self.active.items())}, sort_keys=True)

    @classmethod
    def from_json(cls, text: str) -> EffectSet:
        """Inverse of :meth:`to_json`."""
        data = json.loads(text)
        active: dict[str, Any] = {}
        for name, entry in data.items():
            cls._check(name)
            value = entry['value']
            active[name] = tuple(value) if isinstance(value, list) else value
        return cls(active)

    @classmethod
    def defaults(cls) -> EffectSet:
        """Only the effects documented as on by default."""
        return cls({s.name: s.default for s in _SPECS if s.default_on})

    @classmethod
    def none(cls) -> EffectSet:
        """Everything off, sensor noise included (ideal sensors)."""
        return cls({})

    @staticmethod
    def _check(name: str) -> EffectSpec:
        if name not in EFFECTS:
            raise EffectError(f'unknown effect {name!r}: expected one of '
                              + ', '.join(sorted(EFFECTS)))
        return EFFECTS[name]


def parse_effects(items: Iterable[str], *, defaults: bool = True,
                  simulator: str | None = None) -> EffectSet:
    """Parse ``NAME=VALUE`` strings (the CLI's ``--effect``) on top of the defaults.

    Parameters
    ----------
    items : iterable of str
        ``'basal_power=3'``, ``'leg_anomaly=L2:1.5'``; ``NAME=off`` turns a default effect off.
    defaults : bool
        Start from :meth:`EffectSet.defaults` (True) or from nothing.
    simulator : {'bench', 'robot', 'edubot'}, optional
        Refuse effects that simulator does not implement.
    """
    effects = EffectSet.defaults() if defaults else EffectSet.none()
    for item in items:
        name, sep, text = item.partition('=')
        name = name.strip()
        if not sep:
            raise EffectError(f'effect {item!r}: expected NAME=VALUE')
        spec = EffectSet._check(name)
        if simulator is not None and simulator not in spec.simulators:
            raise EffectError(f'effect {name!r} is not implemented by the {simulator} simulator '
                              f'(it applies to: {", ".join(sorted(spec.simulators))})')
        if text.strip().lower() == 'off':
            effects = effects.without(name)
        else:
            effects = effects.with_effect(name, _parse_value(spec, text.strip()))
    return effects


def effect_table_markdown() -> str:
    """The effect table for the README (name, unit, default, meaning)."""
    rows = ['| effect | unit | default | meaning |', '|---|---|---|---|']
    for s in _SPECS:
        default = f'on ({s.default})' if s.default_on else 'off'
        sims = '' if s.simulators == frozenset({'bench', 'robot'}) else \
            f' ({", ".join(sorted(s.simulators))} only)'
        rows.append(f'| `{s.name}` | {s.unit} | {default} | {s.description}{sims} |')
    return '\n'.join(rows)
