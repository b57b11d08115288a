"""`hexapod-analyze energy` for robots other than AntBot: leg count, mass, actuator limits, legs
that cannot walk every sweep curve, unknown P_out (an outside review with 4- and 8-legged
robots)."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from test_energy_sweeps import StubTrajectory as _SweepStub

from hexapod_common.bags import BagWriter, new_msg, stamp
from hexapod_energy.cli import build_parser, main
from hexapod_energy.errors import InvalidInputError
from hexapod_energy.prediction import OutputPowerModel
from hexapod_energy.recommend import recommend_gait
from hexapod_energy.sweeps import (
    GAIT_TYPE_MIN_SPEED_MPS,
    STANDARD_SWEEPS,
    SweepSpec,
    run_standard_sweeps,
)

SHORT_LEG = """name: ShortReach
a_m: [0.02, 0.05, 0.06]
link_masses_kg: [0.01, 0.04, 0.02]
neutral_tip_m: [0.09, 0.0, -0.05]
"""


class Phase:
    """Analytic phase powers: basal 1.9 W per leg plus rate- and load-dependent parts."""

    def p_stance_w(self, t: np.ndarray, m: np.ndarray) -> np.ndarray:
        f = 1 / np.asarray(t)
        return 1.9 + 0.45 * f + 0.05 * f**2 + 2.0 * np.asarray(m) * (1 + 0.2 * f)

    def p_swing_w(self, t: np.ndarray, m: np.ndarray) -> np.ndarray:
        f = 1 / np.asarray(t)
        return 1.9 + 0.5 * f + 0.06 * f**2 + 0 * np.asarray(m)


class StubTrajectory(_SweepStub):
    """The sweep tests' sinusoidal joints; a step above 125 mm is out of reach."""

    def __init__(self, gait: object, leg_index: int, **kw: object) -> None:
        if gait.step_length_m > 0.125:
            raise ValueError('tip target out of reach (stub)')
        super().__init__(gait, leg_index, **kw)


@pytest.fixture(scope='module')
def opm() -> OutputPowerModel:
    return OutputPowerModel(trajectory_factory=StubTrajectory, n_samples=32)


@pytest.fixture(scope='module')
def bench(tmp_path_factory) -> Path:
    from test_energy_cli import _write_bench

    root = tmp_path_factory.mktemp('other_robots')
    _write_bench(root / 'bench')
    return root / 'bench'


def _help(dest: str) -> str:
    return next(a.help for a in build_parser()._actions if a.dest == dest)


def _doc(out: Path) -> dict:
    return json.loads((out / 'energy.json').read_text())


# ---------------------------------------------------------------- 1: leg count of --recommend

def test_recommend_uses_the_legs_given(bench, tmp_path) -> None:
    """--legs 4 was accepted and ignored: the answer was a 6-legged gait."""
    out = tmp_path / 'o'
    assert main(['--bench', str(bench), '--out', str(out), '--robot-mass', '2.0', '--legs', '4',
                 '--recommend', '--speed', '0.2', '--no-progress']) == 0
    rec = _doc(out)['recommendation']
    assert rec['leg_count'] == 4 and rec['leg_count_source'] == '--legs'
    assert rec['best']['leg_count'] == 4
    assert rec['default']['leg_count'] == 4 and rec['default']['gait'] == 'alternating'


def test_leg_count_from_the_robot_runs_else_six_with_a_warning() -> None:
    from hexapod_energy.cli import _robot_leg_count

    args = SimpleNamespace(legs=None, sweep=True, recommend=False)
    doc: dict = {}
    assert _robot_leg_count(args, [{'leg_count': 4}, {'leg_count': None}], doc) == \
        (4, 'robot bags')
    assert 'warnings' not in doc
    n, source = _robot_leg_count(args, [], doc)
    assert (n, source) == (6, 'assumed: AntBot')
    assert any('assume 6 legs' in w for w in doc['warnings'])
    args.legs = 8
    assert _robot_leg_count(args, [{'leg_count': 6}], doc) == (8, '--legs')


def test_legs_help_names_sweep_and_recommend() -> None:
    legs = _help('legs')
    assert '--sweep' in legs and '--recommend' in legs
    assert 'recommend' in _help('limits') and 'AntBot' in _help('limits')
    assert 'held fixed' in _help('sweep') or 'sweep_settings' in _help('sweep')


# ---------------------------------------------------------------- 2: sweeps at the leg count

