"""gait_phase_from_msg: a GaitPhase with a non-finite number is refused (logged and dropped by
the nodes), as battery_from_msg refuses a NaN voltage."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from hexapod_common.conversions import gait_phase_from_msg


def _msg(**fields):
    base = dict(header=SimpleNamespace(stamp=SimpleNamespace(sec=12, nanosec=500_000_000)),
                gait='tripod', period=0.5, duty_factor=0.5, step_length=0.1, step_height=0.04,
                sweep_angle=0.0, leg_offset=0.0, cycle_phase=0.25,
                leg_names=['L1', 'R1'], phase_offsets=[0.0, 0.5], in_stance=[True, False],
                supporting_legs=1)
    base.update(fields)
    return SimpleNamespace(**base)


def test_a_finite_message_converts():
    s = gait_phase_from_msg(_msg())
    assert s.t_s == 12.5 and s.period_s == 0.5 and s.cycle_phase == 0.25
    assert s.speed_mps == pytest.approx(0.1 / 0.25)


@pytest.mark.parametrize('field', ['period', 'duty_factor', 'step_length', 'cycle_phase',
                                   'step_height', 'sweep_angle', 'leg_offset'])
@pytest.mark.parametrize('value', [math.nan, math.inf, -math.inf])
def test_a_non_finite_field_is_refused_by_name(field, value):
    with pytest.raises(ValueError, match=f'non-finite {field}='):
        gait_phase_from_msg(_msg(**{field: value}))


def test_non_finite_phase_offsets_are_refused():
    with pytest.raises(ValueError, match='phase_offsets'):
        gait_phase_from_msg(_msg(phase_offsets=[0.0, math.nan]))
