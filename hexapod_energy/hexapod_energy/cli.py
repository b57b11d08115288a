"""``hexapod-analyze energy``: offline energetics of bench and robot bags.

Usage::

    hexapod-analyze energy [--bench BAG [BAG ...]] [--robot BAG [BAG ...]] --out DIR
                           [--sweep] [--recommend --speed V --payload KG]
                           [--legs N] [--limits MIN_SWING_S MIN_STANCE_S MAX_FREQ_HZ]
                           [--robot-speed V] [--gait NAME --duty-factor B --step-length M]

Steps: bench bags -> per-session phase powers -> surface fits (LOWESS vs polynomial by k-fold
CV); robot bags -> measured whole-cycle P_in, P_out (joint efforts, else the Eq. 6 model), speed
-> Eq. 1 prediction for the same gait and mass; ``--sweep`` -> Fig. 3 sweeps (four-quadrant
plots, PNG + SVG) and the Fig. 7D power map; ``--recommend`` -> minimum-CoT/M gait.

Bench bags recorded without ``/bench/session`` (another lab's bench, one bag per session) are
given with ``--bench-sessions CSV`` (columns ``bag,load_kg[,frequency_hz,duty_factor,
step_length_m,step_height_m]``, :func:`hexapod_energy.bag_io.read_bench_sessions_file`);
they are read as one bench when their times do not overlap by more than a sample step
(:func:`hexapod_energy.bag_io.merge_bench_data`; else one by one, a warning).

The bench leg on a ``/gait/phase`` of several legs (the project's ``gait_scheduler`` has no
one-leg mode): ``--bench-leg NAME``, else the one leg ``/joint_states`` names; unknown, the
phases are split by contact with a warning. A session whose ``/gait/phase`` walked another
frequency than its label is analysed at the walked one, with a warning naming it. Too few
walking sessions for the surface fits (5 with 5 folds,
:meth:`hexapod_energy.single_leg.SingleLegModel.min_walking_sessions`): ``energy.json`` gets
the sessions' phase powers (``bench.sessions``) and the refusal (``errors``), exit 2.

``--sweep`` and ``--recommend`` are for the robot described: its mass (``--robot-mass``, else
the robot bags' metadata (``robot_mass_kg``, as ``hexapod-sim robot`` records it; bags declaring
different masses are refused), else AntBot's 2.183 kg with a warning), its leg (``--leg``), its
leg count (``--legs N``, else the robot bags' gaits or joint names, else 6 with a warning) and
its actuator limits (``--limits``, measured on the bench's step of the robot's leg; default
AntBot's servo limits, measured on AntBot's leg at 100 mm: swing >= 0.16 s, stance >= 0.15 s,
step frequency <= 3 Hz; each step is scaled by its joint path on the robot's leg against the
path the limits were measured on, :mod:`hexapod_gait.step_limits`).  The duty-factor,
step-length and gait-type sweeps use the robot's leg count, the leg-count sweep 4, 6 and 8 legs
(Fig. 3D), the power map the robot's alternating gait (tripod for 6 legs), beta 0.5, 100 mm;
``sweep_settings`` records what was held fixed.  A curve the leg cannot walk (a step out of its
reach) is skipped with a warning naming the sweep and the curve.  A robot not heavier than its
legs (``M <= N m_leg``) is refused.

Without ``--bench`` (a robot but no single-leg bench) the robot runs get their measured
descriptors only: ``bench`` and every ``predicted_power_in_w`` are null and
``prediction_error`` is absent; ``--sweep`` and ``--recommend`` need the bench surfaces.

Robot bags without ``/gait/phase`` (another lab's robot running its own gait code: only
``/joint_states`` and ``/battery_state``, maybe ``/odom`` or ``/mocap/body``): the whole cycles
come from the joint positions (step period by autocorrelation, :mod:`hexapod_energy.cycles`);
the speed from ``/mocap/body``, else ``/odom`` (nav_msgs/Odometry), else ``--robot-speed V``,
else null; P_out from the joint efforts, else null (the Eq. 6 model needs the gait); the Eq. 1
prediction needs the gait: ``--gait NAME --duty-factor B --step-length M`` describe it (leg count
from joint names that follow ``L1..Lk``/``R1..Rk`` + ``_<joint>``, else ``--legs N``; period from
the joints), else the run has no prediction and is left out of ``prediction_error``.  Every
such fallback is listed in the run's ``notes``.

``energy.json`` schema (version 1; keys are a contract, units in the names or below)::

    {
      "schema": "hexapod_energy.energy/1",
      "leg": {"name", "a_m", "alpha_rad", "d_m", "theta_offset_rad", "link_masses_kg",
              "neutral_tip_m"} (the leg of the Eq. 6 output-power model and of the carried
              mass: --leg FILE, default AntBot; hexapod_energy.leg_description),
      "bench": {"bags": [...], "diagnostics": [{"bag", "force_offset_s", "current_sign",
                "force_sign" (+1, or -1: force.z negated, see --force-sign),
                "phase_split" (schedule | contact | mixed: --phase-split),
                "sessions", "notes" (dropped messages), "warnings" (also in the top-level
                "warnings": a several-leg /gait/phase whose bench leg is not identified, a
                session whose /gait/phase walked another frequency than it is labelled,
                bag_io.bench_phase_samples)}],
                "fit": {"spans", "chosen": {"stance", "swing"},
                "cv_rmse_w": {"stance": {"lowess", "poly", "poly3"}, "swing": {...}},
                "surfaces": {"stance"|"swing": {"kind" (poly | poly3: "coef", "terms"
                over f = 1 / T_phase [Hz] and m = load [kg]; lowess: "span")}} (the chosen
                surfaces), "step_geometry_m": {"step_length",
                "step_height"} (the bench leg's step),
                "fit_rmse_w": {"stance", "swing"}, "basal_power_w": {"<load kg>": W},
                "domain": {"stance"|"swing": {"rate_hz": [lo, hi], "load_kg": [lo, hi]}}
                (the sessions' range; rate = 1 / T_phase),
                "sessions": [PhaseSample fields: p_stance_w and p_swing_w are each
                phase's energy per cycle over its nominal duration, beta T and (1 - beta) T,
                so beta p_stance_w + (1 - beta) p_swing_w is the session's mean power
                whatever fraction the force contact covered; single_leg.phase_powers]}
                (a refused fit, too few walking sessions: "fit" null, "sessions" [PhaseSample
                fields] beside it, "fit_error" [str], and the top-level "errors"; exit 2)},
      "robot_runs": [{"bag", "gait", "leg_count", "duty_factor", "period_s", "step_length_m",
                      "step_height_m", "payload_kg", "mass_kg", "windows" (whole gait
                      cycles averaged), "window_s" (their summed length [s], not one
                      window's), "measured_power_in_w", "predicted_power_in_w",
                      "residual_w" (measured - predicted; prediction_error's bias_w has
                      the opposite sign, predicted - measured),
                      "power_breakdown_w": {"stance_w", "swing_w" (Eq. 1's phases),
                      "holding_w" (every leg's bench basal power at the load it carries),
                      "stance_motion_w", "swing_motion_w" (what moving adds),
                      "predicted_w", "measured_w", "unmodelled_w" (measured - predicted),
                      "holding_share" (holding / measured), "holding_missing" (why
                      the holding split is null: no 0 Hz bench session)} or null without
                      a prediction
                      (where the watts go; plot where_the_watts_go.png),
                      "prediction_outside_bench" [str] (where Eq. 1 read the surfaces
                      beyond the bench's sessions; empty inside; also a warning),
                      "power_out_w", "power_out_source" ("effort" | "model" | "none";
                      --power-out), "power_out_effort_w" (nan/null without efforts),
                      "power_out_model_w", "efficiency", "speed" [m/s],
                      "cost_of_transport" [J/m], "specific_cost_of_transport" [J/(m kg)]
                      (power_out_w, efficiency and both costs of transport, which use
                      P_in - P_out, are null when P_out is unknown: source "none"),
                      "specific_resistance", "cycle_source" ("gait_phase" | "joints"),
                      "speed_source" (mocap | odometry | odometry_twist | gait_schedule |
                      given | none; the windows' sources joined by '+' when they differ,
                      e.g. "mocap+none": mocap where it tracked, no speed elsewhere),
                      "speed_span": {"windows", "window_s", "power_in_w", "power_out_w"}
                      (the windows with a known speed, when only some have one: both costs
                      of transport and the specific resistance are over these) or null,
                      "power_in_trend": {"span_s", "windows", "bin_time_s",
                      "bin_power_in_w" (medians of the windows' tenths), "first_w",
                      "last_w", "change_w", "change_fraction", "change_sigma_w", "drift"
                      (bool; a drift is also a note and a warning)} or null under 30
                      windows or 30 s (hexapod_energy.trend; plot power_in_over_time.png),
                      "notes" [str] (this run's input fallbacks),
                      "segment": {"index", "of", "t_start_s", "t_end_s"} (a bag whose
                      /gait/phase changes walking schedule gives one run per schedule;
                      without /gait/phase, one per joint-derived step period)}],
      "prediction_error": {"runs" (runs with a prediction), "rmse_w", "mae_w",
                           "bias_w" (mean predicted - measured),
                           "mean_power_w", "relative_rmse", "max_abs_relative"},
      "sweeps": {"<sweep name>": [SweepCurve.to_dict()]},     # with --sweep; each curve's
                  # "outside_bench" (n_speed x n_payload bool) marks extrapolated points
                  # (dotted in the plots), "outside_bench_reasons" says how; a curve the
                  # leg cannot walk is left out (listed in sweep_settings "skipped");
                  # "not_walkable" names a whole side in swing ('' when none: the paper's
                  # wave at beta 0.5, Fig. 3C, is kept and drawn); "optimal_points"
                  # {"max_power_out", "min_cot_per_mass", "max_efficiency"}: each
                  # {"speed_mps", "value", "unit" (W, J/(m kg), fraction), "outside_bench"};
                  # "min_efficiency" (every point) with "min_efficiency_speed_mps",
                  # "min_efficiency_payload_kg" and "min_efficiency_outside_bench" (that
                  # point extrapolated), "min_efficiency_on_bench" (the points the bench
                  # covers; null: none) with "min_efficiency_on_bench_speed_mps" and
                  # "min_efficiency_on_bench_payload_kg"
      "sweep_settings": {"robot_mass_kg" (payload excluded), "leg_count",
                  "leg_count_source" (--legs | robot bags | assumed), "payloads_kg",
                  "load_offset_kg", "limits": {"min_swing_s", "min_stance_s",
                  "max_step_frequency_hz"}, "limits_source" (AntBot's servo limits, or
                  --limits), "held_fixed": {"<sweep name>": str}, "skipped" [str],
                  "plot_nominal_payload_kg": {"<sweep name>": kg} (the payload of the
                  four-quadrant plot's solid curves and markers: 0.14 for gait_type, the
                  paper's Fig. 3C load; the curves' "optimal_points" are at their first
                  payload), "plot_optimal_points": {"<sweep name>": [{"label",
                  "payload_kg", "optimal_points"}]} (the plot's markers, for a plot whose
                  nominal payload is not the sweep's first: gait_type)},
                                                              # with --sweep
      "gait_type_comparison": {"base", "other" (curve labels: the alternating gait at beta
                  0.5, the wave gait at its typical duty factor), "speeds_mps",
                  "payloads_kg", "ratio" (n_speed x n_payload: CoT/M other / base, below 1
                  where the wave is cheaper), "outside_bench" (either curve extrapolated),
                  "below_one_until_mps" [per payload, null: never cheaper], "best_ratio",
                  "best_speed_mps", and the same on the points the bench covers for both
                  curves: "below_one_until_mps_on_bench", "best_ratio_on_bench",
                  "best_speed_mps_on_bench" (null: never cheaper there / no such point)},
                  # with --sweep; plot gait_type_comparison.png (four_quadrant_gait_type.png
                  # draws its solid curves at the paper's 140 g, the band 0-500 g)
      "power_map": {"speeds_mps", "payloads_kg", "power_out_w" (n_speed x n_payload),
                    "seconds", "gait", "leg_count", "duty_factor",
                    "step_length_m"},                         # with --sweep
      "recommendation": Recommendation.to_dict() + {"leg_count_source",
                  "limits_source"},                           # with --recommend; only
                  # configurations inside the bench's domain unless none is ("note"); it
                  # records "leg_count", "robot_mass_kg", "mass_kg" (with payload), "limits"
      "options": {option: value} (the options of this analysis once resolved: robot_mass
                  is the mass used, see robot_mass's source; bag paths as given),
      "robot_mass": {"kg" (payload excluded: CoT, CoT/M, specific resistance, the Eq. 6
                  model and the sweeps use it), "source" (--robot-mass | bags' metadata
                  (robot_mass_kg in their custom data, as hexapod-sim records it) |
                  assumed (AntBot) | assumed (AntBot's body with the --leg file's legs),
                  with a warning), "note" (with the bags' metadata)},
      "warnings": [str],                                      # when any
      "errors": [str],     # the analysis refused after the bench's phase powers were
                           # written (the surface fit: too few walking sessions); exit 2
      "failed_bags": [{"bag", "error"}],   # robot bags refused (the others are analysed;
                                           # all refused: exit 2)
      "plots": [relative paths]
    }

``power_out_w`` everywhere is the mean *positive* joint power (servos do not regenerate; see
:mod:`hexapod_energy.dynamics`), the definition the ``energy_monitor`` node uses too.

Exit codes: 0 success, 2 input refused (missing topic, bad option, nothing analysable), 1 an
unforeseen failure (a bug), 130 interrupted.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys
import time
import types
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hexapod_energy.descriptors import (
    MAX_SPEED_MPS,
    VELOCITY_UNITS_NOTE,
    ZERO_EFFORT_NOTE,
    gait_from_sample,
    implausible_effort_power,
)
from hexapod_common.cli_args import NumberArgumentParser
from hexapod_common.conversions import LEG_JOINT_RE
from hexapod_energy.descriptors import MODEL_LEG_JOINTS, model_leg_mismatch
from hexapod_common.jsondoc import json_safe
from hexapod_energy.errors import EnergyError, FitError, InvalidInputError
from hexapod_energy.trend import TREND_MIN_SPAN_S, TREND_MIN_WINDOWS, power_in_trend, trend_note
from hexapod_gait.kinematics import ANTBOT_MASS_KG  # the default robot's mass

__all__ = ['add_cli', 'build_parser', 'gait_from_sample', 'main', 'run']



#: a run's note when its legs are not the Eq. 6 model's (model_leg_mismatch)
NO_MODEL_LEG_NOTE = 'no Eq. 6 P_out model: its leg'


def _leg_count(args: argparse.Namespace, run_: Any) -> int | None:
    """Legs of a run without /gait/phase: ``--legs``, else counted from joint names that
    follow the contract (``L1..Lk``/``R1..Rk`` + ``_<joint>``), else None."""
    names = list(run_.extra.get('joint_names', []))
    matches = [LEG_JOINT_RE.match(n) for n in names]
    # other joints beside contract legs (a gripper) are left out, not a reason for None
    found = len({m.group(1) + m.group(2) for m in matches if m}) \
        if names and any(matches) else None
    if getattr(args, 'legs', None):
        if found is not None and found != int(args.legs):
            # --legs used to override the names silently (6 contract legs read as 4:
            # 24.1 W predicted for 35.1 W)
            raise EnergyError(
                f'--legs {args.legs}, but the joint names of {run_.path} give {found} legs '
                f'({", ".join(names[:4])}{", ..." if len(names) > 4 else ""}); --legs is for '
                'joint names that do not follow L1..Lk/R1..Rk_<joint>')
        return int(args.legs)
    return found


def add_given_gait_arguments(p: argparse.ArgumentParser, purpose: str,
                             legs_help: str | None = None) -> None:
    """``--gait``, ``--duty-factor``, ``--step-length`` and ``--legs``: the gait of robot bags
    without /gait/phase (another lab's gait code; ``energy`` and ``residuals``); ``legs_help``
    replaces ``--legs``'s help (``energy`` uses it for ``--sweep``/``--recommend`` too)."""
    p.add_argument('--gait', default=None, metavar='NAME',
                   help=f'gait of robot bags without /gait/phase, {purpose} (hexapod_gait '
                        'name: tripod, alternating, wave, ripple, tetrapod; with --duty-factor '
                        'and --step-length; cycles and period from the joint positions, leg '
                        'count from the joint names)')
    p.add_argument('--duty-factor', type=float, default=None, metavar='B',
                   help='duty factor of robot bags without /gait/phase (with --gait)')
    p.add_argument('--step-length', type=float, default=None, metavar='M',
                   help='step length of robot bags without /gait/phase [m] (with --gait)')
    p.add_argument('--step-height', type=float, default=None, metavar='M',
                   help='step height (lift) of robot bags without /gait/phase [m] (with '
                        '--gait; default the bench\'s, else 0.04): Eq. 1 maps another lift '
                        'onto the bench\'s path')
    p.add_argument('--legs', type=int, default=None, metavar='N',
                   help=legs_help or
                   'leg count of robot bags without /gait/phase whose joint names do not '
                   'follow L1..Lk/R1..Rk_<joint> (with --gait; default: from the names)')


class FitRefused(EnergyError):
    """The bench surface fit refused after ``energy.json`` got the sessions' phase powers
    (``bench.sessions``, ``errors``): exit 2, the file kept."""

    def __init__(self, message: str, warnings: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.warnings = list(warnings)


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--bench', nargs='*', default=[], metavar='BAG',
                   help='bench bags (MiMiC-Ant single-leg sessions); without them robot runs '
                        'get their measured descriptors but no Eq. 1 prediction')
    p.add_argument('--bench-sessions', default=None, metavar='CSV',
                   help='bench bags recorded without /bench/session (one bag per session): a '
                        'CSV with columns bag,load_kg[,frequency_hz,duty_factor,step_length_m,'
                        'step_height_m]; '
                        'an empty frequency comes from /gait/phase or the leg tip\'s period')
    p.add_argument('--bench-leg', default=None, metavar='NAME',
                   help='the bench leg\'s name on a /gait/phase of several legs (the '
                        'project\'s gait_scheduler publishes six); default: the one leg '
                        'whose coxa, femur and tibia joints are on /joint_states (unknown: '
                        'stance and swing split by contact, with a warning)')
    p.add_argument('--robot', nargs='*', default=[], metavar='BAG',
                   help='robot bags to compare with the Eq. 1 prediction')
    p.add_argument('--out', required=True, metavar='DIR', help='output folder')
    p.add_argument('--sweep', action='store_true',
                   help='run the Fig. 3 sweeps and the Fig. 7D power map, with plots, for the '
                        'robot described (--robot-mass, --leg, --legs, --limits): duty factor '
                        '0.5-0.8 (100 mm steps), step length 70-140 mm (beta 0.5) and gait type '
                        '(alternating/tripod 0.5, wave at 1 - 1/N and at 0.5) at the robot\'s '
                        'N legs; leg count 4/6/8 (alternating, beta 0.5, 100 mm); power map: '
                        'alternating (tripod for 6 legs), beta 0.5, 100 mm, N legs; payload '
                        '0-0.5 kg (energy.json "sweep_settings")')
    p.add_argument('--recommend', action='store_true',
                   help='recommend the gait minimising CoT/M at --speed and --payload for the '
                        'robot described (--robot-mass, --leg, --legs, --limits)')
    p.add_argument('--speed', type=float, default=None, metavar='V',
                   help='target speed for --recommend [m/s]')
    p.add_argument('--payload', type=float, default=0.0, metavar='KG',
                   help='payload for --recommend [kg] (default 0)')
    p.add_argument('--robot-mass', type=float, default=None, metavar='KG',
                   help='robot mass without payload [kg] (default: the robot bags\' '
                        'declared robot_mass_kg, as hexapod-sim records it, else 2.183, '
                        'AntBot, with a warning: CoT/M and specific resistance scale with it)')
    p.add_argument('--leg', default=None, metavar='FILE',
                   help="the robot's leg for the Eq. 6 output-power model and the carried "
                   'mass: a YAML/JSON file with a_m, link_masses_kg, neutral_tip_m (DH table, '
                   'link masses, stance pose; hexapod_energy.leg_description); default AntBot')
    p.add_argument('--robot-payload', type=float, default=None, metavar='KG',
                   help='payload of the robot runs [kg] (default: from the bag metadata, '
                        'else 0)')
    p.add_argument('--current-sign', choices=('ros', 'positive_discharge', 'auto'),
                   default='auto', help='battery current sign convention (default auto)')
    p.add_argument('--phase-split', choices=('auto', 'schedule', 'contact'), default='auto',
                   help="how bench samples are labelled stance or swing: 'contact' (the "
                        "paper's: normal force above a threshold and the tip low), "
                        "'schedule' (the bench leg's commanded stance on /gait/phase, the "
                        "timeline Eq. 1 composes the phases on), 'auto' (default: the "
                        "schedule where the bag has it, else the contact)")
    p.add_argument('--force-sign', choices=('auto', 'positive', 'negative'), default='auto',
                   help='sign of the bench force in compression (default auto: decided from '
                        'the 0 Hz sessions against the walking ones, a flip noted)')
    p.add_argument('--swing-load', choices=('zero', 'carried'), default='zero',
                   help='load of a swinging leg in Eq. 1 (default zero)')
    p.add_argument('--load-offset', type=float, default=0.0, metavar='KG',
                   help='subtract KG from the carried mass m_c before reading the bench '
                        'surfaces (default 0, the paper\'s convention: a robot\'s stance tip '
                        'carries M g / L, the bench tip (m_leg + load) g); use KG for a bench '
                        'whose tip carries an extra stage mass, or a robot model whose stance '
                        'tips carry only m_c g')
    p.add_argument('--limits', type=float, nargs=3, default=None,
                   metavar=('MIN_SWING_S', 'MIN_STANCE_S', 'MAX_FREQ_HZ'),
                   help='actuator limits: shortest swing [s], shortest stance [s] (measured '
                        'on the bench\'s step of the robot\'s leg, --leg; other steps and legs '
                        'scale with their joint path), highest step frequency [Hz] (default '
                        'AntBot\'s servo limits 0.16 0.15 3, measured on AntBot\'s leg at '
                        '100 mm); they set the sweeps\' maximum speeds, the gaits --recommend '
                        'may choose, and the infeasible-schedule warning of robot runs')
    p.add_argument('--power-out', choices=('auto', 'effort', 'model'), default='auto',
                   help='P_out source: joint effort x velocity (positive part), the Eq. 6 '
                        'inverse-dynamics model, or auto (default: effort when the bag has '
                        'efforts and they give P_out < P_in, else the model, with a warning)')
    p.add_argument('--robot-speed', type=float, default=None, metavar='V',
                   help='speed of robot runs that have no /gait/phase, /mocap/body or /odom '
                        '[m/s] (default: unknown, CoT and specific resistance null)')
    add_given_gait_arguments(
        p, 'for the Eq. 1 prediction and the P_out model',
        legs_help='leg count of the robot: of robot bags without /gait/phase whose joint names '
                  'do not follow L1..Lk/R1..Rk_<joint> (with --gait), and of the robot --sweep '
                  'and --recommend describe (default: from the robot bags\' gaits or joint '
                  'names, else 6, AntBot\'s, with a warning)')
    p.add_argument('--folds', type=int, default=5, help='k of the k-fold CV (default 5)')
    p.add_argument('--no-progress', action='store_true', help='hide the progress bar')


def add_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``energy`` subcommand on ``hexapod-analyze``'s subparsers."""
    p = subparsers.add_parser(
        'energy', help='energetics of bench and robot bags (Brodoline et al. 2024)',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_arguments(p)
    p.set_defaults(func=_handler)
    return p


def _net_joint_power_w(run_: Any) -> float:
    """Window-weighted mean net (signed) joint power of a robot run [W] (NaN without)."""
    wins = [d for d in run_.extra.get('windows', ()) if math.isfinite(d.joint_power_net_w)]
    if not wins:
        return math.nan
    w = np.array([d.window_s for d in wins])
    return float(np.sum(w * np.array([d.joint_power_net_w for d in wins])) / np.sum(w))


def build_parser() -> argparse.ArgumentParser:
    """Stand-alone parser (same options as ``hexapod-analyze energy``)."""
    p = NumberArgumentParser(prog='hexapod-analyze energy', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_arguments(p)
    return p


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Carry out the analysis; returns the ``energy.json`` document (also written). An
    earlier run's result in ``--out`` is kept when this one fails or is interrupted
    (:func:`hexapod_common.outdir.replacing_outputs`); a refused bench fit is a result."""
    from hexapod_common.outdir import replacing_outputs

    with replacing_outputs(args.out, 'energy.json', keep=(FitRefused,)):
        return _run(args)


@dataclasses.dataclass
class _Setup:
    """The checked inputs of one ``energy`` run (:func:`_checked_setup`)."""

    bench_bags: list[tuple[str, Any]]   # (path, session spec or None)
    leg: Any                            # the leg description (``--leg`` or AntBot's)
    robot: Any                          # :class:`hexapod_energy.prediction.RobotSpec`
    limits: Any
    limits_source: str
    robot_speed: float | None
    mass_given: bool
    mass_warning: str
    mass_note: str = ''                 # the mass taken from the robot bags' metadata
    mass_source: str = '--robot-mass'   # energy.json "robot_mass" "source"


def _checked_setup(args: argparse.Namespace) -> _Setup:
    """Refuse bad options up front (before any bag is read) and gather what the run uses;
    fills ``args.robot_mass`` with AntBot's when not given."""
    from hexapod_energy.bag_io import read_bench_sessions_file
    from hexapod_energy.leg_description import antbot_leg, load_leg_description
    from hexapod_energy.prediction import RobotSpec, load_offset_problem

    if getattr(args, 'folds', 5) < 2:
        raise EnergyError(f'--folds must be >= 2 (k-fold cross-validation), got {args.folds}')
    if args.recommend and (args.speed is None or not (math.isfinite(args.speed) and
                                                      args.speed > 0)):
        raise EnergyError(f'--recommend needs --speed V with V > 0 [m/s], got {args.speed}')
    if not math.isfinite(getattr(args, 'load_offset', 0.0)):
        raise EnergyError(f'--load-offset must be finite, got {args.load_offset}')
    specs = read_bench_sessions_file(args.bench_sessions) \
        if getattr(args, 'bench_sessions', None) else {}
    bench_bags = [(str(b), None) for b in args.bench] + list(specs.items())
    if not bench_bags and not args.robot:
        raise EnergyError('nothing to analyse: give --bench BAG... and/or --robot BAG...')
    if not bench_bags and (args.sweep or args.recommend):
        raise EnergyError('--sweep and --recommend need the bench surfaces: give --bench BAG...')
    given_gait = [getattr(args, k, None) for k in ('gait', 'duty_factor', 'step_length')]
    if any(v is not None for v in given_gait) and any(v is None for v in given_gait):
        raise EnergyError('--gait, --duty-factor and --step-length go together (the gait of '
                          'robot runs without /gait/phase)')
    if given_gait[2] is not None and not (math.isfinite(args.step_length) and
                                          args.step_length > 0):
        # 0 was read as a Buehler clock (no prediction) without naming the option
        raise EnergyError(f'--step-length must be > 0 m, got {args.step_length}')
    robot_speed = getattr(args, 'robot_speed', None)
    if robot_speed is not None and not (math.isfinite(robot_speed) and
                                        0 < robot_speed <= MAX_SPEED_MPS):
        # 1e9 m/s was taken (SR 1.6e-9)
        raise EnergyError(f'--robot-speed must be in (0, {MAX_SPEED_MPS:g}] m/s, got '
                          f'{robot_speed}')
    leg = load_leg_description(args.leg) if getattr(args, 'leg', None) else antbot_leg()
    from hexapod_energy.bag_io import resolve_robot_mass

    # a simulated robot of another leg count records its mass: AntBot's was assumed
    # with --leg, AntBot's body with the file's legs (the simulators' rule: 2.183 kg was
    # assumed for a robot of PhantomX-like legs that sim_robot walks as 2.237 kg)
    leg_given = bool(getattr(args, 'leg', None))
    legs_n = getattr(args, 'legs', None)
    mass = resolve_robot_mass(
        args.robot_mass, args.robot or [],
        leg_mass_kg=leg.spec.leg_mass_kg if leg_given else None,
        leg_count=legs_n if isinstance(legs_n, int) and legs_n >= 2 else 6)
    args.robot_mass, mass_source, mass_note = mass.kg, mass.source, mass.note
    # a declared mass is a given one (the bench's loads are checked against it)
    mass_given = not mass.assumed
    mass_warning = ''
    if mass.assumed and (args.robot or args.sweep or args.recommend):
        whose = (f"AntBot's {ANTBOT_MASS_KG} kg" if not leg_given else
                 f"AntBot's body with the --leg file's {leg.spec.leg_mass_kg:.3f} kg legs, "
                 f'{mass.kg:.3f} kg')
        mass_warning = (f'robot mass not given (--robot-mass): {whose} '
                        'assumed; CoT, CoT/M and specific resistance scale with the mass')
    if not (math.isfinite(args.robot_mass) and args.robot_mass > 0):
        raise EnergyError(f'--robot-mass must be > 0 kg, got {args.robot_mass}')
    if args.robot_mass > ROBOT_MASS_MAX_KG:
        # 3200 (grams) was taken as kg: SR 0.00717 and CoT/M 0.0557, 1000x low
        raise EnergyError(
            f'robot mass {args.robot_mass:g} kg ({mass_source}) is above {ROBOT_MASS_MAX_KG:g} '
            'kg, more than a legged robot this method is for (its legs on a single-leg bench '
            'of at most 50 kg each): it looks like grams. --robot-mass is kilograms '
            f'({args.robot_mass:g} g is {args.robot_mass / 1000:g} kg)')
    for flag, value in (('--payload', args.payload),
                        ('--robot-payload', getattr(args, 'robot_payload', None))):
        # a negative or NaN payload gave a lighter robot (or NaN descriptors) and a 1e9 kg
        # one a 932 MW "recommendation", with exit 0
        if value is not None and not (math.isfinite(value) and value >= 0):
            raise EnergyError(f'{flag} must be >= 0 kg, got {value}')
        if value is not None and value > 10 * args.robot_mass:
            raise EnergyError(f'{flag} {value:g} kg is over 10 times the robot\'s '
                              f'{args.robot_mass:g} kg: not a load its legs can carry')
    robot = RobotSpec(mass_kg=args.robot_mass, leg=leg.spec)
    limits, limits_source = _actuator_limits(
        args, leg if getattr(args, 'leg', None) else None)
    if getattr(args, 'legs', None) is not None:
        if args.legs < 2 or args.legs % 2:
            raise EnergyError(f'--legs must be an even number >= 2, got {args.legs}')
        _check_mass(robot, args.legs, '--legs')
    # a load offset above a stance leg's load was clamped to 0 kg without a word
    # (--load-offset 1e9: 23.4 W predicted for 24.9 W, no extrapolation warning)
    why = load_offset_problem(args.load_offset, robot.mass_kg, robot.leg_mass_kg,
                              int(getattr(args, 'legs', None) or 6))
    if why:
        raise EnergyError(why)
    return _Setup(bench_bags=bench_bags, leg=leg, robot=robot, limits=limits,
                  limits_source=limits_source, robot_speed=robot_speed,
                  mass_given=mass_given, mass_warning=mass_warning, mass_note=mass_note,
                  mass_source=mass_source)


def _warn(doc: dict[str, Any], bar: Any, line: str) -> None:
    """A warning kept in ``energy.json`` and said on the terminal at once (above the bar)."""
    doc.setdefault('warnings', []).append(line)
    bar.write(f'hexapod-analyze energy: warning: {line}', file=sys.stderr)


def _run(args: argparse.Namespace) -> dict[str, Any]:
    from contextlib import ExitStack

    from tqdm import tqdm

    from hexapod_common.bags import message_progress
    from hexapod_common.outdir import prepare_out_dir, write_text_atomic
    from hexapod_common.progress import bar_options

    setup = _checked_setup(args)
    # a file by that name, no permission: refused up front. An earlier run's energy.json and
    # plots are already set aside by :func:`run` (put back if this run does not finish)
    out = prepare_out_dir(args.out)
    n_steps = len(setup.bench_bags) + len(args.robot) + 1 + \
        (_sweep_steps() if args.sweep else 0) + (1 if args.recommend else 0)
    bar = tqdm(total=n_steps, desc='energy', unit='step', **bar_options(args.no_progress),
               file=sys.stderr)
    # a second bar of the messages read: one long bag shows progress, not 0/2 for minutes
    reading = ExitStack()
    reading.enter_context(message_progress('energy: bag', disable=args.no_progress))
    doc: dict[str, Any] = {'schema': 'hexapod_energy.energy/1', 'plots': []}
    doc['options'] = _options(args)
    doc['robot_mass'] = {'kg': float(args.robot_mass), 'source': setup.mass_source}
    if setup.mass_warning:
        doc['warnings'] = [setup.mass_warning]
    if setup.mass_note:
        doc['robot_mass']['note'] = setup.mass_note
        bar.write(f'hexapod-analyze energy: {setup.mass_note}', file=sys.stderr)
    if not args.recommend and (args.speed is not None or args.payload):
        doc.setdefault('warnings', []).append(
            '--speed and --payload are for --recommend (the target speed and payload), '
            'ignored without it; the robot runs\' payload is --robot-payload')
    try:
        model = _fit_bench(args, setup, doc, out, bar)
        opm = setup.leg.output_power_model(args.robot_mass)
        doc['leg'] = setup.leg.summary()
        runs, trend_series, failed = _robot_runs(args, setup, model, opm, doc, bar)
        if args.robot and len(failed) == len(args.robot):
            raise EnergyError(failed[0]['error'] if len(failed) == 1 else
                              'every robot bag was refused: ' + '; '.join(
                                  f['error'] for f in failed))
        doc['robot_runs'] = runs
        if failed:
            doc['failed_bags'] = failed
        for n in sorted({r['leg_count'] for r in runs if r['leg_count']}):
            _check_mass(setup.robot, int(n), 'the robot bags')
        if trend_series:
            from hexapod_energy.plots import power_in_over_time_plot

            for s in trend_series:
                s['label'] = _run_label(runs[s['run']])
            doc['plots'] += [str(p.relative_to(out)) for p in power_in_over_time_plot(
                trend_series, out / 'power_in_over_time',
                title=f'Input power over each run ({len(trend_series)} run(s) of at least '
                      f'{TREND_MIN_WINDOWS} cycles and {TREND_MIN_SPAN_S:g} s)')]
        legs_n, legs_source = _robot_leg_count(args, runs, doc)
        if args.sweep or args.recommend:
            _check_mass(setup.robot, legs_n, legs_source)
            other = sorted({r['bag'] for r in runs if any(
                str(n).startswith(NO_MODEL_LEG_NOTE) for n in r.get('notes', []))})
            if other:
                # the sweeps' P_out, reach and step lengths are the model leg's: a 2-DOF
                # hexapod was recommended 140 mm steps of AntBot's leg without a word
                doc.setdefault('warnings', []).append(
                    f'--sweep/--recommend describe a robot with {setup.leg.name}\'s 3-DOF '
                    f'leg (reach, Eq. 6 P_out), not the legs of {", ".join(other)} (their '
                    'joints per leg differ): not this robot\'s figures')
        _prediction_error(doc, runs, out, f'{setup.leg.name} robot, {args.robot_mass:.4g} kg')
        if args.sweep:
            _sweep(doc, model, opm, out, bar, args.load_offset, leg_count=legs_n,
                   leg_count_source=legs_source, limits=setup.limits,
                   limits_source=setup.limits_source)
        if args.recommend:
            _recommendation(args, doc, model, opm, legs_n, legs_source, setup)
            bar.update(1)
    finally:
        reading.close()
        bar.close()
    write_text_atomic(out / 'energy.json', json.dumps(json_safe(doc), indent=1))   # last
    return doc


def _fit_bench(args: argparse.Namespace, setup: _Setup, doc: dict[str, Any], out: Path,
               bar: Any) -> Any:
    """Read the bench bags, split their power into phases, fit the surfaces and draw them;
    ``doc['bench']``. None without bench bags; :class:`FitRefused` (the sessions' phase
    powers written) when the surfaces cannot be fitted."""
    from hexapod_common.outdir import write_text_atomic

    from hexapod_energy.bag_io import (
        bench_load_problem,
        bench_phase_samples,
        merge_bench_data,
        read_bench_bag,
    )
    from hexapod_energy.prediction import NO_BASAL_NOTE
    from hexapod_energy.single_leg import SingleLegModel

    leg, bench_bags = setup.leg, setup.bench_bags
    samples, diags = [], []
    one_session = []
    recorded_one = []       # bags whose /bench/session names one session (bench_sequencer's)
    alone = []
    for path, spec in bench_bags:
        data = read_bench_bag(path, spec, leg_dh=leg.dh, leg_name=leg.name,
                              bench_leg=getattr(args, 'bench_leg', None))
        bar.update(1)
        if spec is not None:
            one_session.append(data)
        elif len({x.get('session_id') for x in data.sessions if x.get('session_id')}) == 1:
            recorded_one.append(data)
        else:
            alone.append(data)

    def phases(data: Any) -> None:
        s, d = bench_phase_samples(data, current_sign=args.current_sign,
                                   force_sign=getattr(args, 'force_sign', 'auto'),
                                   phase_split=getattr(args, 'phase_split', 'auto'))
        samples.extend(s)
        diags.append(d)

    for data in alone:
        phases(data)
    # bags of one session each: one bench (force offset and sign from every session, the
    # power clock's lag over the walking frequencies). bench_sequencer writes one bag per
    # session: each was analysed alone, its force sign and power lag never checked (an
    # outside review of the README's commands)
    for group, what in ((one_session, 'of --bench-sessions'),
                        (recorded_one, 'each recording one session on /bench/session')):
        if not group or (len(group) < 2 and group is recorded_one):
            for data in group:
                phases(data)
            continue
        why_apart: list[str] = []
        merged = merge_bench_data(group, why_apart)
        if why_apart:
            # said: each bag then gets its own force offset and sign (a 0 Hz bag: unchecked)
            _warn(doc, bar, f'the {len(group)} bench bags {what} are analysed one by one, '
                            f'not as one bench: {why_apart[0]}')
        for data in [merged] if merged is not None else group:
            phases(data)
    if setup.mass_given:
        # loads in grams under the 50 kg bound (0-50 g) are above a small robot's mass
        carried = args.robot_mass + max(args.payload or 0.0,
                                        getattr(args, 'robot_payload', None) or 0.0)
        why = bench_load_problem([(f'session {x.session_id}', x.load_kg) for x in samples],
                                 robot_mass_kg=carried,
                                 robot_what=f'robot ({setup.mass_source}, with any payload)')
        if why:
            raise EnergyError(why)
    for d in diags:
        # a bench leg not identified (the contact split), a session that walked another
        # frequency than its label: said on the terminal at once and kept in "warnings"
        for w in d.get('warnings', []):
            _warn(doc, bar, f'{d["bag"]}: {w}')
    try:
        model = SingleLegModel(folds=args.folds).fit(samples) if bench_bags else None
    except (FitError, InvalidInputError) as err:
        # the per-session phase powers do not depend on the surfaces: a lab checking its
        # bench with a short plan gets them (outside review D8), then the refusal
        doc['bench'] = {'bags': [b for b, _ in bench_bags], 'diagnostics': diags,
                        'fit': None, 'sessions': [dataclasses.asdict(x) for x in samples],
                        'fit_error': str(err)}
        doc['errors'] = [f'bench surface fit refused: {err}']
        write_text_atomic(out / 'energy.json', json.dumps(json_safe(doc), indent=1))
        raise FitRefused(
            f'{err} (the {len(samples)} sessions\' phase powers are in '
            f'{out / "energy.json"} bench.sessions; no surfaces, no Eq. 1 prediction)',
            doc.get('warnings', [])) from err
    if model is not None and not model.basal_power_w_:
        # basal power and the holding split were empty / null without a word
        _warn(doc, bar, NO_BASAL_NOTE)
    elif model is not None and (uncovered := _loads_without_basal(model)):
        # a lost 0 Hz session (a recorder that missed the latched first messages): that
        # load's basal power was the nearest one's without a word (review of the change)
        _warn(doc, bar,
              f'no 0 Hz session at load(s) {", ".join(f"{m:g}" for m in uncovered)} kg: '
              f'their basal power is held from the nearest 0 Hz session\'s (at '
              f'{", ".join(f"{m:g}" for m in model.basal_power_w_)} kg), not measured')
    if model is not None:
        model.bench_leg_ = leg   # the leg whose joint paths map other step geometries
        _limits_on_bench(setup, model)
        if model.bench_step_ is None:
            doc.setdefault('warnings', []).append(
                'the bench sessions record no step length and height (no /bench/session '
                'or /gait/phase with them; give step_length_m and step_height_m in the '
                'sessions file): robot runs, sweeps and candidates with another step are '
                'read at their phase durations alone, not mapped onto the bench\'s path')
    bar.update(1)
    doc['bench'] = ({'bags': [b for b, _ in bench_bags], 'diagnostics': diags,
                     'fit': model.summary()} if model is not None else None)
    if model is not None:
        from hexapod_energy.plots import bench_surfaces_plot

        doc['plots'] += [str(p.relative_to(out)) for p in bench_surfaces_plot(
            model, out / 'bench_surfaces',
            title=f'Single-leg bench: {len(model.samples_)} sessions, phase powers and '
                  'fitted surfaces')]
    return model


def _robot_runs(args: argparse.Namespace, setup: _Setup, model: Any, opm: Any,
                doc: dict[str, Any], bar: Any
                ) -> tuple[list[dict[str, Any]], list[dict[str, Any]], list[dict[str, str]]]:
    """Every robot bag's runs (one per walking schedule), the P_in-over-time series to draw,
    and the bags refused (by name; the others are kept)."""
    from hexapod_common.errors import HexapodError

    from hexapod_energy.bag_io import read_robot_segments

    runs: list[dict[str, Any]] = []
    trend_series: list[dict[str, Any]] = []   # window P_in over time, for the plot
    failed: list[dict[str, str]] = []
    for path in args.robot:
        try:
            # a bag whose /gait/phase changes schedule (speed sweep, gait switch, stop)
            # holds one run per walking schedule
            segments = read_robot_segments(path, mass_kg=setup.robot.mass_kg,
                                           current_sign=args.current_sign,
                                           speed_mps=setup.robot_speed)
        except (EnergyError, HexapodError, ValueError) as err:
            # one unreadable robot bag does not lose the others: refused by name (as
            # ``slip`` does); every one refused is an error
            failed.append({'bag': str(path), 'error': str(err)})
            if len(args.robot) > 1:  # a lone bag's refusal is the error itself
                print(f'hexapod-analyze energy: refused {path}: {err}', file=sys.stderr)
            bar.update(1)
            continue
        for run_ in segments:
            entry, series = _robot_run(args, setup, model, opm, doc, path, run_)
            if series is not None:
                trend_series.append({**series, 'run': len(runs)})
            runs.append(entry)
        bar.update(1)
    return runs, trend_series, failed


def _robot_run(args: argparse.Namespace, setup: _Setup, model: Any, opm: Any,
               doc: dict[str, Any], path: str, run_: Any
               ) -> tuple[dict[str, Any], dict[str, Any] | None]:
    """One robot run's ``robot_runs`` entry: measured P_in, the Eq. 1 prediction and where
    its watts go, P_out (efforts or the Eq. 6 model), the descriptors, and its notes (each
    also a warning); with its P_in-over-time series when it has one."""
    from hexapod_energy.metrics import descriptors
    from hexapod_energy.prediction import NO_BASAL_NOTE, bench_domain_check, power_breakdown_w

    robot = setup.robot
    notes = list(run_.extra.get('notes', []))
    payload = args.robot_payload if args.robot_payload is not None else \
        (run_.payload_kg or 0.0)
    if args.robot_payload is None and run_.payload_kg:
        notes.append(f'payload {run_.payload_kg:g} kg from the bag\'s metadata '
                     '(--robot-payload overrides it)')
    mass = robot.total_mass_kg(payload)
    # a robot standing: no schedule period, or the stand of a stepping gait (gait_scheduler's
    # stand keeps the walking period, step length and height 0; it was read as a Buehler
    # clock: an outside review)
    g = run_.gait
    standing = g is not None and (g.period_s <= 0 or (
        str(g.gait) != 'buehler' and not g.step_length_m > 0 and not g.step_height_m > 0
        and not float(getattr(g, 'sweep_angle_rad', 0.0) or 0.0) > 0))
    gait = None if standing else gait_from_sample(run_.gait) \
        if run_.gait is not None else _given_gait(args, run_, notes, model)
    predicted = p_model = math.nan
    breakdown = None
    if standing:
        # every leg holds its share of the body: the bench's 0 Hz sessions
        # (basal power at a load) predict it; the joints do no work
        p_model = 0.0
        notes.append(_standing_note(args, run_, model, robot, mass))
    # a RHex-class robot's Buehler clock (rotating legs, no step length): Eq. 1
    # and the Eq. 6 model are for stepping servo legs (an EduBot run was predicted
    # at 62.8 W for 34.5 W measured, its P_out 0 W: new-user review)
    clock = gait is not None and (gait.name == 'buehler' or not gait.step_length_m > 0)
    walked = gait   # the schedule as recorded, for the JSON
    if clock:
        notes.append('a Buehler clock (rotating legs, no step length): the '
                     'single-leg bench method (Eq. 1) and the Eq. 6 P_out model '
                     'are for stepping servo legs: no prediction, P_out from the '
                     'joint efforts only')
        gait = None
    if gait is not None and model is None:
        notes.append('no bench bags (--bench): no Eq. 1 prediction')
    outside: list[str] = []
    if gait is not None and model is not None:
        # Eq. 1 and where its watts go, in one evaluation
        breakdown = power_breakdown_w(model, gait, total_mass_kg=mass,
                                      leg_mass_kg=robot.leg_mass_kg,
                                      swing_load=args.swing_load,
                                      load_offset_kg=args.load_offset)
        predicted = breakdown['predicted_w']
        outside = bench_domain_check(model, gait, total_mass_kg=mass,
                                     leg_mass_kg=robot.leg_mass_kg,
                                     swing_load=args.swing_load,
                                     load_offset_kg=args.load_offset)[0]
        if outside:
            from hexapod_energy.prediction import phase_duration_scales

            k_st, k_sw = phase_duration_scales(model, gait)
            beta, period = gait.duty_factor, gait.period_s
            # the durations quoted are the bench step's equivalents (an outside review read
            # "stance 1.8 s" for a 1.4 s stance on an 80 mm step)
            where = ('' if k_st == 1.0 and k_sw == 1.0 else
                     f" (durations at the bench step's equivalent, x{k_st:.3g} stance and "
                     f"x{k_sw:.3g} swing: this run's stance {beta * period:.3g} s and swing "
                     f"{(1.0 - beta) * period:.3g} s on its {1e3 * gait.step_length_m:.0f} mm "
                     'step)')
            basal = getattr(model, 'basal_power_w_', None) or {}
            load_note = ('; the power breakdown\'s holding_w extrapolates the 0 Hz sessions\' '
                         'basal power along its last load step the same way'
                         if basal and len(basal) >= 2 and any('load' in x for x in outside)
                         else '')
            notes.append('the Eq. 1 prediction extrapolates the bench surfaces: ' +
                         '; '.join(outside) + where + load_note)
        other = _duty_factor_note(model, gait)
        if other:
            notes.append(other)
    shape = model_leg_mismatch(run_.extra.get('joint_name_set')
                               or run_.extra.get('joint_names') or [])
    if gait is not None and shape:
        # a leg the model cannot describe: its P_out is not this robot's
        notes.append(f'{NO_MODEL_LEG_NOTE} ({setup.leg.name}) has the joints '
                     f'{", ".join(MODEL_LEG_JOINTS)}, this robot\'s legs have others '
                     f'({shape}); P_out from the joint efforts only (--power-out auto or '
                     'effort), unknown without them')
    elif gait is not None:
        try:
            p_model = float(opm.power_out_w(gait, payload_kg=payload))
        except (ValueError, ImportError) as err:
            doc.setdefault('warnings', []).append(f'{path}: no P_out model: {err}')
    if gait is not None:  # a schedule the robot cannot walk (--limits, L(t) = 0)
        from hexapod_energy.prediction import geometry_limits
        from hexapod_energy.recommend import infeasible_schedule

        # the limits' own step and leg (AntBot's 100 mm path, or --limits on the robot's
        # leg) against this step on the robot's leg (as the gait node and hexapod-sim check)
        robot_leg = types.SimpleNamespace(bench_leg_=setup.leg)
        bad = infeasible_schedule(gait, geometry_limits(robot_leg, gait, setup.limits))
        if bad:
            notes.insert(0, 'infeasible schedule, not a gait the robot can '
                            'walk: ' + '; '.join(bad))
    for note in notes:
        doc.setdefault('warnings', []).append(f'{path}: {note}')
    p_out, source = _chosen_power_out(args, setup, run_, p_model, clock, mass, notes, doc,
                                      path)
    # the accumulator used robot.mass_kg; descriptors are recomputed with the payload
    d = descriptors(power_in_w=run_.power_in_w, power_out_w=p_out, mass_kg=mass,
                    speed_mps=run_.speed_mps)
    unpowered = run_.power_in_w <= 0
    if unpowered:
        # a negative P_in (a current sign forced wrong): efficiency -0.21, CoT -271.9 and SR
        # -7.17 were written where P_out >= P_in nulls them (outside review C2)
        nan = math.nan
        d = dataclasses.replace(d, efficiency=nan, cost_of_transport_j_per_m=nan,
                                specific_cost_of_transport_j_per_m_kg=nan,
                                specific_resistance=nan)
        notes.append(f'measured P_in {run_.power_in_w:.3g} W is not positive (the battery '
                     'current sign? --current-sign): efficiency, the costs of transport and '
                     'the specific resistance unknown')
    span = run_.extra.get('speed_span')
    if span is not None and not unpowered:
        # speed known over part of the run: what divides by it is over that part
        d_span = descriptors(
            power_in_w=span['power_in_w'], mass_kg=mass, speed_mps=run_.speed_mps,
            power_out_w=span['power_out_w'] if source == 'effort' else p_out)
        d = dataclasses.replace(
            d, cost_of_transport_j_per_m=d_span.cost_of_transport_j_per_m,
            specific_cost_of_transport_j_per_m_kg=(
                d_span.specific_cost_of_transport_j_per_m_kg),
            specific_resistance=d_span.specific_resistance)
        notes.append(
            f"speed known in {span['windows']} of {run_.windows} windows: cost of "
            f"transport and specific resistance over those ({span['window_s']:.2f} "
            f"s, P_in {span['power_in_w']:.2f} W there, {run_.power_in_w:.2f} W "
            'over the run)')
    trend, series = _power_trend(run_)
    drift = trend_note(trend)
    if drift:
        notes.append(drift)
        doc.setdefault('warnings', []).append(f'{path}: {drift}')
    legs = _leg_count(args, run_) if run_.gait is None else None
    if series is not None:
        series = {**series, 'predicted_w': predicted, 'drift': trend['drift']}
    entry = {
        'bag': str(path),
        'gait': walked.name if walked else ('stand' if standing else None),
        'leg_count': walked.leg_count if walked else
        (len(run_.gait.leg_names) or None if standing else legs),
        'duty_factor': walked.duty_factor if walked else None,
        'period_s': walked.period_s if walked else
        (0.0 if standing else run_.extra.get('period_s')),
        'step_length_m': walked.step_length_m if walked else None,
        'step_height_m': walked.step_height_m if walked else None,
        'payload_kg': payload, 'mass_kg': mass,
        'windows': run_.windows, 'window_s': run_.window_s,
        'measured_power_in_w': run_.power_in_w, 'predicted_power_in_w': predicted,
        'residual_w': run_.power_in_w - predicted,
        'power_breakdown_w': None if breakdown is None else {
            **breakdown, 'measured_w': run_.power_in_w,
            'unmodelled_w': run_.power_in_w - breakdown['predicted_w'],
            'holding_share': breakdown['holding_w'] / run_.power_in_w
            if run_.power_in_w > 0 else math.nan,
            **({} if math.isfinite(breakdown['holding_w']) else
               {'holding_missing': NO_BASAL_NOTE})},
        'prediction_outside_bench': outside,
        'power_out_w': p_out, 'power_out_source': source, 'power_out_model_w': p_model,
        'power_out_effort_w': run_.power_out_w,
        'efficiency': d.efficiency, 'speed': d.speed_mps,
        'cost_of_transport': d.cost_of_transport_j_per_m,
        'specific_cost_of_transport': d.specific_cost_of_transport_j_per_m_kg,
        'specific_resistance': d.specific_resistance,
        'cycle_source': run_.extra.get('cycle_source', 'gait_phase'),
        'speed_source': run_.extra.get('speed_source', ''),
        'speed_span': run_.extra.get('speed_span'),
        'power_in_trend': trend,
        'notes': notes,
        'segment': run_.extra.get('segment'),
    }
    return entry, series


def _standing_note(args: argparse.Namespace, run_: Any, model: Any, robot: Any,
                   mass: float) -> str:
    """The note of a standing run: no Eq. 1 prediction, with what the bench's 0 Hz sessions
    say its legs would draw holding the body."""
    legs_st = len(run_.gait.leg_names) or 6
    basal = getattr(model, 'basal_power_at_w', None)
    held = ''
    if basal is not None and math.isfinite(float(basal(0.0))):
        from hexapod_gait.gait import carried_mass_per_leg_kg
        m_c = float(carried_mass_per_leg_kg(mass, robot.leg_mass_kg, np.array([legs_st]))[0])
        b_w = legs_st * float(basal(max(m_c - args.load_offset, 0.0)))
        held = (f'; {legs_st} legs at the bench\'s 0 Hz power for the '
                f'{m_c:.3g} kg each holds would draw {b_w:.3g} W, '
                f'unloaded {legs_st * float(basal(0.0)):.3g} W')
    return (f'the robot stands ({run_.windows} window(s) of 1 s): its input power, speed 0 '
            '(CoT undefined); Eq. 1 is for walking, no prediction' + held)


#: a robot mass above this [kg] is refused as not kilograms (outside review B2: 3200 for a 3.2
#: kg octopod passed); the heaviest legged robots measured this way are tens of kg, and four
#: legs at the bench's BENCH_LOAD_MAX_KG carry 200 kg
ROBOT_MASS_MAX_KG = 200.0


def _chosen_power_out(args: argparse.Namespace, setup: _Setup, run_: Any, p_model: float,
                      clock: bool, mass: float, notes: list[str], doc: dict[str, Any],
                      path: str) -> tuple[float, str]:
    """A run's P_out and its source: the joint efforts when present, trusted and not
    overridden (``--power-out``), else the Eq. 6 model when it is below the measured P_in,
    else unknown (NaN, 'none'); why, in the run's notes and the warnings."""
    effort_ok = math.isfinite(run_.power_out_w) and args.power_out != 'model'
    # a continuously rotating leg does little negative work: the PWM-load test
    # (net / positive power near 1) is for position-controlled servos
    why = implausible_effort_power(run_.power_out_w, run_.power_in_w,
                                   math.nan if clock else _net_joint_power_w(run_))
    if math.isfinite(run_.power_out_w) and \
            any(n.startswith(VELOCITY_UNITS_NOTE) for n in notes):
        # velocities by a factor of no unit (a gear ratio: P_out 3.2x was taken) or joints in
        # several units; above P_in the refusal blamed the efforts (outside review B1, C3). A
        # unit recognised (deg/s, rpm, rev/s) was converted to rad/s in the windows
        why = (f'P_out from effort x velocity ({run_.power_out_w:.3g} W) is not the joints\' '
               'output: the joint velocities are not rad/s (see the note on them)')
    # why the joint efforts give no P_out, for the model's note
    if not math.isfinite(run_.power_out_w):
        no_effort = ('the joint efforts are all 0.0: no effort interface'
                     if any(n.startswith(ZERO_EFFORT_NOTE) for n in notes)
                     else 'no joint efforts in the bag')
    elif args.power_out == 'model':
        no_effort = (f'--power-out model: the joint efforts (P_out '
                     f'{run_.power_out_w:.3g} W) not used')
    else:
        no_effort = ''
    if effort_ok and args.power_out == 'auto' and why:
        effort_ok = False
        no_effort = f'joint efforts refused: {why}'
        doc.setdefault('warnings', []).append(
            f'{path}: {why}; ' + ('using the model' if math.isfinite(p_model)
                                  else 'P_out unknown'))
    leg = setup.leg
    if effort_ok:
        return run_.power_out_w, 'effort'
    if math.isfinite(p_model) and run_.power_in_w > 0 and p_model >= run_.power_in_w:
        # the model's output above the measured input is impossible: the mass,
        # payload or leg described is not this robot's (a 1000 kg payload gave
        # efficiency 1.004 and a negative cost of transport, without a word)
        notes.append(
            f'the Eq. 6 model gives P_out {p_model:.3g} W, not below the measured '
            f'P_in {run_.power_in_w:.3g} W (efficiency >= 1 is impossible): the '
            f'mass ({mass:g} kg with the payload), payload or leg given is not '
            "this robot's; P_out, efficiency and the costs of transport unknown")
        doc.setdefault('warnings', []).append(f'{path}: {notes[-1]}')
        return math.nan, 'none'
    if math.isfinite(p_model):
        # said whenever the model stands in (with --leg and no efforts nothing said so but
        # power_out_source; and a leg file named "Oktopus-8 leg" read "Oktopus-8 leg's leg")
        whose = leg.name if leg.name.lower().rstrip().endswith('leg') else f'{leg.name}\'s leg'
        why = [no_effort] if no_effort else []
        if getattr(args, 'leg', None) is None:
            why.append('give --leg for another leg')
        notes.append(f'P_out {p_model:.4g} W from the Eq. 6 model of {whose}'
                     + (f' ({"; ".join(why)})' if why else ''))
        return p_model, 'model'
    # no efforts to trust and no model (no gait, or a path the leg cannot
    # reach): P_out is unknown, not 0, and so are eta and the CoTs
    return math.nan, 'none'


def _prediction_error(doc: dict[str, Any], runs: list[dict[str, Any]], out: Path,
                      robot_name: str) -> None:
    """``prediction_error`` over the runs with a prediction, and the plots of the runs: the
    prediction against measurement and where the watts go, or the measured runs alone when
    there is no bench model."""
    measured_only = runs
    runs = [r for r in runs if math.isfinite(r['predicted_power_in_w'])]
    if measured_only and not runs:
        # no bench model (no --bench): the measured runs still get their plot
        from hexapod_energy.plots import measured_runs_plot

        doc['plots'] += [str(p.relative_to(out)) for p in measured_runs_plot(
            [_run_label(r) for r in measured_only],
            [r['measured_power_in_w'] for r in measured_only],
            [r['specific_cost_of_transport'] for r in measured_only],
            out / 'measured_runs',
            title=f'Measured robot runs ({robot_name}; no --bench: no prediction)')]
    if not runs:
        return
    meas = np.array([r['measured_power_in_w'] for r in runs])
    pred = np.array([r['predicted_power_in_w'] for r in runs])
    err = pred - meas
    doc['prediction_error'] = {
        'runs': len(runs), 'rmse_w': float(np.sqrt(np.mean(err**2))),
        'mae_w': float(np.mean(np.abs(err))), 'bias_w': float(np.mean(err)),
        'mean_power_w': float(np.mean(meas)),
        'relative_rmse': float(np.sqrt(np.mean(err**2)) / np.mean(meas)),
        'max_abs_relative': float(np.max(np.abs(err) / meas)),
    }
    from hexapod_energy.plots import prediction_plot, watts_plot

    doc['plots'] += [str(p.relative_to(out)) for p in prediction_plot(
        [r['speed'] for r in runs], meas, pred, out / 'prediction',
        labels=[_run_label(r, speed=False) for r in runs],
        title=f'Eq. 1 prediction against measurement ({robot_name})',
        outside=[bool(r.get('prediction_outside_bench')) for r in runs])]
    # a run whose prediction extrapolates the bench says so under its bar
    labels = [_run_label(r) + ('\n(extrapolated)' if r.get('prediction_outside_bench')
                               else '') for r in runs]
    doc['plots'] += [str(p.relative_to(out)) for p in watts_plot(
        labels, [r['power_breakdown_w'] for r in runs], meas,
        [r['power_out_w'] for r in runs], out / 'where_the_watts_go',
        title=f'{robot_name}; {_run_set_name(runs)}',
        efficiency=[r['efficiency'] for r in runs])]


def _recommendation(args: argparse.Namespace, doc: dict[str, Any], model: Any, opm: Any,
                    legs_n: int, legs_source: str, setup: _Setup) -> None:
    """``doc['recommendation']``: the gait that minimises CoT/M at ``--speed`` and
    ``--payload``, with a warning when its saving is within the model's error."""
    from hexapod_energy.recommend import recommend_gait

    # the robot's own lift when its runs walked one (every candidate was priced at AntBot's
    # 40 mm: +4.3 % for a robot lifting 30 mm, and the JSON did not say so)
    lifts = [float(r['step_height_m']) for r in doc.get('robot_runs', [])
             if isinstance(r.get('step_height_m'), (int, float))
             and math.isfinite(r['step_height_m']) and r['step_height_m'] > 0]
    height, height_source = (float(np.median(lifts)), 'the robot runs\' gait schedules') \
        if lifts else (0.04, 'default (AntBot\'s 40 mm; no robot run with a step height)')
    rec = recommend_gait(model, opm, speed_mps=args.speed, payload_kg=args.payload,
                         load_offset_kg=args.load_offset, leg_count=legs_n,
                         limits=setup.limits, step_height_m=height)
    doc['recommendation'] = {**rec.to_dict(), 'leg_count_source': legs_source,
                             'limits_source': setup.limits_source,
                             'step_height_source': height_source}
    if rec.note:
        doc.setdefault('warnings', []).append(f'recommendation: {rec.note}')
    # a saving smaller than the model's error is not a finding: the measured robot
    # runs' prediction error when there are some, else the 5 % the issue allows
    err = doc.get('prediction_error', {}).get('relative_rmse')
    resolution = max(float(err) if err is not None else 0.0, RECOMMEND_RESOLUTION)
    saving = rec.saving_fraction
    doc['recommendation']['model_resolution'] = resolution
    if saving is not None and 0.0 < saving < resolution:
        doc.setdefault('warnings', []).append(
            f'recommendation: its saving over the default ({100 * saving:.1f} %) is '
            f'within the model\'s error ({100 * resolution:.0f} %'
            + (', the robot runs\' prediction error' if err is not None and
               err >= RECOMMEND_RESOLUTION else '') + '): measure both on the robot '
            'before switching')


def _actuator_limits(args: argparse.Namespace, leg: Any = None) -> tuple[Any, str]:
    """The actuator limits of ``--sweep``/``--recommend`` and where they come from: AntBot's
    servo limits measured on AntBot's leg, or ``--limits`` measured on the robot's leg
    (``leg``, ``--leg``'s; None: AntBot's) at the 100 mm, 40 mm bench step (the bench's own
    step once the fit knows it: :func:`_limits_on_bench`)."""
    from hexapod_gait.feasibility import ANTBOT_LIMITS, ActuatorLimits
    from hexapod_gait.step_limits import measured_on_leg

    given = getattr(args, 'limits', None)
    if given is None:
        return ANTBOT_LIMITS, ("AntBot's servo limits (hexapod_gait ANTBOT_LIMITS, measured on "
                               "AntBot's leg; --limits for another robot)")
    if not all(math.isfinite(float(x)) for x in given):
        raise EnergyError(f'--limits MIN_SWING_S MIN_STANCE_S MAX_FREQ_HZ must be finite, got '
                          f'{list(given)}')
    try:
        lim = ActuatorLimits(*(float(x) for x in given))
    except ValueError as err:
        raise EnergyError(f'--limits MIN_SWING_S MIN_STANCE_S MAX_FREQ_HZ: {err}') from err
    # limits measured on the user's bench are the user's leg's (a leg's joint speeds)
    return measured_on_leg(lim, leg), '--limits'


def _limits_on_bench(setup: _Setup, model: Any) -> None:
    """``--limits`` were measured on the bench's step (``--limits``' help): once the fit
    knows it (``model.bench_step_``), they are on that step of the robot's leg."""
    step = getattr(model, 'bench_step_', None)
    if setup.limits_source != '--limits' or step is None:
        return
    from hexapod_gait.step_limits import measured_on_leg

    setup.limits = measured_on_leg(setup.limits, setup.leg, (float(step[0]), float(step[1])))


def _power_trend(run_: Any) -> tuple[dict[str, Any] | None, dict[str, Any] | None]:
    """A robot run's input power over time (:func:`hexapod_energy.trend.power_in_trend`) and,
    when it has one, its windows for the plot (centres from the run's start, P_in)."""
    wins = run_.extra.get('windows') or []
    t_end = [d.t_end_s for d in wins]
    w_s = [d.window_s for d in wins]
    p_in = [d.power_in_w for d in wins]
    trend = power_in_trend(t_end, w_s, p_in)
    if trend is None:
        return None, None
    t = np.asarray(t_end, dtype=float) - 0.5 * np.asarray(w_s, dtype=float)
    t0 = float(np.nanmin(np.asarray(t_end, dtype=float) - np.asarray(w_s, dtype=float)))
    return trend, {'time_s': t - t0, 'power_in_w': np.asarray(p_in, dtype=float),
                   'bin_time_s': trend['bin_time_s'], 'bin_power_in_w': trend['bin_power_in_w']}


def _check_mass(robot: Any, legs: int, source: str) -> None:
    """Refuse a robot not heavier than its legs (``M <= N m_leg``: negative body mass)."""
    legs_kg = legs * robot.leg_mass_kg
    if robot.mass_kg <= legs_kg:
        raise EnergyError(
            f'robot mass {robot.mass_kg:.4g} kg (payload excluded) <= {legs} legs ({source}) x '
            f'{robot.leg_mass_kg:.4g} kg = {legs_kg:.4g} kg: the legs alone outweigh the robot; '
            'check --robot-mass, --leg and --legs')


def _duty_factor_note(model: Any, gait: Any) -> str | None:
    """A note when the robot walks a duty factor the bench did not: Eq. 1 prices a swing by
    its duration alone, but a swing after a slower stance costs less (the residual loop's
    ``swing_reversal``: on the simulated AntBot a beta 0.5 bench over-predicts wave 5/6 runs
    by about 5 % and tetrapod 2/3 runs by 5 %, nearly all in the swing)."""
    betas = sorted({round(float(s.duty_factor), 2) for s in getattr(model, 'samples_', [])
                    if getattr(s, 'frequency_hz', 0.0) > 0 and 0 < float(s.duty_factor) < 1})
    beta = float(getattr(gait, 'duty_factor', float('nan')))
    if not betas or not math.isfinite(beta) or min(abs(beta - b) for b in betas) <= 0.05:
        return None
    walked = ', '.join(f'{b:g}' for b in betas)
    head = (f'duty factor {beta:.2f}, which the bench did not walk ({walked}): Eq. 1 prices '
            'each swing by its duration alone, but a swing costs more after a faster stance')
    if min(betas) < beta < max(betas):
        return head + ' (hexapod-analyze residuals names it swing_reversal)'
    slower = beta > max(betas)
    return (head + f"; after the {'slower' if slower else 'faster'} stances of this gait the "
            f"prediction is likely {'high' if slower else 'low'} by a few percent "
            '(hexapod-analyze residuals names it swing_reversal)')


def _robot_leg_count(args: argparse.Namespace, runs: list[dict[str, Any]],
                     doc: dict[str, Any]) -> tuple[int, str]:
    """Leg count of the robot --sweep and --recommend describe, and its source: ``--legs``,
    else the robot runs' (their gaits or joint names; the commonest, with a warning, when they
    disagree), else 6 (AntBot), with a warning when --sweep or --recommend uses it."""
    warns: list[str] = []
    counts = [int(r['leg_count']) for r in runs if r.get('leg_count')]
    given = getattr(args, 'legs', None)
    n, source = 6, 'assumed: AntBot'
    if given is not None:
        other = sorted(set(counts) - {int(given)})
        if other:
            warns.append(f'--legs {given} but robot runs walk on {other} legs')
        n, source = int(given), '--legs'
    elif counts:
        n, source = max(set(counts), key=counts.count), 'robot bags'
        if len(set(counts)) > 1:
            warns.append(f'robot runs walk on {sorted(set(counts))} legs: --sweep and '
                         f'--recommend use {n} (give --legs N)')
    elif args.sweep or args.recommend:
        warns.append('leg count unknown (no --legs, no robot bag gives it): --sweep and '
                     '--recommend assume 6 legs (AntBot); give --legs N')
    if warns:
        doc.setdefault('warnings', []).extend(warns)
    return n, source


#: how a run's cycles and speed were found, in a plot title
_CYCLE_SOURCES = {'gait_phase': 'cycles from /gait/phase', 'joints': 'cycles from the joints'}
_SPEED_SOURCES = {'mocap': 'speed from mocap', 'odometry': 'speed from odometry',
                  'odometry_twist': 'speed from odometry twist',
                  'gait_schedule': 'speed from the gait schedule',
                  'given': 'speed given (--robot-speed)', 'none': 'speed unknown'}
_POWER_OUT_SOURCES = {'effort': 'the joint efforts', 'model': 'the Eq. 6 model',
                      'none': 'nowhere (unknown)'}


def _run_set_name(runs: Sequence[dict[str, Any]]) -> str:
    """A set of robot runs in a plot title: their bags (first and last of many) and how their
    cycles, speed and gait were found (another lab's bag: 'cycles from the joints, speed given
    (--robot-speed), gait given (--gait)')."""
    names = list(dict.fromkeys(_run_label(r, speed=False) for r in runs))
    bags = ', '.join(names) if len(names) <= 3 else f'{names[0]} ... {names[-1]}'
    head = f"{len(runs)} run{'s' if len(runs) != 1 else ''} ({bags})"
    how = []
    for key, table in (('cycle_source', _CYCLE_SOURCES), ('speed_source', _SPEED_SOURCES)):
        found = list(dict.fromkeys(str(r.get(key) or 'none') for r in runs))
        how.append(' / '.join(table.get(f, f"{key.split('_')[0]} {f}") for f in found))
    if any(r.get('cycle_source') == 'joints' and r.get('gait') for r in runs):
        how.append('gait given (--gait)')
    sources = list(dict.fromkeys(str(r.get('power_out_source') or 'none') for r in runs))
    how.append('P_out from ' + ' / '.join(_POWER_OUT_SOURCES.get(f, f) for f in sources))
    return head + ': ' + ', '.join(how)


def _run_label(run: dict[str, Any], *, speed: bool = True) -> str:
    """A run's plot label: bag name, walking schedule when the bag holds several, speed."""
    seg = run.get('segment') or {}
    label = Path(run['bag']).name + (f" [{seg['index'] + 1}]" if seg.get('of', 1) > 1 else '')
    return label + (f"\n{run['speed'] or 0:.2f} m/s" if speed else '')


#: a recommended saving below this fraction (or the robot runs' prediction error, when
#: larger) is reported as within the model's error: the issue's 5 % prediction bar
RECOMMEND_RESOLUTION = 0.05


def _given_gait(args: argparse.Namespace, run_: Any, notes: list[str],
                model: Any = None) -> Any:
    """GaitPattern of a run without /gait/phase from --gait/--duty-factor/--step-length, the
    period found from the joints and the leg count from the joint names; None (noted) without
    them."""
    from hexapod_gait.gait import make_gait

    name = getattr(args, 'gait', None)
    if name is None:
        notes.append('no /gait/phase and no --gait/--duty-factor/--step-length: no Eq. 1 '
                     'prediction and no P_out model for this run')
        return None
    legs = _leg_count(args, run_)
    if legs is None:
        names = list(run_.extra.get('joint_names', []))
        raise EnergyError(
            f'--gait {args.gait} for {run_.path}: the joint names ({", ".join(names[:4])}'
            f'{", ..." if len(names) > 4 else ""}) do not follow the contract\'s '
            '<leg>_<joint> with legs L1..Lk, R1..Rk (DESIGN section 4), so the leg count is '
            'unknown: give --legs N')
    if name == 'tripod' and legs != 6:
        # a tripod is three legs: on another leg count the alternating gait is the same
        # pattern (two groups in antiphase); said, as the note would read "as given"
        name = 'alternating'
        notes.append(f'--gait tripod on {legs} legs: taken as the alternating gait (two '
                     'groups in antiphase, the tripod of a 6-leg robot)')
    height = getattr(args, 'step_height', None)
    if height is None:
        bench = getattr(model, 'bench_step_', None) if model is not None else None
        height, height_src = (bench[1], "the bench's") if bench else (0.04, 'assumed')
    else:
        height_src = 'given'
    if not (math.isfinite(height) and height > 0):
        raise EnergyError(f'--step-height must be > 0 m, got {height}')
    try:
        gait = make_gait(name, leg_count=legs, duty_factor=args.duty_factor,
                         period_s=run_.extra['period_s'], step_length_m=args.step_length,
                         step_height_m=height)
    except (ValueError, KeyError) as err:
        source = 'given by --legs' if getattr(args, 'legs', None) else 'from the joint names'
        raise EnergyError(f'--gait {args.gait} for {run_.path} ({legs} legs {source}): '
                          f'{err}') from err
    from hexapod_energy.prediction import joint_paths
    from hexapod_gait.errors import HexapodGaitError

    if model is not None:
        try:
            # a step the leg cannot reach (--step-length 5) was predicted like the bench's
            joint_paths(gait.duty_factor, gait.step_length_m, gait.step_height_m,
                         getattr(model, 'bench_leg_', None))
        except HexapodGaitError as err:
            raise EnergyError(f'--step-length {gait.step_length_m:g} m / --step-height '
                              f'{gait.step_height_m:g} m: out of the leg\'s reach ({err})'
                              ) from err
    notes.append(f'gait {gait.name} (beta {gait.duty_factor}, step {gait.step_length_m} m) as '
                 f'given, step height {height:g} m ({height_src}), {legs} legs '
                 f'{"given by --legs" if getattr(args, "legs", None) else "from the joint names"}'
                 f', period {gait.period_s:.4f} s from '
                 'the joints')
    return gait


def _sweep(doc: dict[str, Any], model: Any, opm: Any, out: Path, bar: Any,
           load_offset_kg: float = 0.0, *, leg_count: int = 6,
           leg_count_source: str = 'assumed: AntBot', limits: Any | None = None,
           limits_source: str = "AntBot's servo limits") -> None:
    """The Fig. 3 sweeps at the robot's ``leg_count`` (the leg-count sweep 4/6/8) and the
    Fig. 7D power map of its alternating gait; curves the leg cannot walk are skipped (warned),
    what is held fixed goes to ``sweep_settings``."""
    from hexapod_gait.feasibility import ANTBOT_LIMITS
    from hexapod_gait.gait import make_gait

    from hexapod_energy.plots import comparison_plot, four_quadrant_plot, power_map_plot
    from hexapod_energy.recommend import default_gait_name
    from hexapod_energy.sweeps import (
        DEFAULT_PAYLOADS_KG,
        GAIT_TYPE_MIN_SPEED_MPS,
        MIN_SPEED_MPS,
        PAPER_GAIT_TYPE_PAYLOAD_KG,
        compare_curves,
        run_standard_sweeps,
        standard_sweeps,
        with_payload,
    )

    def tick() -> None:
        if bar is not None:
            bar.update(1)

    lim = ANTBOT_LIMITS if limits is None else limits
    specs = standard_sweeps(leg_count)
    skipped: list[str] = []
    curves = run_standard_sweeps(model, opm, progress=bar, load_offset_kg=load_offset_kg,
                                 sweeps=specs, limits=lim, skipped=skipped)
    doc['sweeps'] = {k: [c.to_dict() for c in v] for k, v in curves.items()}
    alt = default_gait_name(leg_count)
    wave = specs['gait_type'][1].duty_factor
    doc['sweep_settings'] = {
        'robot_mass_kg': float(opm.robot.mass_kg), 'leg_count': leg_count,
        'leg_count_source': leg_count_source, 'payloads_kg': list(DEFAULT_PAYLOADS_KG),
        'load_offset_kg': load_offset_kg,
        'limits': {'min_swing_s': lim.min_swing_s, 'min_stance_s': lim.min_stance_s,
                   'max_step_frequency_hz': lim.max_step_frequency_hz},
        'limits_source': limits_source,
        'held_fixed': {
            'duty_factor': f'{alt}, {leg_count} legs, step 100 mm, step height 40 mm',
            'step_length': f'{alt}, {leg_count} legs, beta 0.5, step height 40 mm',
            'gait_type': f'{leg_count} legs, step 100 mm ({alt} beta 0.5, wave beta {wave:g} '
                         f'and 0.5), from {GAIT_TYPE_MIN_SPEED_MPS:g} m/s (the others from '
                         f'{MIN_SPEED_MPS:g})',
            'leg_count': 'alternating, beta 0.5, step 100 mm (4, 6 and 8 legs whatever the '
                         "robot's)",
            'power_map': f'{alt}, {leg_count} legs, beta 0.5, step 100 mm'},
        'skipped': skipped}
    for line in skipped:
        doc.setdefault('warnings', []).append(line)
    titles = {'duty_factor': 'Fig. 3A duty factor', 'step_length': 'Fig. 3B step length',
              'gait_type': 'Fig. 3C gait type', 'leg_count': 'Fig. 3D leg count'}
    for name in specs:
        tick()   # one step per plot, drawn or not
        if not curves.get(name):
            continue  # every curve skipped (warned)
        # the subtitle (robot mass, the parameters the curves share, the nominal payload and
        # the band) and the payload band's legend entry come from the curves
        drawn, nominal = curves[name], None
        if name == 'gait_type':
            # the paper's Fig. 3C is at a 140 g load: its solid curves too (energy.json keeps
            # the sweep's payloads; the band stays 0-500 g)
            try:
                drawn = [with_payload(c, PAPER_GAIT_TYPE_PAYLOAD_KG, model, opm, limits=lim,
                                      load_offset_kg=load_offset_kg) for c in drawn]
                nominal = PAPER_GAIT_TYPE_PAYLOAD_KG
            except ValueError as err:
                drawn = curves[name]
                doc.setdefault('warnings', []).append(
                    f'Fig. 3C plot at {1000 * DEFAULT_PAYLOADS_KG[0]:g} g, not the paper\'s '
                    f'{1000 * PAPER_GAIT_TYPE_PAYLOAD_KG:g} g: {err}')
        paths = four_quadrant_plot(drawn, out / f'four_quadrant_{name}',
                                   title=titles.get(name, name), nominal_payload_kg=nominal)
        doc['sweep_settings'].setdefault('plot_nominal_payload_kg', {})[name] = \
            float(drawn[0].payloads_kg[0]) if nominal is None else nominal
        if nominal is not None:
            # the plot's markers are at its nominal payload, not at the sweep's first: the
            # report's table gave Fig. 3C's 0 g points beside a plot of 140 g (a review)
            doc['sweep_settings'].setdefault('plot_optimal_points', {})[name] = [
                {'label': c.spec.label, 'payload_kg': nominal, 'optimal_points':
                 c.optimal_points(int(np.argmin(np.abs(np.asarray(c.payloads_kg) - nominal))))}
                for c in drawn]
        doc['plots'] += [str(p.relative_to(out)) for p in paths]
    gait_curves = curves.get('gait_type') or []
    tick()
    if len(gait_curves) >= 2 and gait_curves[0].spec.gait != gait_curves[1].spec.gait:
        # Fig. 3C's question in one line per payload: where the wave gait loses less
        try:
            cmp = compare_curves(gait_curves[0], gait_curves[1])
        except EnergyError as err:
            doc.setdefault('warnings', []).append(f'gait-type comparison skipped: {err}')
        else:
            doc['gait_type_comparison'] = {
                k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in cmp.items()}
            doc['plots'] += [str(p.relative_to(out))
                             for p in comparison_plot(cmp, out / 'gait_type_comparison')]
    speeds = np.linspace(0.1, 0.6, 50)
    payloads = np.linspace(0.0, 0.5, 50)
    tick()
    t0 = time.perf_counter()
    gait = make_gait(alt, leg_count=leg_count)
    try:
        pm = opm.power_map_w(gait, speeds, payloads)
    except ValueError as err:
        doc.setdefault('warnings', []).append(f'power map skipped: {err}')
        return
    seconds = time.perf_counter() - t0
    doc['power_map'] = {'speeds_mps': speeds.tolist(), 'payloads_kg': payloads.tolist(),
                        'power_out_w': pm.tolist(), 'seconds': seconds, 'gait': gait.name,
                        'leg_count': gait.leg_count, 'duty_factor': gait.duty_factor,
                        'step_length_m': gait.step_length_m}
    doc['plots'] += [str(p.relative_to(out))
                     for p in power_map_plot(
                         speeds, payloads, pm, out / 'power_map',
                         gait_label=f'{gait.name} ({gait.leg_count} legs) beta '
                                    f'{gait.duty_factor:g}, step '
                                    f'{1000 * gait.step_length_m:.0f} mm')]


def _options(args: argparse.Namespace) -> dict[str, Any]:
    """The options this analysis ran with (energy.json ``options``, shown by the report):
    what produced the numbers, beside the bags."""
    out: dict[str, Any] = {}
    for key, value in sorted(vars(args).items()):
        if key in ('func', 'command', 'no_progress') or callable(value):
            continue
        if isinstance(value, (list, tuple)):
            value = [str(v) for v in value]
        elif not isinstance(value, (str, int, float, bool, type(None))):
            value = str(value)
        out[key] = value
    return out


def _sweep_steps() -> int:
    """The progress bar's steps of ``--sweep``: one per curve, one per four-quadrant plot, the
    gait-type comparison and the power map (it counted 16 for 14 curves and ticked nothing
    while the plots were drawn: it stood at 83 % for 15 s and ended at 91 %)."""
    from hexapod_energy.sweeps import standard_sweeps

    specs = standard_sweeps(6)     # the same curves for every leg count
    return sum(len(v) for v in specs.values()) + len(specs) + 2


def _handler(args: argparse.Namespace) -> int:
    from hexapod_common.errors import HexapodError

    out = Path(args.out)
    existed = out.exists()
    try:
        doc = run(args)
    except (EnergyError, HexapodError, ValueError) as err:
        print(f'hexapod-analyze energy: error: {err}', file=sys.stderr)
        if isinstance(err, FitRefused):
            return 2   # energy.json holds the sessions' phase powers (warnings said above)
        if not existed and out.is_dir() and not any(out.iterdir()):
            out.rmdir()   # a refused run leaves no empty --out folder behind
        return 2
    err = doc.get('prediction_error')
    line = f"wrote {Path(args.out) / 'energy.json'}"
    if err:
        line += f" (prediction rmse {err['rmse_w']:.3f} W, {100 * err['relative_rmse']:.2f} %)"
    print(line)
    warns = list(dict.fromkeys(doc.get('warnings', [])))
    if warns:
        # said on the terminal too (an assumed mass, refused efforts, an extrapolation), not
        # only inside energy.json
        # each one (a review: only the first was shown, and an option ignored was hidden),
        # up to MAX_WARNINGS_SHOWN
        print(f'hexapod-analyze energy: {len(warns)} warning(s) (energy.json "warnings"):',
              file=sys.stderr)
        for w in warns[:MAX_WARNINGS_SHOWN]:
            print(f'  - {w}', file=sys.stderr)
        if len(warns) > MAX_WARNINGS_SHOWN:
            print(f'  ... and {len(warns) - MAX_WARNINGS_SHOWN} more in energy.json',
                  file=sys.stderr)
    return 0



def _loads_without_basal(model: Any) -> list[float]:
    """Walking loads the 0 Hz sessions do not bracket (below the lightest or above the
    heaviest standing load, by more than 1 g): their basal power is held, not measured."""
    basal = sorted(model.basal_power_w_)
    walking = sorted({float(s.load_kg) for s in model.samples_ if s.frequency_hz > 0})
    return [m for m in walking if m < basal[0] - 1e-3 or m > basal[-1] + 1e-3]

#: warnings printed on the terminal after ``energy`` (all of them are in energy.json)
MAX_WARNINGS_SHOWN = 12


def main(argv: Sequence[str] | None = None) -> int:
    """Stand-alone entry (``python -m hexapod_energy.cli``)."""
    return _handler(build_parser().parse_args(argv))


if __name__ == '__main__':
    sys.exit(main())