def test_standard_sweeps_follow_the_leg_count() -> None:
    from hexapod_energy.sweeps import standard_sweeps

    four = standard_sweeps(4)
    for name in ('duty_factor', 'step_length', 'gait_type'):
        assert {s.leg_count for s in four[name]} == {4}
    assert [s.leg_count for s in four['leg_count']] == [4, 6, 8]
    assert four['gait_type'][0].gait == 'alternating'
    assert four['gait_type'][1].duty_factor == pytest.approx(0.75)
    assert standard_sweeps(8)['gait_type'][1].duty_factor == pytest.approx(0.875)
    # AntBot's set is the paper's, unchanged
    assert STANDARD_SWEEPS == standard_sweeps(6)
    assert STANDARD_SWEEPS['gait_type'][1] == SweepSpec('wave beta 0.83', 'wave', 6, 0.83,
                                                        min_speed_mps=GAIT_TYPE_MIN_SPEED_MPS)
    assert STANDARD_SWEEPS['duty_factor'][0].gait == 'tripod'


def test_sweep_output_is_for_the_robots_legs_and_says_what_is_fixed(opm, tmp_path) -> None:
    from hexapod_gait.feasibility import ActuatorLimits

    from hexapod_energy.cli import _sweep

    doc: dict = {'plots': []}
    lim = ActuatorLimits(0.3, 0.25, 2.0)
    _sweep(doc, Phase(), opm, tmp_path, None, leg_count=4, leg_count_source='--legs',
           limits=lim, limits_source='--limits')
    legs = {k: [c['leg_count'] for c in v] for k, v in doc['sweeps'].items()}
    assert legs['duty_factor'] == [4] * 4 and legs['gait_type'] == [4] * 3
    assert legs['leg_count'] == [4, 6, 8]
    assert doc['power_map']['leg_count'] == 4 and doc['power_map']['gait'] == 'alternating'
    st = doc['sweep_settings']
    assert st['leg_count'] == 4 and st['robot_mass_kg'] == pytest.approx(opm.robot.mass_kg)
    assert st['limits'] == {'min_swing_s': 0.3, 'min_stance_s': 0.25,
                            'max_step_frequency_hz': 2.0}
    assert st['limits_source'] == '--limits'
    assert set(st['held_fixed']) >= set(doc['sweeps']) | {'power_map'}
    # 4: the limits set the maximum speed: beta 0.5, 100 mm, T_min = max(0.5, 0.6, 0.5)
    beta05 = doc['sweeps']['duty_factor'][0]
    assert beta05['max_speed_mps'] == pytest.approx(0.1 / (0.5 * 0.6))


# ---------------------------------------------------------------- 3: mass said and recorded

def test_recommend_without_a_mass_warns_and_records_it(bench, tmp_path) -> None:
    out = tmp_path / 'o'
    assert main(['--bench', str(bench), '--out', str(out), '--recommend', '--speed', '0.2',
                 '--no-progress']) == 0
    doc = _doc(out)
    assert any('robot mass not given' in w for w in doc['warnings'])
    rec = doc['recommendation']
    assert rec['robot_mass_kg'] == pytest.approx(2.183)
    assert rec['mass_kg'] == pytest.approx(2.183)
    assert rec['leg_count_source'] == 'assumed: AntBot'


# ---------------------------------------------------------------- 4: actuator limits

def test_limits_option_is_used_validated_and_reported(bench, tmp_path, capsys) -> None:
    out = tmp_path / 'o'
    assert main(['--bench', str(bench), '--out', str(out), '--robot-mass', '2.183',
                 '--recommend', '--speed', '0.1', '--limits', '0.4', '0.4', '1.0',
                 '--no-progress']) == 0
    rec = _doc(out)['recommendation']
    assert rec['limits'] == {'min_swing_s': 0.4, 'min_stance_s': 0.4,
                             'max_step_frequency_hz': 1.0}
    assert rec['limits_source'] == '--limits'
    best = rec['best']
    assert best['period_s'] * (1 - best['duty_factor']) >= 0.4 - 1e-9
    assert best['period_s'] * best['duty_factor'] >= 0.4 - 1e-9
    assert best['period_s'] >= 1.0 - 1e-9
    capsys.readouterr()
    assert main(['--bench', str(bench), '--out', str(tmp_path / 'bad'), '--recommend',
                 '--speed', '0.1', '--limits', '0.4', '-1', '1', '--no-progress']) == 2
    err = capsys.readouterr().err
    assert '--limits' in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / 'bad').exists()
    default = tmp_path / 'd'
    assert main(['--bench', str(bench), '--out', str(default), '--robot-mass', '2.183',
                 '--recommend', '--speed', '0.1', '--no-progress']) == 0
    rec = _doc(default)['recommendation']
    assert rec['limits']['min_swing_s'] == 0.16 and 'AntBot' in rec['limits_source']


