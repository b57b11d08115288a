"""``hexapod-sim bench|robot|edubot --out BAG ...``: simulated hardware straight into a bag.

Examples::

    hexapod-sim robot --out run1 --duration 30 --speed 0.6 --effect basal_power=3
    hexapod-sim robot --out stand --duration 10 --period 0
    hexapod-sim robot --out fast --speed 0.9 --allow-infeasible   # beyond the servo limits
    hexapod-sim robot --out px --speed 0.2 --leg phantomx.yaml    # another robot's leg

``robot`` refuses (exit 2) a gait the project calls infeasible: a phase shorter than AntBot's
servo limits allow (swing 0.16 s, stance 0.15 s, 3 Hz; ``hexapod_gait.feasibility``; with
``--servo`` another preset scaled by its no-load speed, :func:`servo_limits`) or a part
of the cycle with no leg on the ground (L(t) = 0); ``--allow-infeasible`` simulates it anyway,
with a warning on stderr. ``bench`` refuses a step frequency far beyond them (phases under
half the limits, :data:`BENCH_LIMIT_MARGIN`; a test rig may walk past the robot's limits: the
paper's plan goes to 3.3 Hz; ``--allow-infeasible`` simulates it anyway).
    hexapod-sim bench --out plan --loads 0,0.095,0.515 --frequencies 0,1,3 --duration 20
    hexapod-sim bench --out px --loads 0,0.2 --frequencies 0,1,2 --leg phantomx.yaml

``--leg FILE`` (a leg file, the one ``gait_scheduler -p leg_file`` and ``hexapod-analyze
energy --leg`` read: DH table, link masses, ``neutral_tip_m``) walks that leg instead of
AntBot's: its links, masses and rod inertias, its neutral tip (standing pose, stance midpoint)
and its inverse kinematics for the joint commands; the servos stay the ``--servo`` preset's
(AX-18A by default). The feasibility checks (reach, the servo limits scaled to the step's joint
path) are the file's leg's, as the gait node's with ``-p leg_file``. ``robot`` without a mass
simulates AntBot's 1.187 kg body with ``--legs`` of the file's legs
(:func:`~.robot_sim.default_robot_mass_kg`). On ``bench``, ``--leg`` also names the bench leg's
place (R2 by default, joint names ``R2_*``): ``--leg R2 --leg phantomx.yaml`` gives both.

Values that cannot work are refused up front (exit 2, one line naming the option): besides
the signs, a run of fewer than 2 or more than 2e6 samples (``--duration`` x ``--rate``), more
than 24 h or 10 kHz, ``--legs`` outside 2..64, a ``--payload`` over 10 times the robot's mass
and bench ``--loads`` over 5 kg. A run that fails leaves no bag behind.

Prints one JSON line per bag: robot and bench the bag path, message counts and the effects that
were on; edubot the bag, gait, seed, duration, power, speed and specific resistance.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from hexapod_common.cli_args import NumberArgumentParser

from .effects import EFFECTS, EffectError, parse_effects

__all__ = ['build_parser', 'main']


def _floats(text: str) -> tuple[float, ...]:
    try:
        values = tuple(float(x) for x in text.split(',') if x.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected comma-separated numbers, got {text!r}') \
            from None
    if not values:
        raise argparse.ArgumentTypeError('expected at least one number')
    return values


def _common(p: argparse.ArgumentParser, simulator: str) -> None:
    p.add_argument('--out', required=True, help='bag folder to create (must not exist)')
    p.add_argument('--storage', choices=('mcap', 'sqlite3'), default='mcap')
    p.add_argument('--seed', type=int, default=0, help='noise seed (same seed, same bag)')
    p.add_argument('--effect', action='append', default=[], metavar='NAME=VALUE',
                   help='switch an effect on (NAME=off turns a default one off); this '
                        'simulator implements: '
                        + ', '.join(sorted(n for n, s in EFFECTS.items()
                                           if simulator in s.simulators)))
    p.add_argument('--servo', default='ax18a', help='servo preset: ax18a, ax12a, xl430, xm430')
    p.add_argument('--rate', type=float, default=100.0, help='sample rate [Hz]')
    p.add_argument('--no-progress', action='store_true', help='no progress bar')


def build_parser() -> argparse.ArgumentParser:
    parser = NumberArgumentParser(prog='hexapod-sim', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest='command', required=True)

    robot = sub.add_parser('robot', help='servo hexapod (AntBot defaults)')
    _common(robot, 'robot')
    robot.add_argument('--duration', type=float, default=10.0, help='simulated time [s]')
    robot.add_argument('--gait', default='tripod')
    robot.add_argument('--duty-factor', type=float, default=0.5)
    robot.add_argument('--period', type=float, default=1.0, help='gait period [s]; 0 = stand')
    robot.add_argument('--speed', type=float, default=None,
                       help='body speed [m/s], > 0; overrides --period')
    robot.add_argument('--step-length', type=float, default=0.10, help='[m]')
    robot.add_argument('--step-height', type=float, default=0.04, help='[m]')
    robot.add_argument('--legs', type=int, default=6,
                       help='leg count, an even number >= 2 (default 6); the robot is '
                       "AntBot's body with that many legs (1.851 kg on 4, 2.515 kg on 8; "
                       "with --leg FILE, AntBot's 1.187 kg body and that many of the "
                       "file's legs)")
    robot.add_argument('--leg', default=None, metavar='FILE',
                       help="the robot's leg file (DH table, link masses, neutral_tip_m; "
                       "gait_scheduler's -p leg_file, energy's --leg): every leg walks it "
                       "with AX-18A (--servo) servos; default AntBot's leg")
    robot.add_argument('--payload', type=float, default=0.0, help='[kg]')
    robot.add_argument('--ambient-c', type=float, default=26.0,
                       help='air temperature around the servos [degC] (default 26)')
    robot.add_argument('--initial-temperature', type=float, default=None,
                       help='servo temperature at the start [degC] (default: the ambient; '
                       'a warm start for thermal-drift studies)')
    robot.add_argument('--battery', action='store_true', help='3S LiPo instead of a 11.9 V supply')
    robot.add_argument('--allow-infeasible', action='store_true',
                       help='simulate a gait beyond the servo limits (AX-18A: swing >= 0.16 '
                            's, stance >= 0.15 s, <= 3 Hz; other --servo presets scaled by '
                            'their no-load speed) or with no leg on the ground at some phase; '
                            'refused (exit 2) without it')
    robot.set_defaults(func=_run_robot)

    bench = sub.add_parser('bench', help='single leg on the MiMiC-Ant bench, a plan of sessions')
    _common(bench, 'bench')
    bench.add_argument('--duration', type=float, default=10.0,
                       help='walking time of each session [s]')
    bench.add_argument('--loads', type=_floats, default=(0.0, 0.095, 0.141, 0.187, 0.515),
                       help='comma-separated loads [kg]')
    bench.add_argument('--frequencies', type=_floats, default=(0.0, 0.5, 1.0, 2.0, 3.0),
                       help='comma-separated step frequencies [Hz]')
    bench.add_argument('--duty-factor', type=float, default=0.5)
    bench.add_argument('--step-length', type=float, default=0.10, help='[m]')
    bench.add_argument('--step-height', type=float, default=0.04, help='[m]')
    bench.add_argument('--leg', action='append', default=[], metavar='NAME|FILE',
                       help="the bench leg: its place NAME (R2 by default, joints R2_*) and/or "
                       "a leg FILE (DH table, link masses, neutral_tip_m, as energy's "
                       "--leg) walked with AX-18A (--servo) servos; default AntBot's leg; "
                       'may be given twice (--leg R1 --leg leg.yaml)')
    bench.add_argument('--max-cool', type=float, default=1800.0,
                       help='longest cooling between sessions [s]')
    bench.add_argument('--allow-infeasible', action='store_true',
                       help='simulate step frequencies whose phases are under half the servo '
                            'limits (refused, exit 2, without it)')
    bench.set_defaults(func=_run_bench)

    try:
        edubot = importlib.import_module('hexapod_bench_drivers.edubot_sim')
    except ImportError:
        edubot = None
    if edubot is not None and hasattr(edubot, 'add_cli'):
        edubot.add_cli(sub)
    return parser


class _Progress:
    def __init__(self, total: int, label: str, enabled: bool) -> None:
        self.bar: Any = None
        if enabled:
            try:
                from tqdm import tqdm
                from hexapod_common.progress import bar_options
            except ImportError:
                return
            self.bar = tqdm(total=total, desc=label, unit='sample', file=sys.stderr,
                            leave=False, **bar_options())

    def __call__(self, n: int) -> None:
        if self.bar is not None:
            self.bar.update(n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def _finish(args: argparse.Namespace, trace: Any, effects: Any, t0: float) -> int:
    from .sim_bag import write_trace
    progress = _Progress(trace.sample_count, 'bag', not args.no_progress)
    try:
        counts = write_trace(trace, args.out, storage=args.storage, seed=args.seed,
                             progress=progress)
    finally:
        progress.close()
    wall = time.perf_counter() - t0
    sim_s = float(trace.t_s[-1]) if trace.sample_count else 0.0
    print(json.dumps({'bag': str(args.out), 'simulator': trace.kind, 'simulated_s': sim_s,
                      'wall_s': round(wall, 3),
                      'real_time_factor': round(sim_s / wall, 2) if wall > 0 else None,
                      'messages': counts, 'effects': json.loads(effects.to_json())}))
    return 0


def servo_limits(servo: str = 'ax18a') -> Any:
    """AntBot's actuator limits (``hexapod_gait.feasibility.ANTBOT_LIMITS``, AX-18A) for the
    servo preset ``servo``: phase durations scaled by the AX-18A's no-load speed over the
    preset's at their voltage (and the step frequency by its inverse), since the shortest
    phase is set by how fast the joints can turn. AX-12A (59 rpm against 97): swing >= 0.263 s,
    stance >= 0.247 s, <= 1.82 Hz."""
    from hexapod_gait.feasibility import ANTBOT_LIMITS, ActuatorLimits

    from .servo_model import ServoParams

    ref, own = ServoParams.ax18a(), ServoParams.by_name(servo)
    ratio = ((ref.no_load_speed_rad_s / ref.rated_voltage_v)
             / (own.no_load_speed_rad_s / own.rated_voltage_v))
    if abs(ratio - 1.0) < 1e-12:
        return ANTBOT_LIMITS
    return ActuatorLimits(ANTBOT_LIMITS.min_swing_s * ratio, ANTBOT_LIMITS.min_stance_s * ratio,
                          ANTBOT_LIMITS.max_step_frequency_hz / ratio)


def _leg_kw(leg: Any) -> dict[str, Any]:
    """The ``kinematics`` and ``neutral_tip_m`` keywords of ``leg`` (a leg file) for the
    ``hexapod_gait`` checks; empty for AntBot's leg (None)."""
    if leg is None:
        return {}
    return {'kinematics': leg.kinematics(), 'neutral_tip_m': leg.neutral_tip_m}


