"""Leg and joint naming (DESIGN section 4).

Legs are ``L1..Lk`` (left side, front to rear) followed by ``R1..Rk`` (right side, front to rear),
with ``k = leg_count / 2``. 3-DOF legs have joints ``<leg>_coxa``, ``<leg>_femur``,
``<leg>_tibia``; RHex-class legs have one joint ``<leg>_hip``.
"""

from __future__ import annotations

from .errors import InvalidGaitError

__all__ = [
    'leg_names',
    'joint_names',
    'all_joint_names',
    'leg_side',
    'leg_rank',
    'JOINT_SUFFIXES_3DOF',
    'JOINT_SUFFIXES_1DOF',
]

JOINT_SUFFIXES_3DOF: tuple[str, str, str] = ('coxa', 'femur', 'tibia')
JOINT_SUFFIXES_1DOF: tuple[str] = ('hip',)


def leg_names(leg_count: int) -> tuple[str, ...]:
    """Names of the legs of an even-legged robot.

    Parameters
    ----------
    leg_count : int
        Number of legs, even and at least 2.

    Returns
    -------
    tuple of str, length ``leg_count``
        ``('L1', ..., 'Lk', 'R1', ..., 'Rk')``, front to rear on each side.
    """
    if isinstance(leg_count, bool) or int(leg_count) != leg_count:
        raise InvalidGaitError(f'leg_count must be an integer, got {leg_count!r}')
    leg_count = int(leg_count)
    if leg_count < 2 or leg_count % 2:
        raise InvalidGaitError(f'leg_count must be even and >= 2, got {leg_count}')
    k = leg_count // 2
    return tuple(f'L{i}' for i in range(1, k + 1)) + tuple(f'R{i}' for i in range(1, k + 1))


def leg_side(leg: str) -> str:
    """``'left'`` or ``'right'`` from a leg name such as ``'L2'``."""
    if leg[:1] == 'L':
        return 'left'
    if leg[:1] == 'R':
        return 'right'
    raise InvalidGaitError(f"leg name must start with 'L' or 'R', got {leg!r}")


def leg_rank(leg: str) -> int:
    """Position of a leg on its side, 1 = front, from a leg name such as ``'R3'``."""
    leg_side(leg)
    try:
        rank = int(leg[1:])
    except ValueError:
        raise InvalidGaitError(f"leg name must look like 'L1' or 'R3', got {leg!r}") from None
    if rank < 1:
        raise InvalidGaitError(f'leg rank must be >= 1, got {leg!r}')
    return rank


def joint_names(leg: str, dof: int = 3) -> tuple[str, ...]:
    """Joint names of one leg.

    Parameters
    ----------
    leg : str
        Leg name, e.g. ``'L1'``.
    dof : {3, 1}
        3 for coxa/femur/tibia legs, 1 for RHex-class hip-only legs.

    Returns
    -------
    tuple of str, length ``dof``
        ``('L1_coxa', 'L1_femur', 'L1_tibia')`` or ``('L1_hip',)``.
    """
    leg_rank(leg)
    if dof == 3:
        return tuple(f'{leg}_{s}' for s in JOINT_SUFFIXES_3DOF)
    if dof == 1:
        return tuple(f'{leg}_{s}' for s in JOINT_SUFFIXES_1DOF)
    raise InvalidGaitError(f'dof must be 3 or 1, got {dof!r}')


def all_joint_names(legs: tuple[str, ...] | list[str], dof: int = 3) -> tuple[str, ...]:
    """Joint names of several legs, leg-major (all joints of the first leg first)."""
    return tuple(name for leg in legs for name in joint_names(leg, dof))
