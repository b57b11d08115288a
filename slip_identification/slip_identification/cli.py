"""``hexapod-analyze slip BAG... --out DIR [--jobs N]``: per-stance SLIP fits of recorded runs.

Writes ``DIR/slip.json``, the Figs. 7-9 scatter plots (``fig7_speed_vs_sr``,
``fig8_power_vs_speed``, ``fig9_nerr_vs_sr``: Fig. 9 with ``nerr_world``, Eq. 2 literal, and
``nerr`` side by side) and ``slip_fit_stances`` (the SLIP fit against the data: measured
states and the SLIP re-simulated from the fitted parameters for the best, median and worst
stance by nerr of each gait, :mod:`slip_identification.plots`), each as PNG and SVG;
``--no-plots`` writes ``slip.json`` alone (an earlier run's figures in ``DIR`` are removed all
the same, so that none is left beside the new result). Schema of ``slip.json``::

    {
      "schema": "slip/1",
      "model": "slip",
      "estimator": "paper",   # which estimator the top-level stance values come from
      "starts": "multi",      # its Nelder-Mead starts: multi (the paper's and the stance's
                              # own scales, lowest nerr kept) or paper (--starts)
      "mass_kg": 3.31,
      "stances": [            # one per fitted single-tripod stance (paper's estimator)
        {"bag", "gait" (on /gait/phase at the touchdown), "tripod",
         "touchdown", "liftoff" [s, proprioception clock],
         "stiffness" [N/m], "rest_length" [m], "foot_x" [m, world frame],
         "stiffness_stderr", "rest_length_stderr", "foot_x_stderr",
         "nerr", "nerr_world" (Eq. 2 read literally, bx in the world frame: the paper's
         Table 3 measure), "nerr_noise_floor", "converged", "samples", "iterations",
         "start" (the Nelder-Mead start kept: paper|stance1|stance2; see "starts"),
         "other_minimum": {same parameter keys, "nerr", "force_swing", "start"} or null
                          (another start's converged result with k 1.5x or l0 1.1x apart:
                          a walk's or pace's bounce beside its constant-force valley; no
                          standard error covers the jump between them),
         "force_swing" (range of the fitted spring force over the stance over its mean;
                        under 1 a nearly constant leg force: k and l0 not identified apart),
         "position_fit": {same parameter and stderr keys, "nerr", "converged", "start",
                          "force_swing"} or null (its least-squares starts follow "starts"),
         "power_w", "speed_mps", "sr"}     # the run's values, as in the paper
      ],
      "runs": [{"bag", "gait" (the first), "gaits" (every gait on /gait/phase, in order),
                "offset_s",
                "offset_method" (given|geometry|contact|joint|xcorr),
                "edges" (geometry|paper|effort), "shift_s": {"left", "right"}, "power_w",
                "speed_mps", "sr", "current_sign" (power, speed and SR over the whole
                gait cycles the motion capture tracked: see frame.energetics),
                "frame": {"energetics": {"start_s", "end_s", "whole_cycles" (0: under one
                          cycle tracked, the tracked span used, noted), "steady_only"
                          (--steady-only: the cycles from frame.steady_start_s only),
                          "cycle_power_w" (each whole cycle's mean input power, null
                          under 10 battery samples in it; one over 25 % from the median
                          is noted: a start-up transient?)},
                          "tilt_deg", "yaw_deg", "origin_m", "ground_source"
                          (geometry|mocap_origin), "ground_m", "geometry_rms_m",
                          "geometry_noise_m" (the height's white noise, from its fourth
                          differences), "geometry_residual_ratio" (rms over that noise,
                          at least 0.1 mm; over 1.3 a note: the offset may sit in a local
                          minimum), "geometry_fit_poor" (ratio over 3: offset, ground and
                          edges unreliable, with a note), "geometry_unrefined" (its
                          output-error refinement failed: equation-error residual, 20-23 %
                          low without flight, with a note), "offset_other_starts" (the
                          proprioceptive estimates disagree: the fit from each,
                          {"first_start_s", "first_offset_s", "first_rms_m",
                           <estimator>: {"start_s", "offset_s", "rms_m"}}),
                          "offset_initial", "ground_tilt_rad" and "rotation" (geometry:
                          the frame turned by the ground's slope), "ground_tilt_source"
                          (strides|fitted: from whole strides' mean heights, or fitted
                          with the body-height dynamics),
                          "pitch_offset_deg" and "pitch_offset_source" (given|fitted|
                          assumed: the rigid body's pitch zero against the hip line,
                          --pitch-offset), "pitch_offset_check_deg" (a given zero: the
                          one the data prefer, null when they keep the given one),
                          "steady_start_s" (--steady-only; null when no steady state),
                          "steady_state_seen" (false: the pitch repeats in no two gait
                          periods, with a note; null: under two periods or no gait period),
                          "speed_trend" (three whole cycles or more: the per-cycle speeds'
                          linear trend {"accel_mps2", "t_stat", "relative_change",
                          "cycles", "slope_equivalent_deg"}; over 0.15 m/s^2, t >= 4 and
                          5 % a warning), "gravity" (ground|mocap, --gravity: gravity
                          normal to the fitted ground, or along the mocap's -z),
                          "gravity_ground_mps2" and "gravity_slope_deg" (mocap: gravity's
                          [x, y, z] in the final frame, and the slope, positive downhill
                          along x; the SLIP fits carry its x part),
                          "walks_backwards" (every hip turns backwards and the body moves
                          against the rigid body's x axis: x along that heading, the speed
                          negative, a note), "heading_to_travel_deg" (the rigid body's
                          x axis against the travel),
                          "edges_pooled"
                          (geometry edges pooled with the same leg's at other strides in
                          steady state: {"pooled_edges",
                          "pooled_moved_over_1ms", "pooled_max_move_s"}),
                          "offset_half_stride" (no hip efforts: the offset fitted from
                          half a stride either side, {"stride_s",
                          "xcorr_offset_s", "xcorr_rms_m", "alias_offsets_s",
                          "alias_rms_m", "chosen_offset_s"}), "offset_damping_tradeoff"
                          (damping time assumed or fitted, against undamped legs:
                          {"damping", "fitted_damping_time_s", "fitted_offset_s",
                          "fitted_rms_m", "undamped_offset_s", "undamped_rms_m"}),
                          "geometry_damping_time_s", "geometry_damping_fitted",
                          "geometry_leg_stiffness_n_m" (one leg's stiffness from the
                          body-height fit), "damping_stiffness_check" (that stiffness
                          over 25 % off EduBot's 3800 N/m with EduBot's damping time:
                          {"leg_stiffness_n_m", "default_damping_time_s",
                          "default_offset_s", "default_rms_m", "fitted_damping_time_s",
                          "fitted_offset_s", "fitted_rms_m", "kept"}),
                          "effort_contact_lag_s" (aerial gaits: geometric touchdowns
                          minus hip-effort onsets, median; a warning when it is over 6 ms
                          from minus "effort_onset_rise_s", how late a slowly rising effort
                          crosses the onset's threshold),
                          "com_height_m" (mocap_origin: median COM height above the
                          origin's plane, with a note that heights are measured from it),
                          "frozen_mocap_samples" (poses repeating the previous one exactly,
                          a bridge that lost the body: left out as missing data, a note)},
                "ground_m" [m, fitted ground height in the path frame, null without it],
                "paper_edges": [{"tripod", "touchdown", "liftoff"}],    # side by side:
                "geometry_edges": [{"tripod", "touchdown", "liftoff"}], # single support
                "geometry": LegGeometry fields used (--leg-radius, --hip-x, --hip-z,
                            --hip-zero override the EduBot's) or null (--geometry none),
                "stances", "skipped",
                "notes": [str]}],   # input fallbacks: hip angles or efforts absent (paper
                                    # edges / xcorr offset), hip angles wrapped (unwrapped),
                                    # no joint velocities (from position differences),
                                    # no sample in the default box,
                                    # no /gait/phase; "frame" also has "box": {"lower_m",
                                    # "upper_m", "source" (given|default|tracked_samples)}
      "gaits": {"<gait>": {"stances", "nerr_mean", "nerr_std", "nerr_world_mean",
                           "nerr_world_std", "power_w_mean", ...,
                           "nerr_noise_floor_median" (what the mocap noise alone gives),
                           "stiffness_median", "stiffness_iqr", "rest_length_median",
                           "rest_length_iqr", "constant_force_stances" (force_swing < 1),
                           "two_minima_stances" (other_minimum's nerr within 10 %)
                           }},  # Table 3
      "skipped": [{"bag", "label", "tripod", "touchdown", "liftoff", "reason"}],  # stances
                  # a mocap dropout cuts or hides (geometric edges) also have "edges":
                  # geometry_cut | clock (placed by the shifted clock inside the gap)
      "skipped_counts": {"<reason>": n},   # too_short, nan, mocap_gap, outside_volume,
                                           # transient (--steady-only), ...
      "failed_bags": [{"bag", "error"}],   # e.g. a missing topic
      "plots": [file names]  # the figures written beside it (PNG and SVG; [] with
                             # --no-plots)
      "warnings": [str]    # e.g. the robot mass assumed (no --mass); "<bag>: ..." for a
                           # run resting on an assumption its data contradict (runs[].warnings,
                           # also in its notes: legs not EduBot's, efforts against contacts)
    }

Estimators. The top-level per-stance values are the paper's estimator (Komsuoglu et al.:
spline-derived 1 kHz state, initial state fixed to the first sample, Nelder-Mead on the
normalised state error), because its ``nerr`` is the paper's SLIP-measure that Table 3 and
Figs. 7-9 are about. Its standard errors under-cover with realistic motion capture (the fixed
initial state carries the spline's end noise); ``position_fit`` holds the second estimator (the
measured positions fitted directly with the initial velocity free), whose parameters and
standard errors meet the accuracy and coverage bars: prefer it for k, l0, fx with uncertainty.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import multiprocessing
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor, wait
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from hexapod_common.cli_args import NumberArgumentParser
from hexapod_common.jsondoc import json_safe

from .energetics import data_source, gait_table, plot_figures
from .errors import MissingTopicError, SlipDataError, SlipError
from .model import EDUBOT_MASS_KG, SlipModel
from .geometry import LegGeometry
from .joints import (
    assemble_joint_frames,
    command_columns,
    rotation_signs,
    stamp_order as _stamp_order,
)
from .pipeline import RunData, analyze_run, rotate_body
from .preprocess import Box, walks_backwards
from .stamps import RepeatedStamps

__all__ = ['add_cli', 'analyze_bag', 'live_params_line', 'main', 'read_run']

TOPICS = ('/joint_states', '/joint_commands', '/mocap/body', '/battery_state')
#: without these no stance can be fitted; /battery_state only gives the run's power and SR;
#: /joint_commands (the Buehler clock's target speeds) only the paper's shifted-clock edges
REQUIRED_TOPICS = ('/joint_states', '/mocap/body')


def read_run(path: str | Path) -> RunData:
    """Read the four topics of one bag (and ``/gait/phase`` for the gait name).

    ``/battery_state`` is optional (without usable samples, power and SR are null); a message
    whose header stamp is zero takes the bag's receive time; input fallbacks are listed in
    ``RunData.notes`` (messages recorded twice, same topic, log time and bytes, count once).
    A message whose stamp equals or precedes its stream's previous one while its values
    differ (a driver stamping with its last bus read when a read is skipped; streams are
    topics, per name set for joint states, per source for batteries) is re-stamped from its
    receive time plus the stream's median stamp - receive offset, or dropped when that offset
    is not well defined (:mod:`.stamps`), with a note giving the count.
    ``/joint_states`` goes through :func:`.joints.assemble_joint_frames`:
    messages split over name groups are assembled, hip angles wrapped into ``[-pi, pi)`` or
    ``[0, 2 pi)`` are unwrapped per joint, and positions without any velocities give
    central-difference speeds (each noted).
    """
    from hexapod_common.bags import (
        SampleColumns,
        duplicates_note,
        iter_messages,
        open_reader,
        prepare_battery_columns,
    )
    from hexapod_common.clocks import ClockCheck
    from hexapod_common.conversions import (
        battery_from_msg,
        gait_phase_from_msg,
        joint_state_from_msg,
        pose_from_msg,
    )

    # every sample kept as compact columns, not as objects (a 30 min EduBot bag took 745 MB)
    js, jc, mo, bt = SampleColumns(), SampleColumns(), SampleColumns(), SampleColumns()
    gait = 'unknown'
    changes: list[tuple[float, str]] = []
    zero: dict[str, int] = {}
    dropped: dict[str, int] = {}
    why: dict[str, str] = {}   # the first reason a topic's message was dropped
    n_phase = 0   # usable /gait/phase messages
    dups: dict[str, int] = {}   # messages recorded twice (same topic, log time, bytes)
    clocks = ClockCheck()
    repeats = RepeatedStamps()   # new values under the previous stamp (a skipped bus read)
    with open_reader(path) as reader:
        reader_notes = list(getattr(reader, 'notes', ()))  # e.g. mcap without metadata.yaml
        present = {c.topic for c in reader.connections}
        missing = [t for t in REQUIRED_TOPICS if t not in present]
        if missing:
            hint = ('; it records /tf: motion capture broadcast as tf is read with '
                    'hexapod-analyze --mocap-tf PARENT:CHILD (e.g. world:base_link)'
                    if '/mocap/body' in missing and '/tf' in present else '')
            raise MissingTopicError(f'bag {path} lacks topic(s) {missing}; needs '
                                    f'{list(REQUIRED_TOPICS)} (and /battery_state for power)'
                                    + hint)
        streams = {'/joint_states': (js, joint_state_from_msg),
                   '/joint_commands': (jc, joint_state_from_msg),
                   '/mocap/body': (mo, pose_from_msg), '/battery_state': (bt, battery_from_msg)}
        for m in iter_messages(reader, list(TOPICS) + ['/gait/phase'], duplicates=dups):
            # the reader's own deserializer: rosbag2 CDR, or ROS 1 bags through AnyReader
            msg = reader.deserialize(m.data, m.msgtype)
            try:
                if m.topic == '/gait/phase':
                    phase = gait_phase_from_msg(msg)
                    n_phase += 1
                    name = _gait_name(phase)
                    if gait == 'unknown':
                        gait = name
                    if not changes or changes[-1][1] != name:
                        changes.append((phase.t_s or 1e-9 * m.stamp_ns, name))
                    continue
                sample = streams[m.topic][1](msg)
            except ValueError as err:
                dropped[m.topic] = dropped.get(m.topic, 0) + 1
                why.setdefault(m.topic, str(err))
                continue  # a bad message is dropped, as the nodes do
            if sample.t_s == 0.0:  # a driver that leaves header.stamp at 0
                if m.stamp_ns != 0:  # (stamp 0 at bag time 0: a clock starting at 0)
                    zero[m.topic] = zero.get(m.topic, 0) + 1
                sample = dataclasses.replace(sample, t_s=1e-9 * m.stamp_ns)
            else:
                clocks.observe(m.topic, sample.t_s, 1e-9 * m.stamp_ns)
                store = streams[m.topic][0]
                repeats.observe(m.topic, _stream_group(sample), len(store), sample,
                                1e-9 * m.stamp_ns)
            streams[m.topic][0].append(sample)
    notes = reader_notes + [
        f'{n} {t} message(s) with a zero header stamp: bag receive time used'
        for t, n in sorted(zero.items())] + duplicates_note(dups)
    for topic in TOPICS:   # re-stamped from the receive times (or dropped), noted
        fixed, repeat_notes = repeats.resolve(topic, streams[topic][0], _rebuilt)
        streams[topic] = (fixed, streams[topic][1])
        notes.extend(repeat_notes)
    js, jc, mo, bt = (streams[t][0] for t in TOPICS)
    shifts, clock_notes = clocks.shifts()   # a topic stamped on another clock
    notes.extend(clock_notes)
    for topic, dt in shifts.items():
        if topic in streams:
            streams[topic][0].shift('t_s', dt)
    # joints that are not a leg's beside the legs (a gripper): left out, noted
    js = _legs_only(js, '/joint_states', notes)
    jc = _legs_only(jc, '/joint_commands', notes)
    notes += [f'{n} {t} message(s) dropped (bad or NaN fields, e.g. {why[t]})'
              for t, n in sorted(dropped.items())]
    if gait == 'unknown' and '/gait/phase' in present and not n_phase:
        # recorded, but every message dropped (or none sent): not 'no /gait/phase in the bag'
        n_bad = dropped.get('/gait/phase', 0)
        notes.append('/gait/phase recorded but ' +
                     (f'none of its {n_bad} message(s) usable (all dropped: '
                      f'{why["/gait/phase"]})' if n_bad else 'without messages') +
                     ': the gait name is unknown')
    try:
        bt, battery_notes = prepare_battery_columns(bt)
        notes.extend(battery_notes)
    except ValueError as err:   # no power measured, or --battery-source not in this bag
        notes.append(str(err))
        bt = SampleColumns()
    if not len(bt):
        notes.append('no usable /battery_state message (absent, or NaN voltage/current): the '
                     "run's power and specific resistance are null")
    if not len(js):
        raise MissingTopicError(f'bag {path}: /joint_states has no usable message')
    try:
        joints = assemble_joint_frames(js)
    except SlipDataError as err:
        raise MissingTopicError(f'bag {path}: {err}') from err
    names = joints.names
    # split over name groups, hip angles unwrapped, velocities derived from positions
    notes.extend(joints.notes)
    signs = rotation_signs(joints.position) if joints.position is not None else \
        np.ones(len(names))
    hips = [n for n in names if n.endswith('_hip')]
    if hips and all(signs[names.index(n)] < 0 for n in hips) and len(mo):
        # every hip turns backwards: mirrored motors, or a robot walking backwards (its body
        # moving against the rigid body's heading), which the pipeline reads as such
        net = [-4.0] * len(hips)   # rotation_signs: each below -pi
        ix = np.argsort(_rows(mo, 't_s'), kind='stable')
        if walks_backwards(_rows(mo, 'position_m')[ix], _rows(mo, 'orientation_xyzw')[ix],
                           net)[0]:
            signs = np.ones(len(names))
    if (signs < 0).any():
        joints = dataclasses.replace(
            joints, position=joints.position * signs, velocity=joints.velocity * signs,
            effort=joints.effort * signs if joints.effort is not None else None)
        flipped = [n for n, sg in zip(names, signs) if sg < 0]
        order = [f'{side}{k}_hip' for side in 'LR' for k in (1, 2, 3)]
        online = [float(signs[names.index(n)]) if n in names else 1.0 for n in order]
        notes.append(f'{", ".join(flipped)} turn backwards over the run (net rotation below '
                     '-pi: motors mounted mirrored?): their angles, speeds, efforts and commanded '
                     f'speeds are negated (online: slip_fitter -p hip_signs:={online})')
        if hips and set(hips) <= set(flipped):
            notes.append('every hip turns backwards while the body moves along the motion-'
                         'capture rigid body\'s heading (or the heading is unknown): read as '
                         'motors mounted mirrored on a robot walking forward. A robot walking '
                         'backwards is read as such when its body moves against the rigid '
                         'body\'s x axis (runs[].frame.walks_backwards)')
    try:
        command_t_s, command_velocity = command_columns(jc, names, notes)
    except SlipDataError as err:
        raise MissingTopicError(f'bag {path}: /joint_commands: {err}') from err
    if (signs < 0).any() and command_velocity.size:
        command_velocity = command_velocity * signs
    for topic, n in (('/joint_states', joints.t_s.size), ('/mocap/body', len(mo))):
        if not n:
            raise MissingTopicError(f'bag {path}: {topic} has no usable message (with '
                                    'velocities for the joint names of /joint_states)')
    # every stream in stamp order (samples received out of it keep their own stamps)
    command_t_s, command_velocity = _stamp_order('/joint_commands', notes, command_t_s,
                                                 command_velocity)
    mo_t, mo_p, mo_q = _stamp_order('/mocap/body', notes, _rows(mo, 't_s'),
                                    _rows(mo, 'position_m'), _rows(mo, 'orientation_xyzw'))
    bt_t, bt_v, bt_i = _stamp_order('/battery_state', notes, _rows(bt, 't_s'),
                                    _rows(bt, 'voltage_v'), _rows(bt, 'current_a'))
    return RunData(
        joint_names=names, joint_t_s=joints.t_s, joint_velocity=joints.velocity,
        command_t_s=command_t_s, command_velocity=command_velocity,
        mocap_t_s=mo_t, mocap_position_m=mo_p, mocap_quat_xyzw=mo_q, battery_t_s=bt_t,
        battery_voltage_v=bt_v, battery_current_a=bt_i, gait=gait, label=str(path),
        joint_effort=joints.effort, joint_position=joints.position,
        notes=tuple(notes), gait_changes=tuple(changes))


class _Samples(list):  # type: ignore[type-arg]
    """A list of samples with :meth:`SampleColumns.distinct`."""

    def distinct(self, name: str) -> list[Any]:
        return list(dict.fromkeys(getattr(s, name) for s in self))


def _legs_only(samples: Any, topic: str, notes: list[str]) -> Any:
    """``samples`` (JointStateSample columns of a bag) without the joints that are not a
    leg's when the bag names leg joints (:class:`LegJointFilter`; decided from the whole bag,
    so a gripper's message before the legs' is left out too: it had made the joint set);
    the samples themselves when there is nothing to leave out."""
    from hexapod_common.conversions import LEG_JOINT_RE, LegJointFilter

    sets = samples.distinct('names') if len(samples) else []
    if not LegJointFilter.names_have_legs(sets) or \
            all(LEG_JOINT_RE.match(n) for names in sets for n in names):
        return samples
    f = LegJointFilter(legs_present=True)
    out = _Samples(x for x in (f.apply(s) for s in samples) if x is not None)
    notes.append(f'{topic}: {f.note("the stance detection and the fits")}')
    return out


def _stream_group(sample: Any) -> Any:
    """What tells streams of one topic apart: a joint state's names (messages split over
    name groups share stamps), a battery's source (several batteries on one topic)."""
    names = getattr(sample, 'names', None)
    return names if names is not None else getattr(sample, 'source', None)


