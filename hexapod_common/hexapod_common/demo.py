"""``hexapod-demo``: the whole graph on simulated hardware, recorded, replayed, analysed.

1. **Live**: ``gait_scheduler`` drives ``sim_robot`` (AntBot, 18 simulated AX-18A servos);
   ``energy_monitor`` publishes EnergeticDescriptors per gait cycle; ``bag_recorder`` records
   every contract topic. All nodes on one executor, in real time.
2. **Replay**: the recorded bag goes through a fresh ``energy_monitor`` in one process
   (``hexapod_common.replay.run_offline``); its descriptors must equal the live ones.
3. **Batch analysis**: ``hexapod-sim`` writes a bench plan and robot runs straight into bags;
   the robot carries an effect the analysis is not told about; ``hexapod-analyze energy``
   fits the single-leg surfaces and predicts the robot, and the residual loop finds the missing
   effect and reports the error before and after.
4. **SLIP**: ``hexapod-sim edubot`` writes RHex-class runs of the Table 1 gaits (motion capture
   in a tilted, offset frame with a hidden clock offset); ``hexapod-analyze slip`` finds the
   offset, the ground and the stances, fits a SLIP to every single-tripod stance and prints the
   per-gait table of Komsuoglu et al. Table 3 beside the paper's values.
5. ``report.html`` gathers the results. A summary is printed and saved as ``demo.json``.

Every run writes into ``--out`` itself (default ``demo_out``): an earlier demo run there (it
holds ``demo.json``) is first moved aside to ``<out>.prev``, replacing an older one; a
non-empty folder that is not a demo run is refused (exit 2) rather than mixed with it.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import shutil
import signal
import sys
import threading
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from hexapod_common.cli_args import NumberArgumentParser

__all__ = ['main']

def _energy_params() -> list:
    from rclpy.parameter import Parameter

    # AX servos report load as PWM duty, not torque: effort x velocity is not output power,
    # so the demo takes P_out from the Eq. 6 inverse-dynamics model of the gait.
    return [Parameter('current_sign', value='ros'),
            Parameter('power_out_source', value='model')]


FIELDS = ('window', 'speed', 'power_in', 'power_out', 'efficiency',
          'specific_cost_of_transport', 'specific_resistance')


def _say(text: str) -> None:
    print(text, flush=True)


#: Longest live graph [s] (wall time: the demo waits for it).
MAX_LIVE_SECONDS = 600.0


def check_args(args: argparse.Namespace) -> str | None:
    """Why an option of ``hexapod-demo`` cannot work, naming it, else None: checked before the
    live graph starts (``--speed 0`` walked at 0.2 m/s while saying 0, ``--speed nan`` ended in
    a ParameterError traceback from inside the graph, ``--live-seconds 1e9`` never ended)."""
    from hexapod_gait.errors import HexapodGaitError
    from hexapod_gait.feasibility import ActuatorLimits, period_for_speed
    from hexapod_gait.gait_node import GaitParams

    from hexapod_bench_drivers.effects import EffectError, parse_effects

    live = args.live_seconds
    if not (math.isfinite(live) and 0 < live <= MAX_LIVE_SECONDS):
        return (f'--live-seconds must be a finite number > 0 and <= {MAX_LIVE_SECONDS:g} s '
                f'(wall time of the live graph), got {live:g}')
    # the gait the live gait_scheduler walks: its defaults and actuator limits
    g = GaitParams()
    limits = ActuatorLimits(g.min_swing, g.min_stance, g.max_step_frequency)
    speed = args.speed
    if not (math.isfinite(speed) and speed > 0):
        return f'--speed must be a finite number > 0 m/s, got {speed:g}'
    try:
        period = period_for_speed(speed, g.duty_factor, g.step_length, limits)
    except HexapodGaitError as err:
        return f'--speed: {g.gait} gait on {g.leg_count} legs: {err}'
    if 2 * period > live:
        return (f'--speed {speed:g} m/s walks a {period:.3g} s gait cycle: the {live:g} s live '
                f'graph (--live-seconds) would not see 2 cycles; give at least '
                f'{2 * g.step_length / (g.duty_factor * live):.3g} m/s or more --live-seconds')
    try:
        parse_effects([args.hidden_effect], simulator='robot')
    except EffectError as err:
        return f'--hidden-effect: {err}'
    return _check_out(Path(args.out))


#: The file that marks a folder as a demo run (written first, completed last).
DEMO_MARKER = 'demo.json'


def previous_run_folder(out: Path) -> Path:
    """Where an earlier demo run in ``out`` is moved: ``<out>.prev`` beside it."""
    out = Path(os.path.abspath(out))
    return out.with_name(out.name + '.prev')


def _check_out(out: Path) -> str | None:
    """Why the output folder ``out`` cannot be used, else None (nothing is created).

    ``out`` is new, empty or an earlier demo run (it holds ``demo.json``: that run is moved
    aside to ``<out>.prev``, an older ``.prev`` run replaced); a folder holding anything else
    is refused, never mixed with the new run's results."""
    from hexapod_common.outdir import creatable_problem

    if out.exists() and not out.is_dir():
        return f'--out {out} is a file, not a folder'
    if not out.is_dir():
        return creatable_problem(out)
    if not any(out.iterdir()):
        return None
    prev = previous_run_folder(out)
    if not (out / DEMO_MARKER).is_file():
        return (f'--out {out} is not empty and is not an earlier demo run (it has no '
                f'{DEMO_MARKER}): give a new or empty folder; the demo does not mix its results '
                'with other files')
    here = Path.cwd().resolve()
    if out.resolve() == here or out.resolve() in here.parents:
        return (f'--out {out} holds the current folder: the earlier demo run in it cannot be '
                f'moved aside to {prev}; run from outside it')
    if prev.exists() and not (prev.is_dir() and (not any(prev.iterdir()) or
                                                 (prev / DEMO_MARKER).is_file())):
        return (f'--out {out}: the earlier demo run in it would be moved to {prev}, which '
                'exists and is not an earlier demo run; move it away')
    if not os.access(prev.parent, os.W_OK):
        return (f'--out {out}: cannot move the earlier demo run in it aside to {prev} (no '
                f'permission to write in {prev.parent})')
    return None