def _unreachable(gait: Any, leg: Any = None) -> str | None:
    """Why the tip path of ``gait`` leaves the workspace of ``leg`` (a leg file; None:
    AntBot's leg) from its neutral tip, else None (the gait node's reach check)."""
    if gait is None:
        return None
    from hexapod_gait.config import check_reachable
    from hexapod_gait.errors import UnreachableError

    try:
        check_reachable(gait, **_leg_kw(leg))
    except UnreachableError as err:
        return f'{err}' + (f' (leg {leg.name!r})' if leg is not None else '')
    return None


def _infeasible(gait: Any, servo: str = 'ax18a', *, support: bool = True,
                leg: Any = None) -> list[str]:
    """Why the project calls ``gait`` infeasible: AntBot's servo limits
    (``hexapod_gait.feasibility``) for the servo preset (:func:`servo_limits`; measured on
    AntBot's leg), scaled to the step's joint path on ``leg`` against AntBot's 100 mm bench
    path (a leg file, as ``gait_scheduler -p leg_file`` scales them; None: AntBot's leg) and, with ``support``, phases with no leg on the ground (L(t) = 0);
    empty when it is not (or when standing, ``gait`` None)."""
    if gait is None:
        return []
    import numpy as np
    from hexapod_gait.feasibility import feasibility_violations
    from hexapod_gait.step_limits import limits_for_gait

    lim = servo_limits(servo)
    # the limits are phase durations on the 100 mm, 40 mm bench tip path: another step
    # reaches the servos' top speed at other durations (the gait node's own scaling, on the
    # leg it walks)
    lim = limits_for_gait(gait, lim, **_leg_kw(leg))
    out = feasibility_violations(gait, lim)
    if out:
        whose = "AntBot's servo limits" if servo.lower() in ('ax18a', 'ax-18a') else \
            f"AntBot's servo limits for {servo} servos"
        path = 'this step\'s joint path' if leg is None else \
            f'this step\'s joint path on leg {leg.name!r}'
        out[-1] += (f' ({whose} on {path}: swing >= '
                    f'{lim.min_swing_s:.3g} s, stance >= {lim.min_stance_s:.3g} s, <= '
                    f'{lim.max_step_frequency_hz:g} Hz)')
    if not support:
        return out
    bp, supporting = gait.support_profile()
    airborne = float(np.diff(np.append(np.asarray(bp, float), 1.0))[supporting == 0].sum())
    if airborne > 1e-9:
        out.append(f'no leg on the ground {100 * airborne:.0f} % of the cycle (L(t) = 0)')
    else:
        # every leg of one side in swing at once (on 4 or more legs) (a wave at the default
        # duty factor 0.5): gait_scheduler refuses it and energy calls the run infeasible;
        # the simulator walked it silently
        from hexapod_gait.config import check_static_support
        from hexapod_gait.errors import InfeasibleGaitError

        try:
            check_static_support(gait)
        except InfeasibleGaitError as err:
            out.append(str(err))
    return out


