"""Catalogue of candidate effects for the energy residual loop (DESIGN section 8).

Core module: numpy only. Each effect is one small class: a physically named extension of the
whole-robot power model ``P_model = P_pred + sum_e X_e beta_e``, with the regressor columns
``X_e`` it computes from a :class:`WindowTable` (per-window means of what the bags provide) and
the conversion of the fitted coefficients ``beta_e`` into named, unit-carrying parameters.
Coefficients are bounded to the physical sign (every effect here *adds* input power), so a
model that over-predicts cannot be "explained" by an effect that would have to be negative.

To add an effect, subclass :class:`EnergyEffect`, implement :meth:`~EnergyEffect.columns` and
:meth:`~EnergyEffect.params`, and append an instance to :func:`default_catalogue`.

=================== ============================================ =============================
name                regressor (window mean)                       parameter [unit]
=================== ============================================ =============================
basal_power         1                                             ``power_w`` [W]
thermal_drift       sum_i (T_i - T_r) from /servo_status [K];     ``w_per_k`` [W/K],
                    its variation must explain too; T_r fitted ``reference_c`` [degC]
thermal_drift       energy drawn since the run's start [kJ], only  ``w_per_kj`` [W/kJ]
                    without /servo_status (ThermalDriftTime)
hot_windings        mean_i (T_i - T_ref) x P_pred [K W]; its      ``per_k`` [1/K]
                    variation must explain too
kinematic_error     step frequency 1/T from /gait/phase [Hz]      ``w_per_hz`` [W/Hz]
supply_resistance   -I^2 [A^2], only when V falls with I (before  ``resistance_ohm`` [ohm] from
                                                                  the V-I slope, and
                                                                  ``power_coefficient_ohm``
cable_resistance    I^2 [A^2], a resistance after the monitor       ``resistance_ohm`` [ohm]
                    (its own R I^2 is measured)
speed_friction      DRIVE_LOSS_FACTOR * v^2 [m^2/s^2]              ``c_n_s_per_m`` [N s/m]
leg_anomaly         fraction of the window leg j is in stance     ``power_w`` [W], ``leg``
stance_preload      max(L - 3, 0), L the legs in stance from       ``w_per_leg`` [W per extra
                    /gait/phase (an over-constrained stance)      stance leg]
carried_mass        dP_pred/dM, the bench model's mass            ``mass_kg`` [kg]
                    sensitivity (undeclared payload)
swing_reversal      swings per second x (stance tip speed - the   ``j_per_mps`` [J s/m]
                    bench's before a swing as long); its
                    variation must explain too
standing_hold       standing: N (P_basal(m_c) - P_basal(lightest  ``holding_change`` [-],
                    bench load)), the bench's holding power;      -1 to +1
                    walking: 0
power_gain          P_pred (sensor gain, converter efficiency,    ``gain_excess`` [-] (the
                    another supply voltage)                       factor minus 1), ``factor``
time_offset         (realignment, see :mod:`residuals`)           ``offset_s`` [s]
model_offset        1, coefficient <= 0 (opt-in, not default)     ``offset_w`` [W]
=================== ============================================ =============================

There is no always-on constant in the model: the bench-to-robot transfer bias is reported as
the baseline ``bias`` instead of being fitted away, so a constant extra consumption is free to
show as ``basal_power``. On simulated data with the paper's tip-load convention
(``load_offset_kg = 0``: the simulated robot's stance tips carry ``M g / L``) and
cross-validated LOWESS spans the clean bias is -0.24 W on 27-45 W; a negative constant has
no physical effect in this catalogue (every effect adds power), so clean data adds nothing.

``T_ref`` is the servo temperature the bench model was measured at (median over the bench's
walking sessions): ``hot_windings`` is relative to the bench conditions; ``thermal_drift``'s
reference ``T_r`` is fitted between a few kelvin below the robot's coldest servo reading and
above the bench's (:class:`ThermalDrift`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

__all__ = [
    'DRIVE_LOSS_FACTOR',
    'BasalPower',
    'CableResistance',
    'CarriedMass',
    'EnergyEffect',
    'HotWindings',
    'KinematicError',
    'LegAnomaly',
    'ModelOffset',
    'PowerGain',
    'STATICALLY_DETERMINATE_LEGS',
    'SpeedFriction',
    'StancePreload',
    'StandingHold',
    'SupplyResistance',
    'SwingReversal',
    'ThermalDrift',
    'ThermalDriftTime',
    'TimeOffset',
    'WindowTable',
    'default_catalogue',
]

#: Electrical input power per watt of viscous ground friction ``c v^2`` for the AX-18A
#: hexapod (drive losses: winding copper loss and 254:1 gear friction): the slope of the extra
#: input power against ``c v^2`` fitted with an offset over 0.2-0.4 m/s tripod runs of the servo
#: model (point-wise ratios 3.1 to 5: the losses grow with the load). The fitted coefficient on
#: ``v^2`` divided by this factor is
#: the friction coefficient ``c`` [N s/m].
DRIVE_LOSS_FACTOR = 3.0


@dataclass
class WindowTable:
    """Per-window means of one or more robot runs, arrays (n,) unless noted.

    Attributes
    ----------
    run : int array       index of the run of each window
    t_s : window centre [s] (bag time)
    duration_s : window length [s]
    measured_w, predicted_w : mean measured and predicted input power [W]
    step_frequency_hz : 1 / T, 0 standing [Hz]
    speed_mps : body speed from the gait schedule [m/s]
    current_sq_a2 : mean of I^2 (discharge current) [A^2]
    temp_excess_k : mean of sum_i (T_i - T_ref) [K], nan without /servo_status
    stance_fraction : (n, legs) fraction of the window each leg is in stance
    leg_names : tuple of str
    supply_slope_ohm, supply_slope_stderr_ohm : -dV/dI over all samples (lagged) [ohm]
    """

    run: np.ndarray
    t_s: np.ndarray
    duration_s: np.ndarray
    measured_w: np.ndarray
    predicted_w: np.ndarray
    step_frequency_hz: np.ndarray
    speed_mps: np.ndarray
    current_sq_a2: np.ndarray
    temp_excess_k: np.ndarray
    stance_fraction: np.ndarray
    leg_names: tuple[str, ...]
    supply_slope_ohm: float = 0.0
    supply_slope_stderr_ohm: float = float('inf')
    extra: dict[str, Any] = field(default_factory=dict)

    @property
    def residual_w(self) -> np.ndarray:
        """Measured minus predicted [W], (n,)."""
        return self.measured_w - self.predicted_w

    def subset(self, mask: np.ndarray) -> WindowTable:
        """The windows in ``mask`` (bool (n,))."""
        kw = {k: getattr(self, k)[mask] for k in (
            'run', 't_s', 'duration_s', 'measured_w', 'predicted_w', 'step_frequency_hz',
            'speed_mps', 'current_sq_a2', 'temp_excess_k', 'stance_fraction')}
        n = self.t_s.shape[0]
        # per-window arrays in ``extra`` (first axis n) are cut too; run-level entries are kept
        extra = {k: (v[mask] if isinstance(v, np.ndarray) and v.ndim and v.shape[0] == n
                     else v) for k, v in self.extra.items()}
        return WindowTable(**kw, leg_names=self.leg_names, supply_slope_ohm=self.supply_slope_ohm,
                           supply_slope_stderr_ohm=self.supply_slope_stderr_ohm,
                           extra=extra)


class EnergyEffect:
    """One candidate effect. Subclasses set ``name``, ``unit`` and implement two methods."""

    name = ''
    unit = ''
    #: bounds of every coefficient (effects add power: lower 0, upper inf)
    lower = 0.0
    upper = float('inf')
    #: False: evaluated and reported as an alternative explanation of what an added effect
    #: explains, never added itself (an effect that would stand for too many others)
    selectable = True
    #: True: added only when its columns minus their means (their variation over the windows)
    #: also lower the held-out error: a near-constant column must not pass for an offset
    needs_variation = False
    #: True (with ``needs_variation``): its variation is tested beside a free offset, as its
    #: column is of one sign by nature (what an offset leaves must follow it)
    variation_beside_offset = False
    #: True: a transfer error of the bench-derived model that every candidate may be fitted
    #: beside (a candidate that passes only with it adds both; ``EffectSelection``)
    companion = False

    def applicable(self, table: WindowTable) -> bool:
        """Whether the bags give this effect's regressor (and any evidence it needs)."""
        return True

    def variation_columns(self, table: WindowTable) -> np.ndarray:
        """The part of :meth:`columns` that the effect's own cause varies (the test of
        :attr:`needs_variation`): by default the columns minus their means."""
        x = self.columns(table)
        return x - np.mean(x, axis=0)

    def selectable_on(self, table: WindowTable) -> bool:
        """Whether the loop may add it on these windows (default :attr:`selectable`)."""
        return self.selectable

    def needs_variation_on(self, table: WindowTable) -> bool:
        """Whether its variation must explain too on these windows (default
        :attr:`needs_variation`)."""
        return self.needs_variation

    def columns(self, table: WindowTable) -> np.ndarray:
        """Regressor columns (n, k) whose coefficients this effect fits."""
        raise NotImplementedError

    def span_columns(self, table: WindowTable) -> np.ndarray:
        """The columns that the span checks of the selection compare (default
        :meth:`columns`): a column whose coefficient is tied to another's
        (:meth:`linked_ratio_bounds`) is left out, as it cannot stand for anything alone."""
        return self.columns(table)

    def linked_ratio_bounds(self, table: WindowTable) -> tuple[float, float, float] | None:
        """For an effect of two columns whose second coefficient is bounded by the first's:
        ``(lo, hi, preferred)`` with ``lo c0 <= c1 <= hi c0`` and ``preferred c0`` the value
        taken when the windows cannot tell (a column exactly proportional to the second one,
        a constant, is fitted beside it); None otherwise (the default)."""
        return None

    def params(self, coef: np.ndarray, stderr: np.ndarray, table: WindowTable
               ) -> tuple[dict[str, Any], dict[str, Any]]:
        """Named parameters and their standard errors from the fitted coefficients."""
        raise NotImplementedError

    def implausible(self, params: dict[str, Any], table: WindowTable) -> str | None:
        """Why fitted ``params`` lie beyond what the effect can physically be on this robot
        (the loop then does not add it), None when plausible (the default)."""
        return None


