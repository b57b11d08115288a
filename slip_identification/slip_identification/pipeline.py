"""One run, arrays in, per-stance fits out: the composition of preprocess, stance and fit.

Used by the ``hexapod-analyze slip`` command (arrays read from a bag) and usable on any
recording. Core module: numpy/scipy only.
"""

from __future__ import annotations

import dataclasses
import math
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from .energetics import battery_power_w, specific_resistance
from .errors import SlipDataError, StanceRejectedError
from .fit import SlipFitResult, SlipFitter, SlipPositionFitter, Stance, validate_stance
from .geometry import (
    DAMPING_STIFFNESS_TOLERANCE,
    GRAVITY_M_S2,
    GeometryFit,
    LegGeometry,
    body_pitch_rad,
    fit_ground_offset,
    offset_ground_grid,
    leg_contacts,
    prefer_fit,
    white_noise_std,
    single_support,
)
from .model import SlipModel
from .proprio_edges import (
    alternating_touchdowns,
    effort_onsets,
    estimate_offset_contacts,
    estimate_offset_joint,
    refine_touchdowns,
    tripod_touchdowns,
)
from .preprocess import (
    Box,
    WorldFrame,
    check_straight,
    estimate_offset,
    fit_world_frame,
    frozen_pose_mask,
    max_mocap_gap_s,
    permissible_mask,
    sagittal_state,
    walks_backwards,
)
from .steady import steady_start_s, steady_windows
from .stance import (
    StanceWindow,
    best_shift,
    edges_from_target,
    open_stance_windows,
    refine_clock_edges,
    single_tripod_stances,
    tripod_stance_windows,
)

__all__ = ['RunData', 'RunResult', 'analyze_run', 'body_up_rotation', 'rotate_body',
           'run_data_from_sim', 'TRIPODS']

FloatArray = NDArray[np.float64]
TRIPODS = {'left': ('L1', 'R2', 'L3'), 'right': ('R1', 'L2', 'R3')}


@dataclass(frozen=True)
class RunData:
    """Raw streams of one run (times [s] in each stream's own clock).

    ``joint_names`` (J,), ``joint_t_s`` (n,), ``joint_velocity`` (n, J) measured hip speeds;
    ``command_t_s`` (c,), ``command_velocity`` (c, J) target speeds (same names);
    ``mocap_t_s`` (m,), ``mocap_position_m`` (m, 3), ``mocap_quat_xyzw`` (m, 4);
    ``battery_t_s``, ``battery_voltage_v``, ``battery_current_a`` (b,); ``gait`` name;
    ``joint_effort`` (n, J) measured hip efforts [N m] or None (needed by ``edges='effort'`` and
    the contact-based offset); ``joint_position`` (n, J) measured hip angles [rad] (unwrapped)
    or None (needed by the geometric edges and offset).
    """

    joint_names: tuple[str, ...]
    joint_t_s: FloatArray
    joint_velocity: FloatArray
    command_t_s: FloatArray
    command_velocity: FloatArray
    mocap_t_s: FloatArray
    mocap_position_m: FloatArray
    mocap_quat_xyzw: FloatArray
    battery_t_s: FloatArray
    battery_voltage_v: FloatArray
    battery_current_a: FloatArray
    gait: str = 'unknown'
    label: str = ''
    joint_effort: FloatArray | None = None
    joint_position: FloatArray | None = None
    notes: tuple[str, ...] = ()  # input fallbacks of the reader, reported in slip.json
    #: ``(t [s], gait name)`` at each change of the gait on ``/gait/phase`` (first included)
    gait_changes: tuple[tuple[float, str], ...] = ()

    def gait_at(self, t_s: float) -> str:
        """The gait on ``/gait/phase`` at proprioception time ``t_s`` (``gait`` without
        changes recorded)."""
        name = self.gait_changes[0][1] if self.gait_changes else self.gait
        for t, g in self.gait_changes:
            if t <= t_s:
                name = g
        return name


@dataclass
class RunResult:
    """Fits, skipped stances with reasons, and run energetics."""

    fits: list[SlipFitResult] = field(default_factory=list)
    #: the measured stances behind ``fits`` (one each, same order): what the fits and the
    #: fit-against-data figure re-simulate from, and what the residual loop fits its templates
    #: to (:func:`hexapod_energy.residuals_cli.run_slip_loop`)
    stances: list[Stance] = field(default_factory=list)
    position_fits: list[SlipFitResult] = field(default_factory=list)
    skipped: list[dict[str, Any]] = field(default_factory=list)
    skipped_counts: Counter[str] = field(default_factory=Counter)
    offset_s: float = 0.0
    shift_s: dict[str, float] = field(default_factory=dict)
    power_w: float = math.nan
    speed_mps: float = math.nan
    sr: float = math.nan
    current_sign: str = ''
    frame: dict[str, Any] = field(default_factory=dict)
    offset_method: str = 'given'
    edges: str = 'paper'
    ground_m: float = math.nan
    paper_windows: list[StanceWindow] = field(default_factory=list)
    geometry_windows: list[StanceWindow] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    #: results resting on an assumption the data contradict (also in ``notes``)
    warnings: list[str] = field(default_factory=list)

    def warn(self, text: str) -> None:
        """A note that is also a warning (``slip.json`` ``warnings``, stderr)."""
        self.notes.append(text)
        self.warnings.append(text)


def _check_hexapod_hips(names: tuple[str, ...], res: RunResult) -> None:
    """A warning when the joint states lack some of the six hips the tripods (and EduBot's
    geometry) are made of: the tripods are then built from the hips present (an outside
    review's 4-hip run: two legs per tripod, the edges 155 ms off, exit 0 without a word)."""
    six = [f'{leg}_hip' for tp in TRIPODS.values() for leg in tp]
    missing = [h for h in six if h not in names]
    if not missing or len(missing) == len(six):
        return  # all six, or none (refused later, naming the tripods' hips)
    have = [h for h in six if h in names]
    res.warn(
        f'the joint states carry {len(have)} of the six hips the tripods are made of '
        f'(missing {", ".join(missing)}): the analysis assumes a six-legged RHex-class robot '
        f'(tripods left L1 R2 L3, right R1 L2 R3; EduBot\'s geometry unless given) and builds '
        f'each tripod from the hips present; the body-height fit, stream offset, stance '
        f'edges and SLIP fits are not valid for a robot with other legs (a 4-hip run read '
        f'every edge about 155 ms off)')


def _check_backwards(names: tuple[str, ...], position: FloatArray | None, pm: FloatArray,
                     quats: FloatArray, res: RunResult) -> bool:
    """Whether the robot walks backwards (:func:`.preprocess.walks_backwards`: every hip turns
    backwards and the body moves against the rigid body's heading), said in a note and in
    ``frame['walks_backwards']``. The world x then points along the heading, against the
    travel: the hips named 1 are ahead of the COM, the pitch is the robot's and the speed is
    negative. Before, x was always taken along the travel, which put a robot walking backwards
    front to back (its hip positions and pitch reversed: edge RMS 10.8 against 0.8 ms)."""
    hips = [i for i, n in enumerate(names) if n.endswith('_hip')]
    if position is None or not hips:
        return False
    net = []
    for i in hips:
        q = position[:, i]
        q = q[np.isfinite(q)]
        net.append(float(q[-1] - q[0]) if q.size >= 2 else math.nan)
    back, angle = walks_backwards(pm, quats, net)
    if math.isfinite(angle):
        res.frame['heading_to_travel_deg'] = angle
    res.frame['walks_backwards'] = back
    if back:
        res.notes.append(
            f'the robot walks backwards: every hip turns backwards and the body moves '
            f'{angle:.0f} deg from the motion-capture rigid body\'s x axis, so the world x is '
            'taken along that heading (against the travel; the speed is negative). A robot '
            'whose hip motors are mounted mirrored, walking forward, with a rigid body created '
            'facing backwards would look the same: negate its hips (hip signs) and redefine '
            'the rigid body')
    return back


#: a path moving faster than this (median over the samples) is not a legged robot in metres
MAX_PLAUSIBLE_SPEED_M_S = 20.0


def _check_position_unit(t_s: FloatArray, p_m: FloatArray, label: str) -> None:
    """Refuse motion capture whose positions are not in metres (millimetres move the body
    1000 times faster: an outside review's run was refused as 'not straight, lateral
    deviation 0.714 m')."""
    if t_s.size < 3:
        return
    dt = np.diff(t_s)
    ok = dt > 0
    if not ok.any():
        return
    v = np.linalg.norm(np.diff(p_m, axis=0)[ok], axis=1) / dt[ok]
    v = v[np.isfinite(v)]
    if v.size == 0:
        return
    speed = float(np.median(v))
    span = float(np.max(np.ptp(p_m, axis=0)))
    if speed > MAX_PLAUSIBLE_SPEED_M_S:
        raise SlipDataError(
            f'run {label!r}: the motion-capture positions move at a median {speed:.0f} m/s '
            f'and span {span:.1f} m: not metres? (millimetres would read 1000 times too '
            f'far; /mocap/body must be in metres, REP-103: scale the bridge\'s output)')


def _tripod_mean(names: tuple[str, ...], values: FloatArray, tripod: str) -> FloatArray:
    cols = [names.index(f'{leg}_hip') for leg in TRIPODS[tripod] if f'{leg}_hip' in names]
    if not cols:
        raise SlipDataError(f'no {tripod} tripod hips ({TRIPODS[tripod]}_hip) in {names}')
    return np.asarray(values, dtype=float)[:, cols].mean(axis=1)


#: relative body-height RMS by which a start half a stride away must beat the cross-correlation's
#: to be taken: below it the two are the same fit (the tripods mirror each other)
HALF_STRIDE_BETTER = 0.05


def _stances_in_gaps(cut: list[tuple[str, float, float]], unknown: FloatArray,
                     found: list[StanceWindow], paper: list[StanceWindow]
                     ) -> list[tuple[str, float, float, str]]:
    """Single supports the geometric edges cannot give because a motion-capture gap cuts or
    hides them: ``(tripod, touchdown, lift-off, how)``. Pieces cut by a gap come from the
    contacts (``how`` 'geometry_cut'); stances wholly inside a gap from the shifted clock's
    windows that overlap it and no geometric stance (``how`` 'clock'). Gaps here are the
    interior ones (not the run's ends)."""
    gaps = np.asarray(unknown, dtype=float).reshape(-1, 2)
    gaps = gaps[np.isfinite(gaps).all(axis=1)]
    out = [(tp, a, b, 'geometry_cut') for tp, a, b in cut
           if np.any((gaps[:, 0] <= b + 1e-3) & (gaps[:, 1] >= a - 1e-3))]
    taken = [(w.touchdown_s, w.liftoff_s) for w in found] + [(a, b) for _, a, b, _ in out]
    for w in paper:
        a, b = w.touchdown_s, w.liftoff_s
        in_gap = np.any((gaps[:, 0] < b) & (gaps[:, 1] > a))
        if in_gap and not any(c < b and d > a for c, d in taken):
            out.append((w.tripod, a, b, 'clock'))
    return sorted(out, key=lambda x: x[1])