def prepare_out(out: Path) -> Path | None:
    """Make ``out`` an empty folder for a new run: an earlier demo run in it (checked by
    :func:`_check_out`) moves to ``<out>.prev``, replacing an older one. Returns where the
    earlier run went, None when there was none."""
    moved = None
    if out.is_dir() and any(out.iterdir()):
        prev = previous_run_folder(out)
        if prev.is_dir():
            shutil.rmtree(prev)
        elif prev.exists():
            prev.unlink()
        os.replace(os.path.abspath(out), prev)
        moved = prev
    out.mkdir(parents=True, exist_ok=True)
    return moved


def run_live(out: Path, seconds: float, speed_mps: float) -> tuple[Path, list[Any]]:
    """Run the live graph for ``seconds`` of wall time; returns the bag and the descriptors."""
    import rclpy
    from hexapod_interfaces.msg import EnergeticDescriptors
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.parameter import Parameter
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

    from hexapod_bench_drivers.sim_nodes import SimRobotNode
    from hexapod_common.recorder_node import BagRecorderNode
    from hexapod_energy.energy_node import EnergyMonitorNode
    from hexapod_gait.gait_node import GaitSchedulerNode

    bag = out / 'live_robot'
    context = rclpy.Context()
    rclpy.init(context=context)
    executor = SingleThreadedExecutor(context=context)
    ns = f'/demo_{random.randrange(1 << 30)}'  # keep apart from any other graph on the host
    nodes = [
        BagRecorderNode(context=context, namespace=ns, parameter_overrides=[
            Parameter('output', value=str(bag)),
            Parameter('topics', value=['joint_states', 'joint_commands', 'servo_status',
                                       'battery_state', 'gait/phase', 'energy/descriptors']),
            Parameter('discovery_period', value=0.1)]),
        EnergyMonitorNode(context=context, namespace=ns, parameter_overrides=_energy_params()),
        SimRobotNode(context=context, namespace=ns, parameter_overrides=[
            Parameter('seed', value=1)]),
    ]
    live: list[Any] = []
    probe = rclpy.create_node('demo_probe', context=context, namespace=ns)
    probe.create_subscription(EnergeticDescriptors, 'energy/descriptors', live.append,
                              QoSProfile(history=HistoryPolicy.KEEP_ALL,
                                         reliability=ReliabilityPolicy.RELIABLE))
    nodes.append(probe)
    for node in nodes:
        executor.add_node(node)
    # let the recorder see the simulator's publishers before the gait starts
    deadline = time.monotonic() + 5
    while len(nodes[0].counts) < 3 and time.monotonic() < deadline:
        executor.spin_once(timeout_sec=0.05)
    gait = GaitSchedulerNode(context=context, namespace=ns, parameter_overrides=[
        Parameter('speed', value=speed_mps)])
    nodes.append(gait)
    executor.add_node(gait)
    t_end = time.monotonic() + seconds
    while time.monotonic() < t_end:
        executor.spin_once(timeout_sec=0.05)
    executor.remove_node(gait)
    executor.remove_node(nodes[2])
    drain = time.monotonic() + 0.5
    while time.monotonic() < drain:
        executor.spin_once(timeout_sec=0.02)
    counts = dict(nodes[0].counts)
    for node in nodes:
        node.destroy_node()
    executor.shutdown()
    context.try_shutdown()
    _say(f'   recorded {sum(counts.values())} messages on {len(counts)} topics -> {bag}')
    return bag, live