def _read_leg(path: str | None) -> Any:
    """The leg file at ``path`` (:func:`hexapod_gait.leg_file.read_leg_file`; its
    ``LegFileError``, a ValueError, names the file and the problem), None for None."""
    if path is None:
        return None
    from hexapod_gait.leg_file import read_leg_file

    return read_leg_file(path)


def _run_robot(args: argparse.Namespace) -> int:
    from .robot_sim import RobotConfig, RobotSimulator, default_robot_mass_kg

    leg = _read_leg(args.leg)
    # AntBot's body with this many legs (as sim_robot and the leg-count sweep: 1.851 kg on 4
    # legs); the six-leg 2.183 kg was kept for any leg count (a review); with a leg file,
    # AntBot's body and that many of the file's legs
    mass = default_robot_mass_kg(args.legs, None if leg is None
                                 else sum(leg.dh.link_masses_kg))
    if args.payload > MAX_PAYLOAD_RATIO * mass:
        print(f'hexapod-sim robot: error: --payload {args.payload:g} kg is more than '
              f'{MAX_PAYLOAD_RATIO:g} x the robot\'s mass ({mass:g} kg): at most '
              f'{MAX_PAYLOAD_RATIO * mass:.4g} kg', file=sys.stderr)
        return 2
    effects = parse_effects(args.effect, simulator='robot')
    config = RobotConfig(robot_mass_kg=mass,
                         leg_count=args.legs, gait=args.gait, duty_factor=args.duty_factor,
                         period_s=args.period,
                         speed_mps=args.speed if args.speed is not None else 0.0,
                         step_length_m=args.step_length, step_height_m=args.step_height,
                         payload_kg=args.payload, ambient_temperature_c=args.ambient_c,
                         initial_temperature_c=(args.ambient_c
                                                if args.initial_temperature is None
                                                else args.initial_temperature),
                         supply='battery' if args.battery else 'supply', servo=args.servo,
                         rate_hz=args.rate)
    gait = config.gait_pattern()
    far = _unreachable(gait, leg)
    if far:
        print(f'hexapod-sim robot: error: {far}', file=sys.stderr)
        return 2
    why = _infeasible(gait, args.servo, leg=leg)
    if why:
        what = (f'{gait.name} gait, duty factor {gait.duty_factor:g}, period '
                f'{gait.period_s:.4g} s, {gait.leg_count} legs')
        if not getattr(args, 'allow_infeasible', False):
            print(f'hexapod-sim robot: error: infeasible {what}: ' + '; '.join(why)
                  + ' (--allow-infeasible simulates it anyway)', file=sys.stderr)
            return 2
        print(f'hexapod-sim robot: warning: simulating an infeasible {what} '
              '(--allow-infeasible): ' + '; '.join(why), file=sys.stderr)
    t0 = time.perf_counter()
    sim = RobotSimulator(config, effects=effects, seed=args.seed, leg=leg)
    progress = _Progress(int(args.duration * args.rate), 'robot', not args.no_progress)
    try:
        trace = sim.run(args.duration, progress=progress)
    finally:
        progress.close()
    return _finish(args, trace, effects, t0)