class BasalPower(EnergyEffect):
    """Constant extra input power ``P += power_w`` [W] (electronics, holding)."""

    name, unit = 'basal_power', 'W'

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.ones((table.t_s.shape[0], 1))

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return {'power_w': float(coef[0])}, {'power_w': float(stderr[0])}


class ModelOffset(EnergyEffect):
    """The bench-derived prediction over-predicts the robot by a constant:
    ``P += offset_w`` with ``offset_w <= 0`` [W].

    The transfer error of the single-leg method (a tip-load convention that does not match the
    robot, surface smoothing at the robot's operating point, a duty factor the bench did not
    walk: :class:`SwingReversal`). Only negative: a positive constant is extra consumption and
    is named :class:`BasalPower`, which shares this column, so the two never compete for the
    same sign.
    """

    name, unit = 'model_offset', 'W'
    lower, upper = float('-inf'), 0.0
    def columns(self, table: WindowTable) -> np.ndarray:
        return np.ones((table.t_s.shape[0], 1))

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return {'offset_w': float(coef[0])}, {'offset_w': float(stderr[0])}


class ThermalDrift(EnergyEffect):
    """Extra power per kelvin of servo temperature above a reference:
    ``P += w_per_k * sum_i (T_i - T_r)`` [W/K], ``T_r`` = ``reference_c`` fitted.

    The column holds the runs' common temperature difference from the bench, a near constant,
    which alone can stand for any offset: robot servos 1 K cooler than the bench's turned a
    model that over-predicts by 1 W into 'thermal_drift' (an outside review; and the demo's
    spurious 0.023 W/K). So it is selected only when the temperature's variation within and
    between runs explains the residual too (``needs_variation``); then the whole column is
    fitted (hotter runs draw more from their first second).

    The temperature at which the drift is zero is not the bench's: a drift is physically per
    kelvin above what the servos relax to (the ambient, the robot's start). Referenced to the
    bench's walking temperature (28 degC against a robot starting at 26 degC) it needed a
    constant of ``w N (T_bench - T_amb)`` beside it, and the loop added a spurious 2 W
    ``basal_power`` (or an undeclared mass) to every thermal drift (an outside review: a
    900 s run read 0.058 W/K plus 2.07 W). So with the windows' temperature sums
    (``extra['temp_sum_c']``, ``extra['servo_count']``) the reference is a parameter of the
    fit, counted in the BIC: the columns are ``sum_i T_i - N T_a`` and ``N`` (``T_a`` the
    bench's temperature, ``extra['temp_bench_c']``), the second coefficient ``w (T_a - T_r)``
    bounded so that ``T_r`` lies between :attr:`REFERENCE_BELOW_K` below the coldest robot
    servo reading (``extra['temp_coldest_c']``, the mean over the servos) and
    :attr:`REFERENCE_ABOVE_K` above the bench's temperature. When a constant beside it
    leaves ``T_r`` undetermined, the coldest reading is taken (the ambient proxy). Without
    those extras the bench's reference of ``temp_excess_k`` is used, one column. Runs that
    all start warm (no reading near the ambient) cannot place it: a drift's constant below
    the coldest reading is then another effect's (a basal power) to take."""

    name, unit = 'thermal_drift', 'W/K'

    #: selected only when the temperature's variation (the column minus its mean) explains
    #: the residual too, not just its constant part (see the class docstring)
    needs_variation = True
    #: the reference may lie this far [K] below the coldest robot reading (servos do not cool
    #: below the ambient; a sensor's offset): each kelvin lets the drift's constant take
    #: ``w N`` (0.9 W at 0.05 W/K and 18 servos) of a real basal power
    REFERENCE_BELOW_K = 1.0
    #: ... and this far [K] above the bench's temperature (or the coldest reading, if warmer)
    REFERENCE_ABOVE_K = 3.0

    def _x(self, table: WindowTable) -> np.ndarray:
        return np.asarray(table.temp_excess_k, dtype=float)

    def _reference(self, table: WindowTable) -> tuple[float, float, float, float] | None:
        """(anchor, lowest, highest, coldest) [degC] of the reference, None without the
        temperature sums."""
        ex = table.extra
        s, n = ex.get('temp_sum_c'), ex.get('servo_count')
        cold = float(ex.get('temp_coldest_c', math.nan))
        bench = float(ex.get('temp_bench_c', math.nan))
        if s is None or n is None or not math.isfinite(cold):
            return None
        s, n = np.asarray(s, dtype=float), np.asarray(n, dtype=float)
        if s.shape != table.t_s.shape or not (np.all(np.isfinite(s)) and np.all(n > 0)):
            return None
        anchor = bench if math.isfinite(bench) else cold
        return (anchor, cold - self.REFERENCE_BELOW_K,
                max(anchor, cold) + self.REFERENCE_ABOVE_K, cold)

    def applicable(self, table: WindowTable) -> bool:
        x = self._x(table)
        return bool(np.all(np.isfinite(x)) and np.ptp(x) > 0.5)

    def columns(self, table: WindowTable) -> np.ndarray:
        ref = self._reference(table)
        if ref is None:
            return self._x(table)[:, None]
        n = np.asarray(table.extra['servo_count'], dtype=float)
        s = np.asarray(table.extra['temp_sum_c'], dtype=float)
        return np.column_stack([s - n * ref[0], n])

    def span_columns(self, table: WindowTable) -> np.ndarray:
        return self.columns(table)[:, :1]

    def variation_columns(self, table: WindowTable) -> np.ndarray:
        x = self.columns(table)[:, :1]
        return x - np.mean(x, axis=0)

    def linked_ratio_bounds(self, table: WindowTable) -> tuple[float, float, float] | None:
        ref = self._reference(table)
        if ref is None:
            return None
        anchor, lo, hi, cold = ref
        # c1 = w (T_a - T_r), T_r in [lo, hi]; preferred T_r: the coldest reading
        return anchor - hi, anchor - lo, anchor - min(max(cold, lo), hi)

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        ref = self._reference(table) if coef.size == 2 else None
        # per servo-kelvin: the regressor sums over the servos, so the robot's extra power per
        # kelvin of its mean servo temperature is N times it (an outside review read 'W/K'
        # 18x off); both are given, the unit said
        n = table.extra.get('servo_count')
        n_mean = float(np.mean(np.asarray(n, dtype=float))) if n is not None and \
            np.size(n) else math.nan
        per = {'w_per_k_unit': 'W per kelvin of each servo (the regressor sums the servos)'}
        if math.isfinite(n_mean) and n_mean > 0:
            per.update(servo_count=n_mean, w_per_k_of_mean_temperature=float(coef[0]) * n_mean)
        if ref is None:
            return ({'w_per_k': float(coef[0]), **per},
                    {'w_per_k': float(stderr[0]), 'w_per_k_of_mean_temperature':
                     float(stderr[0]) * n_mean if math.isfinite(n_mean) else math.nan,
                     'servo_count': 0.0})
        a, c = float(coef[0]), float(coef[1])
        anchor, lo, hi, _ = ref
        t_r = anchor - c / a if a > 0 else math.nan
        se_r = float(stderr[1]) / a if a > 0 else math.nan
        p: dict[str, Any] = {'w_per_k': a, **per, 'reference_c': t_r,
                             'reference_range_c': [round(lo, 2), round(hi, 2)]}
        if a > 0 and t_r <= lo + 0.01:
            p['reference_at_bound'] = 'lower'
        elif a > 0 and t_r >= hi - 0.01:
            p['reference_at_bound'] = 'upper'
        return p, {'w_per_k': float(stderr[0]), 'reference_c': se_r, 'servo_count': 0.0,
                   'w_per_k_of_mean_temperature': float(stderr[0]) * n_mean
                   if math.isfinite(n_mean) else math.nan}