def replay_offline(bag: Path, namespace_of: str) -> list[Any]:
    """Descriptors of a fresh energy_monitor fed the bag in one process."""
    import rclpy
    from rclpy.parameter import Parameter

    from hexapod_common.replay import run_offline
    from hexapod_energy.energy_node import EnergyMonitorNode

    context = rclpy.Context()
    rclpy.init(context=context)
    node = EnergyMonitorNode(context=context, namespace=namespace_of,
                             parameter_overrides=_energy_params())
    try:
        out = run_offline([node], bag)
    finally:
        node.destroy_node()
        context.try_shutdown()
    return next((v for k, v in out.items() if k.endswith('energy/descriptors')), [])


#: what demo.json keeps of residuals.json (its ``unit`` labels the errors in the report)
RESIDUAL_KEYS = ('unit', 'baseline', 'effects_added', 'final', 'heldout', 'added_params',
                 'summary')


#: the demo's recommendation speed [m/s]: Brodoline et al.'s Fig. 3A low-speed point
RECOMMEND_SPEED_MPS = 0.26


def sweep_summary(energy: dict[str, Any]) -> dict[str, Any]:
    """What the demo says of ``energy.json``'s sweeps and recommendation: each sweep's curve
    of lowest CoT/M (its value, speed and whether the bench covers it) and the
    recommendation against the default gait."""
    out: dict[str, Any] = {'lowest_cot_per_mass': {}}
    for name, curves in (energy.get('sweeps') or {}).items():
        best = None
        for c in curves:
            p = (c.get('optimal_points') or {}).get('min_cot_per_mass') or {}
            if isinstance(p.get('value'), (int, float)) and (
                    best is None or p['value'] < best['value']):
                best = {'curve': c.get('label'), 'value': p['value'],
                        'speed_mps': p.get('speed_mps'),
                        'outside_bench': bool(p.get('outside_bench'))}
        if best is not None:
            out['lowest_cot_per_mass'][name] = best
    rec = energy.get('recommendation') or {}
    if rec.get('best'):
        b, d = rec['best'], rec.get('default') or {}
        out['recommendation'] = {
            'speed_mps': rec.get('speed_mps'), 'payload_kg': rec.get('payload_kg'),
            'gait': b.get('gait'), 'duty_factor': b.get('duty_factor'),
            'step_length_m': b.get('step_length_m'),
            'cot_per_mass': b.get('specific_cost_of_transport'),
            'default_cot_per_mass': d.get('specific_cost_of_transport'),
            'saving_fraction': rec.get('saving_fraction'), 'note': rec.get('note')}
    return out


