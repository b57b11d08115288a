"""energy_monitor fed joint velocities in deg/s (a known gap: the model's P_out, or a refusal
without one): the unit is recognised from the positions' derivative and converted, the
published P_out and efficiency those of the same robot in rad/s, and the conversion is logged
once, naming the unit and the factor measured. A gear ratio (3.2) is refused, as before."""

from __future__ import annotations

import math

import pytest
from harness import ros_env
from sensor_msgs.msg import JointState
from test_energy_review_live_node import _Rig

from hexapod_energy.descriptors import VELOCITY_CONVERTED_NOTE, VELOCITY_UNITS_NOTE


class _ScaledRig(_Rig):
    """The reviewer's robot with its joint velocities times ``factor``."""

    def __init__(self, env, factor: float, **params):
        super().__init__(env, **params)
        self.factor = factor
        # stamps from a whole second: both runs' stamps round alike (their windows agree to
        # 1e-9, not to the 1e-7 two clock fractions gave)
        self.t0 = float(math.floor(self.t0))

    def joints(self, t: float, legs=None, effort=True) -> JointState:
        js = super().joints(t, **({'legs': legs} if legs is not None else {}), effort=effort)
        js.velocity = [v * self.factor for v in js.velocity]
        return js


def _walk(name: str, factor: float) -> tuple[list, list[str]]:
    with ros_env(name) as env:
        rig = _ScaledRig(env, factor)
        rig.walk(0.0, 7.0)
        msgs = rig.settle(5)
        return [(m.power_out, m.efficiency) for m in msgs], list(rig.logged['warning'])


@pytest.mark.timeout(240)
def test_deg_per_second_is_converted_live_and_said_once():
    ref, ref_warned = _walk('energy_units_rad', 1.0)
    assert all(math.isfinite(p) and p > 0 for p, _ in ref)
    assert not [w for w in ref_warned if 'rad/s' in w]
    got, warned = _walk('energy_units_deg', 180.0 / math.pi)
    n = min(len(ref), len(got))
    assert n >= 5
    for (p, e), (p_ref, e_ref) in zip(got[:n], ref[:n]):
        assert p == pytest.approx(p_ref, rel=1e-9) and e == pytest.approx(e_ref, rel=1e-9)
    said = [w for w in warned if w.startswith(VELOCITY_CONVERTED_NOTE)]
    assert len(said) == 1 and 'deg/s' in said[0] and 'times the derivative' in said[0]
    assert not [w for w in warned if w.startswith(VELOCITY_UNITS_NOTE)]


@pytest.mark.timeout(240)
def test_a_gear_ratio_is_refused_live():
    got, warned = _walk('energy_units_gear', 3.2)
    assert got
    assert any(w.startswith('P_out from effort x velocity refused (velocities not rad/s); '
                            'P_out from the Eq. 6 model') for w in warned)
    refused = [w for w in warned if w.startswith(VELOCITY_UNITS_NOTE)]
    assert refused and '3.2 times' in refused[0]
    assert not [w for w in warned if w.startswith(VELOCITY_CONVERTED_NOTE)]