#: a bench session is refused when its phases are shorter than this fraction of the servo's
#: minimal phase durations (or its step frequency this many times the limit's): a test rig may
#: walk a leg past the robot's limits (the paper's plan goes to 3.3 Hz), not at 1e9 Hz
BENCH_LIMIT_MARGIN = 2.0


def _bench_leg(values: Sequence[str]) -> tuple[str, str | None]:
    """The bench leg's place and leg file from the ``--leg`` values: a value with a path
    separator, a ``.yaml``/``.yml``/``.json`` suffix or naming an existing file is a leg file,
    any other a place (R2 by default); at most one of each (ValueError)."""
    places, files = [], []
    for v in values:
        path = Path(v)
        is_file = (any(sep in v for sep in ('/', '\\'))
                   or path.suffix.lower() in ('.yaml', '.yml', '.json') or path.is_file())
        (files if is_file else places).append(v)
    if len(places) > 1 or len(files) > 1:
        raise ValueError(f'--leg given {len(values)} times ({", ".join(values)}): at most one '
                         'place (e.g. R2) and one leg file')
    return (places[0] if places else 'R2'), (files[0] if files else None)


def _bench_infeasible(args: argparse.Namespace, leg: Any = None) -> list[str]:
    """The step frequencies of ``args`` far beyond what the bench leg can walk: phases under
    1 / :data:`BENCH_LIMIT_MARGIN` of the servo limits (:func:`_infeasible` of the gait at
    that frequency over the margin; a single leg needs no support), each with why; empty
    when all are within it."""
    from hexapod_gait.gait import make_gait
    out = []
    for f in sorted(set(args.frequencies)):
        if f <= 0:
            continue     # 0 Hz: the standing (basal) session
        gait = make_gait('tripod', duty_factor=args.duty_factor,
                         period_s=BENCH_LIMIT_MARGIN / f,
                         step_length_m=args.step_length, step_height_m=args.step_height)
        why = _infeasible(gait, args.servo, support=False, leg=leg)
        if why:
            out.append(f'{f:g} Hz: phases under 1/{BENCH_LIMIT_MARGIN:g} of the servo limits')
    return out