def batch_analysis(out: Path, hidden: str, quick: bool) -> dict[str, Any]:
    """Simulated bench plan + robot runs with a hidden effect -> energy analysis -> residuals."""
    from hexapod_bench_drivers.sim_cli import main as sim_main

    bench = out / 'bench'
    loads = '0,0.095,0.187,0.515' if quick else '0,0.095,0.141,0.187,0.515'
    freqs = '0,0.5,1,1.5,2,2.5,3' if quick else '0,0.5,1,1.5,2,2.5,3,3.3'
    rc = sim_main(['bench', '--out', str(bench), '--loads', loads, '--frequencies', freqs,
                   '--duration', '5', '--max-cool', '5', '--seed', '1', '--no-progress'])
    if rc:
        _child_failed('hexapod-sim bench', rc)
    robots = []
    for k, speed in enumerate((0.15, 0.3, 0.45, 0.6)):
        bag = out / f'robot_{k}'
        rc = sim_main(['robot', '--out', str(bag), '--speed', str(speed), '--duration', '15',
                       '--seed', str(10 + k), '--effect', hidden, '--no-progress'])
        if rc:
            _child_failed('hexapod-sim robot', rc)
        robots.append(bag)
    from hexapod_energy.cli import main as energy_main
    from hexapod_energy.prediction import RobotSpec

    # The simulated robot's stance tips carry (m_c + m_leg) g each, as a real robot's, and the
    # bench tip (m_leg + load) g: the paper's convention, no --load-offset.
    # with the paper's sweeps (four-quadrant Fig. 3A-D, power map Fig. 7D) and a
    # recommendation at Fig. 3A's 0.26 m/s: the report had none of them (a review)
    rc = energy_main(['--bench', str(bench), '--robot', *map(str, robots),
                      '--out', str(out / 'energy'), '--no-progress',
                      '--power-out', 'model', '--robot-mass', f'{RobotSpec().mass_kg:.4f}',
                      '--sweep', '--recommend', '--speed', str(RECOMMEND_SPEED_MPS),
                      '--payload', '0'])
    if rc:
        _child_failed('hexapod-analyze energy', rc)
    energy = json.loads((out / 'energy' / 'energy.json').read_text())
    result: dict[str, Any] = {'hidden_effect': hidden,
                              'prediction_error': energy.get('prediction_error'),
                              'sweeps': sweep_summary(energy)}
    try:
        from hexapod_energy.residuals import run_energy_loop
    except ImportError as err:
        result['residuals'] = f'unavailable: {err}'
        return result
    res = run_energy_loop([bench], robots, out / 'residuals')
    result['residuals'] = {k: res.get(k) for k in RESIDUAL_KEYS}
    result['other_lab'] = other_lab_check(out, robots[1], bench, energy['robot_runs'][1])
    return result


def other_lab_check(out: Path, robot_bag: Path, bench: Path, reference: dict[str, Any]
                    ) -> dict[str, Any]:
    """The 0.3 m/s run as a lab with its own gait code records it (``ros2 bag record
    /joint_states /battery_state``: no ``/gait/phase``) -> ``hexapod-analyze energy`` with the
    gait described on the command line; its figures against the full bag's."""
    from hexapod_common.bags import BagWriter, iter_messages, open_reader
    from hexapod_energy.cli import main as energy_main
    from hexapod_energy.prediction import RobotSpec

    lab = out / 'other_lab_robot'
    with open_reader(robot_bag) as reader, BagWriter(lab) as writer:
        for m in iter_messages(reader, ['/joint_states', '/battery_state']):
            writer.write(m.topic, m.msgtype, m.data, m.stamp_ns)
    rc = energy_main(['--bench', str(bench), '--robot', str(lab), '--out',
                      str(out / 'other_lab'), '--no-progress',
                      '--robot-mass', f'{RobotSpec().mass_kg:.4f}',
                      '--robot-speed', f"{reference['speed']:.6g}", '--gait', 'tripod',
                      '--duty-factor', '0.5', '--step-length', '0.1'])
    if rc:
        raise RuntimeError(f'hexapod-analyze energy on the no-/gait/phase bag failed ({rc})')
    run = json.loads((out / 'other_lab' / 'energy.json').read_text())['robot_runs'][0]
    return {'period_s': run['period_s'], 'reference_period_s': reference['period_s'],
            'power_in_w': run['measured_power_in_w'],
            'reference_power_in_w': reference['measured_power_in_w'],
            'power_out_source': run['power_out_source'], 'cycle_source': run['cycle_source']}


EDUBOT_MASS_KG = 3.31


def _table3() -> dict[str, tuple[float, float, float]]:
    """Komsuoglu et al. Table 3 (``slip_identification.energetics.PAPER_TABLE3``), in its
    gait order: gait -> (nerr mean, P [W], v [m/s]); SR = P / (m g v), m 3.31 kg."""
    from slip_identification.energetics import PAPER_TABLE3

    return {g: (e['nerr'][0], e['power_w'][0], e['speed_mps'][0])
            for g, e in PAPER_TABLE3.items()}


def _bag_truth(bag: Path) -> dict[str, Any]:
    """The simulator's truth from the bag's custom metadata (for display only: the analysis
    never reads it)."""
    import yaml

    meta = yaml.safe_load((bag / 'metadata.yaml').read_text())['rosbag2_bagfile_information']
    raw = (meta.get('custom_data') or {}).get('hexapod_sim.edubot_truth')
    return json.loads(raw) if raw else {}