#: Largest relative rise of a servo's input power per kelvin of winding temperature that
#: :class:`HotWindings` may fit [1/K]: all of it copper loss, copper resistance +0.393 %/K and
#: a ferrite magnet's flux -0.2 %/K (the current for a torque, squared: +0.4 %/K), rounded up.
MAX_WINDING_COEFF_PER_K = 0.01


class HotWindings(EnergyEffect):
    """Servo windings warmer than on the bench: ``P += per_k * mean_i (T_i - T_ref) * P_pred``
    [1/K].

    A DC motor's copper resistance rises 0.393 %/K and its magnet's flux falls (NdFeB about
    0.1 %/K, ferrite 0.2 %/K), so every torque costs more current and more copper loss when
    the windings are hot: the bench's powers, measured at ``T_ref`` (26 +- 1 degC in
    Brodoline et al.'s protocol), grow with the temperature in proportion to what the servos
    spend. The regressor is the robot's mean servo temperature above the bench's times the
    predicted power, window by window; ``per_k`` is bounded by
    :data:`MAX_WINDING_COEFF_PER_K`. A robot whose servos are warm from earlier walking draws
    more at every speed, more the more it spends (simulated AntBot at 50 degC against a
    27 degC bench: +2.9 W at 28 W, +0.42 %/K of the predicted power); :class:`ThermalDrift`
    (a constant per kelvin and servo) read it as 0.0063 W/K with a ``speed_friction`` beside
    it to follow its growth with speed.

    Like :class:`ThermalDrift` it must be explained by the temperature's variation too
    (``needs_variation``: the mean temperature difference times the predicted power is the
    shape of a sensor gain, ``power_gain``). Servos that are all about as warm (the temperature
    varies by less than :attr:`MIN_SPREAD_K` over the windows) but more than
    :attr:`MIN_UNIFORM_K` from the bench's cannot be told from a gain, so it is then evaluated
    as ``power_gain`` is, named beside what the loop adds, never added (an outside review:
    clean runs at 35-55 degC were named a kinematic error of 0.6-2.8 W/Hz, the temperatures
    unmentioned)."""

    name, unit = 'hot_windings', '1/K'
    upper = MAX_WINDING_COEFF_PER_K
    needs_variation = True
    #: the temperature spread over the windows [K] above which it may be added
    MIN_SPREAD_K = 1.0
    #: a uniform mean temperature difference [K] beyond which it is named as an alternative
    MIN_UNIFORM_K = 3.0

    def _dt(self, table: WindowTable) -> np.ndarray | None:
        dt = table.extra.get('temp_excess_mean_k')
        x = table.extra.get('winding_excess_w')
        if dt is None or x is None:
            return None
        dt = np.asarray(dt, dtype=float)
        ok = dt.size and np.all(np.isfinite(dt)) and np.all(np.isfinite(x))
        return dt if ok else None

    def applicable(self, table: WindowTable) -> bool:
        dt = self._dt(table)
        return bool(dt is not None and (np.ptp(dt) > self.MIN_SPREAD_K
                                        or abs(float(np.mean(dt))) > self.MIN_UNIFORM_K))

    def selectable_on(self, table: WindowTable) -> bool:
        dt = self._dt(table)
        return bool(dt is not None and np.ptp(dt) > self.MIN_SPREAD_K)

    def needs_variation_on(self, table: WindowTable) -> bool:
        return self.selectable_on(table)

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.asarray(table.extra['winding_excess_w'], dtype=float)[:, None]

    def variation_columns(self, table: WindowTable) -> np.ndarray:
        # the temperature's variation only: a constant difference times P_pred is a gain
        dt = np.asarray(table.extra['temp_excess_mean_k'], dtype=float)
        return self.columns(table) - float(np.mean(dt)) * \
            np.asarray(table.predicted_w, dtype=float)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return {'per_k': float(coef[0])}, {'per_k': float(stderr[0])}