def _damping_tradeoff(gfit: Any, geometry: LegGeometry, geo_inputs: tuple[Any, ...],
                      geo_x: FloatArray, off: float, off_range: float, res: RunResult,
                      given: dict[str, Any] | None = None
                      ) -> tuple[Any, LegGeometry, tuple[Any, ...]]:
    """The legs' damping time unknown: the fit with it free against undamped legs.

    The damper advances the leg force like a clock shift, so the damping time and the offset
    trade off and the free fit can settle on either (undamped legs of another lab fitted 3.4
    ms and an offset 7.4 ms late). The better fit of the body height is kept
    (:func:`~slip_identification.geometry.prefer_fit`) and both are reported.

    ``given``: the offset is given (``--offset``), and these are the first fit's pitch-zero
    arguments; the undamped fit keeps the offset and gets the same pitch-zero freedom. Before,
    a given offset left EduBot's 3.4 ms unchecked on an outside review's undamped legs: a
    spurious pitch zero of -2.44 deg was fitted to make up for it and the edges were 8-16 ms
    off.
    """
    undamped = dataclasses.replace(geometry, leg_damping_time_s=0.0, damping_assumed=False)
    inputs0 = (undamped,) + tuple(geo_inputs[1:])
    kw: dict[str, Any] = ({'fix_offset': True, **given} if given is not None else
                          {'fix_offset': False, 'fit_pitch_offset': False,
                           'pitch_offset_rad': gfit.pitch_offset_rad})
    try:
        f0 = fit_ground_offset(*inputs0, initial_offset_s=off, offset_range_s=off_range,
                               x_m=geo_x, **kw)
    except SlipDataError:
        return gfit, geometry, geo_inputs
    how = 'fitted' if geometry.leg_damping_time_s is None else 'assumed'
    res.frame['offset_damping_tradeoff'] = {
        'damping': how,
        'fitted_damping_time_s': gfit.damping_ratio_s, 'fitted_offset_s': gfit.offset_s,
        'fitted_rms_m': gfit.rms_m, 'undamped_offset_s': f0.offset_s, 'undamped_rms_m': f0.rms_m}
    take0 = prefer_fit(f0, gfit)
    res.notes.append(
        f'leg damping time unknown: {how} {1e3 * gfit.damping_ratio_s:.2f} ms gives the '
        f'offset {gfit.offset_s:+.4f} s (body-height rms {1e3 * gfit.rms_m:.3f} mm), undamped '
        f'legs {f0.offset_s:+.4f} s ({1e3 * f0.rms_m:.3f} mm); the damping time and the offset '
        f'trade off, the ' + ('undamped' if take0 else how) + ' fit is kept (it fits better)')
    if take0:
        return f0, undamped, inputs0
    return gfit, geometry, geo_inputs


def _stiffness_check(gfit: Any, geometry: LegGeometry, geo_inputs: tuple[Any, ...],
                     geo_x: FloatArray, off: float, off_range: float, mass_kg: float,
                     res: RunResult) -> tuple[Any, LegGeometry, tuple[Any, ...]]:
    """The default damping time (EduBot's 12.9 N s/m over 3800 N/m) checked against the legs'
    stiffness that the body-height fit finds (``frame['geometry_leg_stiffness_n_m']``).

    The damping time and the offset trade off (the damper advances the force like a clock
    shift) and the body-height residual barely tells them apart (an outside review: legs of
    2000 N/m fitted 0.194 mm rms with EduBot's 3.39 ms, 0.189 mm with 6.31 ms fitted, the
    offset 10 ms and every edge 7 ms off with the default), but the stiffness is pinned well
    (EduBot simulated runs 3480-3930 N/m; the review's 2000 and 7000 N/m legs 2095 and 6034).
    A stiffness more than :data:`DAMPING_STIFFNESS_TOLERANCE` off EduBot's says the legs are
    not EduBot's: the damping time is then fitted (started from EduBot's damper on the fitted
    spring) and kept unless it fits the body height clearly worse (:func:`~slip_identification.
    geometry.prefer_fit`); a warning either way.
    """
    ref = geometry.damping_stiffness_n_m
    k_leg = float(gfit.stiffness_per_kg) * float(mass_kg)
    if ref is None or not math.isfinite(k_leg):
        return gfit, geometry, geo_inputs
    res.frame['geometry_leg_stiffness_n_m'] = k_leg
    if abs(k_leg / ref - 1.0) <= DAMPING_STIFFNESS_TOLERANCE or \
            geometry.leg_damping_time_s is None or k_leg <= 0:
        return gfit, geometry, geo_inputs
    tau0 = float(geometry.leg_damping_time_s)
    free = dataclasses.replace(geometry, leg_damping_time_s=None, damping_stiffness_n_m=None)
    inputs1 = (free,) + tuple(geo_inputs[1:])
    head = (f'the legs\' stiffness fitted to the body height, {k_leg:.0f} N/m per leg (mass '
            f'{mass_kg:g} kg), is not EduBot\'s {ref:.0f} N/m: so EduBot\'s leg damping time '
            f'({1e3 * tau0:.2f} ms) need not be this robot\'s, and it moves the stream offset '
            f'and the edges (the two trade off)')
    try:
        f1 = fit_ground_offset(*inputs1, initial_offset_s=off, offset_range_s=off_range,
                               fix_offset=False, x_m=geo_x, tau_s=tau0 * ref / k_leg,
                               fix_tau=False, fit_pitch_offset=False,
                               pitch_offset_rad=gfit.pitch_offset_rad)
    except SlipDataError as err:
        res.warn(f'{head}; fitting the damping time failed ({err}): EduBot\'s is kept, the '
                 f'offset {gfit.offset_s:+.4f} s and the edges may be off by several ms; give '
                 f'--leg-damping-time SECONDS (or check --mass)')
        return gfit, geometry, geo_inputs
    take = prefer_fit(f1, gfit, 1.01)
    res.frame['damping_stiffness_check'] = {
        'leg_stiffness_n_m': k_leg, 'default_damping_time_s': tau0,
        'default_offset_s': gfit.offset_s, 'default_rms_m': gfit.rms_m,
        'fitted_damping_time_s': f1.damping_ratio_s, 'fitted_offset_s': f1.offset_s,
        'fitted_rms_m': f1.rms_m, 'kept': 'fitted' if take else 'default'}
    res.warn(f'{head}. The damping time is fitted: {1e3 * f1.damping_ratio_s:.2f} ms, '
             f'offset {f1.offset_s:+.4f} s (body-height rms {1e3 * f1.rms_m:.3f} mm), against '
             f'{gfit.offset_s:+.4f} s ({1e3 * gfit.rms_m:.3f} mm) with EduBot\'s; the '
             + ('fitted one is kept' if take else 'fitted one fits worse, EduBot\'s is kept '
                '(the offset and edges may be off by several ms)')
             + '. Give --leg-damping-time SECONDS if it is known (or check --mass)')
    if not take:
        return gfit, geometry, geo_inputs
    return f1, free, inputs1


#: geometric touchdowns and hip-effort onsets further apart than this (median over the legs'
#: touchdowns) contradict the leg description [s]: EduBot simulated running and jogging
#: (3 seeds) +1.5 to +3.8 ms; the review's runs: hip zero 0.15 rad +19.6 ms, a logged hip
#: offset +0.15 rad -12.4 ms, four hips +12.5 ms
EFFORT_CONTACT_MAX_S = 0.006


def _effort_contact_check(contacts: dict[str, FloatArray], names: tuple[str, ...],
                          tj: FloatArray, effort: FloatArray | None, gfit: Any,
                          geometry: LegGeometry, res: RunResult) -> None:
    """The geometric contacts' touchdowns against the hip-effort onsets (the motors feel the
    landing; an independent clock of the same touchdowns), on aerial gaits (the geometric
    fit's flight windows; on slow gaits an effort onset need not be a touchdown: EduBot pace
    and walk +0.4 to +11.8 and -5 ms). The body height alone cannot tell a hip zero off from
    a clock offset (a hip zero 0.15 rad off fitted 0.209 mm rms, the true zero 0.211 mm: the
    offset 17.5 ms and every edge off, silently), the efforts can
    (``frame['effort_contact_lag_s']``: geometric touchdown minus effort onset, median)."""
    if effort is None or not getattr(gfit, 'flight', False):
        return
    diffs, rises = [], []
    for leg, iv in contacts.items():
        col = f'{leg}_hip'
        if col not in names:
            continue
        on = effort_onsets(tj, effort[:, names.index(col)])
        if on.size == 0:
            continue
        # the onset is a threshold crossing (15 % of the effort's range): a force rising
        # slowly crosses it late. Its foot, the line through the 15 % and 50 % crossings
        # taken back to the baseline, says how late (an outside review's undamped legs, 0.13 s
        # stances: 6 ms, and a warning that the leg description did not fit the robot)
        half = effort_onsets(tj, effort[:, names.index(col)], threshold_frac=0.5)
        for a in np.asarray(iv, dtype=float).reshape(-1, 2)[:, 0]:
            j = int(np.argmin(np.abs(on - a)))
            if abs(on[j] - a) < 0.04:
                diffs.append(a - on[j])
                k = np.searchsorted(half, on[j])
                if k < half.size and half[k] - on[j] < 0.04:
                    rises.append((half[k] - on[j]) * 0.15 / 0.35)
    if len(diffs) < 6:
        return
    lag = float(np.median(diffs))
    rise = float(np.median(rises)) if len(rises) >= 6 else 0.0
    res.frame['effort_contact_lag_s'] = lag
    res.frame['effort_onset_rise_s'] = rise
    if abs(lag + rise) <= EFFORT_CONTACT_MAX_S:
        return    # touchdowns within 6 ms of the efforts' feet
    res.warn(
        f'the legs\' geometric touchdowns come {1e3 * abs(lag):.1f} ms '
        f'{"after" if lag > 0 else "before"} the hip-effort onsets (median of {len(diffs)}; '
        f'{1e3 * (lag + rise):+.1f} ms from where the efforts start rising, their threshold '
        f'crossed {1e3 * rise:.1f} ms into the rise; EduBot simulated aerial gaits: +1.5 to '
        f'+3.8 ms from the onsets): the leg description does not fit '
        f'this robot, and the stream offset ({gfit.offset_s:+.4f} s) and stance edges from it '
        f'may be off by about as much. Likely causes: a hip encoder zero off (--hip-zero RAD, '
        f'now {geometry.hip_zero_rad:g}; a positive lag asks for a larger zero), another leg '
        f'stiffness or damping (--leg-damping-time), another leg geometry (--leg-radius, '
        f'--hip-x, --hip-z) or hips missing from the joint states')


#: a fit from another estimate replaces the first only when it lands this far from it [s]
OTHER_START_MIN_MOVE_S = 0.005


def _other_starts(gfit: Any, geo_inputs: tuple[Any, ...], geo_x: FloatArray, first_s: float,
                  starts: dict[str, float], off_range: float, res: RunResult,
                  p0_kw: dict[str, Any]) -> Any:
    """The geometric fit from the other proprioceptive estimates of the offset; the one that
    fits clearly better and lands elsewhere is kept (else None).

    The fit searches +-60 ms around the first estimate (``first_s``, the hip-effort
    contacts); when that estimate is further off, the fit stays in a local minimum. On a
    reviewer's clock (10.5 rad/s, duty 0.5) the contact estimate was 75 ms off and the fit
    settled 118 ms off (body-height rms 0.342 mm against 0.232 mm of noise) while the joint
    estimate was 0.2 ms off. Another estimate is tried when it lies outside the first's
    search range; it is fitted as the first was (the same pitch-zero handling), and kept
    when its rms is 5 % lower (:func:`~slip_identification.geometry.prefer_fit`) and its
    offset more than :data:`OTHER_START_MIN_MOVE_S` away
    (a fit over other windows that lands on the first offset again is no evidence;
    ``frame['offset_other_starts']``).
    """
    far = {k: v for k, v in starts.items() if abs(v - first_s) > off_range}
    if not far:
        return None
    best, tried = gfit, {}
    for name, start in far.items():
        try:
            f = fit_ground_offset(*geo_inputs, initial_offset_s=start, offset_range_s=off_range,
                                  fix_offset=False, x_m=geo_x, **p0_kw)
        except SlipDataError:
            continue
        tried[name] = {'start_s': start, 'offset_s': f.offset_s, 'rms_m': f.rms_m}
        if prefer_fit(f, best, 1 - HALF_STRIDE_BETTER) and \
                abs(f.offset_s - gfit.offset_s) > OTHER_START_MIN_MOVE_S:
            best = f
    if not tried:
        return None
    res.frame['offset_other_starts'] = {'first_start_s': first_s,
                                        'first_offset_s': gfit.offset_s,
                                        'first_rms_m': gfit.rms_m, **tried}
    if best is gfit:
        return None
    res.notes.append(
        f'the offset estimates disagree: the geometric fit from the first ({first_s:+.4f} s) '
        f'settled at {gfit.offset_s:+.4f} s (body-height rms {1e3 * gfit.rms_m:.3f} mm), the '
        f'fit from another fits clearly better and is kept: {best.offset_s:+.4f} s, '
        f'{1e3 * best.rms_m:.3f} mm (starts ' + ', '.join(
            f"{k} {v['start_s']:+.4f} s" for k, v in tried.items()) + ')')
    return best