# ---------------------------------------------------------------- 5: unreachable curve skipped

def test_a_curve_the_leg_cannot_walk_is_skipped_with_a_warning(opm, tmp_path) -> None:
    specs = {'step_length': tuple(SweepSpec(f'step {s}', 'tripod', 6, 0.5, s)
                                  for s in (0.10, 0.14))}
    with pytest.raises(ValueError, match='out of reach'):
        run_standard_sweeps(Phase(), opm, sweeps=specs, n_speeds=5)
    skipped: list[str] = []
    curves = run_standard_sweeps(Phase(), opm, sweeps=specs, n_speeds=5, skipped=skipped)
    assert [c.spec.label for c in curves['step_length']] == ['step 0.1']
    assert len(skipped) == 1 and "'step_length'" in skipped[0] and "'step 0.14'" in skipped[0]
    # the CLI's sweep: the rest written, the skipped curve said in warnings and settings
    from hexapod_energy.cli import _sweep

    doc: dict = {'plots': []}
    _sweep(doc, Phase(), opm, tmp_path, None, leg_count=6)
    assert [c['label'] for c in doc['sweeps']['step_length']] == ['step 70 mm', 'step 100 mm',
                                                                  'step 120 mm']
    assert any("'step 140 mm' skipped" in w for w in doc['warnings'])
    assert doc['sweep_settings']['skipped'] == [w for w in doc['warnings'] if 'skipped' in w]
    assert 'four_quadrant_step_length.png' in doc['plots']
    # Fig. 3C's comparison: one line per payload, wave over tripod
    cmp = doc['gait_type_comparison']
    assert cmp['base'] == 'tripod beta 0.5' and cmp['other'] == 'wave beta 0.83'
    assert len(cmp['below_one_until_mps']) == len(cmp['payloads_kg'])
    assert 'gait_type_comparison.png' in doc['plots']
    assert (tmp_path / 'gait_type_comparison.png').stat().st_size > 10_000


# ---------------------------------------------------------------- 6: P_out unknown is null

def _write_robot_step(path: Path, step_m: float, period_s: float = 0.8) -> None:
    """Tripod robot bag with /gait/phase (step ``step_m``), battery only (no efforts)."""
    legs = ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')
    offsets = (0.0, 0.5, 0.0, 0.5, 0.0, 0.5)
    with BagWriter(path) as w:
        for t in np.arange(0.0, 6 * period_s, 0.01):
            ns = int(round(t * 1e9))
            w.write('/battery_state', 'sensor_msgs/msg/BatteryState', new_msg(
                'sensor_msgs/msg/BatteryState', header=stamp(ns), voltage=12.0,
                current=-20.0 / 12.0), ns)
            w.write('/gait/phase', 'hexapod_interfaces/msg/GaitPhase', new_msg(
                'hexapod_interfaces/msg/GaitPhase', header=stamp(ns), gait='tripod',
                period=period_s, duty_factor=0.5, step_length=step_m, step_height=0.04,
                cycle_phase=(t / period_s) % 1.0, leg_names=list(legs),
                phase_offsets=list(offsets), in_stance=[True] * 6, supporting_legs=3), ns)


def test_unknown_power_out_is_null_not_zero(bench, tmp_path) -> None:
    from hexapod_common.report import write_report

    leg = tmp_path / 'short_leg.yaml'
    leg.write_text(SHORT_LEG)
    _write_robot_step(tmp_path / 'robot', 0.14)
    out = tmp_path / 'o'
    assert main(['--bench', str(bench), '--robot', str(tmp_path / 'robot'), '--leg', str(leg),
                 '--robot-mass', '1.2', '--out', str(out), '--no-progress']) == 0
    doc = _doc(out)
    r = doc['robot_runs'][0]
    assert r['power_out_source'] == 'none'
    for key in ('power_out_w', 'efficiency', 'cost_of_transport',
                'specific_cost_of_transport'):
        assert r[key] is None, key
    assert r['specific_resistance'] is not None and r['measured_power_in_w'] > 0
    assert any('no P_out model' in w for w in doc['warnings'])
    assert 'where_the_watts_go.png' in doc['plots']
    assert write_report(out).stat().st_size > 0