def _rebuilt(samples: Any, drop: set[int], restamp: dict[int, float]) -> Any:
    """``samples`` (SampleColumns) without the rows ``drop``, rows ``restamp`` re-stamped."""
    from hexapod_common.bags import SampleColumns

    out = SampleColumns()
    for k, s in enumerate(samples):
        if k in drop:
            continue
        out.append(dataclasses.replace(s, t_s=restamp[k]) if k in restamp else s)
    return out


def _rows(samples: Any, name: str) -> np.ndarray:
    """``np.array([getattr(s, name) for s in samples])`` from a :class:`SampleColumns`
    without rebuilding its samples (a number field's column; an array field's rows)."""
    if not len(samples):
        return np.array([])
    value = getattr(samples[0], name)
    if isinstance(value, np.ndarray):
        stacked = samples.stacked(name)
        if stacked is not None:
            return np.array(stacked)
    elif isinstance(value, float):
        column = samples.column(name)
        if isinstance(column, np.ndarray):
            return np.array(column)
    return np.array([getattr(s, name) for s in samples])


def _gait_name(phase: Any) -> str:
    """Table 1 preset name of a Buehler-clock GaitPhase (period and duty within 1 %)."""
    if phase.gait != 'buehler':
        return str(phase.gait)
    from hexapod_gait.buehler import BUEHLER_PRESETS
    for name, clk in BUEHLER_PRESETS.items():
        if abs(clk.period_s - phase.period_s) <= 0.01 * clk.period_s and \
                abs(clk.duty_factor - phase.duty_factor) <= 0.01:
            return name
    return 'buehler'