#: grid candidates (local minima of the best cost over the ground) refitted at most
GRID_CANDIDATES = 3


def _grid_start(gfit: Any, geo_inputs: tuple[Any, ...], geo_x: FloatArray, start: float,
                off_range: float, res: RunResult, p0_kw: dict[str, Any]) -> Any:
    """A fit from a whole grid of offsets and ground heights, when the first leaves the body
    height unexplained (residual over :data:`GEOMETRY_RESIDUAL_HIGH` times the mocap noise);
    the better fit is returned (else None).

    The geometric fit takes the ground at its start and searches the offset near that ground;
    from a start far off (without hip efforts the cross-correlation's: 96 ms off on an
    outside review's RHex-class runner) the ground was 143 mm off, the offset 76 ms off with
    a residual 10 times the noise, and every stiffness and rest length 5 times off, with a note
    only. The grid (:func:`~slip_identification.geometry.offset_ground_grid`, +-0.2 s, or twice
    the first search's range, by +-25 cm) gives up to :data:`GRID_CANDIDATES` starts (the
    best ground at each offset, its local minima, the lowest first); one is kept when it
    lowers the body-height residual by :data:`HALF_STRIDE_BETTER` (``frame['offset_grid']``;
    residuals compared by :func:`~slip_identification.geometry.prefer_fit`). A first fit
    whose output-error refinement failed (``unrefined``) is searched from the grid whatever
    its residual, which reads low (the equation-error fit's).
    """
    noise = white_noise_std(geo_inputs[6])
    if gfit.rms_m <= GEOMETRY_RESIDUAL_HIGH * max(noise, 1e-4) and not gfit.unrefined:
        return None
    half = max(2.0 * off_range, 0.2)
    try:
        offs, grounds, cost = offset_ground_grid(
            *geo_inputs, initial_offset_s=start, offset_range_s=half, x_m=geo_x,
            pitch_offset_rad=float(p0_kw.get('pitch_offset_rad', 0.0)))
    except SlipDataError:
        return None
    best_j = np.argmin(cost, axis=1)
    prof = cost[np.arange(offs.size), best_j]
    minima = [i for i in range(offs.size)
              if (i == 0 or prof[i] <= prof[i - 1]) and
              (i == offs.size - 1 or prof[i] <= prof[i + 1])]
    minima.sort(key=lambda i: prof[i])
    tried = []
    best = gfit
    for i in minima[:GRID_CANDIDATES]:
        d, g = float(offs[i]), float(grounds[best_j[i]])
        if abs(d - gfit.offset_s) < 0.01 and abs(g - gfit.ground_m) < 0.01:
            continue   # the first fit's own basin
        try:
            f = fit_ground_offset(*geo_inputs, initial_offset_s=d, offset_range_s=0.03,
                                  ground_range_m=(g - 0.02, g + 0.02), fix_offset=False,
                                  x_m=geo_x, **p0_kw)
        except SlipDataError:
            continue
        tried.append({'start_s': d, 'start_ground_m': g, 'offset_s': f.offset_s,
                      'ground_m': f.ground_m, 'rms_m': f.rms_m})
        if prefer_fit(f, best, 1 - HALF_STRIDE_BETTER):
            best = f
    res.frame['offset_grid'] = {'first_offset_s': gfit.offset_s, 'first_ground_m': gfit.ground_m,
                                'first_rms_m': gfit.rms_m, 'range_s': half, 'tried': tried,
                                'kept': best is not gfit}
    if best is gfit:
        return None
    res.notes.append(
        f'the geometric fit from the first estimate ({start:+.4f} s) left the body height '
        f'unexplained ({1e3 * gfit.rms_m:.2f} mm RMS against {1e3 * noise:.2f} mm of mocap '
        f'noise at {gfit.offset_s:+.4f} s, ground {gfit.ground_m:+.3f} m); a grid of offsets '
        f'(+-{half:.2f} s) and grounds found a better start: offset {best.offset_s:+.4f} s, '
        f'ground {best.ground_m:+.3f} m, {1e3 * best.rms_m:.2f} mm RMS, kept')
    return best


def _stride_period_s(tj: FloatArray, speed: dict[str, FloatArray]) -> float:
    """Stride period [s] of a RHex-class run: one hip revolution per stride (the tripods'
    mean hip speed), NaN when the hips do not turn on (not a rotating-leg gait)."""
    w = 0.5 * (np.asarray(speed['left']) + np.asarray(speed['right']))
    w = w[np.isfinite(w)]
    if w.size < 10:
        return math.nan
    mean = float(np.mean(w))
    return 2 * math.pi / abs(mean) if abs(mean) > 1.0 else math.nan


def _half_stride_check(gfit: Any, geo_inputs: tuple[Any, ...], geo_x: FloatArray,
                       speed: dict[str, FloatArray], tj: FloatArray, off_range: float,
                       res: RunResult, p0_kw: dict[str, Any] | None = None, *,
                       with_efforts: bool = False) -> Any:
    """The cross-correlation's offset against starts half a stride either side.

    In the sagittal plane the two tripods (front and rear legs of one side with the other
    side's middle leg) are mirror images: mocap heights shifted by half a stride fit the hip
    angles just as well, with the tripods' stances swapped. Without hip efforts nothing in the
    geometric fit tells them apart, so the cross-correlation's sign decides. A start half a
    stride away is taken only when it fits clearly better (an asymmetric robot); when it fits
    as well the ambiguity is said (res.notes, res.frame['offset_half_stride']). A start whose
    output-error refinement failed (``GeometryFit.unrefined``) is compared with a refined fit
    by the equation-error residuals (:func:`~slip_identification.geometry.prefer_fit`).
    ``with_efforts``: the run has hip efforts, but their offset estimates refused it (a gait
    without an aerial phase): starts that fit alike are decided by those estimators'
    assumption, clocks within a quarter stride (the one nearest zero is kept, noted).
    """
    period = _stride_period_s(tj, speed)
    if not math.isfinite(period):
        return gfit
    half = 0.5 * period
    # the starts are compared at one pitch zero, the setup's, not the start's: a zero fitted
    # at each start let a start a stride off fit noise-free running better (zero -4.1 deg).
    # That zero is the first fit's when it was fitted (compared at 0, a rigid body 3 deg off
    # sent jogging a whole stride off), else the prior; the zero is fitted again at a start
    # chosen over the first
    p0_kw = p0_kw or {}
    free_fit = gfit
    p0 = (gfit.pitch_offset_rad if gfit.pitch_offset_fitted
          else float(p0_kw.get('pitch_offset_rad', 0.0)))
    best = gfit
    alt = []
    for start in (gfit.offset_s - half, gfit.offset_s + half):
        try:
            f = fit_ground_offset(*geo_inputs, initial_offset_s=start, offset_range_s=off_range,
                                  fix_offset=False, x_m=geo_x, fit_pitch_offset=False,
                                  pitch_offset_rad=p0)
        except SlipDataError:
            continue
        alt.append(f)
        # a start whose output-error refinement failed has the equation-error fit's residual,
        # below a refined fit's at any offset: not comparable (a simulated walk's start half a
        # stride off, 0.164 against 0.202 mm, was taken: 524 ms off; prefer_fit)
        if prefer_fit(f, best, 1 - HALF_STRIDE_BETTER):
            best = f
    if not alt:
        return free_fit
    rms = [f.rms_m for f in alt]
    # the starts that fit alike (comparable residuals within HALF_STRIDE_BETTER)
    ties = [f for f in alt if prefer_fit(f, gfit, 1 + HALF_STRIDE_BETTER)]
    if best is not gfit:
        res.notes.append(
            f'the cross-correlation\'s offset {gfit.offset_s:+.4f} s was half a stride off: '
            f'the start {best.offset_s:+.4f} s fits the body height clearly better (rms '
            f'{1e3 * best.rms_m:.3f} mm against {1e3 * gfit.rms_m:.3f} mm)')
    elif with_efforts and ties:
        # hip efforts recorded, their estimates refused the run (no aerial phase): those
        # estimators assume clocks within a quarter stride (they iterate from 0), which is
        # what chose between the aliases while they still accepted such runs
        best = min([gfit] + ties, key=lambda f: abs(f.offset_s))
        res.notes.append(
            f'offset ambiguous by half a stride ({half:.3f} s): the geometric fit cannot tell '
            f'the tripods apart (they mirror each other in the sagittal plane; body-height '
            f'rms {1e3 * gfit.rms_m:.3f} mm at {gfit.offset_s:+.4f} s, ' + ', '.join(
                f'{1e3 * f.rms_m:.3f} mm at {f.offset_s:+.4f} s' for f in alt) +
            f'); the one nearest zero, {best.offset_s:+.4f} s, is kept: the hip-effort '
            f'estimates (which refused the run) assume clocks within a quarter stride '
            f'({0.5 * half:.3f} s). If they differ by more, give --offset')
    elif ties:
        # a warning: the tripods' labels (and every per-tripod figure) may be swapped
        res.warn(
            f'offset ambiguous by half a stride ({half:.3f} s): without hip efforts the '
            f'geometric fit cannot tell the tripods apart (they mirror each other in the '
            f'sagittal plane; body-height rms {1e3 * gfit.rms_m:.3f} mm at '
            f'{gfit.offset_s:+.4f} s, ' + ', '.join(
                f'{1e3 * f.rms_m:.3f} mm at {f.offset_s:+.4f} s' for f in alt) +
            '); the first fit\'s was kept (from the cross-correlation, or a grid search when '
            'that left the body height unexplained), so the tripods\' labels and their '
            'figures may be swapped. If the stances look swapped (foot positions a step '
            'off), give --offset, or record hip efforts')
    res.frame['offset_half_stride'] = {
        'stride_s': period, 'xcorr_offset_s': gfit.offset_s, 'xcorr_rms_m': gfit.rms_m,
        'alias_offsets_s': [f.offset_s for f in alt], 'alias_rms_m': rms,
        'chosen_offset_s': best.offset_s}
    if best is gfit:
        return free_fit
    try:
        # the pitch zero fitted again at the start chosen
        return fit_ground_offset(*geo_inputs, initial_offset_s=best.offset_s,
                                 offset_range_s=0.01, fix_offset=False, x_m=geo_x, **p0_kw)
    except SlipDataError:
        return best


def _tilted_frame(frame: WorldFrame, tilt_rad: float, x0_m: float, ground_m: float
                  ) -> WorldFrame:
    """``frame`` turned about its y axis so that a ground rising by ``tilt_rad`` along x is
    level, and moved so that the ground (height ``ground_m`` at ``x = x0_m``) is at z = 0."""
    r = np.asarray(frame.rotation, dtype=float)
    xa = r[0] + tilt_rad * r[2]
    n = r[2] - tilt_rad * r[0]
    xa /= np.linalg.norm(xa)
    n = n - (n @ xa) * xa
    n /= np.linalg.norm(n)
    rot = np.vstack([xa, np.cross(n, xa), n])
    origin = np.asarray(frame.origin_m, dtype=float) + (ground_m - tilt_rad * x0_m) * n
    return WorldFrame(rotation=rot, origin_m=origin)