def slip_run_summary(run: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
    """One run of ``slip.json`` for ``demo.json``: what was found beside the simulator's
    hidden truth, and the run's power, speed, SR and skipped stances (the report's per-run
    table)."""
    frame = truth.get('frame', {})
    return {'bag': run['bag'], 'gait': run.get('gait'),
            'offset_s': run.get('offset_s'), 'offset_method': run.get('offset_method'),
            'true_offset_s': truth.get('clock_offset_s'),
            'ground_m': run.get('ground_m'),
            'true_ground_m': frame.get('ground_plane_z_m'),
            'tilt_deg': (run.get('frame') or {}).get('tilt_deg'),
            'true_tilt_deg': frame.get('tilt_deg'), 'stances': run.get('stances'),
            'skipped': run.get('skipped'), 'power_w': run.get('power_w'),
            'speed_mps': run.get('speed_mps'), 'sr': run.get('sr')}


def slip_analysis(out: Path, quick: bool) -> dict[str, Any]:
    """Simulated EduBot runs of the Table 1 gaits -> ``hexapod-analyze slip``."""
    from hexapod_bench_drivers.sim_cli import main as sim_main
    from slip_identification.cli import main as slip_main

    from slip_identification.energetics import paper_table3_rows

    gaits = ('running', 'walk') if quick else tuple(_table3())
    bags = []
    for k, gait in enumerate(gaits):
        bag = out / f'edubot_{gait}'
        rc = sim_main(['edubot', '--out', str(bag), '--gait', gait, '--duration', '6',
                       '--seed', str(k + 1)])
        if rc:
            _child_failed('hexapod-sim edubot', rc)
        bags.append(bag)
    rc = slip_main([*map(str, bags), '--out', str(out / 'slip'), '--jobs', '2',
                    '--mass', f'{EDUBOT_MASS_KG:g}'])
    if rc:
        _child_failed('hexapod-analyze slip', rc)
    doc = json.loads((out / 'slip' / 'slip.json').read_text())
    runs = [slip_run_summary(run, _bag_truth(Path(run['bag']))) for run in doc.get('runs', [])]
    return {'gaits': doc.get('gaits', {}), 'runs': runs,
            'skipped_counts': doc.get('skipped_counts', {}),
            'paper_table3': paper_table3_rows(EDUBOT_MASS_KG)}


def _say_slip(slip: dict[str, Any]) -> None:
    for r in slip['runs']:
        def ms(x: Any) -> str:
            return f'{1e3 * x:+.1f} ms' if isinstance(x, (int, float)) else 'n/a'

        def mm(x: Any) -> str:
            return f'{1e3 * x:.1f} mm' if isinstance(x, (int, float)) else 'n/a'

        _say(f'   {r["gait"]:8s} clock offset {ms(r["offset_s"])} ({r["offset_method"]}; hidden '
             f'{ms(r["true_offset_s"])}), ground {mm(r["ground_m"])} (hidden '
             f'{mm(r["true_ground_m"])}), {r["stances"]} stances')
    _say('   gait      stances  nerr   nerr world (Table 3)  P [W]         v [m/s]       SR'
         '           (Table 3 in brackets; nerr: bx from each stance\'s first sample, '
         'nerr world: Eq. 2 read literally)')
    table3 = _table3()
    order = {g: k for k, g in enumerate(table3)}
    for gait, row in sorted(slip['gaits'].items(), key=lambda kv: order.get(kv[0], 99)):
        ref = table3.get(gait, (math.nan,) * 3)
        sr_ref = ref[1] / (EDUBOT_MASS_KG * 9.81 * ref[2])
        _say(f'   {gait:8s} {int(row.get("stances", 0)):6d}   '
             f'{row.get("nerr_mean", math.nan):.3f}  {row.get("nerr_world_mean", math.nan):.3f} '
             f'({ref[0]:.3f})       {row.get("power_w_mean", math.nan):5.1f} ({ref[1]:5.1f})  '
             f'{row.get("speed_mps_mean", math.nan):.2f} ({ref[2]:.2f})   '
             f'{row.get("sr_mean", math.nan):.2f} ({sr_ref:.2f})')
    if slip.get('skipped_counts'):
        _say(f'   skipped stances: {slip["skipped_counts"]}')


def _child_failed(what: str, rc: int) -> None:
    """A step's command returned ``rc``: 130 is the user's Ctrl-C it caught (the demo stops
    as interrupted), anything else a failure."""
    if rc == 130:
        raise KeyboardInterrupt
    raise RuntimeError(f'{what} failed with exit code {rc}')


class _Terminated(Exception):
    """SIGTERM arrived (raised in the main thread by :func:`_on_sigterm`)."""


def _on_sigterm(signum: int, frame: Any) -> None:
    raise _Terminated()


def _say_sweeps(sw: dict[str, Any]) -> None:
    low = sw.get('lowest_cot_per_mass') or {}
    if low:
        _say('   sweeps (four-quadrant plots Fig. 3A-D, power map Fig. 7D in energy/), lowest '
             'CoT/M [J/(m kg)] per sweep (* extrapolates the bench):')
        for name, b in low.items():
            _say(f"     {name.replace('_', ' ')}: {b['curve']} {b['value']:.1f} at "
                 f"{b['speed_mps']:.2f} m/s{' *' if b['outside_bench'] else ''}")
    rec = sw.get('recommendation')
    if rec:
        saving = rec.get('saving_fraction')
        _say(f"   recommendation at {rec['speed_mps']:g} m/s, {rec['payload_kg']:g} kg: "
             f"{rec['gait']} beta {rec['duty_factor']:.2f}, step "
             f"{1000 * rec['step_length_m']:.0f} mm, CoT/M {rec['cot_per_mass']:.1f} "
             f"(default tripod beta 0.5, 100 mm: {rec['default_cot_per_mass']:.1f}; saving "
             f"{100 * saving:+.1f} %)" if isinstance(saving, (int, float)) else
             f"   recommendation at {rec['speed_mps']:g} m/s: {rec['gait']}")
        if rec.get('note'):
            _say(f"     {rec['note']}")


def main(argv: Sequence[str] | None = None) -> int:
    """``hexapod-demo``; Ctrl-C stops it with one line and exit 130 (it printed a traceback,
    or exit 1 naming a step's exit code 130: an outside review), SIGTERM with one line and
    exit 143 (it died without a word, its bags half written); ``demo.json`` stays
    ``incomplete``."""
    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _on_sigterm) if main_thread else None
    try:
        return _main_interruptible(argv)
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, signal.SIG_DFL if previous is None else previous)


