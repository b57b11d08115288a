"""Pins found missing by a mutation review (gait feasibility, batteries, bag columns, the
energy effects catalogue, the SLIP model): each test fails on a one-line change that passed
the suite."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexapod_common.bags import SampleColumns
from hexapod_common.battery import BatteryCombiner, combine_battery_samples, milli_factors
from hexapod_common.conversions import BatterySample
from hexapod_gait.feasibility import InfeasibleGaitError, max_speed_mps, period_for_speed


# --- hexapod_gait.feasibility ------------------------------------------------------------

@pytest.mark.parametrize('beta', [0.5, 0.6, 0.7])
def test_a_speed_a_few_percent_over_the_maximum_is_refused(beta):
    """period_for_speed refuses any speed above max_speed_mps (only a 1e-9 relative slack
    for a gait built exactly at a limit): 1 % and 5 % over it are infeasible (a 10 % slack
    let the scheduler command a period shorter than the servos' minimum swing or stance)."""
    v_max = max_speed_mps(beta, 0.10)
    period_for_speed(v_max, beta, 0.10)                       # exactly at the limit
    for over in (1.01, 1.05):
        with pytest.raises(InfeasibleGaitError, match='maximum speed'):
            period_for_speed(over * v_max, beta, 0.10)


# --- hexapod_common.battery --------------------------------------------------------------

def _bat(t, v, i, source):
    return BatterySample(float(t), float(v), float(i), 25.0, source)


def test_a_slowly_reporting_battery_stays_in_the_sum_between_its_reports():
    """A logic pack reporting every 3 s beside a servo pack at 10 Hz: the sum keeps its 6 W
    between reports (a source leaves only after max(stale_s, 5 x its own interval) of
    silence, here 15 s, once its interval is known from its second report, and 10 s before
    it). A fixed 2 s limit dropped it for the last third of every interval: 30 W read as
    24 W."""
    samples = [_bat(k * 0.1, 12.0, 2.0, 'servo') for k in range(120)]
    samples += [_bat(t, 12.0, 0.5, 'logic') for t in (0.0, 3.0, 6.0, 9.0)]
    out, notes = combine_battery_samples(samples)
    power = np.array([s.voltage_v * s.current_a for s in out])
    assert power.size > 110 and power == pytest.approx(30.0, rel=1e-12)
    # before its interval was known (the first 3 s) it was left out after 2 s; now a source
    # seen once waits FIRST_REPORT_STALE_S (10 s) for its second report
    assert not [n for n in notes if 'silent' in n]
    # silent for more than 5 intervals (15 s): left out, noted
    late = [_bat(12.0 + k * 0.1, 12.0, 2.0, 'servo') for k in range(180)]
    out, notes = combine_battery_samples(samples + late)
    tail = [s.voltage_v * s.current_a for s in out if s.t_s > 9.0 + 15.0 + 0.05]
    assert tail and tail == pytest.approx([24.0] * len(tail), rel=1e-12)
    assert any("'logic' silent for more than 15.0 s" in n for n in notes)


def test_millivolts_beside_a_current_that_no_unit_makes_plausible_keep_the_drivers_unit():
    """A voltage in mV beside a current under 1000: the power decides whether the current
    is mA or A, and when neither reading is a legged robot's draw (20 units beside 12 V:
    0.24 mW or 0.24 W) the driver's own unit, mA. A mutant left such a current in A."""
    assert milli_factors(12000.0, 0.02) == (1e-3, 1e-3)
    assert milli_factors(12000.0, 900.0) == (1e-3, 1e-3)      # 10.8 W in mA
    assert milli_factors(12000.0, 2.5) == (1e-3, 1.0)         # 30 W in A
    assert milli_factors(12.0, 2.5) == (1.0, 1.0)


def test_a_reference_battery_reading_zero_volts_still_gives_the_summed_power():
    """The combined sample carries the reference (first seen) source's voltage and the summed
    power over it; a reference reading 0 V (a rail without a voltage sensor) is replaced by
    1 V, so V x I is still the sum (dividing by its 0 V raised ZeroDivisionError)."""
    comb = BatteryCombiner(expected=('aux', 'pack'))
    assert comb.add(_bat(0.0, 0.0, 0.0, 'aux')) is None
    out = comb.add(_bat(0.05, 12.0, 2.0, 'pack'))
    assert out is not None and math.isfinite(out.current_a)
    assert out.voltage_v * out.current_a == pytest.approx(24.0, rel=1e-12)


# --- hexapod_common.bags -----------------------------------------------------------------

def test_a_clock_shift_moves_stamps_stored_as_numpy_scalars_forward():
    """SampleColumns.shift adds dt to a field (a clock offset). Stamps that are numpy floats
    (not Python floats) are stored in another kind of column; they must move the same way
    (a mutant subtracted dt there: the stream moved the other way by twice the offset)."""
    cols = SampleColumns()
    for k in range(4):
        cols.append(BatterySample(np.float64(1.0 + 0.1 * k), 12.0, 1.0, 25.0, 'a'))
    cols.shift('t_s', 0.5)
    assert [s.t_s for s in cols] == pytest.approx([1.5, 1.6, 1.7, 1.8], rel=1e-12)
    plain = SampleColumns()
    for k in range(4):
        plain.append(BatterySample(1.0 + 0.1 * k, 12.0, 1.0, 25.0, 'a'))
    plain.shift('t_s', 0.5)
    assert [s.t_s for s in plain] == pytest.approx([1.5, 1.6, 1.7, 1.8], rel=1e-12)


# --- hexapod_energy.effects_catalogue ----------------------------------------------------

def test_a_supply_resistance_is_found_with_a_positive_power_coefficient():
    """A series resistance lowers the servos' voltage and so their input power: P = P_pred
    - k I^2 with k > 0. The effect's regressor is -I^2 with a coefficient bounded >= 0, so a
    residual of -0.6 I^2 is found as k = 0.6 ohm (the regressor +I^2 could only fit k = 0
    and the effect was never found)."""
    from hexapod_energy.effects_catalogue import SupplyResistance, WindowTable
    from hexapod_energy.residuals import EffectSelection, split_mask

    rng = np.random.default_rng(5)
    n = 180
    t = np.arange(n) * 0.5
    i2 = 4.0 + 3.0 * np.sin(t / 5.0) + rng.uniform(0.0, 1.0, n)
    y = -0.6 * i2 + rng.normal(0.0, 0.02, n)
    table = WindowTable(run=np.repeat(np.arange(3), n // 3), t_s=t, duration_s=np.full(n, 0.5),
                        measured_w=30.0 + y, predicted_w=np.full(n, 30.0),
                        step_frequency_hz=np.full(n, 1.5), speed_mps=np.full(n, 0.3),
                        current_sq_a2=i2, temp_excess_k=np.full(n, np.nan),
                        stance_fraction=np.full((n, 6), 0.5), leg_names=tuple('ABCDEF'),
                        supply_slope_ohm=0.8, supply_slope_stderr_ohm=0.01)
    sel = EffectSelection(catalogue=[SupplyResistance()]).fit(table, split_mask(table))
    assert [e.name for e in sel.selected_] == ['supply_resistance']
    (rec,) = [c for c in sel.candidates_ if c['name'] == 'supply_resistance']
    assert rec['params']['power_coefficient_ohm'] == pytest.approx(0.6, rel=0.02)
    assert rec['params']['resistance_ohm'] == 0.8


# --- slip_identification.model -----------------------------------------------------------

def test_touchdown_state_puts_the_foot_ahead_of_the_mass_at_rest_length():
    """touchdown_state: leg at rest length, foot ahead of the mass by l0 sin(angle) (the
    angle is positive with the foot ahead), velocity pointing down and forward, so the leg
    starts compressing: the synthetic stances' touchdown position. With the mass ahead of the
    foot the leg started sideways to the velocity (no compression)."""
    from slip_identification.model import SlipModel
    from slip_identification.synthetic import make_stance

    params = np.array([3000.0, 0.15, 0.5])
    x = SlipModel().touchdown_state(params, speed_mps=0.8, angle_rad=0.3)
    assert x[0] == pytest.approx(0.5 - 0.15 * math.sin(0.3), rel=1e-12)
    assert math.hypot(x[0] - 0.5, x[2]) == pytest.approx(0.15, rel=1e-12)
    radial = (x[0] - 0.5) * x[1] + x[2] * x[3]                 # d(r^2)/dt / 2
    assert radial < -0.5 * 0.15 * 0.8 * math.sin(0.6)
    synthetic = make_stance(params, speed_mps=0.8 * math.cos(0.3), angle_rad=0.3,
                            vz_mps=-0.8 * math.sin(0.3)).stance
    assert synthetic.state[0] == pytest.approx(x, rel=1e-9, abs=1e-12)