def _check_body_up(pm: FloatArray, up: FloatArray, label: str, t_s: FloatArray | None = None,
                   quats: FloatArray | None = None) -> None:
    """Refuse a run whose body z axis (the analysis' "up") is not the robot's up.

    Two signs of a motion-capture rigid body defined with other axes than the robot's (z up):
    its z lies along the direction of travel (within 60 deg), or, across the run, the COM
    accelerates much more along the horizontal axis perpendicular to the travel than along the
    body z (a legged robot's COM bounces vertically: 13.5 against 0.6 m/s^2 RMS on simulated
    EduBot running, 2.2 against 0.6 on pace; refused above a ratio of 2). The error names the
    body axis that points up (the bounce's direction, its sign from the bounce's skew: short
    stance pushes up, long flights down) for ``--body-up``.
    """
    ok = np.all(np.isfinite(pm), axis=1)
    p = pm[ok]
    if len(p) < 2:
        return
    travel = p[-1] - p[0]
    norm = float(np.linalg.norm(travel))
    if norm < 0.05:
        return
    travel = travel / norm
    hint = ('give the rigid body\'s axis that points up (hexapod-analyze slip --body-up '
            'x|y|-x|-y|-z, slip_fitter -p body_up:=...) or redefine the rigid body')
    angle = math.degrees(math.acos(min(1.0, abs(float(np.dot(up, travel))))))
    if angle < 60.0:
        raise SlipDataError(
            f'run {label!r}: the body frame\'s z axis is {angle:.0f} deg from the direction of '
            'travel, so it is not the robot\'s up: the motion-capture rigid body\'s axes are '
            f'not the robot\'s (z up); {hint}')
    if t_s is None or quats is None or len(p) < 50:
        return
    from scipy.signal import savgol_filter
    from scipy.stats import skew

    t = np.asarray(t_s, dtype=float)[ok]
    dt = float(np.median(np.diff(t)))
    if not dt > 0:
        return
    u = up - np.dot(up, travel) * travel
    u = u / np.linalg.norm(u)
    v = np.cross(travel, u)
    acc = savgol_filter(p, 7, 2, deriv=2, delta=dt, axis=0)
    au, av = acc @ u, acc @ v
    if float(np.std(av)) <= 2.0 * float(np.std(au)):
        return
    true_up = v if float(skew(av)) > 0 else -v
    q = np.asarray(quats, dtype=float)[ok]
    q = q[np.all(np.isfinite(q), axis=1)]
    axis = 'unknown'
    if len(q):
        from scipy.spatial.transform import Rotation

        body = Rotation.from_quat(q).inv().apply(np.tile(true_up, (len(q), 1))).mean(axis=0)
        k = int(np.argmax(np.abs(body)))
        axis = ('-' if body[k] < 0 else '') + 'xyz'[k]
    raise SlipDataError(
        f'run {label!r}: the COM bounces across the body\'s z axis, not along it '
        f'({np.std(av):.1f} m/s^2 RMS perpendicular to the travel and to the body z, '
        f'{np.std(au):.1f} along the body z): the rigid body\'s z is not the robot\'s up; its '
        f'{axis} axis points up: --body-up {axis} (slip_fitter -p body_up:={axis}); '
        '--body-up z keeps the z axis (a robot that sways more than it bounces)')


def body_up_rotation(axis: str) -> FloatArray:
    """Quaternion (x, y, z, w) ``r`` such that ``q * r`` has its z axis along the recorded
    body's ``axis`` (``x``, ``y``, ``z``, ``-x``, ``-y``, ``-z``): for rigid bodies defined with
    another axis up."""
    from scipy.spatial.transform import Rotation

    turns = {'z': ('x', 0.0), '-z': ('x', 180.0), 'x': ('y', 90.0), '-x': ('y', -90.0),
             'y': ('x', -90.0), '-y': ('x', 90.0)}
    if axis not in turns:
        raise ValueError(f'body up axis must be one of {list(turns)}, got {axis!r}')
    about, deg = turns[axis]
    return Rotation.from_euler(about, deg, degrees=True).as_quat()


def rotate_body(quat_xyzw: FloatArray, axis: str) -> FloatArray:
    """Body orientations (n, 4) re-expressed with ``axis`` of the recorded body as z."""
    if axis == 'z':
        return np.asarray(quat_xyzw, dtype=float)
    from scipy.spatial.transform import Rotation

    q = np.atleast_2d(np.asarray(quat_xyzw, dtype=float))
    ok = np.all(np.isfinite(q), axis=1) & (np.linalg.norm(q, axis=1) > 0)
    out = np.full_like(q, np.nan)
    if ok.any():
        out[ok] = (Rotation.from_quat(q[ok]) * Rotation.from_quat(body_up_rotation(axis))
                   ).as_quat()
    return out


def _up_from_quats(q: FloatArray) -> FloatArray:
    """Mean body z axis from (m, 4) x, y, z, w quaternions."""
    x, y, z, w = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    up = np.column_stack([2 * (x * z + w * y), 2 * (y * z - w * x), 1 - 2 * (x * x + y * y)])
    up = up[np.all(np.isfinite(up), axis=1)]
    m = up.mean(axis=0)
    return m / np.linalg.norm(m)


def _resolve_box(pm: FloatArray, box: Box | None, res: RunResult) -> Box:
    """The permissible box: ``box`` when given; by default the paper's 2 x 1 x 1 m box
    around the mocap origin, or, when that holds under half of the finite samples (another
    lab's mocap origin is not the middle of its tracking volume, and its axes need not be
    the run's), the bounds of every finite sample (the mocap system reports only what it
    tracks), with a note."""
    if box is not None:
        res.frame['box'] = {'lower_m': list(box.lower_m), 'upper_m': list(box.upper_m),
                            'source': 'given'}
        return box
    box = Box()
    finite = np.all(np.isfinite(pm), axis=1)
    n_in = int(permissible_mask(pm, box).sum())
    if finite.any() and n_in < 0.5 * finite.sum():
        lo = np.min(pm[finite], axis=0) - 1e-6
        hi = np.max(pm[finite], axis=0) + 1e-6
        whole = Box(tuple(lo.tolist()), tuple(hi.tolist()))
        res.notes.append(
            f'{n_in} of {int(finite.sum())} mocap samples lie inside the default 2 x 1 x 1 m '
            'box around the mocap origin: every tracked sample is used instead (give --box '
            'to restrict the volume)')
        res.frame['box'] = {'lower_m': list(whole.lower_m), 'upper_m': list(whole.upper_m),
                            'source': 'tracked_samples'}
        return whole
    res.frame['box'] = {'lower_m': list(box.lower_m), 'upper_m': list(box.upper_m),
                        'source': 'default'}
    return box


#: a given pitch zero (--pitch-offset) and the one the data prefer further apart than this
#: get a note [deg]: a free zero scatters by 0.1-0.2 deg on slow gaits and is up to 0.8 deg
#: off on simulated running
PITCH_OFFSET_CHECK_DEG = 1.0


#: the geometric fit's residual RMS over the body height's white noise above which the fit
#: is reported as not explaining the data (simulated gaits: 0.8-1.2; a gait that stumbles onto
#: its belly: 5-12)
GEOMETRY_RESIDUAL_RATIO = 3.0
#: ... and above which it is reported as suspect: the offset may sit in a local minimum
#: (simulated gaits at their fitted offsets: 0.76-1.19 over four gaits, seeds 1-8; a
#: reviewer's clock whose first estimate was 75-160 ms off: 1.45-1.56)
GEOMETRY_RESIDUAL_HIGH = 1.3


def _check_geometry_residual(gfit: GeometryFit, height_m: FloatArray, res: RunResult) -> None:
    """A note when the body-height residual is well above the mocap's white noise (from the
    heights' fourth differences): over :data:`GEOMETRY_RESIDUAL_RATIO` times the legs'
    geometry and springs do not explain the body's motion, and the offset, ground, pitch zero
    and edges from them are unreliable; over :data:`GEOMETRY_RESIDUAL_HIGH` times the fit is
    suspect. ``frame['geometry_noise_m']``, ``frame['geometry_residual_ratio']``,
    ``frame['geometry_fit_poor']``, ``frame['geometry_unrefined']``.

    A final fit whose output-error refinement failed (``GeometryFit.unrefined``) is said in a
    note: its residual is the equation-error fit's, 20-23 % below a refined fit's on gaits
    without flight (4-5 % with flight; simulated EduBot), so its ratio reads low against the
    thresholds above, and its offset and edges rest on windows fitted one by one."""
    noise = white_noise_std(height_m)
    ratio = float(gfit.rms_m / max(noise, 1e-4))
    poor = bool(ratio > GEOMETRY_RESIDUAL_RATIO)
    res.frame['geometry_noise_m'] = noise
    res.frame['geometry_residual_ratio'] = ratio
    res.frame['geometry_fit_poor'] = poor
    res.frame['geometry_unrefined'] = bool(gfit.unrefined)
    if gfit.unrefined:
        res.notes.append(
            f'the geometric fit\'s output-error refinement did not converge: the stream offset '
            f'({gfit.offset_s:+.4f} s), ground and edges come from the equation-error fit of '
            f'{gfit.windows} windows fitted one by one, and its residual ({1e3 * gfit.rms_m:.3f} '
            f'mm RMS, {ratio:.2f} times the motion-capture noise) reads 20-23 % low on gaits '
            f'without flight, so the checks against the noise are lenient. Legs much stiffer '
            f'or a leg description unlike the robot leave fits unrefined; compare the other '
            f'estimators (--offset contact, --offset joint) or give the offset')
    if poor:
        res.warn(
            f'the geometric fit does not explain the body height: residual '
            f'{1e3 * gfit.rms_m:.2f} mm RMS against {1e3 * noise:.2f} mm of motion-capture '
            f'noise, over {gfit.windows} windows. The stream offset ({gfit.offset_s:+.4f} s), '
            f'ground, slope ({math.degrees(gfit.tilt_rad):+.2f} deg), rigid-body pitch zero '
            f'({math.degrees(gfit.pitch_offset_rad):+.2f} deg) and stance edges from it are '
            f'unreliable. Causes seen on simulated runs: a gait that is not steady (the body '
            f'stumbling onto its belly), a wrong leg geometry (--leg-radius, --hip-x, --hip-z, '
            f'--hip-zero); give the offset (--offset S) if it is known')
    elif ratio > GEOMETRY_RESIDUAL_HIGH:
        res.notes.append(
            f'the geometric fit leaves {ratio:.2f} times the motion-capture noise '
            f'({1e3 * gfit.rms_m:.3f} mm RMS against {1e3 * noise:.3f} mm; fits of steady '
            f'simulated gaits leave 0.8-1.2 times): the stream offset ({gfit.offset_s:+.4f} s) '
            f'may sit in a local minimum of the fit (simulated runs like this were 100-160 ms '
            f'off) or the legs do not explain all of the body\'s motion. Compare the offsets '
            f'of the other estimators (--offset contact, --offset joint) or give the offset')