def _f(x: float) -> float | None:
    return float(x) if math.isfinite(float(x)) else None


def _pitch_offset_arg(text: str) -> str:
    """``--pitch-offset``: 'auto' or a finite angle within +-45 deg."""
    if text == 'auto':
        return text
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"'auto' or degrees, got {text!r}") from None
    if not (math.isfinite(v) and abs(v) <= 45.0):
        raise argparse.ArgumentTypeError(f'a pitch offset within +-45 deg, got {text!r}')
    return text


class Analysis(NamedTuple):
    """One run analysed with ``slip``'s options (:func:`analyze_data`)."""

    run: Any                    # the run as analysed (re-expressed by --body-up)
    result: Any                 # :class:`.pipeline.RunAnalysis`
    model: SlipModel
    geometry: LegGeometry | None
    notes: list[str]            # about the options (the geometry's), before the result's


def default_options(**changes: Any) -> dict[str, Any]:
    """The options of ``hexapod-analyze slip BAG --out DIR`` (its arguments' defaults, the
    robot mass EduBot's), with ``changes``: another analysis of ``slip``'s stances (the SLIP
    residual loop) takes them from here, so that the two cannot drift apart (the loop had
    restated them, and once ran other edges and no clock offset)."""
    parser = NumberArgumentParser(add_help=False)
    add_cli(parser.add_subparsers())
    args = parser.parse_args(['slip', 'BAG', '--out', 'DIR'])
    args.mass = EDUBOT_MASS_KG
    options = options_from_args(args)
    unknown = set(changes) - set(options)
    if unknown:
        raise KeyError(f'not slip options: {sorted(unknown)}')
    options.update(changes)
    return options