# ---------------------------------------------------------------- 7: --load-offset help

def test_load_offset_help_states_the_papers_convention() -> None:
    help_ = ' '.join(_help('load_offset').split())
    assert '0.166' not in help_ and 'hexapod-sim' not in help_
    assert 'M g / L' in help_ and '(m_leg + load) g' in help_ and 'stage mass' in help_


# ---------------------------------------------------------------- 8: impossible robot

def test_a_robot_lighter_than_its_legs_is_refused(bench, tmp_path, capsys) -> None:
    # AntBot's legs weigh 0.166 kg: 6 of them 0.996 kg > 0.9 kg
    for extra in (['--legs', '6'], []):
        out = tmp_path / f'o{len(extra)}'
        assert main(['--bench', str(bench), '--out', str(out), '--robot-mass', '0.9',
                     '--recommend', '--speed', '0.2', '--no-progress'] + extra) == 2
        err = capsys.readouterr().err
        assert 'outweigh' in err and len(err.strip().splitlines()) == 1
    # four such legs are lighter than the robot
    assert main(['--bench', str(bench), '--out', str(tmp_path / 'q'), '--robot-mass', '0.9',
                 '--legs', '4', '--recommend', '--speed', '0.2', '--no-progress']) == 0


# ---------------------------------------------------------------- 9: recommend_gait's grid

def test_tetrapod_is_searched_for_other_leg_counts(opm) -> None:
    rec = recommend_gait(Phase(), opm, speed_mps=0.1, leg_count=8, gaits=('tetrapod',),
                         step_lengths_m=(0.1,))
    assert rec.best.gait == 'tetrapod' and rec.best.leg_count == 8 and rec.evaluated > 0


def test_no_candidate_says_what_happened(opm) -> None:
    with pytest.raises(InvalidInputError) as err:
        recommend_gait(Phase(), opm, speed_mps=5.0, leg_count=8, gaits=('tetrapod',))
    msg = str(err.value)
    assert '0 configurations' not in msg and 'exceed the actuator limits' in msg
    with pytest.raises(InvalidInputError, match='no configuration was searched'):
        recommend_gait(Phase(), opm, speed_mps=0.1, gaits=())
    with pytest.raises(InvalidInputError, match='not gaits for this leg count'):
        recommend_gait(Phase(), opm, speed_mps=0.1, leg_count=4, gaits=('tripod',))


def test_each_gaits_typical_duty_factor_is_a_candidate(opm) -> None:
    """An 8-leg wave's typical beta 7/8 was beyond the grid's 0.85."""
    rec = recommend_gait(Phase(), opm, speed_mps=0.05, leg_count=8, gaits=('wave',),
                         step_lengths_m=(0.1,))
    # 0.5-0.85 by 0.05, 5/6 and 7/8; a wave at 0.5-0.6 lifts a whole side (rejected)
    assert rec.evaluated == 7 and rec.rejected == 3
    only = recommend_gait(Phase(), opm, speed_mps=0.05, leg_count=8, gaits=('wave',),
                          step_lengths_m=(0.1,), duty_factors=(0.875,))
    assert only.best.duty_factor == pytest.approx(0.875)
    d = rec.to_dict()
    assert d['leg_count'] == 8 and d['robot_mass_kg'] == pytest.approx(opm.robot.mass_kg)


def test_progress_bars_in_a_log_refresh_once_a_minute(tmp_path):
    """A bar written to a file (``make demo > log``) refreshes at most once a minute besides its
    first and last state; on a terminal as tqdm does; --no-progress turns it off."""
    import io

    from tqdm import tqdm

    from hexapod_common.progress import LOG_REFRESH_S, bar_options

    class Tty(io.StringIO):
        def isatty(self) -> bool:
            return True

    assert bar_options(True) == {'disable': True}
    assert bar_options(stream=Tty()) == {}
    log = io.StringIO()
    assert bar_options(stream=log)['mininterval'] == LOG_REFRESH_S >= 30
    with tqdm(total=5000, file=log, desc='work', **bar_options(stream=log)) as bar:
        for _ in range(5000):
            bar.update(1)
    # the first and the last state reach the log
    frames = [f for f in log.getvalue().split('\r') if f.strip()]
    assert 'work:   0%' in frames[0] and 'work: 100%' in frames[-1]