def _check_given_pitch_offset(gfit: GeometryFit, geo_inputs: tuple[Any, ...], geo_x: FloatArray,
                              off: float, off_range: float, fit_offset: bool, given_rad: float,
                              res: RunResult) -> None:
    """Fit the rigid body's pitch zero beside the given one (the given one its prior): when the
    data keep a zero more than :data:`PITCH_OFFSET_CHECK_DEG` away (a wrong sign, a zero
    measured on another rigid body), say so with the stream offset of both; the given zero is
    used either way (``frame['pitch_offset_check_deg']``: the data's zero, None when the
    data do not move it from the given one)."""
    try:
        free = fit_ground_offset(*geo_inputs, initial_offset_s=off, offset_range_s=off_range,
                                 fix_offset=not fit_offset, x_m=geo_x, fit_pitch_offset=True,
                                 pitch_offset_rad=given_rad)
    except SlipDataError as err:
        res.notes.append(f'the given pitch zero could not be checked against the data ({err})')
        return
    data_deg = math.degrees(free.pitch_offset_rad)
    res.frame['pitch_offset_check_deg'] = data_deg if free.pitch_offset_fitted else None
    if free.pitch_offset_fitted and \
            abs(data_deg - math.degrees(given_rad)) > PITCH_OFFSET_CHECK_DEG:
        msg = (f'the given pitch zero ({math.degrees(given_rad):+.2f} deg, --pitch-offset) '
               f'disagrees with the data, which prefer {data_deg:+.2f} deg')
        if fit_offset:
            msg += (f' (stream offset {1e3 * gfit.offset_s:+.1f} ms with the given zero, '
                    f'{1e3 * free.offset_s:+.1f} ms with the data\'s)')
        res.notes.append(msg + '; the given zero is used. Check its sign (minus the pitch the '
                         'rigid body reports while the hips are level) or use '
                         '--pitch-offset auto')


def _check_transient(t_s: FloatArray, pitch_rad: FloatArray, period_s: float,
                     res: RunResult) -> None:
    """Note a run whose body pitch repeats in no two consecutive gait periods (a start-up or
    speed transient throughout the motion capture: :func:`.steady.steady_windows`); sets
    ``frame['steady_state_seen']`` (None without a period or under two periods covered)."""
    res.frame['steady_state_seen'] = None
    if not math.isfinite(period_s):
        return
    t0, d, swing, steady = steady_windows(t_s, pitch_rad, period_s)
    if t0.size == 0:
        return
    k = int(np.argmin(d))
    res.frame['steady_state_seen'] = bool(steady[k])
    if steady[k]:
        return
    res.notes.append(
        f'no steady state in the motion capture: in its most repeatable window the body pitch '
        f'differs from one gait period ({period_s:.3f} s) to the next by '
        f'{math.degrees(d[k]):.2f} deg RMS, more than its own swing ({math.degrees(swing[k]):.2f} '
        f'deg; steady runs differ by a fraction of it). The robot is still settling into its '
        f'gait or changing speed over the whole recording, or its gait does not repeat from '
        f'stride to stride: the stream offset, ground, slope and stance edges are fitted to '
        f'no steady motion (simulated 3 s pace runs like this were 4-27 ms off) and the SLIP '
        f'fits describe no steady gait; record longer in the volume (--steady-only skips '
        f'every stance of such a run)')


