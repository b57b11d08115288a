"""``hexapod-analyze residuals``: model against measurement, traced effects, before/after.

Usage::

    hexapod-analyze residuals --bench BAG [BAG ...] --robot BAG [BAG ...] --out DIR
    hexapod-analyze residuals --slip BAG [BAG ...] --out DIR

Energy: the bench bags give the single-leg model, the robot bags the measured ``P_in``
(``/battery_state``), the gait (``/gait/phase``) and the candidate regressors (``/servo_status``,
``/joint_states``); the catalogue effects are selected by held-out RMSE and BIC
(:mod:`hexapod_energy.residuals`). SLIP: every stance of the EduBot bags is fitted with plain
SLIP, SLIP + leg damping and SLIP + hip torque (:mod:`slip_identification.residuals`); the
stances are ``hexapod-analyze slip``'s (geometric single support, fitted mocap offset).

``residuals.json``::

    {"model": "energy"|"slip", "unit": "W"|"nerr", "baseline": {"rmse", "mae", "bias"},
     "candidates": [{"name", "heldout_rmse", "delta_bic", "selected", "params", "stderr",
                     (slip:) "improves", "rejected_because": [why it was not added: a test
                     it failed, or why its parameter is not one property of the robot]}],
     "effects_added": [names in order], "final": {"rmse", "mae", "bias"},
     "heldout": {"rmse_before", "rmse_after"}, "summary": "plain words", "plots": [...],
     (energy:) "heldout_kind": "held-out time blocks of the same runs ...",
     (energy, 3+ runs, effects added:) "leave_one_run_out": {"kind", "rmse_before",
                 "rmse_after", "transfers" (the runs left out lose >= 5 % of their error and
                 >= half of what the held-out blocks lost), "verdict" ("transfers", "partly":
                 left-out error above twice the blocks', "little", "worse"), "criterion",
                 "heldout_blocks", "share_of_block_gain", "ratio_to_blocks_after",
                 "per_run": [{"run", "rmse_before", "rmse_after", "effects_added"}]} (each run
                 scored with the effects selected and fitted on the others),
     (energy:) "attribution": {"status" ("identified", "identified, with suspect
                 companions", "suspect", "undecided", "nothing added"), "identified": [added effects
                 no other candidate explains about as well in their place], "undecided":
                 [{"effect", "or": [candidates as good], "better": [those better]}],
                 "suspect": [{"effect", "beside" | "absorbs"}], "kind"}: effects_added is
                 what the fit includes, attribution what the runs name,
     (energy:) "mass_sensitivity": {"w_per_kg_mean", "uncentred_r_with_constant",
                 "near_constant"}, "payload_kg", "robot_mass": {"kg" (payload excluded),
                 "source" (--robot-mass | bags' metadata (robot_mass_kg, as hexapod-sim
                 records it) | assumed (AntBot) | assumed (AntBot's body with the --leg
                 file's legs))}, "leg": {"name", "a_m", ...,
                 "link_masses_kg", "neutral_tip_m"} (--leg FILE, default AntBot's; as
                 energy.json "leg"),
     (energy:) "added_params": [{"name", "params", "stderr",
                                 "alternatives"?: [{"name", "heldout_rmse", "params",
                                                    "stderr", "share",
                                                    "chosen_heldout_rmse",
                                                    "implausible"?, "z"?, "why"?}],
                                 "identified": false when an alternative, a constant beside
                                 it or a collinear contribution leaves it undecided,
                                 "collinearity"?: {"with", "correlation" (null for a
                                 constant contribution: "correlation_kind"),
                                 "uncentred_correlation", "collinear"},
                                 "constant_beside"?: [the fitted effects a constant is
                                 added beside: suspect],
                                 "at_bound"?: "upper" (the coefficient at the top of the
                                 effect's physical range)}],
     (energy, with /servo_status:) "servo_temperature": {"excess_over_bench_k",
                                   "per_run": [{"run", "excess_k"}]},
     (energy:) "per_run": [{"bag", "gait", "period_s", "measured_w", "predicted_w",
                            "sample_rmse_w", "stream_lag_s", "notes", "outside_bench":
                            [where its schedule reads the bench surfaces outside the
                            bench's sessions]}],
     (energy:) "windows": {"count", "heldout", "kind", "per_cycle"},
     (energy:) "duty_factors": {"bench", "bench_spread", "runs"},
     (slip:) "bags", "stances": {"count", "heldout", "windows" (what the stances and
             their nerr are: hexapod-analyze slip's, so plain SLIP's nerr per stance is
             slip.json's), "per_run": [{"bag", "edges", "offset_s", "offset_method",
             "stances", "touchdown", "nerr" (plain SLIP, per stance)}]}, "mass_kg" (the
             robot mass the templates were fitted with: --mass / --robot-mass, else
             EduBot's 3.31 kg), "mass_given", "warnings" (the mass assumed),
             "alternatives": [{"name", "heldout_rmse", "params", "share"}] (an extension
             that passed every check and removed at least 90 % of the held-out error the
             added one did), "unexplained":
             {"pattern": "step"|"trend"|null, "p_value", "explained_share", "significant",
             "per_run": [{"run", "stances", "ratio", "nerr_before", "nerr_after", "at_s"?}],
             "isolated": [{"run", "at_s", "nerr", "ratio"}]} (the per-stance nerr left, over
             each run's time: slip_identification.residuals.nerr_time_pattern), ...}
    (slip) candidates also carry "lowers_heldout", "consistency" ("one_property",
    "unphysical_sign": one consistent value of the sign physics forbids, such as a negative
    leg damping where the stances gain energy, "inconsistent"), "median_significance",
    "params.per_stance_range"; "rejected_because" lists every reason it was not added.

A candidate record with ``"dropped": true`` was added, then dropped by the backward step (the
effects added after it explain what it did). ``hot_windings`` on servos that are all about as
warm (a spread under 1 K) but more than 3 K from the bench's is named as an alternative only,
like ``power_gain``; the summary then gives the servos' temperature excess.

``unexplained`` (energy): what the added effects left, against the windows' noise
(:mod:`hexapod_energy.unexplained`): ``{"rmse_w", "noise_w", "structured_w", "significant",
"isolated": [{"run", "at_s", "residual_w"}], "pattern"?: "run_offsets"|"trend"|"step"|"other",
"explained_share"?, "per_run"?: [{"run", "mean_w", "slope_w_per_s"? | "step_w", "at_s"?}]}``;
when significant (an effect outside the catalogue: an accessory switched on mid-run, one run
on another floor) the summary says so and gives its shape.

``alternatives`` (energy): other candidates that explained the same residual nearly as well
(at least 90 % of the held-out error the added effect removed in its round, and not worse on
the held-out blocks by 2 standard errors, ``z``, unless never added like ``power_gain``; or,
in its place beside the other added effects, not worse by 2 standard errors and removing at
least half of what it removes, ``why``): the runs cannot tell them apart, and the summary
says so. After forward selection an added effect is exchanged for a candidate that, in its
place, is better on the held-out blocks by 2 standard errors (its record: ``exchanged_for``).
``cable_resistance`` [ohm]: a resistance after the monitor (a cable or tether to the robot),
whose ``R I^2`` the monitor measures; added only where it beats ``speed_friction`` (whose
drive loss also grows with the current) by 2 standard errors, else named beside. The
``thermal_drift`` slope ``w_per_k`` is per servo-kelvin; ``w_per_k_of_mean_temperature``
is the robot's per kelvin of its mean servo temperature. Energy candidates: ``basal_power``,
``thermal_drift`` (on the
servo temperatures, or without ``/servo_status`` on the energy drawn since the run started),
``hot_windings`` (servos warmer than the bench's: the predicted power times their mean excess
temperature, ``per_k`` [1/K]), ``kinematic_error``, ``supply_resistance``,
``speed_friction``, ``carried_mass`` (an undeclared payload, in kg, from the bench model's own
mass sensitivity), ``leg_anomaly`` (per leg), ``stance_preload`` (legs fighting each other in
an over-constrained stance: ``w_per_leg`` [W] per stance leg beyond three, on the window mean
of ``max(L - 3, 0)`` from ``/gait/phase``; a candidate where the walking windows' mean spans
0.2 legs),
``swing_reversal`` (a swing after a slower stance than the bench's costs less, ``j_per_mps``
[J s/m]: the bench's transfer error at other duty factors), ``standing_hold`` (a standing
robot's holding power against the bench's 0 Hz sessions, ``holding_change`` -1 to +1) and
``time_offset`` (:mod:`hexapod_energy.effects_catalogue`). A candidate that passes only beside
``swing_reversal`` or ``standing_hold`` is added with it (its record says ``added_with``).
``thermal_drift``'s params give ``reference_c``, the temperature at which the drift is zero,
fitted between 1 K below the coldest robot servo reading and 3 K above the bench's
(``reference_at_bound`` when at an end). On windows whose mass sensitivity is nearly constant
(``mass_sensitivity``), ``carried_mass`` is named beside an added ``basal_power`` and the
reverse, whatever its share. An alternative with ``share`` >= 1 removed at least as much
of the error as the added effect and is said to explain it "at least as well" (with
``power_gain``, params ``gain_excess`` and ``factor``, the summary says a gain or calibration
error). ``implausible`` (energy): candidates refused because their fit is physically
implausible (``carried_mass`` beyond the robot's declared mass, payload included), each
``{"name", "heldout_rmse", "params", "implausible", "gain_like", "power_gain"}``; with
``gain_like`` nothing more was added (power_gain explained at least as much).
``sample_view.warnings``: the clock-offset search (``|lag| <= max_lag_s``, ``--max-lag``) found
its best lag at its edge, or a realignment that removes little of the per-sample error, or
``--max-lag`` was cut to a tenth of the shortest run (the search sets aside its largest lag at
each end of every run). ``sample_view.refused`` (alone): why there was no clock-offset search
or per-sample view (too little robot data).

Energy residuals are measured minus predicted ``P_in`` per gait-phase window [W] (``1/k`` of
the cycle, ``windows.per_cycle``: 2 for a tripod, 3 a tetrapod, 6 a wave; ``bias`` is
their mean); SLIP residuals are the per-stance nerr. Exit codes: 0 success, 2 input refused
(missing topic or session, too little data), 1 an unforeseen failure (a bug), 130 interrupted.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from hexapod_common.cli_args import NumberArgumentParser

__all__ = ['add_cli', 'build_parser', 'main', 'run', 'run_slip_loop']


def _add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument('--bench', nargs='+', default=[], metavar='BAG',
                   help='bench bags (single-leg sessions) for the energy loop')
    p.add_argument('--robot', nargs='+', default=[], metavar='BAG',
                   help='robot bags (/battery_state, /gait/phase, /servo_status) for the '
                        'energy loop; several runs at different step frequencies are best')
    p.add_argument('--slip', nargs='+', default=[], metavar='BAG',
                   help='RHex-class bags for the SLIP loop (instead of --bench/--robot)')
    p.add_argument('--out', required=True, metavar='DIR', help='output folder')
    p.add_argument('--robot-mass', '--mass', type=float, default=None, metavar='KG',
                   help='robot mass without payload [kg] (default for the energy loop: the '
                        "robot bags' declared robot_mass_kg, else AntBot's 2.183 with a "
                        "warning; EduBot's 3.31 for --slip, with a warning: the fitted "
                        'leg damping and hip torque scale with it)')
    p.add_argument('--leg', default=None, metavar='FILE',
                   help="the robot's leg for the energy loop (a leg file, as energy --leg: "
                        'DH table, link masses, stance pose; its mass sets what a stance leg '
                        "carries in Eq. 1, its joint paths the step scaling); default AntBot's")
    p.add_argument('--robot-payload', type=float, default=0.0, metavar='KG',
                   help='payload of the robot runs [kg] (default 0; unlike energy, not read '
                        "from the bags' metadata: a payload left undeclared is for the loop to "
                        'find)')
    p.add_argument('--phase-split', choices=('auto', 'schedule', 'contact'), default='auto',
                   help="bench stance/swing labels: 'schedule' (the bench leg's commanded "
                        "stance on /gait/phase), 'contact' (the paper's force and tip split), "
                        "'auto' (default: the schedule where the bag has it)")
    p.add_argument('--load-offset', type=float, default=0.0, metavar='KG',
                   help='subtracted from the carried mass before the bench surfaces are read '
                        '[kg]: 0 (default, the paper: a stance tip carries M g / L, the '
                        'simulated robot\'s too); the leg mass for a robot model whose stance '
                        'tips carry only (M - m_leg L) g / L, a stage mass for a bench whose '
                        'tip carries one')
    p.add_argument('--max-lag', type=float, default=0.15, metavar='S',
                   help='largest clock offset of /battery_state against the joint stream the '
                        'per-sample view searches [s] (default 0.15; a larger one costs time '
                        'and, beyond about half the gait period, may find an aliased lag)')
    p.add_argument('--current-sign', choices=('ros', 'positive_discharge', 'auto'),
                   default='auto', help='battery current sign convention (default auto)')
    p.add_argument('--box', type=float, nargs=6, metavar=('X0', 'Y0', 'Z0', 'X1', 'Y1', 'Z1'),
                   help='--slip: permissible box in the mocap frame [m] (default hexapod-analyze '
                        "slip's: 2 x 1 x 1 m, or every tracked sample when the mocap origin "
                        'is not in the tracking volume)')
    from hexapod_energy.cli import add_given_gait_arguments

    add_given_gait_arguments(p, 'for the energy loop\'s Eq. 1 prediction')
    p.add_argument('--no-plots', action='store_true', help='skip the PNG plots')
    p.add_argument('--no-progress', action='store_true', help='no progress bar on stderr')


def add_cli(subparsers: Any) -> argparse.ArgumentParser:
    """Register the ``residuals`` subcommand on ``hexapod-analyze``'s subparsers."""
    p = subparsers.add_parser(
        'residuals', help='residual loop: trace model error to named effects, before/after',
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_arguments(p)
    p.set_defaults(func=_handler)
    return p


def build_parser() -> argparse.ArgumentParser:
    """Stand-alone parser (same options as ``hexapod-analyze residuals``)."""
    p = NumberArgumentParser(prog='hexapod-analyze residuals', description=__doc__,
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_arguments(p)
    return p


#: what the SLIP loop's stances and nerr are (residuals.json ``stances.windows``)
SLIP_STANCES = ("hexapod-analyze slip's: geometric single-support windows (EduBot legs) "
                'with the fitted mocap clock offset and ground, nerr with bx from each '
                "stance's start (slip.json stances[].nerr); plain SLIP's nerr here is "
                "slip.json's on the same bags at the same mass")


def run_slip_loop(bags: list[str], out_dir: str | Path | None = None, *,
                  plots: bool = True, box: Sequence[float] | None = None,
                  progress: Callable[[int], Any] | None = None,
                  mass_kg: float | None = None, payload_kg: float = 0.0) -> dict[str, Any]:
    """SLIP loop on EduBot bags; writes ``residuals.json`` when ``out_dir`` is given;
    ``progress(1)`` after each bag. ``mass_kg``: the robot's mass (None: EduBot's 3.31 kg,
    with a warning; an outside review's ``--robot-mass 3.97`` was taken and ignored);
    ``payload_kg`` rides on the template's point mass with it (it had been ignored without a
    word: a review of the change).

    The stances are ``hexapod-analyze slip``'s (:data:`SLIP_STANCES`: its default options,
    the box ``box`` or its default), found once per bag and fitted with plain SLIP there;
    each extension is fitted to the same stances. Until an outside review the loop ran the
    pipeline with its bare defaults, the shifted clock's edges and no mocap clock offset:
    another set of stances (22 against slip.json's 23 on the demo's running and walk) and
    another nerr under the same name (running 0.095-0.148 against 0.044-0.101)."""
    from slip_identification.cli import analyze_data, default_options, read_run
    from slip_identification.fit import SlipFitter
    from slip_identification.model import EDUBOT_MASS_KG, SlipModel
    from slip_identification.residuals import (
        SLIP_CANDIDATES,
        SlipExtensionSelection,
        slip_loop_document,
    )

    warnings: list[str] = []
    if mass_kg is None:
        mass_kg = EDUBOT_MASS_KG
        warnings.append(f"robot mass not given: EduBot's {EDUBOT_MASS_KG:g} kg assumed (the "
                        'fitted leg damping and hip torque scale with it); give --mass')
    elif not (math.isfinite(mass_kg) and 0 < mass_kg <= 1000):
        from slip_identification.errors import SlipDataError

        raise SlipDataError(f'--mass must be a robot mass > 0 and up to 1000 kg, got {mass_kg}')
    fits: dict[str, list[Any]] = {'slip': [], **{k: [] for k in SLIP_CANDIDATES}}
    # hexapod-analyze slip's options (its defaults: the leg geometry's single-support edges
    # and clock offset, the paper's estimator from several starts; no --box: its 2 x 1 x 1 m
    # box, or every tracked sample when the mocap origin is not in the tracking volume); the
    # position fit is not needed here
    options = default_options(mass_kg=mass_kg + payload_kg, model='slip', position_fit=False,
                              box_lower=list(box[:3]) if box else None,
                              box_upper=list(box[3:]) if box else None)
    per_run: list[dict[str, Any]] = []
    for path in bags:
        res = analyze_data(read_run(path), options).result
        fits['slip'].extend(res.fits)
        for name, ext in SLIP_CANDIDATES.items():
            fits[name].extend(SlipFitter(SlipModel(extensions=ext, mass_kg=mass_kg + payload_kg)
                                         ).fit(res.stances).results_ if res.stances else [])
        per_run.append({'bag': str(path), 'edges': res.edges, 'offset_s': res.offset_s,
                        'offset_method': res.offset_method, 'stances': len(res.fits),
                        'touchdown': [r.touchdown_s for r in res.fits],
                        'nerr': [r.nerr for r in res.fits]})
        if progress is not None:
            progress(1)
    doc = slip_loop_document(SlipExtensionSelection().fit(fits))
    doc['stances'].update(windows=SLIP_STANCES, per_run=per_run)
    doc['bags'] = list(bags)
    doc['mass_kg'] = float(mass_kg)
    doc['mass_given'] = not warnings
    doc['payload_kg'] = float(payload_kg)
    doc['warnings'] = warnings
    if out_dir is not None:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        doc['plots'] = []
        if plots:
            doc['plots'] = _plot_slip(fits, doc, out)
        from hexapod_common.outdir import write_text_atomic

        write_text_atomic(out / 'residuals.json', json.dumps(doc, indent=2) + '\n')   # last
    return doc


def _plot_slip(fits: dict[str, list[Any]], doc: dict[str, Any], out: Path) -> list[str]:
    """nerr per stance against touchdown time: one series per bag (its stances in time
    order, never joined across bags), plain SLIP (before, filled) and, when the loop added an
    extension, SLIP with it (after, hollow); returns the PNG name. The PNG's description (the
    report's caption) says which: an "(after)" series is promised only when one is drawn."""
    import matplotlib

    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    import numpy as np

    added = [n for n in doc.get('effects_added', []) if n in fits]
    after_name = added[-1] if added else None
    # a stance's label is '<bag>#<index>'; the bag groups the stances of one run
    bags: dict[str, list[int]] = {}
    for i, r in enumerate(fits['slip']):
        bags.setdefault(str(getattr(r, 'label', '')).rsplit('#', 1)[0], []).append(i)
    fig, ax = plt.subplots(figsize=(9, 4.5))
    colors = plt.rcParams['axes.prop_cycle'].by_key()['color']
    for k, (bag, idx) in enumerate(bags.items()):
        col = colors[k % len(colors)]
        name = Path(bag).name or f'run {k + 1}'
        order = sorted(idx, key=lambda i: fits['slip'][i].touchdown_s)
        t = np.array([fits['slip'][i].touchdown_s for i in order], dtype=float)
        ax.plot(t, [fits['slip'][i].nerr for i in order], 'o-', ms=5, lw=0.8, color=col,
                label=f'{name}: plain SLIP' + (' (before)' if after_name else ''))
        if after_name is not None:
            ax.plot(t, [fits[after_name][i].nerr for i in order], 's--', ms=5, lw=0.8,
                    mfc='none', color=col, label=f'{name}: after (+ {after_name})')
    held = doc.get('heldout') or {}
    title = ("SLIP-measure nerr per stance (hexapod-analyze slip's stances and nerr): "
             + (f'plain SLIP (before) and with {after_name} (after)' if after_name
                else 'plain SLIP, no extension added'))
    if isinstance(held.get('rmse_before'), (int, float)) and \
            isinstance(held.get('rmse_after'), (int, float)):
        title += (f'\nheld-out rms nerr {held["rmse_before"]:.3g} before, '
                  f'{held["rmse_after"]:.3g} after' if after_name else
                  f'\nheld-out rms nerr {held["rmse_before"]:.3g}')
    ax.set_title(title, fontsize=10)
    ax.set_xlabel('touchdown [s] (bag time of each run)')
    ax.set_ylabel("nerr per stance [-]\n(bx from each stance's start: slip.json's nerr)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc='upper left', bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    fig.tight_layout()
    what = (f'Filled: plain SLIP (before); hollow: with {after_name} (after).' if after_name
            else 'No extension was added: plain SLIP only, no "after" series.')
    fig.savefig(out / 'residual_slip_nerr.png', dpi=90, metadata={'Description': what})
    plt.close(fig)
    return ['residual_slip_nerr.png']


def run(args: argparse.Namespace) -> dict[str, Any]:
    """Carry out the analysis chosen by the options; returns the written document."""
    from hexapod_energy.errors import InvalidInputError
    from hexapod_energy.residuals import run_energy_loop

    from tqdm import tqdm
    from hexapod_common.progress import bar_options

    from hexapod_common.outdir import prepare_out_dir, replacing_outputs

    if args.slip:
        if args.bench or args.robot:
            raise InvalidInputError('give either --slip BAG... or --bench/--robot BAG..., '
                                    'not both')
        prepare_out_dir(args.out)   # before the analysis, not after it
        # an earlier run's residuals.json and plots (kept beside a --no-plots run's JSON):
        # set aside, put back if this run does not finish
        payload = args.robot_payload
        if not (math.isfinite(payload) and payload >= 0):
            raise InvalidInputError(f'--robot-payload must be >= 0 kg, got {payload}')
        with tqdm(total=len(args.slip), desc='residuals', unit='bag', file=sys.stderr,
                  **bar_options(getattr(args, 'no_progress', False))) as bar, \
                replacing_outputs(args.out, 'residuals.json'):
            doc = run_slip_loop(list(args.slip), args.out, plots=not args.no_plots,
                                box=args.box, progress=bar.update, mass_kg=args.robot_mass,
                                payload_kg=payload)
        for w in doc.get('warnings', []):
            print(f'residuals: warning: {w}', file=sys.stderr)
        return doc
    if not args.bench or not args.robot:
        raise InvalidInputError('the energy loop needs both --bench BAG... and --robot BAG... '
                                '(or use --slip BAG...)')
    from hexapod_energy.bag_io import resolve_robot_mass

    # a simulated robot of another leg count records its mass; AntBot's was assumed
    # silently (the undeclared-mass effect then measured the difference)
    given = args.robot_mass is not None
    from hexapod_energy.leg_description import antbot_leg, load_leg_description

    # with --leg, AntBot's body with the file's legs (the simulators' and energy's rule)
    leg = load_leg_description(args.leg) if getattr(args, 'leg', None) else antbot_leg()
    legs_n = getattr(args, 'legs', None)
    mass = resolve_robot_mass(
        args.robot_mass, args.robot,
        leg_mass_kg=leg.spec.leg_mass_kg if getattr(args, 'leg', None) else None,
        leg_count=legs_n if isinstance(legs_n, int) and legs_n >= 2 else 6)
    args.robot_mass, mass_source = mass.kg, mass.source
    whose = (f"AntBot's {mass.kg} kg" if not getattr(args, 'leg', None) else
             f"AntBot's body with the --leg file's {leg.spec.leg_mass_kg:.3f} kg legs, "
             f'{mass.kg:.3f} kg')
    note = mass.note if not mass.assumed else (
        f'warning: robot mass not given (--robot-mass): {whose} assumed; the '
        'undeclared-mass effect is measured against it')
    if not given:
        print(f'hexapod-analyze residuals: {note}', file=sys.stderr)
    # a negative or NaN mass or payload used to run the loop on a lighter robot, exit 0
    if not (math.isfinite(args.robot_mass) and args.robot_mass > 0):
        raise InvalidInputError(f'--robot-mass must be > 0 kg, got {args.robot_mass}')
    if not (math.isfinite(args.robot_payload) and args.robot_payload >= 0):
        raise InvalidInputError(f'--robot-payload must be >= 0 kg, got {args.robot_payload}')
    max_lag = getattr(args, 'max_lag', 0.15)
    if not (math.isfinite(max_lag) and 0.01 <= max_lag <= 5.0):
        raise InvalidInputError(f'--max-lag must be 0.01-5 s, got {max_lag}')
    if not math.isfinite(args.load_offset):
        raise InvalidInputError(f'--load-offset must be finite, got {args.load_offset}')
    legs = getattr(args, 'legs', None)
    if legs is not None:
        leg_kg = leg.spec.leg_mass_kg
        if legs < 2 or legs % 2 or legs * leg_kg >= args.robot_mass:
            # --legs 1e9 built a billion-leg gait before anything checked it (OOM)
            raise InvalidInputError(
                f'--legs must be an even number >= 2 whose legs ({leg_kg:.3g} kg each) weigh '
                f'less than the robot ({args.robot_mass:g} kg), got {legs}')
    prepare_out_dir(args.out)
    given = [getattr(args, k, None) for k in ('gait', 'duty_factor', 'step_length')]
    gait = None
    if any(v is not None for v in given):
        if any(v is None for v in given):
            raise InvalidInputError('--gait, --duty-factor and --step-length go together (the '
                                    'gait of robot bags without /gait/phase)')
        from hexapod_energy.residuals import GivenGait

        height = getattr(args, 'step_height', None)
        if height is not None and not (math.isfinite(height) and height > 0):
            raise InvalidInputError(f'--step-height must be > 0 m, got {height}')
        if not (math.isfinite(args.step_length) and args.step_length > 0):
            raise InvalidInputError(f'--step-length must be > 0 m, got {args.step_length}')
        gait = GivenGait(args.gait, args.duty_factor, args.step_length,
                         getattr(args, 'legs', None),
                         0.04 if height is None else float(height))
    from hexapod_common.bags import message_progress

    quiet = getattr(args, 'no_progress', False)
    # an earlier run's JSON and plots: set aside, put back if this run does not finish
    with tqdm(total=len(args.bench) + len(args.robot) + 1, desc='residuals', unit='step',
              file=sys.stderr, **bar_options(quiet)) as bar, \
            message_progress('residuals: bag', disable=quiet), \
            replacing_outputs(args.out, 'residuals.json'):   # messages: a long bag
        doc = run_energy_loop(args.bench, args.robot, args.out,
                              robot_mass_kg=args.robot_mass, payload_kg=args.robot_payload,
                              current_sign=args.current_sign,
                              load_offset_kg=args.load_offset, plots=not args.no_plots,
                              gait=gait, phase_split=getattr(args, 'phase_split', 'auto'),
                              progress=bar.update, max_lag_s=max_lag,
                              robot_mass_source=mass_source, leg=leg)
    for bag, kg in doc.get('bag_payloads_kg', {}).items():
        print(f'hexapod-analyze residuals: warning: {bag} declares a payload of {kg:g} kg in '
              f'its metadata; the loop takes --robot-payload ({args.robot_payload:g} kg) and '
              'leaves the difference for carried_mass to find (give --robot-payload to '
              'declare it)', file=sys.stderr)
    return doc


def _handler(args: argparse.Namespace) -> int:
    from hexapod_common.errors import HexapodError
    from hexapod_energy.errors import EnergyError

    try:
        from slip_identification.errors import SlipError as _SlipError
    except ImportError:  # pragma: no cover
        _SlipError = EnergyError  # type: ignore[misc,assignment]
    try:
        doc = run(args)
    except (EnergyError, _SlipError, HexapodError, ValueError, OSError) as err:
        print(f'hexapod-analyze residuals: error: {err}', file=sys.stderr)
        return 2
    except Exception as err:  # noqa: BLE001 - one line for the user, not a traceback
        print(f'hexapod-analyze residuals: failed: {type(err).__name__}: {err}',
              file=sys.stderr)
        return 1
    print(doc.get('summary', ''))
    print(f'wrote {Path(args.out) / "residuals.json"}')
    return 0


def main(argv: list[str] | None = None) -> int:
    """Stand-alone entry (``python -m hexapod_energy.residuals_cli``)."""
    args = build_parser().parse_args(argv)
    return _handler(args)


if __name__ == '__main__':  # pragma: no cover
    sys.exit(main())
