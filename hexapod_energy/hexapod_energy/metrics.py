"""Energetic descriptors exactly as DESIGN §4 defines them.

All functions take and return floats or NumPy arrays (broadcast elementwise).

==========================  ==================================  ===========
descriptor                  definition                          unit
==========================  ==================================  ===========
power loss                  P_loss = P_in - P_out               W
efficiency                  eta = P_out / P_in                  1
cost of transport           CoT = P_loss / v                    J/m
specific cost of transport  CoT/M = P_loss / (M v)              J/(m kg)
specific resistance         epsilon = P_in / (M g v)            1
==========================  ==================================  ===========

``g = 9.81 m/s^2`` (:data:`G_MPS2`).  ``M`` is the total mass, payload included.
Division by a zero speed or zero input power returns ``inf``/``nan`` as NumPy does
(a robot standing still has an infinite cost of transport), never an exception.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    'G_MPS2',
    'Descriptors',
    'cost_of_transport',
    'descriptors',
    'efficiency',
    'power_loss',
    'specific_cost_of_transport',
    'specific_resistance',
]

G_MPS2 = 9.81
"""Gravitational acceleration used by every descriptor [m/s^2] (DESIGN §4)."""


def _arr(x: ArrayLike) -> np.ndarray:
    return np.asarray(x, dtype=float)


def _out(x: np.ndarray) -> np.ndarray | float:
    return float(x) if x.ndim == 0 else x


def power_loss(power_in_w: ArrayLike, power_out_w: ArrayLike) -> np.ndarray | float:
    """P_loss = P_in - P_out [W]."""
    return _out(_arr(power_in_w) - _arr(power_out_w))


def efficiency(power_in_w: ArrayLike, power_out_w: ArrayLike) -> np.ndarray | float:
    """eta = P_out / P_in [1]."""
    with np.errstate(divide='ignore', invalid='ignore'):
        return _out(_arr(power_out_w) / _arr(power_in_w))


def cost_of_transport(
    power_in_w: ArrayLike, power_out_w: ArrayLike, speed_mps: ArrayLike
) -> np.ndarray | float:
    """CoT = P_loss / v [J/m]."""
    with np.errstate(divide='ignore', invalid='ignore'):
        return _out((_arr(power_in_w) - _arr(power_out_w)) / _arr(speed_mps))


def specific_cost_of_transport(
    power_in_w: ArrayLike, power_out_w: ArrayLike, mass_kg: ArrayLike, speed_mps: ArrayLike
) -> np.ndarray | float:
    """CoT/M = P_loss / (M v) [J/(m kg)]."""
    with np.errstate(divide='ignore', invalid='ignore'):
        return _out(
            (_arr(power_in_w) - _arr(power_out_w)) / (_arr(mass_kg) * _arr(speed_mps))
        )


def specific_resistance(
    power_in_w: ArrayLike, mass_kg: ArrayLike, speed_mps: ArrayLike
) -> np.ndarray | float:
    """epsilon = P_in / (M g v) [1], with g = :data:`G_MPS2`."""
    with np.errstate(divide='ignore', invalid='ignore'):
        return _out(_arr(power_in_w) / (_arr(mass_kg) * G_MPS2 * _arr(speed_mps)))


@dataclass(frozen=True)
class Descriptors:
    """All descriptors of one operating point (scalars, SI units)."""

    mass_kg: float
    speed_mps: float
    power_in_w: float
    power_out_w: float
    power_loss_w: float
    efficiency: float
    cost_of_transport_j_per_m: float
    specific_cost_of_transport_j_per_m_kg: float
    specific_resistance: float


def descriptors(
    *, power_in_w: float, power_out_w: float, mass_kg: float, speed_mps: float
) -> Descriptors:
    """Every descriptor of DESIGN §4 for one operating point."""
    return Descriptors(
        mass_kg=float(mass_kg),
        speed_mps=float(speed_mps),
        power_in_w=float(power_in_w),
        power_out_w=float(power_out_w),
        power_loss_w=float(power_loss(power_in_w, power_out_w)),
        efficiency=float(efficiency(power_in_w, power_out_w)),
        cost_of_transport_j_per_m=float(cost_of_transport(power_in_w, power_out_w, speed_mps)),
        specific_cost_of_transport_j_per_m_kg=float(
            specific_cost_of_transport(power_in_w, power_out_w, mass_kg, speed_mps)
        ),
        specific_resistance=float(specific_resistance(power_in_w, mass_kg, speed_mps)),
    )