def analyze_run(run: RunData, *, model: SlipModel | None = None, box: Box | None = None,
                offset_s: float | str = 0.0, offset_lag_s: float = 0.0,
                max_lateral_m: float = 0.05, position_fit: bool = True,
                min_stance_s: float = 0.02, edges: str = 'auto',
                geometry: LegGeometry | None = None, steady_only: bool = False,
                check_body_up: bool = True,
                pitch_offset_rad: float | None = None, pool_edges: bool = True,
                starts: str = 'multi', gravity: str = 'ground',
                calibration_only: bool = False) -> RunResult:
    """Preprocess one run, extract single-tripod stances, fit each (see module docs).

    ``calibration_only``: stop once the world frame, stream offset, ground height and pitch
    zero are found (``offset_s``, ``offset_method``, ``ground_m``, ``frame``, ``notes``,
    ``warnings`` set; no stances, fits or energetics): the live ``slip_fitter``'s
    self-calibration (:mod:`.calibration`), the same values as the whole analysis.

    ``starts``: the Nelder-Mead starts of the paper's estimator (:class:`.fit.SlipFitter`)
    and the least-squares starts of the position fit (:class:`.fit.SlipPositionFitter`).

    ``pitch_offset_rad``: the motion-capture rigid body's pitch zero against the robot's hip
    line (its pitch when the hips are level), known and kept; None (default): 0, fitted
    beside it by the geometric fit when the data support it (:func:`.geometry.
    fit_ground_offset`), reported in ``frame['pitch_offset_deg']``.

    ``pool_edges``: geometry edges in steady state pooled over strides (:func:`.geometry.
    leg_contacts` ``pool_steady``; ``frame['edges_pooled']``); False keeps each stride's own.

    ``check_body_up``: refuse a run whose body z axis does not look like the robot's up
    (:func:`_check_body_up`); False when the user has said which body axis is up.

    ``offset_s``: seconds to subtract from mocap times, or a method to estimate it:
    ``'contact'`` (touchdowns from hip-effort onsets against touchdowns from the body height,
    :func:`estimate_offset_contacts`; needs ``run.joint_effort``), ``'joint'`` (one offset
    fitted over all stances' body heights with the touchdowns fixed at the hip-effort onsets,
    :func:`estimate_offset_joint`; needs ``run.joint_effort``), ``'geometry'`` (offset and
    ground height fitted to the body's vertical dynamics with the legs' geometric contacts,
    :func:`.geometry.fit_ground_offset`; needs ``geometry`` and ``run.joint_position``;
    searched +-15 ms around the first of ``'contact'``, ``'joint'`` that accepts the run, or
    +-60 ms around ``'xcorr'``; the start is ``RunResult.frame['offset_initial']``),
    ``'xcorr'`` (cross-correlate the mocap vertical velocity with the tripod speed difference,
    minus ``offset_lag_s``, a calibrated physical lag), or ``'auto'`` (``'geometry'`` when
    its inputs exist, else the first of ``'contact'``, ``'joint'`` (with efforts), ``'xcorr'``
    that accepts the run). The contact estimator's nominal stance is 3/4 of the median time
    between alternating touchdowns (at most 0.12 s).

    ``edges``: ``'paper'`` (shifted clock edges, Section 3), ``'effort'`` (touchdown refined to
    the hip-effort onset, lift-off the paper's edge), ``'geometry'`` (single support from the
    legs' geometric contacts: hip below the half-circle leg's rest height, with the fitted
    ground height and offset) or ``'auto'`` (``'geometry'`` when ``geometry`` and
    ``run.joint_position`` are given, else ``'paper'``). The paper's windows are always
    computed and kept in ``RunResult.paper_windows`` (side by side with
    ``geometry_windows``). With a geometric fit, the world frame's ground is moved to the
    fitted ground height (``RunResult.ground_m``, the frame's vertical translation); without
    it the ground passes through the mocap origin; its slope along the path is fitted too and
    the frame turned by it (``RunResult.frame['ground_tilt_rad']``).

    ``gravity``: ``'ground'`` (default) takes gravity normal to the fitted ground (a level
    floor, whatever the motion capture's tilt); ``'mocap'`` takes it along the motion-capture
    frame's -z (a mocap levelled to gravity): on a sloped ground the SLIP model then carries
    gravity's along-ground part, ``model.with_gravity(R @ (0, 0, -g))`` for the final frame
    ``R`` (``frame['gravity_ground_mps2']``, ``frame['gravity_slope_deg']``, positive
    downhill along x).

    ``steady_only``: stances that begin before the steady state (:func:`.steady.steady_start_s`:
    the body pitch repeats from one clock period to the next; the period from the paper's
    touchdowns of one tripod) are skipped with reason ``'transient'``; the start is
    ``RunResult.frame['steady_start_s']`` (proprioception clock).
    """
    if gravity not in ('ground', 'mocap'):
        raise SlipDataError(f"gravity must be 'ground' or 'mocap', got {gravity!r}")
    if edges not in ('paper', 'effort', 'geometry', 'auto'):
        raise SlipDataError(f"edges must be 'paper', 'effort', 'geometry' or 'auto', "
                            f'got {edges!r}')
    methods = ('auto', 'contact', 'joint', 'xcorr', 'geometry')
    if isinstance(offset_s, str) and offset_s not in methods:
        raise SlipDataError(f"offset_s must be seconds or one of {methods}, got {offset_s!r}")
    effort = None if run.joint_effort is None else np.asarray(run.joint_effort, dtype=float)
    if effort is not None and (effort.shape != np.shape(run.joint_velocity)
                               or not np.any(np.isfinite(effort))):
        effort = None
    position = None if run.joint_position is None else np.asarray(run.joint_position,
                                                                  dtype=float)
    if position is not None and (position.shape != np.shape(run.joint_velocity)
                                 or not np.any(np.isfinite(position))):
        position = None
    can_geo = geometry is not None and position is not None
    has_clock = np.asarray(run.command_t_s).size >= 2
    edges_asked = edges
    if edges == 'auto':
        edges = 'geometry' if can_geo else 'paper'
    if not has_clock and edges in ('paper', 'effort'):
        refined = ' (refined by efforts)' if edges == 'effort' else ''
        raise SlipDataError(
            f"run {run.label!r}: no joint commands (the Buehler clock's target speeds, "
            f"/joint_commands), so the paper's edges{refined} cannot be found; "
            + ('use the geometric edges' if can_geo else 'geometric edges need hip angles '
               '(JointState.position) and a leg geometry'))
    if edges == 'effort' and effort is None:
        raise SlipDataError("edges='effort' needs run.joint_effort shaped like joint_velocity")
    if (edges == 'geometry' or offset_s == 'geometry') and not can_geo:
        raise SlipDataError("geometric edges/offset need a LegGeometry (geometry=...) and "
                            'run.joint_position shaped like joint_velocity')
    model = model if model is not None else SlipModel()
    res = RunResult()
    if edges_asked == 'auto' and not can_geo:
        why = ('no leg geometry given' if geometry is None else
               'the joint states carry no hip angles (JointState.position)')
        res.notes.append(f"geometric stance edges unavailable ({why}): the paper's "
                         'shifted-clock edges are used')
    names = tuple(run.joint_names)
    _check_hexapod_hips(names, res)
    tj = np.asarray(run.joint_t_s, dtype=float)
    speed = {tp: _tripod_mean(names, run.joint_velocity, tp) for tp in TRIPODS}
    target = ({tp: _tripod_mean(names, run.command_velocity, tp) for tp in TRIPODS}
              if has_clock else {})
    tm = np.asarray(run.mocap_t_s, dtype=float)
    pm = np.asarray(run.mocap_position_m, dtype=float)
    box = _resolve_box(pm, box, res)
    inside = permissible_mask(pm, box)
    frozen = frozen_pose_mask(pm, run.mocap_quat_xyzw)
    if frozen.any():
        inside &= ~frozen
        res.notes.append(
            f'{int(frozen.sum())} motion-capture sample(s) repeat the previous pose exactly '
            '(the bridge repeating its last pose after losing the body): left out as missing '
            'data, a stance across them is a mocap gap')
        res.frame['frozen_mocap_samples'] = int(frozen.sum())
    if inside.sum() < 10:
        raise SlipDataError(f'run {run.label!r}: {int(inside.sum())} mocap samples inside the '
                            'permissible box, need >= 10')
    _note_mocap_gaps(tm[inside], res)
    _check_position_unit(tm[inside], pm[inside], run.label)
    quats = np.asarray(run.mocap_quat_xyzw, dtype=float)[inside]
    up = _up_from_quats(quats)
    if check_body_up:
        _check_body_up(pm[inside], up, run.label, tm[inside], quats)
    backwards = _check_backwards(names, position, pm[inside], quats, res)
    frame = fit_world_frame(pm[inside], up_mocap=up, backwards=backwards)
    pw = frame.to_world(pm[inside])
    check_straight(pw, max_lateral_m=max_lateral_m)
    res.frame.update({'tilt_deg': math.degrees(frame.tilt_rad),
                      'yaw_deg': math.degrees(frame.yaw_rad),
                      'origin_m': frame.origin_m.tolist(), 'ground_source': 'mocap_origin'})
    touchdowns: dict[str, FloatArray] = {}
    if effort is not None:
        touchdowns = {tp: tripod_touchdowns(names, tj, effort, TRIPODS[tp]) for tp in TRIPODS}
    method = offset_s if isinstance(offset_s, str) else 'given'
    td_all = (alternating_touchdowns(touchdowns)[0] if touchdowns else np.zeros(0))
    # nominal stance for the contact estimator: 3/4 of the time between alternating
    # touchdowns (at most 0.12 s), so that short stances of fast gaits fit their windows
    stance_s = (float(min(0.12, 0.75 * np.median(np.diff(td_all)))) if td_all.size > 2
                else 0.12)

    def estimate(name: str) -> float:
        if name == 'contact':
            return estimate_offset_contacts(td_all, tm[inside], pw[:, 2], stance_s=stance_s)[0]
        if name == 'joint':
            return estimate_offset_joint(touchdowns, tm[inside], pw[:, 2])[0]
        # differences over the finite samples only: a NaN pose took its neighbours' velocities
        # with it (NaN and missing poses read offsets 46 ms apart on a simulated jogging run)
        fin = np.isfinite(tm) & np.all(np.isfinite(pm), axis=1)
        vz = np.gradient(pm[fin, 2], tm[fin])
        return estimate_offset(tj, speed['left'] - speed['right'], tm[fin], vz,
                               lag_s=offset_lag_s)

    if method in ('contact', 'joint') and effort is None:
        raise SlipDataError(f"offset {method!r} needs run.joint_effort")
    if method == 'auto' and can_geo:
        method = 'geometry'
    if method in ('auto', 'geometry') and effort is None:
        res.notes.append('the joint states carry no hip efforts: the first offset estimate is '
                         "the cross-correlation ('xcorr')")
    init = ''
    if method in ('auto', 'geometry'):
        # first estimate: the proprioceptive ones when efforts exist, else the
        # cross-correlation; an estimator that refuses the run hands over to the next
        chain = (['contact', 'joint'] if effort is not None else []) + ['xcorr']
        refused: list[str] = []
        for i, name in enumerate(chain):
            try:
                off = estimate(name)
                init = name
                break
            except SlipDataError as err:
                if i == len(chain) - 1:
                    raise
                refused.append(f'{name}: {err}')
        if refused and init == 'xcorr':
            # e.g. a gait without an aerial phase: the body height shows no touchdowns
            res.notes.append('the hip-effort offset estimates refused the run (' +
                             '; '.join(refused) + "): the first offset estimate is the "
                             "cross-correlation ('xcorr')")
        if method == 'auto':
            method = init
        res.frame['offset_initial'] = init
    elif method in ('contact', 'joint', 'xcorr'):
        off = estimate(method)
    else:
        off = float(offset_s)
    tj_span = (float(np.min(tj)), float(np.max(tj)))
    tm_span = (float(np.min(tm[inside])) - off, float(np.max(tm[inside])) - off)
    if tm_span[1] < tj_span[0] or tj_span[1] < tm_span[0]:
        raise SlipDataError(
            f'run {run.label!r}: motion capture ({tm_span[0]:.3f}..{tm_span[1]:.3f} s after the '
            f'{off:+.3f} s offset) and joint states ({tj_span[0]:.3f}..{tj_span[1]:.3f} s) do '
            'not overlap: ' + ('with the offset given (stamped on different clocks? --offset '
                               'SECONDS is the mocap clock minus the joint states\')'
                               if method == 'given' else
                               'stamped on different clocks? give the offset (--offset '
                               'SECONDS)'))
    geo_inputs: tuple[Any, ...] = ()
    if can_geo and (edges == 'geometry' or method == 'geometry'):
        assert geometry is not None and position is not None
        pitch = body_pitch_rad(frame.rotation, quats)
        geo_inputs = (geometry, names, tj, position, np.asarray(run.joint_velocity, dtype=float),
                      tm[inside], pw[:, 2], pitch)
        geo_x = pw[:, 0].copy()
        off_range = 0.1 if init == 'xcorr' else 0.06
        p0_kw = ({} if pitch_offset_rad is None else
                 {'fit_pitch_offset': False, 'pitch_offset_rad': float(pitch_offset_rad)})
        gfit = fit_ground_offset(*geo_inputs, initial_offset_s=off,
                                 offset_range_s=off_range,
                                 fix_offset=method != 'geometry', x_m=geo_x, **p0_kw)
        at_edge = (gfit.windows == 0 or abs(gfit.ground_m) > 0.04 or
                   (method == 'geometry' and abs(gfit.offset_s - off) > 0.8 * off_range))
        if at_edge or gfit.unrefined:
            # another lab's mocap origin need not be on the floor: the fit ran into the edge
            # of its +-5 cm ground grid (or its offset range); search +-25 cm and keep the
            # better fit. A first fit whose output-error refinement failed too: with the
            # origin 12 cm above the floor the grid held a ground where the legs never touch
            # (ballistic windows fit the body height; the refinement fails), simulated
            # jogging 27-58 ms and 133 mm off without a note
            wide = fit_ground_offset(*geo_inputs, initial_offset_s=off,
                                     offset_range_s=off_range, ground_range_m=(-0.25, 0.25),
                                     fix_offset=method != 'geometry', x_m=geo_x, **p0_kw)
            if prefer_fit(wide, gfit):
                why = ('reached the edge of its +-5 cm range' if at_edge else
                       'was not refined (the output-error fit failed)')
                res.notes.append(
                    f'the ground fit {why} (ground '
                    f'{gfit.ground_m:+.3f} m, offset {gfit.offset_s:+.3f} s, rms '
                    f'{1e3 * gfit.rms_m:.2f} mm); searched +-25 cm: ground '
                    f'{wide.ground_m:+.3f} m, offset {wide.offset_s:+.3f} s, rms '
                    f'{1e3 * wide.rms_m:.2f} mm (the mocap origin is not on the floor)')
                gfit = wide
        if method == 'geometry':
            found = _grid_start(gfit, geo_inputs, geo_x, off, off_range, res, p0_kw)
            if found is not None:
                gfit, off = found, found.offset_s
        if method == 'geometry' and init in ('contact', 'joint'):
            others: dict[str, float] = {}
            for name in ('contact', 'joint'):
                if name != init:
                    try:
                        others[name] = estimate(name)
                    except SlipDataError:
                        pass
            other = _other_starts(gfit, geo_inputs, geo_x, off, others, off_range, res,
                                  p0_kw)
            if other is not None:
                gfit, off = other, other.offset_s
        if (geometry.leg_damping_time_s is None or geometry.damping_assumed) and \
                method in ('geometry', 'given'):
            gfit, geometry, geo_inputs = _damping_tradeoff(
                gfit, geometry, geo_inputs, geo_x, off, off_range, res,
                given=p0_kw if method == 'given' else None)
        elif method == 'geometry':
            gfit, geometry, geo_inputs = _stiffness_check(gfit, geometry, geo_inputs, geo_x,
                                                          off, off_range, model.mass_kg, res)
        if init == 'xcorr' and method == 'geometry':
            gfit = _half_stride_check(gfit, geo_inputs, geo_x, speed, tj, off_range, res,
                                      p0_kw, with_efforts=effort is not None)
        if pitch_offset_rad is not None:
            _check_given_pitch_offset(gfit, geo_inputs, geo_x, off, off_range,
                                      method == 'geometry', float(pitch_offset_rad), res)
        if gfit.pitch_offset_fitted:
            p0_deg = math.degrees(gfit.pitch_offset_rad)
            res.notes.append(
                f'the motion-capture rigid body\'s up axis is off the hip line\'s normal: its '
                f'pitch is corrected by {p0_deg:+.2f} deg (fitted: it lowers the body-height '
                f'residual more than a free parameter would by chance; on simulated runs such '
                f'a fit is within 0.15 deg on slow gaits, up to 0.8 deg off on running); '
                f'contacts and edges use the corrected pitch. If it is known, give it '
                f'(--pitch-offset DEG, minus the pitch the rigid body reports while the hips '
                f'are level)')
        _check_geometry_residual(gfit, geo_inputs[6], res)
        off = gfit.offset_s
        res.ground_m = gfit.ground_m
        # the fitted ground is the frame's vertical translation and its slope along x a
        # rotation about y: heights above the ground z - g - tilt (x - x0)
        frame = _tilted_frame(frame, gfit.tilt_rad, gfit.tilt_x0_m, gfit.ground_m)
        pw = frame.to_world(pm[inside])
        res.frame.update(tilt_deg=math.degrees(frame.tilt_rad), rotation=frame.rotation.tolist(),
                         origin_m=frame.origin_m.tolist(),
                         ground_m=gfit.ground_m, ground_tilt_rad=gfit.tilt_rad,
                         ground_tilt_source=gfit.tilt_source,
                         pitch_offset_deg=math.degrees(gfit.pitch_offset_rad),
                         pitch_offset_source=('given' if pitch_offset_rad is not None else
                                              'fitted' if gfit.pitch_offset_fitted else
                                              'assumed'),
                         ground_source='geometry', geometry_rms_m=gfit.rms_m,
                         geometry_damping_time_s=gfit.damping_ratio_s,
                         geometry_damping_fitted=geometry.leg_damping_time_s is None)
    res.offset_s = off
    res.offset_method = method
    if method in ('contact', 'joint', 'xcorr'):
        # without the leg geometry's fit the first estimates stand alone: good on aerial
        # gaits, far off on gaits with double support (an outside audit, simulated EduBot:
        # contact +4 ms running and jogging, +22 / -25 / -8.5 ms pace, +65 ms walk; xcorr
        # +15 to -99 ms), silently; 'contact' and 'joint' now refuse gaits without flight
        why = ('the one chosen (--offset ' + method + '), kept fixed in the leg-geometry fit'
               if can_geo else 'alone (no leg-geometry fit: --geometry none, or no hip angles)')
        res.warn(f'the stream offset {1e3 * off:+.1f} ms rests on the {method!r} estimate '
                 f'{why}: on simulated EduBot runs it is within 4 ms on running and jogging '
                 "('contact' and 'joint' refuse gaits without an aerial phase, pace and walk, "
                 'where they were 8-65 ms off; xcorr 15-99 ms off there); stances and fits '
                 'move with it. ' + ('The default (--offset auto) fits it with the geometry'
                                if can_geo else 'Give the leg geometry') +
                 ', or the offset if it is known (--offset S)')
    res.edges = edges
    if calibration_only:
        return res
    res.frame['gravity'] = gravity
    if gravity == 'mocap':
        # the final frame's axes in the (levelled) motion-capture frame: gravity's components
        g_world = np.asarray(frame.rotation, dtype=float) @ np.array(
            [0.0, 0.0, -model.gravity_mps2])
        model = model.with_gravity(g_world)
        res.frame['gravity_ground_mps2'] = g_world.tolist()
        res.frame['gravity_slope_deg'] = math.degrees(math.asin(
            max(-1.0, min(1.0, float(g_world[0]) / float(np.linalg.norm(g_world))))))
    tm = tm - off
    track = sagittal_state(tm[inside], pw)
    # stance extraction: the paper's windows always (reported side by side)
    windows = {}
    opened = {}
    clock_td: dict[str, FloatArray] = {}   # every touchdown, the last stance's if still open
    tc = np.asarray(run.command_t_s, dtype=float)
    for tp in (TRIPODS if has_clock else ()):
        tgt_t, tgt_v = tc, target[tp]

        def tgt(t: FloatArray, tgt_t: FloatArray = tgt_t, tgt_v: FloatArray = tgt_v
                ) -> FloatArray:
            return np.interp(t, tgt_t, tgt_v)

        shift = best_shift(tj, speed[tp], tgt)
        td, lo = edges_from_target(tgt_t + shift, tgt_v)
        # a steady clock: its edges from its cycles' samples together, not each one halfway
        # between two command samples (up to 5 ms off at 100 Hz)
        td, lo = refine_clock_edges(tgt_t, tgt_v, td - shift, lo - shift)
        td, lo = td + shift, lo + shift
        res.shift_s[tp] = shift
        clock_td[tp] = td
        windows[tp] = tripod_stance_windows(td, lo)
        opened[tp] = open_stance_windows(td, lo)
    stance_windows = single_tripod_stances(windows, res.shift_s, open_windows=opened) \
        if has_clock else []
    res.paper_windows = stance_windows
    if edges == 'effort':
        refined = {tp: refine_touchdowns(windows[tp], touchdowns[tp])[0] for tp in TRIPODS}
        stance_windows = single_tripod_stances(refined, res.shift_s, open_windows=opened)
    gap_stances: list[tuple[str, float, float, str]] = []
    if geo_inputs:
        # heights in geo_inputs are those before the ground was moved
        pooled: dict[str, Any] = {}
        contacts, unknown = leg_contacts(*geo_inputs, offset_s=res.offset_s,
                                         ground_m=res.ground_m, fit=gfit, x_m=geo_x,
                                         pool_steady=pool_edges, info=pooled)
        if pooled:
            res.frame['edges_pooled'] = pooled
        _effort_contact_check(contacts, names, tj, effort, gfit, geometry, res)
        cut: list[tuple[str, float, float]] = []
        ss = single_support(contacts, TRIPODS, unknown, dropped=cut)
        res.geometry_windows = sorted(
            (StanceWindow(float(a), float(b), tp, res.shift_s.get(tp, 0.0))
             for tp, iv in ss.items() for a, b in iv), key=lambda w: w.touchdown_s)
        if edges == 'geometry':
            stance_windows = res.geometry_windows
            gap_stances = _stances_in_gaps(cut, unknown, res.geometry_windows,
                                           res.paper_windows)
    t_in0, t_in1 = track.t_s[0], track.t_s[-1]
    t_steady = -math.inf
    # cycle starts: every left touchdown of the clock (the closed stances' alone left out the
    # last tracked cycle when its stance was still open at the data's end: a pace run's SR
    # 2.788 over 5 cycles where 6 were tracked, 2.666; an outside audit)
    tds = (np.sort(np.asarray(clock_td['left'], dtype=float)) if has_clock else
           np.array([w.touchdown_s for w in stance_windows if w.tripod == 'left']))
    period = float(np.median(np.diff(tds))) if tds.size >= 3 else math.nan
    body_pitch = body_pitch_rad(frame.rotation, quats)
    _check_transient(tm[inside], body_pitch, period, res)
    if steady_only:
        # a run with no steady window (the check above) has no steady part
        t_steady = (steady_start_s(tm[inside], body_pitch, period)
                    if math.isfinite(period) and res.frame['steady_state_seen'] is not False
                    else math.inf)
        res.frame['steady_start_s'] = t_steady
    # raw mocap samples (all, in or out of the box) on the proprio clock, for skip reasons
    t_raw = np.asarray(run.mocap_t_s, dtype=float) - res.offset_s
    fin_raw = np.isfinite(t_raw) & np.all(np.isfinite(pm), axis=1) & ~frozen
    dt_raw = float(np.median(np.diff(np.sort(t_raw[fin_raw])))) if fin_raw.sum() > 2 else 0.01

    t_tracked = (float(np.min(t_raw[fin_raw])), float(np.max(t_raw[fin_raw]))) \
        if fin_raw.any() else (math.inf, -math.inf)

    def why_not_whole(a: float, b: float) -> str:
        # a sample of the window (or its neighbours) tracked but outside the box, or a window
        # reaching before the first or after the last tracked sample (a system that publishes
        # nothing outside its volume): it entered or left the volume; otherwise the tracking
        # lost it there
        near = fin_raw & (t_raw >= a - 1.5 * dt_raw) & (t_raw <= b + 1.5 * dt_raw)
        if np.any(near & ~inside) or a < t_tracked[0] + 0.5 * dt_raw or \
                b > t_tracked[1] - 0.5 * dt_raw:
            return 'outside_volume'
        return 'mocap_gap'

    stances: list[Stance] = []
    for k, w in enumerate(stance_windows):
        label = f'{run.label}#{k}'
        if w.liftoff_s < t_in0 or w.touchdown_s > t_in1:
            continue  # outside the tracked part of the run: not a candidate
        reason = ''
        if w.touchdown_s < t_steady:
            reason = 'transient'
        elif w.liftoff_s - w.touchdown_s < min_stance_s:
            reason = 'too_short'
        t, x, rt, rxz, whole = track.window(w.touchdown_s, w.liftoff_s)
        if not reason and not whole:
            reason = why_not_whole(w.touchdown_s, w.liftoff_s)
        if not reason:
            st = Stance(t_s=t, state=x, tripod=w.tripod, raw_t_s=rt, raw_xz_m=rxz, label=label)
            try:
                validate_stance(st)
                stances.append(st)
            except StanceRejectedError as err:
                reason = err.reason
        if reason:
            res.skipped.append({'label': label, 'tripod': w.tripod, 'touchdown': w.touchdown_s,
                                'liftoff': w.liftoff_s, 'reason': reason})
            res.skipped_counts[reason] += 1
    for tp, a, b, how in gap_stances:
        if b < t_in0 or a > t_in1:
            continue
        res.skipped.append({'label': f'{run.label}#gap{len(res.skipped)}', 'tripod': tp,
                            'touchdown': a, 'liftoff': b, 'reason': 'mocap_gap',
                            'edges': how})
        res.skipped_counts['mocap_gap'] += 1
    n_gap = res.skipped_counts.get('mocap_gap', 0)
    if n_gap:
        gaps = res.frame.get('mocap_gaps') or {}
        res.notes.append(
            f'{n_gap} stance(s) left out (skipped mocap_gap): a motion-capture gap longer than '
            f'the spline bridges ({1e3 * gaps.get("bridged_max_s", math.nan):.0f} ms) cuts or '
            'hides them')
    if stances:
        res.fits = SlipFitter(model, starts=starts).fit(stances).results_  # type: ignore[arg-type]
        res.stances = list(stances)
        if position_fit:
            res.position_fits = SlipPositionFitter(
                model, starts=starts).fit(stances).results_  # type: ignore[arg-type]
    # energetics of the run: power and speed over the whole gait cycles inside the tracked
    # interval (Komsuoglu et al.'s per-run averages; `hexapod-analyze energy`'s windows)
    _run_energetics(run, res, track.t_s, track.state[:, 0], tds, t_in0, t_in1,
                    steady_from_s=t_steady if steady_only else None)
    # a robot walking backwards has a negative speed along its heading: the specific
    # resistance is over the distance travelled
    res.sr = specific_resistance(res.power_w, model.mass_kg, abs(res.speed_mps))
    if res.frame.get('ground_source') == 'mocap_origin':
        _note_ground_from_origin(res, track.state[:, 2])
    if gravity == 'ground':
        _note_gravity_normal_to_ground(res)
    return res