def _run_bench(args: argparse.Namespace) -> int:
    from hexapod_gait.gait import make_gait

    from .bench_sim import BenchConfig, BenchPlan, BenchSimulator
    place, leg_path = _bench_leg(args.leg)
    leg = _read_leg(leg_path)
    if any(f > 0 for f in args.frequencies):
        far = _unreachable(make_gait('tripod', duty_factor=args.duty_factor,
                                     step_length_m=args.step_length,
                                     step_height_m=args.step_height), leg)
        if far:
            print(f'hexapod-sim bench: error: {far}', file=sys.stderr)
            return 2
    why = _bench_infeasible(args, leg)
    if why:
        if not args.allow_infeasible:
            print('hexapod-sim bench: error: --frequencies far beyond what the leg can walk: '
                  + ' | '.join(why) + ' (--allow-infeasible simulates them anyway)',
                  file=sys.stderr)
            return 2
        print('hexapod-sim bench: warning: simulating infeasible --frequencies '
              '(--allow-infeasible): ' + ' | '.join(why), file=sys.stderr)
    effects = parse_effects(args.effect, simulator='bench')
    plan = BenchPlan(loads_kg=args.loads, frequencies_hz=args.frequencies,
                     walk_s=args.duration, duty_factor=args.duty_factor,
                     step_length_m=args.step_length, step_height_m=args.step_height,
                     max_cool_s=args.max_cool)
    config = BenchConfig(leg=place, servo=args.servo, rate_hz=args.rate)
    t0 = time.perf_counter()
    sim = BenchSimulator(config, effects=effects, seed=args.seed, leg=leg)
    total = int(len(plan.sessions()) * args.duration * args.rate)
    progress = _Progress(total, 'bench', not args.no_progress)
    try:
        trace = sim.run_plan(plan, progress=progress)
    finally:
        progress.close()
    return _finish(args, trace, effects, t0)