class ThermalDriftTime(EnergyEffect):
    """Servo heating seen through the energy drawn, for bags without ``/servo_status``
    (another lab's servos report no temperature here): ``P += w_per_kj * E / 1000`` [W/kJ].

    ``E`` is the electrical energy the run has drawn since its first sample
    (``extra['elapsed_energy_j']``, the measured power integrated). The windings heat with a
    time constant of minutes (8 min for the AX-18A) from their losses, which are most of
    ``P_in``, so over runs of seconds to a few minutes the temperature, and the extra power it
    causes, grow with the energy drawn: faster runs heat faster. (Walking time alone fitted
    1.15 W/min where the simulated runs drifted 1.3 to 2.0 W/min with speed.) The same name
    as :class:`ThermalDrift`, which takes over whenever servo temperatures are recorded.
    """

    name, unit = 'thermal_drift', 'W/kJ'

    def applicable(self, table: WindowTable) -> bool:
        x = table.extra.get('elapsed_energy_j')
        if x is None or np.all(np.isfinite(table.temp_excess_k)):
            return False
        return bool(np.ptp(np.asarray(x)) > 100.0)

    def columns(self, table: WindowTable) -> np.ndarray:
        return (np.asarray(table.extra['elapsed_energy_j']) / 1000.0)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return ({'w_per_kj': float(coef[0]),
                 'regressor': 'energy drawn since the run started (no /servo_status)'},
                {'w_per_kj': float(stderr[0])})