#: a ground tilted more than this [deg] from the motion capture's z axis is noted
GROUND_TILT_NOTE_DEG = 1.0


def _note_gravity_normal_to_ground(res: RunResult) -> None:
    """Say that gravity is taken normal to the fitted ground when that ground is tilted from
    the motion capture's z axis: right for a level floor under a tilted mocap frame, biased on
    a slope seen by a level one (nothing said it; an outside review's 2 deg slope read the
    paper estimator's stiffness +12 to +39 %)."""
    tilt = res.frame.get('tilt_deg')
    if tilt is None or not math.isfinite(tilt) or abs(tilt) <= GROUND_TILT_NOTE_DEG:
        return
    res.notes.append(
        f'gravity is taken normal to the fitted ground, which is tilted {abs(tilt):.1f} deg '
        'from the motion capture\'s z axis: right for a level floor under a tilted mocap '
        'frame; if the mocap z is vertical (a ground plane calibrated level), the floor slopes '
        'and the stance fits leave the along-ground part of gravity to the spring (an outside '
        'review\'s 2 deg slope read the paper estimator\'s stiffness +12 to +39 %): then '
        'take gravity along the mocap\'s z (--gravity mocap)')


#: a whole cycle whose mean input power is this far from the run's median cycle is noted
#: (a start-up transient: a pace run's first tracked cycles drew 55.9 and 19.6 W against a
#: steady 24.1 W, its SR 2.79 against 2.08 over the steady cycles)
CYCLE_POWER_SPREAD = 0.25
#: battery samples a whole cycle needs for its own mean power (fewer: NaN, and a run whose
#: cycles average fewer is noted)
MIN_BATTERY_PER_CYCLE = 10
#: a /battery_state interval over this many times the median one (and 0.25 s) is a gap,
#: noted (the rule of `hexapod_energy.descriptors.BATTERY_GAP_INTERVALS`)
BATTERY_GAP_INTERVALS = 5.0