def options_from_args(args: argparse.Namespace) -> dict[str, Any]:
    """:func:`analyze_bag`'s options from ``slip``'s parsed (and checked) arguments."""
    methods = ('auto', 'contact', 'joint', 'xcorr', 'geometry')
    return {'offset': args.offset if args.offset in methods else float(args.offset),
            'edges': args.edges, 'geometry': args.geometry,
            'geometry_overrides': _geometry_overrides(args),
            'leg_damping_time': (None if args.leg_damping_time in ('fit', 'none')
                                 else 'default' if args.leg_damping_time == 'default'
                                 else float(args.leg_damping_time)),
            'offset_lag': args.offset_lag, 'max_lateral': args.max_lateral,
            'mass_kg': args.mass, 'model': args.model, 'position_fit': not args.no_position_fit,
            'box_lower': args.box[:3] if args.box else None,
            'box_upper': args.box[3:] if args.box else None,
            'steady_only': args.steady_only, 'body_up': args.body_up,
            'pool_edges': not args.no_edge_pooling, 'starts': args.starts,
            'gravity': args.gravity,
            'pitch_offset_rad': (None if args.pitch_offset == 'auto'
                                 else math.radians(float(args.pitch_offset)))}


def analyze_data(run: Any, options: dict[str, Any]) -> Analysis:
    """Analyse one run read by :func:`read_run` with :func:`analyze_bag`'s ``options``;
    raises what the pipeline raises on data it refuses."""
    body_up = options.get('body_up', 'auto')
    if body_up not in ('auto', 'z'):
        run = dataclasses.replace(
            run, mocap_quat_xyzw=rotate_body(run.mocap_quat_xyzw, body_up),
            notes=run.notes + (f'body orientation re-expressed with the rigid body\'s '
                               f'{body_up} axis as up (--body-up)',))
    # no --box: the pipeline's default box, or every tracked sample when the mocap origin
    # is not in the tracking volume (another lab's frame)
    box = Box(tuple(options['box_lower']), tuple(options['box_upper'])) \
        if options.get('box_lower') else None
    model = SlipModel.from_name(options.get('model', 'slip'),
                                mass_kg=options.get('mass_kg', EDUBOT_MASS_KG))
    geometry = None
    geometry_notes: list[str] = []
    if options.get('pitch_offset_rad') is not None and \
            options.get('geometry', 'edubot') != 'edubot':
        geometry_notes.append('--pitch-offset is not used without a leg geometry (it '
                              'corrects the pitch of the geometric contacts)')
    if options.get('geometry', 'edubot') == 'edubot':
        tau = options.get('leg_damping_time', 'default')
        overrides = dict(options.get('geometry_overrides') or {})
        if tau == 'default' and {'leg_radius_m', 'hip_x_m', 'hip_z_m'} & set(overrides):
            # another robot's legs: EduBot's 3.4 ms damping time need not be theirs (kept
            # silently, it moved the offset 7 ms and every lift-off 3-5 ms on a lab's
            # undamped legs); fitting it trades off against the offset, so the default is
            # checked against undamped legs instead
            overrides['damping_assumed'] = True
            geometry_notes.append(
                'another robot\'s leg geometry without --leg-damping-time: the EduBot '
                'description\'s damping time (3.4 ms) is assumed and checked against '
                'undamped legs; give it (seconds, e.g. from a drop test of one leg, or '
                '\'fit\') for a surer offset')
        if tau != 'default':
            overrides['leg_damping_time_s'] = tau
        if tau != 'default' or overrides.get('damping_assumed'):
            # the damping time is given (or checked against undamped legs): no check
            # against EduBot's leg stiffness
            overrides['damping_stiffness_n_m'] = None
        geometry = LegGeometry(**overrides)
    res = analyze_run(run, model=model, box=box, offset_s=options.get('offset', 0.0),
                      offset_lag_s=options.get('offset_lag', 0.0),
                      edges=options.get('edges', 'paper'),
                      max_lateral_m=options.get('max_lateral', 0.05),
                      position_fit=options.get('position_fit', True), geometry=geometry,
                      steady_only=options.get('steady_only', False),
                      check_body_up=body_up == 'auto',
                      pitch_offset_rad=options.get('pitch_offset_rad'),
                      pool_edges=options.get('pool_edges', True),
                      starts=options.get('starts', 'multi'),
                      gravity=options.get('gravity', 'ground'))
    if res.frame.get('gravity') == 'mocap':   # the model the stances were fitted with
        model = model.with_gravity(res.frame['gravity_ground_mps2'])
    return Analysis(run, res, model, geometry, geometry_notes)