#: Longest ``--duration`` [s] and highest ``--rate`` [Hz].
MAX_DURATION_S = 86400.0
MAX_RATE_HZ = 10_000.0
#: Most output samples of one run (``--duration`` x ``--rate``, a bench plan's sessions
#: included): a robot sample holds about 2.2 kB until the bag is written, so 2e6 take about
#: 4.5 GB and 10 minutes (1e9 s ended in a MemoryError traceback).
MAX_SAMPLES = 2_000_000
#: Heaviest robot payload, in robot masses.
MAX_PAYLOAD_RATIO = 10.0

#: Numeric options of the subcommands and what they must be (checked before simulating);
#: an option a subcommand lacks, or left at None, is skipped. Every value must be finite.
_NUMBER_RULES: dict[str, tuple[str, Callable[[float], bool]]] = {
    'duration': (f'> 0 and <= {MAX_DURATION_S:g} s (24 h)', lambda v: 0 < v <= MAX_DURATION_S),
    'rate': (f'> 0 and <= {MAX_RATE_HZ:g} Hz', lambda v: 0 < v <= MAX_RATE_HZ),
    'legs': ('that is even and from 2 to 64', lambda v: 2 <= v <= 64 and v % 2 == 0),
    'seed': ('>= 0', lambda v: v >= 0),
    'runs': ('from 1 to 1000', lambda v: 1 <= v <= 1000),
    'speed': ('> 0', lambda v: v > 0),
    'period': ('>= 0 (0 = stand)', lambda v: v >= 0),
    'duty_factor': ('in (0, 1)', lambda v: 0 < v < 1),
    'step_length': ('>= 0', lambda v: v >= 0),
    'step_height': ('>= 0', lambda v: v >= 0),
    'payload': ('>= 0', lambda v: v >= 0),
    'ambient_c': ('from -40 to 80 degC', lambda v: -40 <= v <= 80),
    'initial_temperature': ('from -40 to 120 degC', lambda v: -40 <= v <= 120),
    'max_cool': ('>= 0', lambda v: v >= 0),
    'loads': ('>= 0 and <= 5 kg (the paper\'s stage carries up to 0.515 kg)',
              lambda v: 0 <= v <= 5.0),
    'frequencies': ('>= 0', lambda v: v >= 0),
}


