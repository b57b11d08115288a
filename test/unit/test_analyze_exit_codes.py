import re

import pytest
from hexapod_common.analyze_cli import main as analyze


@pytest.mark.parametrize('argv', [
    ['slip', '{tmp}/nobag', '--out', '{tmp}/o1'],
    ['energy', '--robot', '{tmp}/nobag', '--out', '{tmp}/o2', '--no-progress'],
    ['residuals', '--bench', '{tmp}/nobag', '--robot', '{tmp}/nobag', '--out', '{tmp}/o3'],
    ['report', '{tmp}/nofolder'],
])
def test_a_missing_input_exits_2_for_every_command(argv, tmp_path, capsys):
    """One exit status per outcome across commands: a missing bag or folder is input refused,
    exit 2 with one line on stderr (slip said 1 and report 1, energy 2)."""
    rc = analyze([a.format(tmp=tmp_path) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2, err
    assert err and 'Traceback' not in '\n'.join(err)


@pytest.mark.parametrize('argv, says', [
    (['energy', '--bench', '{tmp}/b', '--recommend', '--speed', '0.3', '--payload', '-1'],
     '--payload must be >= 0 kg, got -1.0'),
    (['energy', '--bench', '{tmp}/b', '--recommend', '--speed', '0.3', '--payload', 'nan'],
     '--payload must be >= 0 kg, got nan'),
    (['energy', '--bench', '{tmp}/b', '--recommend', '--speed', 'nan'],
     '--recommend needs --speed V with V > 0 [m/s], got nan'),
    (['energy', '--robot', '{tmp}/r', '--robot-payload', '-0.3'],
     '--robot-payload must be >= 0 kg, got -0.3'),
    (['energy', '--robot', '{tmp}/r', '--load-offset', 'inf'],
     '--load-offset must be finite, got inf'),
    (['residuals', '--bench', '{tmp}/b', '--robot', '{tmp}/r', '--robot-payload', '-1'],
     '--robot-payload must be >= 0 kg, got -1.0'),
    (['residuals', '--bench', '{tmp}/b', '--robot', '{tmp}/r', '--robot-mass', 'nan'],
     '--robot-mass must be > 0 kg, got nan'),
])
def test_a_negative_or_nan_payload_or_speed_is_refused(argv, says, tmp_path, capsys):
    """A negative payload gave a recommendation for a lighter robot (AntBot with -1 kg: 1.18
    kg) and a NaN payload NaN descriptors, both with exit 0 (an outside check); now refused,
    exit 2 naming the flag, before any bag is read."""
    rc = analyze([a.format(tmp=tmp_path) for a in argv] + ['--out', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert rc == 2, err
    assert says in err and 'Traceback' not in err


def test_recommend_gait_refuses_a_negative_payload():
    from hexapod_energy.errors import InvalidInputError
    from hexapod_energy.recommend import recommend_gait

    with pytest.raises(InvalidInputError, match='payload_kg must be finite and >= 0'):
        recommend_gait(None, None, speed_mps=0.3, payload_kg=-1.0)
    with pytest.raises(InvalidInputError, match='speed_mps must be finite and > 0'):
        recommend_gait(None, None, speed_mps=float('nan'))


@pytest.mark.parametrize('argv, says', [
    (['slip', '{tmp}/b', '--hip-z=nan'], '--hip-z must be within +-2 m, got nan'),
    (['slip', '{tmp}/b', '--hip-zero=inf'], '--hip-zero must be within +-2 pi rad'),
    (['slip', '{tmp}/b', '--leg-radius=1e9'], '--leg-radius must be in (0, 2] m'),
    (['slip', '{tmp}/b', '--offset=nan'], '--offset must be seconds within +-1 h, got nan'),
    (['slip', '{tmp}/b', '--offset-lag=nan'], '--offset-lag must be seconds within +-1 s'),
    (['slip', '{tmp}/b', '--max-lateral=nan'], '--max-lateral must be in (0, 10] m'),
    (['slip', '{tmp}/b', '--leg-damping-time=-1'], '--leg-damping-time must be in [0, 1] s'),
    (['slip', '{tmp}/b', '--leg-damping-time=abc'], "--leg-damping-time must be seconds"),
    (['slip', '{tmp}/b', '--box', '1', '0.5', '0.5', '0', '0', '0'],
     '--box X0 Y0 Z0 X1 Y1 Z1 needs finite corners'),
    (['slip', '{tmp}/b', '--jobs', '0'], '--jobs must be >= 1, got 0'),
    (['slip', '{tmp}/b', '--model', 'bogus'], "--model must name a SLIP model"),
    (['slip', '{tmp}/b', '--mass', '1e9'], '--mass must be a robot mass up to 1000 kg'),
    (['energy', '--bench', '{tmp}/b', '--folds', '0'], '--folds must be >= 2'),
    (['energy', '--bench', '{tmp}/b', '--limits', '0.16', '0.15', 'inf'],
     '--limits MIN_SWING_S MIN_STANCE_S MAX_FREQ_HZ must be finite'),
    (['energy', '--bench', '{tmp}/b', '--load-offset', '5'],
     '--load-offset 5 kg is not below the mass a stance leg carries'),
    (['residuals', '--bench', '{tmp}/b', '--robot', '{tmp}/r', '--legs', '1000000000'],
     '--legs must be an even number >= 2 whose legs'),
    (['energy', '--robot', '{tmp}/r', '--gait', 'tripod', '--duty-factor', '0.5',
      '--step-length', '0'], '--step-length must be > 0 m, got 0.0'),
    (['residuals', '--bench', '{tmp}/b', '--robot', '{tmp}/r', '--gait', 'tripod',
      '--duty-factor', '0.5', '--step-length', '0'], '--step-length must be > 0 m, got 0.0'),
    (['energy', '--bench', '{tmp}/b', '--recommend', '--speed', '0.3', '--payload', '1e9'],
     "--payload 1e+09 kg is over 10 times the robot's"),
    (['energy', '--robot', '{tmp}/r', '--robot-speed', '1e9'],
     '--robot-speed must be in (0, 20] m/s'),
    (['energy', '--robot', '{tmp}/r', '--out', '{tmp}/afile'], 'is a file, not a folder'),
    (['slip', '{tmp}/b', '--out', '{tmp}/afile'], 'is a file, not a folder'),
    (['residuals', '--bench', '{tmp}/b', '--robot', '{tmp}/r', '--out', '{tmp}/afile'],
     'is a file, not a folder'),
])
def test_option_values_that_cannot_work_are_refused_naming_the_option(argv, says, tmp_path,
                                                                       capsys):
    """From an outside review of every option: each of these ran (exit 0 with nothing or
    nonsense, a numpy message, an OOM) or blamed the bag; now exit 2 with one line naming
    the option, before any bag is read."""
    (tmp_path / 'afile').write_text('x')
    args = [a.format(tmp=tmp_path) for a in argv]
    if '--out' not in args:
        args += ['--out', str(tmp_path / 'o')]
    rc = analyze(args)
    err = capsys.readouterr().err
    assert rc == 2, err
    assert says in err and 'Traceback' not in err


def _run_with_legs(name: str, legs: int):
    import numpy as np

    from hexapod_energy.residuals import ResidualRun

    n = 50
    z = np.zeros(n)
    return ResidualRun(name=name, t_s=np.arange(n) * 0.01, voltage_v=z + 12, current_a=z + 2,
                       power_w=z + 24, cycle_phase=z, period_s=z + 0.5, duty_factor=z + 0.5,
                       step_length_m=z + 0.1, in_stance=np.ones((n, legs), bool),
                       supporting=z.astype(int) + legs // 2, temp_sum_c=z, servo_count=0,
                       leg_names=tuple(f'L{i}' for i in range(legs)),
                       phase_offsets=(0.0,) * legs, gait='tripod')


@pytest.mark.parametrize('runs, kw, says', [
    ([('a', 6), ('b', 4)], {}, 'different leg counts (a: 6, b: 4)'),
    ([('a', 6)], {'robot_mass_kg': 0.5}, 'the legs alone outweigh the robot'),
    ([('a', 6)], {'load_offset_kg': 5.0}, '--load-offset 5 kg is not below'),
])
def test_the_residual_loop_refuses_runs_it_cannot_describe(runs, kw, says):
    """Runs of a 6- and a 4-leg robot made a numpy shape error; a robot lighter than its
    legs, or a load offset above a stance leg's load, ran with the load clamped to 0 kg."""
    from hexapod_energy.residuals import ResidualDataError, energy_loop_from_runs

    with pytest.raises(ResidualDataError, match=re.escape(says)):
        energy_loop_from_runs(None, [_run_with_legs(n, k) for n, k in runs], None, **kw)


def test_a_given_offset_that_separates_the_streams_is_named_as_given():
    """`slip --offset 1e9` was told 'give the offset (--offset SECONDS)'."""
    import numpy as np

    from slip_identification.errors import SlipDataError
    from slip_identification.pipeline import RunData, analyze_run

    t = np.arange(0, 3, 0.01)
    n = t.size
    run = RunData(joint_names=tuple(f'{k}_hip' for k in ('L1', 'L2', 'L3', 'R1', 'R2', 'R3')),
                  joint_t_s=t, joint_velocity=np.ones((n, 6)), command_t_s=t,
                  command_velocity=np.ones((n, 6)), mocap_t_s=t,
                  mocap_position_m=np.column_stack([0.3 * t - 0.4, 0 * t, 0.1 + 0 * t]),
                  mocap_quat_xyzw=np.tile([0, 0, 0, 1.0], (n, 1)), battery_t_s=t,
                  battery_voltage_v=12 + 0 * t, battery_current_a=1 + 0 * t)
    with pytest.raises(SlipDataError, match='with the offset given'):
        analyze_run(run, offset_s=100.0, check_body_up=False)


@pytest.mark.parametrize('argv', [
    ['energy', '--robot', '{tmp}/r1', '{tmp}/r1/', '{tmp}/r2'],
    ['energy', '--bench', '{tmp}/b', '--robot', '{tmp}/r1', '{tmp}/link'],
    ['slip', '{tmp}/r1', '{tmp}/r1/r1_0.mcap'],
    ['residuals', '--bench', '{tmp}/b', '--robot', '{tmp}/r2', '{tmp}/r2'],
])
def test_a_bag_given_twice_is_refused(argv, tmp_path, capsys):
    """A bag given twice (``run1`` and ``run1/``, a link, a folder and its file) was analysed
    twice without a word: prediction rmse 7.42 W over 3 runs for 9.02 W over 2, 16 slip
    stances from 8 (an outside review)."""
    for name in ('r1', 'r2', 'b'):
        (tmp_path / name).mkdir()
    (tmp_path / 'r1' / 'r1_0.mcap').write_bytes(b'')
    (tmp_path / 'link').symlink_to(tmp_path / 'r1')
    with pytest.raises(SystemExit) as stop:   # argparse's exit, before any bag is read
        analyze([a.format(tmp=tmp_path) for a in argv] + ['--out', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert stop.value.code == 2 and 'is given twice' in err and 'Traceback' not in err


def test_one_bag_under_two_options_gets_the_commands_own_reason(tmp_path, capsys):
    """Review D: '--robot X --slip X' read 'given twice', hiding 'not both'."""
    (tmp_path / 'x').mkdir()
    rc = analyze(['residuals', '--robot', str(tmp_path / 'x'), '--slip', str(tmp_path / 'x'),
                  '--out', str(tmp_path / 'o')])
    err = capsys.readouterr().err
    assert rc == 2 and 'not both' in err and 'given twice' not in err
