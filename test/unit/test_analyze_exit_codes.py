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