def _check_numbers(args: argparse.Namespace) -> str | None:
    """Why a numeric option is refused, else None."""
    for name, (rule, ok) in _NUMBER_RULES.items():
        value = getattr(args, name, None)
        if value is None or isinstance(value, bool):
            continue
        for v in value if isinstance(value, (list, tuple)) else (value,):
            if not isinstance(v, (int, float)):
                continue
            if not math.isfinite(v) or not ok(v):
                option = '--' + name.replace('_', '-')
                got = f'{v:g}' if isinstance(v, float) else str(v)
                return f'{option} must be a finite number {rule}, got {got}'
    return None


def _check_samples(args: argparse.Namespace) -> str | None:
    """Why ``--duration`` x ``--rate`` gives too few samples to write or too many to hold,
    else None (the subcommands with a ``--rate``)."""
    rate = getattr(args, 'rate', None)
    duration = getattr(args, 'duration', None)
    if rate is None or duration is None:
        return None
    per_run = duration * rate
    what = f'--duration {duration:g} s at --rate {rate:g} Hz'
    if per_run < 2:
        return f'{what} holds {per_run:.3g} samples, fewer than 2: the bag would be empty'
    total = per_run
    if getattr(args, 'loads', None) and getattr(args, 'frequencies', None):
        total *= len(args.loads) * len(args.frequencies)
        what += f' x {len(args.loads) * len(args.frequencies)} sessions'
    if total > MAX_SAMPLES:
        return (f'{what} is {total:.3g} samples, more than {MAX_SAMPLES:g} (about 2 kB of '
                'memory each): shorten the run or lower the rate')
    return None


def _check_out(out: str) -> str | None:
    """Why the bag folder ``out`` cannot be created, else None (nothing is left behind)."""
    path = Path(out)
    if path.exists() or path.is_symlink():
        return f'--out {out} exists; refusing to overwrite (remove it or choose another name)'
    from hexapod_common.outdir import creatable_problem

    return creatable_problem(out)


def _created_by_run(out: str) -> list[Path]:
    """The folders a run writing ``out`` creates (``out`` and its missing parents), outermost
    last; taken before the run, so that a failed run removes only what it made."""
    made = []
    path = Path(out).absolute()
    while not path.exists() and path != path.parent:
        made.append(path)
        path = path.parent
    return made


def _remove_partial(made: list[Path]) -> None:
    """Remove what a failed run left: the bag folder and the parents it created (if empty)."""
    import shutil
    if not made:
        return
    shutil.rmtree(made[0], ignore_errors=True)
    for folder in made[1:]:
        try:
            folder.rmdir()
        except OSError:
            break     # not empty (someone else's now) or already gone


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # refuse before simulating: a bench plan takes minutes before the bag is written
    reason = _check_numbers(args) or _check_samples(args) or _check_out(args.out)
    if reason:
        print(f'hexapod-sim {args.command}: error: {reason}', file=sys.stderr)
        return 2
    made = _created_by_run(args.out)
    rc = 1
    try:
        rc = int(args.func(args))
    except EffectError as err:
        print(f'hexapod-sim {args.command}: error: --effect: {err}', file=sys.stderr)
        rc = 2
    except ValueError as err:
        print(f'hexapod-sim {args.command}: error: {err}', file=sys.stderr)
        rc = 2
    except KeyboardInterrupt:
        print(f'hexapod-sim {args.command}: interrupted; no bag written', file=sys.stderr)
        rc = 130
    finally:
        if rc != 0:
            _remove_partial(made)   # a failed run leaves no half-written bag behind
    return rc


if __name__ == '__main__':
    sys.exit(main())