def analyze_bag(path: str, options: dict[str, Any]) -> dict[str, Any]:
    """Analyse one bag; returns a JSON-able dict (``error`` set when the bag is refused)."""
    from hexapod_common.errors import HexapodError

    try:
        run, res, model, geometry, geometry_notes = analyze_data(read_run(path), options)
    except (SlipError, HexapodError, ValueError, OSError) as err:  # a truncated bag too
        return {'bag': path, 'error': str(err)}
    notes = list(run.notes) + geometry_notes + list(res.notes)
    if run.gait == 'unknown' and not any(n.startswith('/gait/phase recorded but')
                                         for n in run.notes):
        notes.append('no /gait/phase in the bag: the gait name is unknown')
    gaits = list(dict.fromkeys(g for _, g in run.gait_changes))
    if len(gaits) > 1:
        en = res.frame.get('energetics') or {}
        span = (f' ({en["start_s"]:.2f} to {en["end_s"]:.2f} s, {en["whole_cycles"]} cycles)'
                if en.get('whole_cycles') else '')
        # not 'over the whole bag': a robot standing before it runs has no gait cycles there
        # (an outside review's 10 s standing then running: 60.0 W, the running's, was right)
        notes.append(f'the gait changes in this bag ({" -> ".join(gaits)}): each stance is '
                     'labelled with the gait at its touchdown; power, speed and specific '
                     'resistance are over the whole gait cycles the motion capture tracked'
                     f'{span}, of every gait in them (record one gait per bag for Table 3)')
    stances = []
    pos = {r.label: r for r in res.position_fits}
    for r in res.fits:
        d: dict[str, Any] = {'bag': path, 'gait': run.gait_at(r.touchdown_s),
                             'tripod': r.tripod,
                             'touchdown': r.touchdown_s, 'liftoff': r.liftoff_s}
        for k, v in r.params.items():
            d[k] = _f(v)
            d[f'{k}_stderr'] = _f(r.stderr[k])
        d.update(nerr=_f(r.nerr), nerr_world=_f(r.nerr_world),
                 nerr_noise_floor=_f(r.nerr_noise_floor),
                 converged=r.converged, samples=r.samples,
                 iterations=r.iterations, start=r.start, force_swing=_f(r.force_swing))
        d['other_minimum'] = ({k: (v if isinstance(v, str) else _f(v))
                               for k, v in r.other_minimum.items()}
                              if r.other_minimum else None)
        p = pos.get(r.label)
        d['position_fit'] = None if p is None else {
            **{k: _f(v) for k, v in p.params.items()},
            **{f'{k}_stderr': _f(v) for k, v in p.stderr.items()},
            'nerr': _f(p.nerr), 'converged': p.converged, 'start': p.start,
            'force_swing': _f(p.force_swing)}
        d.update(power_w=_f(res.power_w), speed_mps=_f(res.speed_mps), sr=_f(res.sr))
        stances.append(d)
    return {'bag': path, 'gait': run.gait, 'stances': stances,
            'traces': _traces(stances, res, model),
            'skipped': [{'bag': path, **s} for s in res.skipped],
            'run': {'bag': path, 'gait': run.gait,
                    'gaits': list(dict.fromkeys(g for _, g in run.gait_changes)) or [run.gait],
                    'offset_s': res.offset_s,
                    'offset_method': res.offset_method, 'edges': res.edges,
                    'shift_s': res.shift_s, 'power_w': _f(res.power_w),
                    'speed_mps': _f(res.speed_mps), 'sr': _f(res.sr),
                    'current_sign': res.current_sign, 'frame': res.frame,
                    'ground_m': _f(res.ground_m),
                    'paper_edges': [{'tripod': w.tripod, 'touchdown': w.touchdown_s,
                                     'liftoff': w.liftoff_s} for w in res.paper_windows],
                    'geometry_edges': [{'tripod': w.tripod, 'touchdown': w.touchdown_s,
                                        'liftoff': w.liftoff_s}
                                       for w in res.geometry_windows],
                    'geometry': None if geometry is None else dataclasses.asdict(geometry),
                    'stances': len(stances), 'skipped': len(res.skipped), 'notes': notes,
                    'warnings': list(res.warnings)}}


def _traces(stances: list[dict[str, Any]], res: Any, model: SlipModel
            ) -> list[dict[str, Any] | None]:
    """The measured states and fits behind ``stances`` for the fit-against-data figure
    (:func:`.plots.stance_trace`; not written to ``slip.json``), one per stance: every
    stance's up to :data:`.plots.TRACE_CAP` stances per gait, else that many ranks spread
    over the gait's nerr (None for the others)."""
    from .plots import stance_trace, trace_subset

    if len(res.stances) != len(res.fits) or len(res.fits) != len(stances):
        return [None] * len(stances)
    keep: set[int] = set()
    for gait in {str(d['gait']) for d in stances}:
        idx = [i for i, d in enumerate(stances) if str(d['gait']) == gait]
        sub = trace_subset([math.nan if stances[i]['nerr'] is None else stances[i]['nerr']
                            for i in idx])
        keep.update(idx[j] for j in sub)
    return [stance_trace(s, r, model) if i in keep else None
            for i, (s, r) in enumerate(zip(res.stances, res.fits))]