class KinematicError(EnergyEffect):
    """Tracking-error power growing with step frequency: ``P += w_per_hz * f_step`` [W/Hz]."""

    name, unit = 'kinematic_error', 'W/Hz'

    def applicable(self, table: WindowTable) -> bool:
        return bool(np.ptp(table.step_frequency_hz) > 0.05)

    def columns(self, table: WindowTable) -> np.ndarray:
        return table.step_frequency_hz[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return {'w_per_hz': float(coef[0])}, {'w_per_hz': float(stderr[0])}


class SupplyResistance(EnergyEffect):
    """Series resistance before the monitor: the voltage falls as ``V = V_s - R I`` and the
    servos, at the lower voltage, draw less: ``P += -k I^2``.

    ``resistance_ohm`` is the lagged V-I slope (exact, from the monitor's own two channels);
    ``power_coefficient_ohm`` is the fitted ``k`` (about 0.5-0.7 R for the AX servos). Only a
    candidate when the voltage falls with the current by more than 4 standard errors.
    """

    name, unit = 'supply_resistance', 'ohm'

    def applicable(self, table: WindowTable) -> bool:
        r, se = table.supply_slope_ohm, table.supply_slope_stderr_ohm
        return bool(r > 4.0 * se and r > 0.005)

    def columns(self, table: WindowTable) -> np.ndarray:
        return -table.current_sq_a2[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return ({'resistance_ohm': table.supply_slope_ohm,
                 'power_coefficient_ohm': float(coef[0])},
                {'resistance_ohm': table.supply_slope_stderr_ohm,
                 'power_coefficient_ohm': float(stderr[0])})


class CableResistance(EnergyEffect):
    """Series resistance *after* the monitor (a tether or cable to the robot, a connector, a
    switch): the monitor measures the cable's own loss with the robot's power,
    ``P += R I^2`` [ohm], ``I`` the monitor's current (window mean of ``I^2``).

    The opposite side of :class:`SupplyResistance` (a resistance before the monitor sags the
    voltage the servos see: the power the monitor reads falls). Brodoline et al.'s own setup,
    an external supply whose current is measured on its cable, has this one; the monitor's
    voltage does not fall with the current through it, so no V-I slope shows it. An outside
    review's 0.15 ohm (1.1-7.9 W per run) read as a speed friction of 9.23 N s/m and hot
    windings, with no candidate for it. Equivalently ``R (P / V)^2`` from the measured power
    and voltage. Bounded by :attr:`upper` (a cable of several ohms would drop volts at a few
    amperes, which a robot's servos would not walk on).
    """

    name, unit = 'cable_resistance', 'ohm'
    #: the largest series resistance taken as a cable [ohm]: 1 ohm drops 3-6 V at the
    #: AX-18A robot's 3-6 A (12 V servos would brown out)
    upper = 1.0
    #: the window-mean I^2 spread [A^2] below which it says nothing
    MIN_SPREAD_A2 = 1.0

    def applicable(self, table: WindowTable) -> bool:
        x = np.asarray(table.current_sq_a2, dtype=float)
        return bool(x.size and np.all(np.isfinite(x)) and np.ptp(x) > self.MIN_SPREAD_A2)

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.asarray(table.current_sq_a2, dtype=float)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return ({'resistance_ohm': float(coef[0]),
                 'side': 'after the monitor (a cable or tether to the robot)'},
                {'resistance_ohm': float(stderr[0])})


class SpeedFriction(EnergyEffect):
    """Viscous ground friction ``F = c v`` on the stance tips: mechanical ``c v^2``, electrical
    ``DRIVE_LOSS_FACTOR c v^2`` [W]; the parameter is ``c`` [N s/m]."""

    name, unit = 'speed_friction', 'N s/m'

    def applicable(self, table: WindowTable) -> bool:
        return bool(np.ptp(table.speed_mps) > 0.01)

    def columns(self, table: WindowTable) -> np.ndarray:
        return (DRIVE_LOSS_FACTOR * table.speed_mps ** 2)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return ({'c_n_s_per_m': float(coef[0]), 'drive_loss_factor': DRIVE_LOSS_FACTOR},
                {'c_n_s_per_m': float(stderr[0]), 'drive_loss_factor': 0.0})


@dataclass
class LegAnomaly(EnergyEffect):
    """One leg draws ``power_w`` extra while in stance: ``P += power_w * in_stance(leg)``.

    One candidate per leg; legs whose stance pattern is identical in the gait (a tripod's three
    legs) cannot be told apart: :meth:`params` names them in ``same_stance_as``, and the legs
    that swing while it stands (a draw of theirs in swing reads the same) in
    ``swing_while_it_stands``.
    """

    leg_index: int = 0
    leg: str = ''

    def __post_init__(self) -> None:
        self.name, self.unit = 'leg_anomaly', 'W'

    def applicable(self, table: WindowTable) -> bool:
        return bool(np.ptp(table.stance_fraction[:, self.leg_index]) > 0.2)

    def columns(self, table: WindowTable) -> np.ndarray:
        return table.stance_fraction[:, self.leg_index][:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        col = table.stance_fraction[:, self.leg_index]
        same = [n for j, n in enumerate(table.leg_names) if j != self.leg_index
                and (np.allclose(table.stance_fraction[:, j], col, atol=0.05)
                     or _within_run_r(table, j, self.leg_index) >= SAME_STANCE_R)]
        # legs that swing while this one stands: a draw of theirs in swing reads the same (a
        # tripod's L1 drawing in swing was named 'L2 (or R1, R3)' without L1: an outside
        # review)
        swing = [n for j, n in enumerate(table.leg_names)
                 if np.allclose(table.stance_fraction[:, j], 1.0 - col, atol=0.05)
                 or _within_run_r(table, j, self.leg_index) <= -SAME_STANCE_R]
        return ({'leg': self.leg, 'power_w': float(coef[0]), 'same_stance_as': same,
                 'swing_while_it_stands': swing},
                {'power_w': float(stderr[0])})


#: Legs on the ground that fix a body's height, roll and pitch: every further stance leg is a
#: redundant support (:class:`StancePreload`)
STATICALLY_DETERMINATE_LEGS = 3


class StancePreload(EnergyEffect):
    """Legs fighting each other: ``P += w_per_leg * max(L - 3, 0)`` [W per extra stance leg],
    ``L`` the legs in stance (from ``/gait/phase``, window mean ``extra['extra_stance_legs']``).

    Three legs on the ground fix the body; with more, a position-controlled robot's stance is
    over-constrained, and small kinematic mismatches (leg zero offsets, uneven ground, body
    flex) make the stance legs push against each other. The servos carry internal forces the
    body does not need, paid as copper and gear losses, more the more redundant supports
    stand: a tripod's window mean is ``6 (beta - 0.5)`` for ``beta >= 0.5`` (0 at the bench's
    0.5), a wave at 5/6 has 2 always, a tetrapod at 2/3 1, standing 3. A single-leg bench
    has one leg and cannot see it. The simulated robot's ``stance_preload`` effect [N] makes
    it physically (internal vertical tip forces through each stance leg's Jacobian); its cost
    is not exactly linear in ``L - 3``: a preload's gear friction holds part of a leg's
    deflection after the other legs lift off (see the README's residual loop section).

    A candidate only where the walking windows' column spans :attr:`MIN_SPREAD` (runs of one
    gait and duty factor give a constant, a basal power's shape; a standing run beside
    tripods at 0.5 alone, ``standing_hold``'s) and the walking runs stand on more than three
    legs at :attr:`MIN_LEVELS` different levels at least: ``swing_reversal``, whose scale is
    free too, also grows with the duty factor, and two levels are fitted by any pair of the
    two (clean runs of tripods at 0.5, a wave at 5/6 and a tetrapod at 2/3 read a spurious
    0.35 W per leg beside it, ``swing_reversal`` 1.55 J s/m for 1.07)."""

    name, unit = 'stance_preload', 'W/leg'
    #: the walking windows' spread of the column [legs] below which it is not a candidate
    MIN_SPREAD = 0.2
    #: the distinct run means of the column above 0 (0.1 apart) it needs over walking runs
    MIN_LEVELS = 3

    def _x(self, table: WindowTable) -> np.ndarray | None:
        x = table.extra.get('extra_stance_legs')
        if x is None:
            return None
        x = np.asarray(x, dtype=float)
        ok = x.shape == table.t_s.shape and bool(np.all(np.isfinite(x)))
        return x if ok else None

    def applicable(self, table: WindowTable) -> bool:
        x = self._x(table)
        walking = np.asarray(table.step_frequency_hz, dtype=float) > 0
        if x is None or not np.any(walking) or not np.ptp(x[walking]) > self.MIN_SPREAD:
            return False
        means = [float(np.mean(x[walking & (table.run == k)]))
                 for k in np.unique(table.run[walking])]
        levels = {round(m, 1) for m in means if m > 0.05}
        return len(levels) >= self.MIN_LEVELS

    def columns(self, table: WindowTable) -> np.ndarray:
        x = self._x(table)
        return (np.zeros(table.t_s.shape[0]) if x is None else x)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return ({'w_per_leg': float(coef[0]),
                 'regressor': 'max(L - 3, 0), L the legs in stance (window mean)'},
                {'w_per_leg': float(stderr[0])})


#: legs whose in-stance fractions follow each other this closely within runs (correlation of
#: the window columns, each run's mean removed) are named as the same stance timing: the
#: half-cycle windows cannot tell them apart
SAME_STANCE_R = 0.9


def _within_run_r(table: WindowTable, a: int, b: int) -> float:
    """Correlation of legs ``a`` and ``b``'s in-stance fractions over the windows, each run's
    mean removed (0 when either does not vary). A wave or tetrapod gait's half-cycle windows
    see which half of the cycle a leg swings in, not which leg: across runs of several gaits
    an anomaly of L1 was named L3 with no other leg said (an outside review)."""
    x = table.stance_fraction[:, [a, b]].astype(float)
    for k in np.unique(table.run):
        m = table.run == k
        x[m] -= x[m].mean(axis=0)
    sa, sb = float(np.sqrt(np.sum(x[:, 0] ** 2))), float(np.sqrt(np.sum(x[:, 1] ** 2)))
    if sa <= 1e-12 or sb <= 1e-12:
        return 0.0
    return float(np.sum(x[:, 0] * x[:, 1]) / (sa * sb))


class CarriedMass(EnergyEffect):
    """The robot carries more than it was declared to (an undeclared payload, a heavier
    battery, cables): ``P += mass_kg * dP_pred/dM`` [kg].

    The regressor is the bench model's own sensitivity to the robot's mass, window by window
    (``extra['mass_slope_w_per_kg']``: the central difference of the Eq. 1 prediction at the
    declared mass, :func:`hexapod_energy.residuals.mass_slope_w_per_kg`), so the extra power
    follows the gait as the bench says a heavier body would: more where fewer legs carry it.
    First order in the extra mass: the bench's stance power is convex in load, so a large
    undeclared mass is over-estimated (simulated AntBot: +0.5 kg reads +0.55 kg).

    Plausible up to :attr:`MAX_ROBOT_FRACTION` of the robot's declared mass
    (``extra['robot_mass_kg']``, payload included; :meth:`implausible`): an undeclared load as
    heavy as the robot doubles what every stance leg carries (its servos at twice the load they
    walk at, which an owner would not miss), and this first-order sensitivity over-reads a large
    mass already. A current shunt reading 7 % high was named an undeclared 4.17 kg on a
    2.18 kg robot (an outside review): a gain, not a load.
    """

    name, unit = 'carried_mass', 'kg'
    #: the largest undeclared mass taken as a load, as a fraction of the declared robot mass
    MAX_ROBOT_FRACTION = 1.0

    def applicable(self, table: WindowTable) -> bool:
        x = table.extra.get('mass_slope_w_per_kg')
        return bool(x is not None and np.all(np.isfinite(x)) and np.any(x > 0))

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.asarray(table.extra['mass_slope_w_per_kg'])[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return {'mass_kg': float(coef[0])}, {'mass_kg': float(stderr[0])}

    def implausible(self, params: dict[str, Any], table: WindowTable) -> str | None:
        robot = table.extra.get('robot_mass_kg')
        mass = params.get('mass_kg')
        if not isinstance(robot, (int, float)) or not robot > 0 or mass is None:
            return None
        bound = self.MAX_ROBOT_FRACTION * float(robot)
        if not float(mass) > bound:
            return None
        return (f'{float(mass):.3g} kg, {100 * float(mass) / float(robot):.0f} % of the '
                f"robot's declared {float(robot):.3g} kg (more than an undeclared load it "
                'could carry unnoticed)')


class SwingReversal(EnergyEffect):
    """A swing costs more after a faster stance: ``P += j_per_mps * (n_sw / T_sw) * (v_st -
    v_b)`` [J s/m], the energy per swing per m/s of the stance tip speed it reverses.

    The single-leg method fits the swing's power on the swing's duration alone (Brodoline et
    al.: "the duty factor has no importance, since the stance and swing phases are split
    afterwards"). But a tip path continuous in velocity (the paper's cubic splines, this
    project's C2 trajectory) starts each swing by reversing the stance's backward tip speed
    ``v_st = L / (beta T)`` and ends it by matching it again, so a swing of the same duration
    costs more after a faster stance. A bench run at one duty factor ``beta_b`` (the paper's
    0.5) ties the two: its swing of ``T_sw`` follows a stance at ``v_b = L_b (1 - beta_b) /
    (beta_b T_sw)``. A robot at another duty factor (wave 0.83, tetrapod 0.67) or step length
    reverses ``v_st`` instead, ``n_sw / T_sw`` times a second (``n_sw`` legs in swing, the
    window mean). Simulated bench at 0.25 s swings: 10.02 W after a 0.25 s stance
    (beta 0.5), 8.91 W after a 1.25 s one (beta 0.83); 0.30 s: 8.20 against 7.44 (beta 0.83) and
    7.59 W (0.7); 0.5 s: 5.42 against 5.10 W: 0.85-0.97 J per swing and m/s, at every swing
    duration. Eq. 1 from that beta 0.5 bench over-predicts simulated wave and tetrapod runs
    by 1.3 W and beta 0.7 tripods by 1.2 W, nearly all in the swing (an outside review: runs
    of several gaits put a spurious undeclared mass or friction beside hidden effects).

    The column is signed (less power after slower stances), the coefficient >= 0 and at most
    ``j_max`` (:attr:`MAX_SWING_SHARE` of the bench's own swing energy per m/s of stance speed;
    at the bound the summary says so). Both stance speeds are taken on the bench's step length:
    a longer step also lengthens the swing, a geometry the bench surfaces do not know, and
    tripod runs at 0.14 m read it as 5.8 J s/m (an outside review). The phase durations are
    those Eq. 1 reads the surfaces at for the run's step geometry (``extra['stance_scale']``,
    ``extra['swing_scale']``, :func:`hexapod_energy.prediction.phase_duration_scales`; 1
    when absent): the swing the surface prices is the bench's swing of that duration. Only a
    candidate with the
    bench's duty factor and step length known (``extra['bench_duty_factor']``,
    ``extra['bench_step_length_m']``, one duty factor on the bench) and robot runs at another
    duty factor. On runs of one duty factor its column is exactly a speed friction's ``v^2``
    shape with the other sign (r = -1.000 on wave runs): a hidden friction or kinematic error
    there reads as a smaller one or a basal power beside it, and the summary says that these
    runs cannot tell them apart (:func:`~hexapod_energy.residuals.summary_text`). Its
    variation must explain what an offset leaves (``needs_variation``)."""

    name, unit = 'swing_reversal', 'J s/m'
    needs_variation = True
    variation_beside_offset = True
    companion = True
    #: the coefficient is ``j / j_max`` in [0, 1] (the column is scaled by ``j_max``)
    upper = 1.0
    #: ``j_max``: this share of a bench swing's energy per m/s of the stance speed before it
    #: (``extra['bench_swing_j_per_mps']``, the median over the bench's sessions of
    #: ``P_sw T_sw / v_b``): the reversal is a part of the swing (simulated AX-18A leg: 7-14 %)
    MAX_SWING_SHARE = 0.3
    #: a bench whose walking sessions' duty factors span more than this has no single reference
    MAX_BENCH_SPREAD = 0.05
    #: a candidate on runs of one duty factor too when it is not the bench's (its column is
    #: then a friction's v^2 shape with the other sign: the summary says so)
    single_duty_factor = True
    #: the column's spread [W per J s/m, i.e. m/s^2] below which it is not a candidate
    MIN_SPREAD = 0.05

    def _x(self, table: WindowTable) -> np.ndarray | None:
        """The column in J s/m units (before scaling by ``j_max``), or None when the windows
        cannot carry it."""
        ex = table.extra
        need = ('duty_factor', 'bench_duty_factor', 'bench_step_length_m')
        if any(k not in ex for k in need):
            return None
        if float(ex.get('bench_duty_factor_spread', 0.0)) > self.MAX_BENCH_SPREAD:
            return None       # a bench of several duty factors: no single reference
        beta = np.asarray(ex['duty_factor'], dtype=float)
        beta_b, step_b = float(ex['bench_duty_factor']), float(ex['bench_step_length_m'])
        f = np.asarray(table.step_frequency_hz, dtype=float)
        if not (0.0 < beta_b < 1.0 and step_b > 0.0):
            return None
        walking = (f > 0) & (beta > 0) & (beta < 1)
        betas = np.unique(np.round(beta[walking], 2))
        if betas.size < 2 and not (betas.size == 1 and self.single_duty_factor and
                                   abs(float(betas[0]) - beta_b) > self.MAX_BENCH_SPREAD):
            return None       # one duty factor: its column is a speed friction's shape
        b = np.where(walking, beta, 0.5)
        period = 1.0 / np.where(walking, f, 1.0)
        t_sw = (1.0 - b) * period
        # the durations Eq. 1 reads the surfaces at for the run's step geometry
        k_st = np.broadcast_to(np.asarray(ex.get('stance_scale', 1.0), dtype=float), f.shape)
        k_sw = np.broadcast_to(np.asarray(ex.get('swing_scale', 1.0), dtype=float), f.shape)
        n_sw = table.stance_fraction.shape[1] - np.sum(table.stance_fraction, axis=1)
        # both stance speeds on the bench's step: a step-length mismatch lengthens the swing
        # too (the bench surfaces do not know it) and is not this effect's to claim
        v_st = step_b / (k_st * b * period)
        v_b = step_b * (1.0 - beta_b) / (beta_b * k_sw * t_sw)
        x = np.where(walking, n_sw / t_sw * (v_st - v_b), 0.0)
        return x if np.all(np.isfinite(x)) else None

    def _j_max(self, table: WindowTable) -> float:
        j = float(table.extra.get('bench_swing_j_per_mps', math.nan))
        return self.MAX_SWING_SHARE * j if math.isfinite(j) and j > 0 else math.nan

    def applicable(self, table: WindowTable) -> bool:
        x = self._x(table)
        return bool(x is not None and math.isfinite(self._j_max(table))
                    and np.ptp(x) > self.MIN_SPREAD)

    def columns(self, table: WindowTable) -> np.ndarray:
        x = self._x(table)
        if x is None or not math.isfinite(self._j_max(table)):
            return np.zeros((table.t_s.shape[0], 1))
        return (x * self._j_max(table))[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        j_max = self._j_max(table)
        return ({'j_per_mps': float(coef[0]) * j_max, 'j_max_per_mps': j_max,
                 'bench_duty_factor': float(table.extra['bench_duty_factor'])},
                {'j_per_mps': float(stderr[0]) * j_max, 'j_max_per_mps': 0.0,
                 'bench_duty_factor': 0.0})


class StandingHold(EnergyEffect):
    """A standing robot holds its weight with another share of motor torque than the bench's
    standing leg: ``P += holding_change * N (P_basal(m_c) - P_basal(m_0))`` while standing.

    A geared servo at rest holds any torque inside its friction band without current
    (stiction; the AX-18A's 254:1 gear holds most of a leg's share of the body), so the current
    of a standing leg depends on how the load came on: a robot set down on its feet while
    powered leaves much of its weight to the gears, one that stood up by itself (its motors
    lifting against the friction) holds more than the load with its motors. The bench's 0 Hz
    session gives one history (the leg stands after the heating walk); ``holding_change`` is
    the robot's holding power relative to it, from -1 (the gears hold it all) to +1 (twice
    the bench's). The simulated AntBot, set down powered, stands at 10.74 W where the bench's
    basal powers predict 15.47 W: -1.0 (an outside review: beside a standing run a hidden 3 W
    basal power was read as a 1.9 W/Hz kinematic error). A companion of the other effects
    (``EffectSelection``), and a standing run's constant part is then its own: standing runs
    pin a basal power only together with walking runs."""

    name, unit = 'standing_hold', '-'
    lower, upper = -1.0, 1.0
    companion = True
    #: the holding power [W] below which standing windows say nothing of it
    MIN_HOLD_W = 0.2

    def applicable(self, table: WindowTable) -> bool:
        x = table.extra.get('standing_holding_w')
        return bool(x is not None and np.all(np.isfinite(x))
                    and np.max(np.abs(np.asarray(x, dtype=float))) > self.MIN_HOLD_W)

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.asarray(table.extra['standing_holding_w'], dtype=float)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        x = np.asarray(table.extra['standing_holding_w'], dtype=float)
        return ({'holding_change': float(coef[0]), 'bench_holding_w': float(np.max(x))},
                {'holding_change': float(stderr[0]), 'bench_holding_w': 0.0})


class PowerGain(EnergyEffect):
    """The measured power is the model's times a factor: ``P += gain_excess * P_pred`` [-]
    (``factor = 1 + gain_excess``).

    A current or voltage sensor's gain error (a shunt 5 % off), a supply converter's
    efficiency, servos run at another supply voltage than the bench's (the drives' losses
    scale with it): everything the bench predicts grows by the same fraction. On tripod runs
    alone it can look like an undeclared payload (both grow with the predicted power); the
    loop then names both as alternatives instead of reading a 5 % gain as 0.72 kg.
    """

    name, unit = 'power_gain', '-'
    #: not added by the loop (it follows the predicted power, so it stands for a kinematic
    #: error or a friction as readily as for a gain): named beside the effect it could be
    selectable = False

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.asarray(table.predicted_w, dtype=float)[:, None]

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        # the coefficient is the excess over 1 (measured = factor x predicted): it was
        # labelled 'gain' (0.0668 for a shunt 7 % high, an outside review)
        c, e = float(coef[0]), float(stderr[0])
        return {'gain_excess': c, 'factor': 1.0 + c}, {'gain_excess': e, 'factor': e}


class TimeOffset(EnergyEffect):
    """Clock offset of ``/battery_state`` against the other streams [s].

    Half-cycle windows cannot see a shift, so this effect has no window column and is never
    applicable to a :class:`WindowTable`: it is fitted and selected in the per-sample view
    (:class:`hexapod_energy.residuals.SampleView`), which realigns the battery stream before
    the windows are built when it is selected.
    """

    name, unit = 'time_offset', 's'

    def applicable(self, table: WindowTable) -> bool:
        return 'offset_s' in table.extra

    def columns(self, table: WindowTable) -> np.ndarray:
        return np.zeros((table.t_s.shape[0], 0))

    def params(self, coef, stderr, table):  # type: ignore[no-untyped-def]
        return ({'offset_s': float(table.extra.get('offset_s', 0.0))},
                {'offset_s': float(table.extra.get('offset_stderr_s', float('nan')))})


def default_catalogue(leg_names: tuple[str, ...] = ()) -> list[EnergyEffect]:
    """Every energy effect, one :class:`LegAnomaly` per leg.

    :class:`ModelOffset` is not in it: it names an error of the bench-derived model, not a
    physical effect of the robot; a caller who wants the transfer bias fitted adds it.
    """
    effects: list[EnergyEffect] = [BasalPower(), ThermalDrift(), ThermalDriftTime(),
                                   HotWindings(), KinematicError(), SupplyResistance(),
                                   CableResistance(), SpeedFriction(), CarriedMass(),
                                   SwingReversal(), StandingHold(), StancePreload(),
                                   PowerGain()]
    effects += [LegAnomaly(leg_index=j, leg=n) for j, n in enumerate(leg_names)]
    effects.append(TimeOffset())
    return effects