def _run_energetics(run: RunData, res: RunResult, t_s: FloatArray, x_m: FloatArray,
                    cycle_starts_s: FloatArray, t_in0: float, t_in1: float, *,
                    steady_from_s: float | None = None) -> None:
    """The run's mean input power and forward speed over the whole gait cycles (one left
    tripod touchdown to another) that the motion capture tracked.

    The tracked span alone starts and ends inside a cycle: a jogging run's first, partly
    tracked cycle (44 W) read the run's power 36.60 W for 35.28 W over whole cycles and its
    specific resistance 1.780 where `hexapod-analyze energy` gave 1.697 (an outside review).
    The speed is the forward displacement interpolated at the cycles' bounds, not between
    the samples nearest them. Under one whole cycle tracked, the tracked span is used, noted.
    ``steady_from_s`` (``--steady-only``): only the cycles from the steady start; it had been
    ignored, so the power, speed and SR of a steady-only run kept its start-up transient.
    ``res.frame['energetics']`` records the interval, the number of cycles and each cycle's
    mean input power; a cycle more than :data:`CYCLE_POWER_SPREAD` from the median is noted.
    """
    ok = np.isfinite(x_m)
    tx, xx = np.asarray(t_s, dtype=float)[ok], np.asarray(x_m, dtype=float)[ok]
    starts = np.sort(np.asarray(cycle_starts_s, dtype=float))
    starts = starts[np.isfinite(starts) & (starts >= t_in0) & (starts <= t_in1)]
    if tx.size > 1:
        starts = starts[(starts >= tx[0]) & (starts <= tx[-1])]
    steady = steady_from_s is not None
    if steady:
        starts = starts[starts >= steady_from_s]   # inf (no steady part): none
    if starts.size >= 2:
        a, b, cycles = float(starts[0]), float(starts[-1]), int(starts.size - 1)
    elif steady:
        res.notes.append('under one whole steady gait cycle tracked by the motion capture: '
                         "the run's power, speed and specific resistance are not computed "
                         '(--steady-only)')
        res.frame['energetics'] = {'start_s': math.nan, 'end_s': math.nan,
                                   'whole_cycles': 0, 'steady_only': True}
        return
    else:
        a, b, cycles = float(t_in0), float(t_in1), 0
        res.notes.append('under one whole gait cycle tracked by the motion capture: the run\'s '
                         'power, speed and specific resistance are over the tracked span '
                         f'({t_in1 - t_in0:.2f} s), which cuts a cycle')
    tb = np.asarray(run.battery_t_s, dtype=float)
    order = np.argsort(tb, kind='stable')
    tb = tb[order]
    vb = np.asarray(run.battery_voltage_v, dtype=float)[order]
    ib = np.asarray(run.battery_current_a, dtype=float)[order]
    sel = (tb >= a) & (tb <= b)
    if sel.sum() >= 2:
        # time-weighted over [a, b], interpolated at the bounds as `energy` does (a plain
        # mean of the samples weighted bursts of samples: up to 2.5 %, an outside review)
        res.power_w, res.current_sign = battery_power_w(vb, ib, t_s=tb, span_s=(a, b))
        per_cycle = sel.sum() / max(cycles, 1)
        if per_cycle < MIN_BATTERY_PER_CYCLE:
            res.notes.append(
                f'the run\'s power rests on {int(sel.sum())} battery samples over '
                f'{max(cycles, 1)} cycle(s) ({per_cycle:.1f} a cycle): instantaneous samples '
                'of a power that swings within each stride alias (1-2 Hz samples of a '
                'running run read half its power); record /battery_state at 50 Hz or more')
        _note_battery_gap(res, tb[np.isfinite(vb) & np.isfinite(ib)], a, b)
    else:
        res.notes.append(f'{int(sel.sum())} battery samples between {a:.2f} s and {b:.2f} s: '
                         'the run\'s power and specific resistance are unknown')
    cycle_w = []
    for c0, c1 in zip(starts[:-1], starts[1:]):
        sel = (tb >= c0) & (tb <= c1)
        try:
            # a cycle's power from a few samples is aliasing, not the cycle's (5 Hz samples
            # of a steady run read 18.9-41.0 W for 32 W: a false transient note)
            cycle_w.append(battery_power_w(vb, ib, sign=res.current_sign, t_s=tb,
                                           span_s=(float(c0), float(c1)))[0]
                           if sel.sum() >= MIN_BATTERY_PER_CYCLE and res.current_sign
                           else math.nan)
        except SlipDataError:
            cycle_w.append(math.nan)
    res.frame['energetics'] = {'start_s': a, 'end_s': b, 'whole_cycles': cycles,
                               'steady_only': steady, 'cycle_power_w': cycle_w}
    if tx.size > 1 and b > a:
        res.speed_mps = float((np.interp(b, tx, xx) - np.interp(a, tx, xx)) / (b - a))
        _check_speed_trend(res, tx, xx, starts)
    cw = np.asarray(cycle_w, dtype=float)
    fin = np.isfinite(cw)
    if fin.sum() >= 3:
        med = float(np.median(cw[fin]))
        off = np.flatnonzero(fin & (np.abs(cw - med) > CYCLE_POWER_SPREAD * med))
        if off.size:
            listed = ', '.join(f'{starts[i]:.2f} s {cw[i]:.1f} W' for i in off[:4])
            more = f' and {off.size - 4} more' if off.size > 4 else ''
            hint = '' if steady else (' (a start-up transient? --steady-only averages the '
                                      'steady cycles only)')
            res.notes.append(
                f'{off.size} of {cw.size} whole cycles draw more than '
                f'{100 * CYCLE_POWER_SPREAD:.0f} % from the median cycle ({med:.1f} W): '
                f'{listed}{more}; they are in the run\'s power, speed and specific '
                f'resistance{hint}')


#: a steady change of the forward speed over the whole cycles beyond this acceleration
#: [m/s^2] (the along-ground gravity of a 1 deg slope: 0.17) is warned when it is also
#: significant (:data:`SPEED_TREND_T`) and changes the speed by :data:`SPEED_TREND_CHANGE`
SPEED_TREND_ACCEL_MPS2 = 0.15
#: t-statistic of the per-cycle speeds' linear trend that counts as significant
SPEED_TREND_T = 4.0
#: relative change of the speed over the cycles that counts
SPEED_TREND_CHANGE = 0.05


def _check_speed_trend(res: RunResult, t_s: FloatArray, x_m: FloatArray,
                       cycle_starts_s: FloatArray) -> None:
    """Warn when the forward speed changes steadily from cycle to cycle.

    The SLIP fits take gravity normal to the fitted ground, so on a slope (or with a mocap
    frame whose z is not vertical: the same data) the along-ground component of gravity is
    left to the spring: an outside review's 2 deg downhill run (speed 1.0 -> 1.4 m/s) read
    the paper estimator's stiffness +12 to +39 % with no word. A start-up or a speed change
    is not steady either. ``frame['speed_trend']`` keeps the per-cycle speeds' linear trend
    (``accel_mps2``, its t-statistic, the change over the cycles and the slope in degrees
    that along-ground gravity alone would need).
    """
    starts = np.asarray(cycle_starts_s, dtype=float)
    if starts.size < 4:      # three whole cycles at least
        return
    xs = np.interp(starts, t_s, x_m)
    dt = np.diff(starts)
    if np.any(dt <= 0):
        return
    v = np.diff(xs) / dt
    tm = 0.5 * (starts[:-1] + starts[1:])
    tc = tm - tm.mean()
    den = float(np.sum(tc ** 2))
    if den <= 0 or not np.all(np.isfinite(v)):
        return
    accel = float(np.sum(tc * (v - v.mean())) / den)
    resid = v - v.mean() - accel * tc
    dof = v.size - 2
    se = math.sqrt(float(np.sum(resid ** 2)) / dof / den) if dof > 0 else math.nan
    t_stat = abs(accel) / se if se > 0 else (math.inf if dof > 0 else math.nan)
    span = float(tm[-1] - tm[0])
    mean_v = float(np.mean(np.abs(v)))
    change = abs(accel) * span / mean_v if mean_v > 0 else math.inf
    slope_deg = math.degrees(math.asin(min(1.0, abs(accel) / GRAVITY_M_S2)))
    res.frame['speed_trend'] = {'accel_mps2': accel, 't_stat': t_stat,
                                'relative_change': change, 'cycles': int(v.size),
                                'slope_equivalent_deg': slope_deg}
    if not (abs(accel) > SPEED_TREND_ACCEL_MPS2 and t_stat >= SPEED_TREND_T
            and change > SPEED_TREND_CHANGE):
        return
    how = 'speeds up' if accel * np.sign(np.mean(v)) > 0 else 'slows down'
    res.warn(
        f'the robot {how} steadily over its {v.size} whole cycles: {float(v[0]):.3f} -> '
        f'{float(v[-1]):.3f} m/s, {accel:+.2f} m/s^2 (t = {t_stat:.1f}), what the along-ground '
        f'gravity of a {slope_deg:.1f} deg slope gives. '
        + ('The SLIP fits take gravity along the motion capture\'s z (--gravity mocap), '
           'so a slope is in the model, but ' if res.frame.get('gravity') == 'mocap' else
           'The SLIP fits take gravity normal to '
           'the fitted ground: on a slope, or with a motion-capture frame whose z is not '
           'vertical, that part of gravity is left to the spring (an outside review\'s 2 deg '
           'slope read the paper estimator\'s stiffness +12 to +39 %; a mocap levelled to '
           'gravity: --gravity mocap), and ')
        + 'a start-up or speed '
        'change is no steady gait either; walk level ground at a steady speed, or read the '
        'stiffness of these stances with care')


def _note_mocap_gaps(t_s: FloatArray, res: RunResult) -> None:
    """Say how many motion-capture samples are missing inside the tracked span (NaN poses,
    poses never published, frozen ones: alike), how many gaps the spline bridges and how many
    split the track (``frame['mocap_gaps']``); nothing when no sample is missing."""
    t = np.sort(np.asarray(t_s, dtype=float)[np.isfinite(t_s)])
    if t.size < 3:
        return
    dt = np.diff(t)
    step = float(np.median(dt))
    if not step > 0:
        return
    holes = dt > 1.5 * step
    if not holes.any():
        return
    bridge = max_mocap_gap_s(step)
    missing = np.maximum(np.rint(dt[holes] / step) - 1, 1)
    long_ = dt[holes] > bridge
    res.frame['mocap_gaps'] = {
        'missing_samples': int(missing.sum()), 'gaps': int(holes.sum()),
        'bridged': int((~long_).sum()), 'long': int(long_.sum()),
        'bridged_max_s': bridge, 'longest_s': float(dt[holes].max())}
    share = 100 * float(missing.sum()) / (t.size + float(missing.sum()))
    res.notes.append(
        f'{int(missing.sum())} motion-capture sample(s) missing inside the tracked span (NaN '
        f'poses, poses not published or repeated; {share:.1f} %) in {int(holes.sum())} '
        f'gap(s): {int((~long_).sum())} of at most '
        f'{1e3 * bridge:.0f} ms bridged by the cubic spline, {int(long_.sum())} longer '
        f'(up to {1e3 * float(dt[holes].max()):.0f} ms) split the track: a stance they touch '
        'is left out (mocap_gap)')


def _note_battery_gap(res: RunResult, t_s: FloatArray, a: float, b: float) -> None:
    """Say when the battery stream has a gap inside ``[a, b]``: the run's time-weighted power
    interpolates across it (an interval over :data:`BATTERY_GAP_INTERVALS` times the median
    interval and 0.25 s, the rule `energy` warns by)."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 3:
        return
    before, after = t[t < a][-1:], t[t > b][:1]
    pts = np.concatenate([before if before.size else [a], t[(t >= a) & (t <= b)],
                          after if after.size else [b]])
    steps = np.diff(pts)
    if not steps.size:
        return
    limit = max(BATTERY_GAP_INTERVALS * float(np.median(np.diff(t))), 0.25)
    k = int(np.argmax(steps))
    if steps[k] > limit:
        n = int(np.count_nonzero(steps > limit))
        res.notes.append(
            f'{n} gap(s) in /battery_state within the whole cycles, the longest '
            f'{steps[k]:.2f} s from {max(pts[k], a):.2f} s: the run\'s power interpolates '
            'across them (a recording gap?)')


def _note_ground_from_origin(res: RunResult, bz_m: FloatArray) -> None:
    """Without a leg geometry the ground is the mocap origin's plane: every height, and so
    every rest length, is measured from it. Say so with the COM height it gives (a mocap origin
    calibrated 12 cm above the floor gave rest lengths of 0.05 m with no word)."""
    bz = np.asarray(bz_m, dtype=float)
    bz = bz[np.isfinite(bz)]
    if not bz.size:
        return
    height = float(np.median(bz))
    res.frame['com_height_m'] = height
    res.notes.append(
        f'ground height taken from the mocap origin (no leg geometry): the COM runs '
        f'{1000 * height:.0f} mm above it, and rest_length and every height are measured from '
        "it; if the origin is not on the floor, give the robot's legs (--geometry, "
        '--leg-radius, --hip-x ...) so the ground is fitted, or recalibrate the origin')


def run_data_from_sim(run: Any, *, with_effort: bool = True) -> RunData:
    """:class:`RunData` from a simulated EduBot run (``edubot_sim.EdubotRun``): the arrays a
    bag of that run would give."""
    names = tuple(f'{leg}_hip' for leg in run.leg_names)
    return RunData(joint_names=names, joint_t_s=run.t_s, joint_velocity=run.hip_velocity_rad_s,
                   command_t_s=run.t_s, command_velocity=run.target_velocity_rad_s,
                   mocap_t_s=run.mocap_t_s, mocap_position_m=run.mocap_position_m,
                   mocap_quat_xyzw=run.mocap_quat_xyzw, battery_t_s=run.t_s,
                   battery_voltage_v=run.battery_voltage_v,
                   battery_current_a=run.battery_current_a, gait=run.gait,
                   joint_effort=run.hip_effort_nm if with_effort else None,
                   joint_position=run.hip_position_rad)