def live_params_line(run: dict[str, Any]) -> str:
    """The live ``slip_fitter`` parameters a run's analysis gives (its ground, stream
    offset and pitch zero): without them the node uses the paper's clock edges and no stream
    offset (a review: stiffness 35-71 % low, rest length 25 % long on a simulated run)."""
    ground = run.get('ground_m')
    frame = run.get('frame') or {}
    offset = float(run.get('offset_s') or 0.0)
    if ground is None or not math.isfinite(ground):
        return (f"slip: {run['bag']}: no geometric ground (edges {run.get('edges')}): the "
                f"live slip_fitter can take -p mocap_offset:={offset:.4f} only")
    return (f"slip: live slip_fitter for {run['bag']}: -p ground:={ground:.4f} "
            f"-p mocap_offset:={offset:.4f} "
            f"-p pitch_offset:={float(frame.get('pitch_offset_deg') or 0.0):.2f}")


def _other_ratio(stance: dict[str, Any]) -> float:
    """The other minimum's nerr over the kept one's (inf without another minimum)."""
    other = stance.get('other_minimum')
    if not other or other.get('nerr') is None or not stance.get('nerr'):
        return math.inf
    return float(other['nerr']) / float(stance['nerr'])


def _geometry_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """LegGeometry fields given on the command line (another RHex-class robot's legs)."""
    out: dict[str, Any] = {}
    if getattr(args, 'leg_radius', None) is not None:
        # a radius of 1e9 m was taken (a 0.2 mm rms claimed with it)
        if not (math.isfinite(args.leg_radius) and 0 < args.leg_radius <= 2.0):
            raise SlipDataError(f'--leg-radius must be in (0, 2] m, got {args.leg_radius}')
        out['leg_radius_m'] = float(args.leg_radius)
    if getattr(args, 'hip_x', None) is not None:
        front, middle, rear = (float(v) for v in args.hip_x)
        if not (all(math.isfinite(v) and abs(v) <= 5.0 for v in (front, middle, rear))
                and front > middle > rear):
            raise SlipDataError(f'--hip-x expects front > middle > rear within +-5 m, got '
                                f'{args.hip_x}')
        out['hip_x_m'] = (front, middle, rear)
    if getattr(args, 'hip_z', None) is not None:
        # NaN or 1e9 analysed nothing and exited 0
        if not (math.isfinite(args.hip_z) and abs(args.hip_z) <= 2.0):
            raise SlipDataError(f'--hip-z must be within +-2 m, got {args.hip_z}')
        out['hip_z_m'] = float(args.hip_z)
    if getattr(args, 'hip_zero', None) is not None:
        if not (math.isfinite(args.hip_zero) and abs(args.hip_zero) <= 2 * math.pi):
            raise SlipDataError(f'--hip-zero must be within +-2 pi rad, got {args.hip_zero}')
        out['hip_zero_rad'] = float(args.hip_zero)
    return out


def _check_options(args: argparse.Namespace) -> None:
    """Refuse option values that cannot work, naming the option, before any bag is read
    (an outside review: NaN offsets ended in 'arange: cannot compute length', a NaN lateral
    bound turned the straight-run check off, a negative damping time was used, an inverted
    --box blamed the bag)."""
    def finite(name: str, value: float, lo: float, hi: float, what: str) -> None:
        if not (math.isfinite(value) and lo <= value <= hi):
            raise SlipDataError(f'{name} must be {what}, got {value}')

    if args.offset not in ('auto', 'contact', 'joint', 'xcorr', 'geometry'):
        try:
            value = float(args.offset)
        except ValueError:
            raise SlipDataError(f"--offset must be seconds or auto, contact, joint, xcorr, "
                                f'geometry, got {args.offset!r}') from None
        finite('--offset', value, -3600.0, 3600.0, 'seconds within +-1 h')
    finite('--offset-lag', args.offset_lag, -1.0, 1.0, 'seconds within +-1 s')
    finite('--max-lateral', args.max_lateral, 1e-6, 10.0, 'in (0, 10] m')
    if args.leg_damping_time not in ('fit', 'none', 'default'):
        try:
            value = float(args.leg_damping_time)
        except ValueError:
            raise SlipDataError(f"--leg-damping-time must be seconds, fit, none or default, "
                                f'got {args.leg_damping_time!r}') from None
        finite('--leg-damping-time', value, 0.0, 1.0, 'in [0, 1] s')
    if args.mass > 1000:
        raise SlipDataError(f'--mass must be a robot mass up to 1000 kg, got {args.mass}')
    if args.box:
        lo, hi = args.box[:3], args.box[3:]
        if not (all(math.isfinite(v) for v in args.box) and all(a < b for a, b in zip(lo, hi))):
            raise SlipDataError(f'--box X0 Y0 Z0 X1 Y1 Z1 needs finite corners with X0 < X1, '
                                f'Y0 < Y1, Z0 < Z1, got {args.box}')
    if args.jobs < 1:
        raise SlipDataError(f'--jobs must be >= 1, got {args.jobs}')
    if not str(args.model).startswith('slip'):
        raise SlipDataError(f"--model must name a SLIP model (slip...), got {args.model!r}")


def _analyze_reporting(path: str, options: dict[str, Any], queue: Any) -> dict[str, Any]:
    """:func:`analyze_bag` in a ``--jobs`` worker, the messages it reads counted to
    ``queue`` (the parent's bar)."""
    from hexapod_common.bags import message_progress

    with message_progress('', callback=queue.put):
        return analyze_bag(path, options)


def _message_total(bags: list[str]) -> int:
    """Messages of the topics ``slip`` reads in ``bags`` (0 when a bag cannot be opened:
    its worker reports the error)."""
    from hexapod_common.bags import open_reader

    total = 0
    for b in bags:
        try:
            with open_reader(b) as reader:
                total += sum(int(getattr(c, 'msgcount', 0) or 0) for c in reader.connections
                             if c.topic in (*TOPICS, '/gait/phase'))
        except Exception:  # noqa: BLE001 - the analysis names the bad bag
            continue
    return total