def _main_interruptible(argv: Sequence[str] | None) -> int:
    try:
        return _main(argv)
    except _Terminated:
        print('hexapod-demo: stopped (SIGTERM); the results so far stay in the output folder, '
              'demo.json says "incomplete"', file=sys.stderr)
        return 143
    except KeyboardInterrupt:
        print('hexapod-demo: interrupted; the results so far stay in the output folder, '
              'demo.json says "incomplete"', file=sys.stderr)
        return 130
    except Exception as err:   # noqa: BLE001 - rclpy's shutdown by its own SIGINT handler
        if type(err).__name__ != 'ExternalShutdownException':
            raise
        print('hexapod-demo: interrupted; demo.json says "incomplete"', file=sys.stderr)
        return 130


def _main(argv: Sequence[str] | None = None) -> int:
    parser = NumberArgumentParser(prog='hexapod-demo', description=__doc__.split('\n')[0])
    parser.add_argument('--out', default='demo_out',
                        help='output folder (default demo_out): new, empty or an earlier demo '
                             'run, which is moved to <out>.prev (replacing an older one); a '
                             'folder holding anything else is refused')
    parser.add_argument('--live-seconds', type=float, default=6.0,
                        help='wall-clock seconds of the live graph, > 0 and <= '
                             f'{MAX_LIVE_SECONDS:g} (default 6)')
    parser.add_argument('--speed', type=float, default=0.3,
                        help='walking speed of the live graph [m/s], > 0 and feasible for '
                             'the tripod gait (AntBot: <= 0.6), at least 2 cycles in '
                             '--live-seconds (default 0.3)')
    parser.add_argument('--hidden-effect', default='supply_resistance=0.35',
                        help='effect put in the robot data and not told to the analysis')
    parser.add_argument('--quick', action='store_true', help='smaller bench plan')
    args = parser.parse_args(argv)
    if reason := check_args(args):
        print(f'hexapod-demo: error: {reason}', file=sys.stderr)
        return 2
    out = Path(args.out)
    moved = prepare_out(out)
    if moved is not None:
        _say(f'0. the earlier demo run in {out} moved to {moved}')
    started = time.strftime('%Y-%m-%dT%H:%M:%S%z')
    summary: dict[str, Any] = {'out': str(out), 'started': started, 'status': 'incomplete'}
    # the marker first: a run that stops half-way is still known as a demo run next time
    (out / DEMO_MARKER).write_text(json.dumps(summary, indent=1))
    t0 = time.monotonic()

    _say(f'1. live graph: gait_scheduler -> sim_robot -> energy_monitor, '
         f'{args.live_seconds:.0f} s at {args.speed} m/s')
    bag, live = run_live(out, args.live_seconds, args.speed)
    for msg in live:
        _say(f'   window {msg.window:.2f} s  v {msg.speed:.3f} m/s  P_in {msg.power_in:6.2f} W'
             f'  P_out {msg.power_out:5.2f} W  eta {100 * msg.efficiency:4.2f} %  '
             f'CoT/M {msg.specific_cost_of_transport:6.1f} J/(m kg)  '
             f'SR {msg.specific_resistance:5.2f}')
    if not live:
        _say('   error: no descriptors were published live')
        return 1

    _say('2. replay of the recorded bag through a fresh energy_monitor (one process)')
    ns = None
    from hexapod_common.bags import open_reader
    with open_reader(bag) as reader:
        topics = [c.topic for c in reader.connections]
    ns = topics[0].rsplit('/', 1)[0]
    ns = ns[:-len('/energy')] if ns.endswith('/energy') else ns
    ns = ns[:-len('/gait')] if ns.endswith('/gait') else ns
    replayed = replay_offline(bag, ns)
    pairs = list(zip(live, replayed))
    worst = max((abs(getattr(a, f) - getattr(b, f)) for a, b in pairs for f in FIELDS
                 if not (math.isnan(getattr(a, f)) and math.isnan(getattr(b, f)))),
                default=math.nan)
    _say(f'   live {len(live)} windows, replayed {len(replayed)}; largest difference over '
         f'{len(pairs)} common windows: {worst:.3g}')
    summary['live'] = {'windows': len(live), 'replayed': len(replayed),
                       'max_abs_difference': worst,
                       'power_in_w': [m.power_in for m in live],
                       'specific_cost_of_transport': [m.specific_cost_of_transport
                                                      for m in live]}

    _say(f'3. batch: bench plan + 4 robot runs with a hidden effect ({args.hidden_effect}), '
         'analysed offline')
    batch = batch_analysis(out, args.hidden_effect, args.quick)
    summary['batch'] = batch
    pe = batch.get('prediction_error') or {}
    if pe:
        _say(f'   single-leg prediction vs measured robot P_in: RMSE '
             f'{pe.get("rmse_w", math.nan):.2f} W, bias (predicted - measured) '
             f'{pe.get("bias_w", math.nan):+.2f} W')
    _say_sweeps(batch.get('sweeps') or {})
    lab = batch.get('other_lab')
    if lab:
        _say(f"   the 0.3 m/s run as a lab with its own gait code records it (joint states and"
             f" battery only, no /gait/phase): period from the joints {lab['period_s']:.4f} s"
             f" (schedule {lab['reference_period_s']:.4f} s), P_in {lab['power_in_w']:.2f} W"
             f" (with the schedule {lab['reference_power_in_w']:.2f} W)")
    res = batch.get('residuals')
    if isinstance(res, dict):
        held = res.get('heldout') or {}
        _say(f'   residual loop added: {res.get("effects_added")}; held-out RMSE '
             f'{held.get("rmse_before", math.nan):.3f} W -> '
             f'{held.get("rmse_after", math.nan):.3f} W')
        if res.get('summary'):
            _say(f'   {res["summary"]}')
    else:
        _say(f'   residual loop: {res}')

    _say('4. SLIP: simulated EduBot runs (Table 1 gaits) -> hexapod-analyze slip')
    slip = slip_analysis(out, args.quick)
    summary['slip'] = slip
    _say_slip(slip)

    summary['status'] = 'complete'
    summary['finished'] = time.strftime('%Y-%m-%dT%H:%M:%S%z')
    (out / DEMO_MARKER).write_text(json.dumps(summary, indent=1, default=str))
    from hexapod_common.report import write_report
    report = write_report(out)
    _say(f'5. report: {report}  ({time.monotonic() - t0:.0f} s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
