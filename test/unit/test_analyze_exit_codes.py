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