def _positive_kg(text: str) -> float:
    """``--mass``: a finite mass > 0 (``nan``, 0 or a negative one was taken as given and
    reported as every bag refused, with NaN written into slip.json)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f'must be a finite mass > 0 kg, got {text}')
    return value


def run_command(args: argparse.Namespace) -> int:
    """Handler of ``hexapod-analyze slip``; returns the exit code. An earlier run's result in
    ``--out`` is kept when this one fails or is interrupted
    (:func:`hexapod_common.outdir.replacing_outputs`)."""
    from hexapod_common.outdir import replacing_outputs

    with replacing_outputs(args.out, 'slip.json'):
        return _run_command(args)


def _run_command(args: argparse.Namespace) -> int:
    from tqdm import tqdm
    from hexapod_common.progress import bar_options

    from hexapod_common.outdir import prepare_out_dir

    warnings: list[str] = []
    if args.mass is None:
        # said: SR scales with it (a 2.183 kg robot's walk read SR 3.14 for 4.76 without a
        # word: an outside review)
        args.mass = EDUBOT_MASS_KG
        warnings.append(f'robot mass not given: EduBot\'s {EDUBOT_MASS_KG:g} kg assumed for '
                        'P/(m g v) (SR); give --mass')
    _check_options(args)
    options = options_from_args(args)
    # before the analysis, not after it; an earlier run's result is set aside by run_command
    out = prepare_out_dir(args.out)
    bags = [str(b) for b in args.bags]
    results: list[dict[str, Any]] = []
    if args.jobs > 1 and len(bags) > 1:
        # not fork: the parallel fit kernels (numba, GNU OpenMP layer) may already have run in
        # this process, and forking after OpenMP aborts the child ('fork() called from a
        # process already using GNU OpenMP')
        ctx = multiprocessing.get_context('forkserver')
        pool = ProcessPoolExecutor(max_workers=args.jobs, mp_context=ctx)
        manager = ctx.Manager()
        try:
            # the workers report the messages they read to one bar here (a long bag shows
            # its progress, not 0/N bags for minutes)
            queue = manager.Queue()
            futs = [pool.submit(_analyze_reporting, b, options, queue) for b in bags]
            with tqdm(total=len(bags), desc='slip', unit='bag', **bar_options()) as bar_bags, \
                    tqdm(total=_message_total(bags) or None, desc='slip: messages',
                         unit='msg', unit_scale=True, leave=False,
                         **bar_options()) as bar_msgs:
                pending = set(futs)
                while pending:
                    done, pending = wait(pending, timeout=0.25)
                    bar_bags.update(len(done))
                    while not queue.empty():
                        bar_msgs.update(queue.get_nowait())
            results.extend(fut.result() for fut in futs)
        except KeyboardInterrupt:
            # Ctrl-C: the bags not started are dropped and the running workers stopped,
            # not waited for (they kept going 14 s)
            # the workers are taken before shutdown, which sets ``_processes`` to None (a
            # Ctrl-C was reported as an AttributeError, exit 1: an outside review)
            procs = list((getattr(pool, '_processes', None) or {}).values())
            pool.shutdown(wait=False, cancel_futures=True)
            for proc in procs:
                proc.terminate()
            manager.shutdown()
            raise
        pool.shutdown()
        manager.shutdown()
    else:
        from hexapod_common.bags import message_progress

        with message_progress('slip: bag'):   # the messages of a long bag as they are read
            for b in tqdm(bags, desc='slip', unit='bag', **bar_options()):
                results.append(analyze_bag(b, options))
    stances = [s for r in results for s in r.get('stances', [])]
    # each stance's measured states and fit, for the fit-against-data figure (not in the JSON)
    traces = [t for r in results
              for t in (r.get('traces') or [None] * len(r.get('stances', [])))]
    skipped = [s for r in results for s in r.get('skipped', [])]
    rows = [{'gait': s['gait'], 'nerr': s['nerr'] if s['nerr'] is not None else math.nan,
             'nerr_world': s['nerr_world'] if s.get('nerr_world') is not None else math.nan,
             'power_w': s['power_w'] or math.nan, 'speed_mps': s['speed_mps'] or math.nan,
             'sr': s['sr'] or math.nan,
             'stiffness': s['stiffness'] if s.get('stiffness') is not None else math.nan,
             'rest_length': s['rest_length'] if s.get('rest_length') is not None
             else math.nan,
             'force_swing': s['force_swing'] if s.get('force_swing') is not None
             else math.nan,
             'other_nerr_ratio': _other_ratio(s),
             'nerr_noise_floor': s['nerr_noise_floor'] if s.get('nerr_noise_floor')
             is not None else math.nan} for s in stances]
    _note_rest_length_outliers(stances, [r['run'] for r in results if 'run' in r])
    # a run's result resting on an assumption its data contradict: a warning too
    warnings.extend(f"{r['bag']}: {w}" for r in results for w in r.get('run', {}).get(
        'warnings', []))
    doc = {'schema': 'slip/1', 'model': args.model, 'estimator': 'paper', 'starts': args.starts,
           'mass_kg': args.mass, 'stances': stances,
           'runs': [r['run'] for r in results if 'run' in r], 'gaits': gait_table(rows),
           'skipped': skipped, 'skipped_counts': dict(Counter(s['reason'] for s in skipped)),
           'failed_bags': [{'bag': r['bag'], 'error': r['error']} for r in results
                           if 'error' in r], 'warnings': warnings}
    from hexapod_common.outdir import write_text_atomic

    doc['plots'] = []
    # --no-plots: no figures; an earlier run's were set aside by run_command and are dropped
    # when this run finishes, so none is left beside this slip.json (as residuals --no-plots)
    if rows and not getattr(args, 'no_plots', False):   # figures first, the JSON last
        from .plots import plot_stance_fits

        source = data_source(doc['runs'])
        written = list(plot_figures(rows, out, mass_kg=args.mass, source=source) or [])
        written += plot_stance_fits(stances, traces, out, source=source, mass_kg=args.mass)
        for p in written:   # each PNG with the SVG beside it
            doc['plots'] += [q.name for q in (p, p.with_suffix('.svg'))
                             if q.is_file() and q.name not in doc['plots']]
    write_text_atomic(out / 'slip.json', json.dumps(json_safe(doc), indent=1, allow_nan=False))
    for f in doc['failed_bags']:
        print(f"slip: refused {f['bag']}: {f['error']}", file=sys.stderr)
    for w in warnings:
        print(f'slip: warning: {w}', file=sys.stderr)
    print(f'slip: {len(stances)} stances fitted, {len(skipped)} skipped, '
          f"{len(doc['failed_bags'])} bag(s) refused -> {out / 'slip.json'}")
    for r in doc['runs']:
        print(live_params_line(r))
    return 0 if len(doc['failed_bags']) < len(bags) else 2   # every bag refused: input


def add_cli(subparsers: Any) -> None:
    """Register the ``slip`` subcommand on an argparse subparsers object."""
    p = subparsers.add_parser('slip', help='per-stance SLIP fits (Komsuoglu et al.)',
                              description=__doc__,
                              formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument('bags', nargs='+', help='bags: rosbag2 folders (sqlite3 or mcap) or ROS 1 '
                   '.bag files')
    p.add_argument('--out', required=True, help='output folder')
    p.add_argument('--jobs', type=int, default=1, help='bags analysed in parallel')
    p.add_argument('--offset', default='auto',
                   help="mocap clock offset [s], or 'geometry' (offset and ground height fitted "
                        "to the body's vertical dynamics with the half-circle legs' geometric "
                        "contacts), 'contact' (touchdowns from hip-effort onsets against body "
                        "height, median), 'joint' (one offset fitted over all stances' body "
                        "heights, touchdowns fixed at the effort onsets), 'xcorr' "
                        "(cross-correlation), 'auto' (geometry when the bag has hip angles and "
                        '--geometry is set, else contact/joint with efforts, else xcorr)')
    p.add_argument('--edges', choices=('auto', 'geometry', 'paper', 'effort'), default='auto',
                   help="stance edges: 'geometry' (hip below the leg's rest height, single "
                        "support), the paper's shifted clock edges, touchdown refined to the "
                        "hip-effort onset; 'auto': geometry when possible, else paper (the "
                        "paper's edges are always in runs[].paper_edges)")
    p.add_argument('--body-up', choices=('auto', 'z', 'x', 'y', '-x', '-y', '-z'),
                   default='auto',
                   help="the motion-capture rigid body's axis that points up (default auto: z, "
                        'and a run whose COM bounces across z rather than along it is refused '
                        'naming the up axis; z: z without that check). The rigid body\'s '
                        'forward axis does not matter: the pitch is the up axis\'s tilt towards '
                        'the run')
    p.add_argument('--pitch-offset', default='auto', type=_pitch_offset_arg, metavar='DEG',
                   help="the correction added to the motion-capture rigid body's pitch [deg] "
                        'so that it reads 0 while the robot\'s hips are level: minus the '
                        'pitch (nose down positive) it reports then; known and kept, not '
                        "checked. 'auto' (default): 0, and a correction fitted beside it kept "
                        'when the body-height fit clearly prefers it (runs[].frame.'
                        'pitch_offset_deg, a note). Needs --geometry')
    p.add_argument('--geometry', choices=('edubot', 'none'), default='edubot',
                   help="robot description for the geometric edges/offset: 'edubot' "
                        '(slip_identification.geometry.LegGeometry defaults, fields overridden by '
                        '--leg-radius/--hip-x/--hip-z/--hip-zero for another robot) or none')
    p.add_argument('--leg-radius', type=float, default=None, metavar='M',
                   help='half-circle leg arc radius R [m] (hip-to-toe chord 2R; EduBot 0.0525)')
    p.add_argument('--hip-x', type=float, nargs=3, default=None,
                   metavar=('FRONT', 'MIDDLE', 'REAR'),
                   help='hip positions along the body axis from the COM [m] (EduBot 0.2 0 -0.2)')
    p.add_argument('--hip-z', type=float, default=None, metavar='M',
                   help='hip height above the tracked body point [m] (EduBot 0)')
    p.add_argument('--hip-zero', type=float, default=None, metavar='RAD',
                   help='leg angle from the body\'s downward axis at hip angle 0 [rad] (EduBot 0)')
    p.add_argument('--leg-damping-time', default='default',
                   help="leg radial damping over stiffness [s] for the geometric fit, 'fit' "
                        "to fit it, or 'default' (the EduBot description's; fitted when "
                        "another robot's legs are given with --leg-radius/--hip-x/...)")
    p.add_argument('--offset-lag', type=float, default=0.0,
                   help="physical lag removed from the 'auto' offset [s]")
    p.add_argument('--max-lateral', type=float, default=0.05,
                   help='straight-run limit on lateral deviation [m]')
    p.add_argument('--box', type=float, nargs=6, metavar=('X0', 'Y0', 'Z0', 'X1', 'Y1', 'Z1'),
                   help='permissible box in the mocap frame [m] (default 2 x 1 x 1 m)')
    p.add_argument('--mass', type=_positive_kg, default=None,
                   help=f'robot mass [kg], > 0 (default EduBot\'s {EDUBOT_MASS_KG:g} kg, with '
                        'a warning: P, SR and the Table 3 comparison scale with it)')
    p.add_argument('--model', default='slip', help="'slip' or 'slip+leg_damping' etc.")
    p.add_argument('--starts', choices=('multi', 'paper'), default='multi',
                   help="the SLIP-measure's Nelder-Mead starts: multi (default; the paper's "
                        "(2000 N/m, 0.15 m) and two from the stance's own duration and leg "
                        "length, the lowest nerr kept: the paper defines the measure as the "
                        "minimum) or paper (its start alone, as the paper computed it; it "
                        'can stop in a local minimum). The position fit takes the same '
                        'starts, keeping the lowest residual sum of squares')
    p.add_argument('--no-position-fit', action='store_true',
                   help='skip the second estimator (initial state free)')
    p.add_argument('--gravity', choices=('ground', 'mocap'), default='ground',
                   help="gravity's direction for the SLIP fits: normal to the fitted ground "
                        "(default: a level floor, whatever the mocap frame's tilt) or along "
                        "the mocap frame's -z (a mocap levelled to gravity: a sloped ground's "
                        'along-ground gravity is then in the model)')
    p.add_argument('--steady-only', action='store_true',
                   help="skip stances before the steady state (reason 'transient'; the body "
                        'pitch repeats from one clock period to the next)')
    p.add_argument('--no-edge-pooling', action='store_true',
                   help='geometry edges from each stride alone: steady-state edges are '
                        'otherwise shrunk toward the same leg\'s at other strides as far as '
                        'the height noise leaves them undetermined (a study of stride-to-'
                        'stride variability wants them alone)')
    p.add_argument('--no-plots', action='store_true',
                   help="skip the figures: slip.json alone, its 'plots' []; an earlier run's "
                        'figures in --out are removed all the same')
    p.set_defaults(func=run_command)


#: a stance whose rest length is further than this factor from its gait's median is named
REST_LENGTH_OUTLIER = 1.5


def _note_rest_length_outliers(stances: list[dict[str, Any]], runs: list[dict[str, Any]]
                               ) -> None:
    """Name, in each run's notes, the stances whose fitted rest length lies more than
    :data:`REST_LENGTH_OUTLIER` times from their gait's median: when the body height barely
    changes (a walk), stiffness and rest length trade off along ``k (l0 - l) = m g``, and a
    soft long spring (the demo's walk: 340 N/m and 0.197 m beside 2,400 N/m and 0.11 m) fits
    as well; such a fit converges, and only its standard errors show it."""
    by_gait: dict[str, list[float]] = {}
    for s in stances:
        if s.get('rest_length') is not None and math.isfinite(s['rest_length']):
            by_gait.setdefault(s['gait'], []).append(float(s['rest_length']))
    far: dict[str, list[dict[str, Any]]] = {}
    for s in stances:
        vals = by_gait.get(s['gait'], [])
        if len(vals) < 4 or s.get('rest_length') is None:
            continue
        med = float(np.median(vals))
        ratio = s['rest_length'] / med if med > 0 else math.nan
        if not (1 / REST_LENGTH_OUTLIER <= ratio <= REST_LENGTH_OUTLIER):
            far.setdefault(str(s['bag']), []).append(s)
    for run in runs:
        bad = far.get(str(run.get('bag')))
        if not bad:
            continue
        med = float(np.median(by_gait[bad[0]['gait']]))
        run.setdefault('notes', []).append(
            f"{len(bad)} stance(s) fitted a rest length far from the gait's median "
            f"({med:.4f} m): " + ', '.join(
                f"t = {s['touchdown']:.3f} s l0 {s['rest_length']:.4f} m, k "
                f"{s['stiffness']:.0f} N/m" for s in bad)
            + ' (stiffness and rest length trade off when the body height barely changes: '
            'a soft long spring fits as well; the gait table gives medians)')


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry: ``python -m slip_identification.cli BAG... --out DIR``."""
    ap = NumberArgumentParser(prog='hexapod-analyze')
    sub = ap.add_subparsers(dest='command', required=True)
    add_cli(sub)
    args = ap.parse_args(['slip'] + (argv if argv is not None else __import__('sys').argv[1:]))
    return int(args.func(args))


if __name__ == '__main__':
    raise SystemExit(main())
