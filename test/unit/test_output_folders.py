"""An output folder never pairs one run's JSON with another run's figures, and an interrupted
run never leaves results that look complete (outside review C, F1-F5, F9, F10).

Each analysis command removes its own JSON and figures of an earlier run
(:data:`hexapod_common.outdir.OUTPUTS`), writes its figures, then its JSON last and
atomically; an unfinished run removes the figures it wrote. The analyses are replaced by
canned results or one tiny bag, the plotting by a stub that writes a file and (for the
interruptions) raises ``KeyboardInterrupt`` as a Ctrl-C would.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from hexapod_common.analyze_cli import main as analyze
from hexapod_common.outdir import OUTPUTS, owned_by, remove_outputs, write_text_atomic

PNG = b'\x89PNG\r\n\x1a\n'   # enough of a PNG for the report to inline it


def _fill(folder: Path, names: list[str], text: str = 'old') -> None:
    folder.mkdir(parents=True, exist_ok=True)
    for n in names:
        (folder / n).write_bytes(PNG if n.endswith('.png') else text.encode())


def _files(folder: Path) -> set[str]:
    return {p.name for p in folder.iterdir()}


# ------------------------------------------------------------------------------ slip

OLD_SLIP = ['slip.json', 'fig7_speed_vs_sr.png', 'fig8_power_vs_speed.png',
            'fig9_nerr_vs_sr.png']


def _stance(bag: str, k: int) -> dict:
    return {'gait': 'pace', 'bag': bag, 'touchdown': float(k), 'nerr': 0.1, 'power_w': 30.0,
            'speed_mps': 0.5, 'sr': 2.0, 'stiffness': 2000.0, 'rest_length': 0.11,
            'force_swing': 1.0}


@pytest.fixture
def canned_slip(monkeypatch, tmp_path):
    """``slip`` on a canned analysis: a bag folder named 'pace' gives two stances, one named
    'nomocap' is refused."""
    import slip_identification.cli as slip_cli

    def analyze_bag(path, options):
        if Path(path).name == 'nomocap':
            return {'bag': path, 'error': 'lacks topic /mocap/body'}
        return {'run': {'bag': path, 'gait': 'pace'},
                'stances': [_stance(path, k) for k in range(2)], 'skipped': []}

    monkeypatch.setattr(slip_cli, 'analyze_bag', analyze_bag)
    for name in ('pace', 'nomocap'):
        (tmp_path / name).mkdir()
    return tmp_path


def test_slip_interrupted_while_plotting_puts_the_earlier_result_back(
        canned_slip, monkeypatch, capsys):
    """F1: a Ctrl-C while the figures were drawn left the new, complete-looking slip.json
    beside the previous run's fig7/8/9 (exit 130 'nothing more written')."""
    import slip_identification.cli as slip_cli

    out = canned_slip / 'out'
    _fill(out, OLD_SLIP + ['notes.txt'])

    def plot_figures(rows, folder, **kw):
        assert not (Path(folder) / 'slip.json').exists()   # the JSON comes last
        (Path(folder) / 'fig7_speed_vs_sr.png').write_bytes(PNG)
        raise KeyboardInterrupt

    monkeypatch.setattr(slip_cli, 'plot_figures', plot_figures)
    rc = analyze(['slip', str(canned_slip / 'pace'), '--out', str(out)])
    assert rc == 130
    assert 'interrupted; no result written' in capsys.readouterr().err
    # the earlier run's result, whole, is put back (review D: a first version left none)
    assert _files(out) == set(OLD_SLIP) | {'notes.txt'}
    assert (out / 'slip.json').read_text() == 'old'


def test_slip_writes_its_json_after_the_figures(canned_slip, monkeypatch):
    import slip_identification.cli as slip_cli

    out = canned_slip / 'out'
    _fill(out, OLD_SLIP)
    seen = {}

    def plot_figures(rows, folder, **kw):
        seen['json_then'] = (Path(folder) / 'slip.json').exists()
        seen['kw'] = kw
        (Path(folder) / 'fig8_power_vs_speed.png').write_bytes(PNG)

    monkeypatch.setattr(slip_cli, 'plot_figures', plot_figures)
    assert analyze(['slip', str(canned_slip / 'pace'), '--out', str(out)]) == 0
    assert seen['json_then'] is False
    assert seen['kw']['mass_kg'] == pytest.approx(3.31)   # titles: no slip.json to read yet
    assert _files(out) == {'slip.json', 'fig8_power_vs_speed.png'}
    assert len(json.loads((out / 'slip.json').read_text())['stances']) == 2


def test_slip_with_no_stance_removes_the_earlier_runs_figures(canned_slip, capsys):
    """F2: every bag refused: slip.json names the refusal, and the earlier 8-stance run's
    figures no longer sit beside it ('0 stances fitted' above three old plots)."""
    out = canned_slip / 'out'
    _fill(out, OLD_SLIP)
    rc = analyze(['slip', str(canned_slip / 'nomocap'), '--out', str(out)])
    assert rc == 2
    assert _files(out) == {'slip.json'}
    doc = json.loads((out / 'slip.json').read_text())
    assert doc['stances'] == [] and doc['failed_bags']


def test_slip_no_plots_draws_nothing_and_removes_the_earlier_figures(canned_slip,
                                                                     monkeypatch):
    """``slip --no-plots`` (the analysis tests' runs, which never look at the figures): no
    figure is drawn, slip.json says 'plots' [] and holds the stances, and the earlier run's
    figures do not stay beside it (as ``residuals --no-plots``, F5); other files are kept."""
    import slip_identification.cli as slip_cli
    import slip_identification.plots as slip_plots

    def drawn(*a, **kw):
        raise AssertionError('a figure drawn with --no-plots')

    monkeypatch.setattr(slip_cli, 'plot_figures', drawn)
    monkeypatch.setattr(slip_plots, 'plot_stance_fits', drawn)
    out = canned_slip / 'out'
    _fill(out, OLD_SLIP + ['slip_fit_stances.png', 'slip_fit_stances.svg', 'notes.txt'])
    assert analyze(['slip', str(canned_slip / 'pace'), '--out', str(out), '--no-plots']) == 0
    assert _files(out) == {'slip.json', 'notes.txt'}
    doc = json.loads((out / 'slip.json').read_text())
    assert doc['plots'] == [] and len(doc['stances']) == 2


# ---------------------------------------------------------------------------- energy

@pytest.fixture(scope='module')
def robot_bag(tmp_path_factory):
    from test_energy_cli import _write_robot

    bag = tmp_path_factory.mktemp('robot') / 'robot0'
    _write_robot(bag, 0.5)
    return bag


#: one of every figure ``energy`` may write, from an earlier run
OLD_ENERGY = ['energy.json', 'four_quadrant_duty_factor.png', 'four_quadrant_duty_factor.svg',
              'gait_type_comparison.png', 'gait_type_comparison.svg', 'power_map.png',
              'prediction.png', 'prediction.svg', 'where_the_watts_go.png',
              'power_in_over_time.png', 'power_in_over_time.svg', 'measured_runs.png',
              'measured_runs.svg']


def test_energy_removes_every_plot_of_an_earlier_run(robot_bag, tmp_path):
    """F3: gait_type_comparison.*, measured_runs.* and power_in_over_time.* of an earlier
    run stayed (only four_quadrant_*, power_map, prediction, where_the_watts_go were removed)
    and report.html showed them as the new result's."""
    out = tmp_path / 'o'
    _fill(out, OLD_ENERGY + ['slip.json', 'fig7_speed_vs_sr.png'])
    rc = analyze(['energy', '--robot', str(robot_bag), '--out', str(out), '--robot-mass',
                  '2.183', '--no-progress'])
    assert rc == 0
    doc = json.loads((out / 'energy.json').read_text())
    assert doc['plots'] and 'measured_runs.png' in doc['plots']
    # its own files are exactly what it wrote now; another command's are left alone
    assert _files(out) == {'energy.json', 'slip.json', 'fig7_speed_vs_sr.png',
                           *doc['plots']}
    assert (out / 'measured_runs.png').read_bytes() != PNG


def test_every_plot_energy_names_is_owned_by_energy_json():
    """The removal list and the report's ownership are one list: the plot names of
    hexapod_energy.cli (a name missing there survived a later run)."""
    import re

    src = (Path(__file__).resolve().parents[2] / 'hexapod_energy' / 'hexapod_energy' /
           'cli.py').read_text()
    stems = set(re.findall(r"out / '([a-z_]+)'", src)) | {
        'four_quadrant_' + x for x in re.findall(r"out / f'four_quadrant_\{(\w+)\}'", src)}
    assert {'prediction', 'gait_type_comparison', 'measured_runs',
            'power_in_over_time'} <= stems
    for stem in stems:
        name = stem if not stem.endswith('_name') else 'four_quadrant_gait_type'
        for ext in ('png', 'svg'):
            assert owned_by('energy.json', f'{name}.{ext}'), name
    assert not owned_by('energy.json', 'fig7_speed_vs_sr.png')


def test_energy_interrupted_while_plotting_puts_the_earlier_result_back(
        robot_bag, tmp_path, monkeypatch, capsys):
    """F4: a Ctrl-C during the plots kept the old energy.json beside half the new plots;
    report showed the old table above the new figures."""
    import hexapod_energy.plots as plots

    out = tmp_path / 'o'
    _fill(out, OLD_ENERGY)

    def measured_runs_plot(*a, **kw):
        (out / 'measured_runs.png').write_bytes(PNG)
        raise KeyboardInterrupt

    monkeypatch.setattr(plots, 'measured_runs_plot', measured_runs_plot)
    rc = analyze(['energy', '--robot', str(robot_bag), '--out', str(out), '--robot-mass',
                  '2.183', '--no-progress'])
    assert rc == 130
    assert 'interrupted; no result written' in capsys.readouterr().err
    assert _files(out) == set(OLD_ENERGY) and (out / 'energy.json').read_text() == 'old'


# ------------------------------------------------------------------------- residuals

OLD_RESID = ['residuals.json', 'residual_time.png', 'residual_regressors.png']


@pytest.fixture
def fake_loop(monkeypatch, tmp_path):
    """``residuals``' energy loop replaced: writes residuals.json (and a plot unless
    --no-plots), or raises KeyboardInterrupt after its first plot."""
    import hexapod_energy.residuals as residuals

    calls = {'interrupt': False}

    def run_energy_loop(bench, robots, out_dir, *, plots=True, **kw):
        out = Path(out_dir)
        if plots:
            (out / 'residual_time.png').write_bytes(PNG)
            if calls['interrupt']:
                raise KeyboardInterrupt
        write_text_atomic(out / 'residuals.json', json.dumps({'plots': []}))
        return {'summary': 'fake'}

    monkeypatch.setattr(residuals, 'run_energy_loop', run_energy_loop)
    for name in ('b', 'r'):
        (tmp_path / name).mkdir()
    return calls


def test_residuals_no_plots_removes_the_earlier_plots(fake_loop, tmp_path):
    """F5: --no-plots into a used folder kept the earlier run's residual_*.png beside the
    new residuals.json ("plots": [])."""
    out = tmp_path / 'o'
    _fill(out, OLD_RESID)
    rc = analyze(['residuals', '--bench', str(tmp_path / 'b'), '--robot', str(tmp_path / 'r'),
                  '--out', str(out), '--no-plots', '--no-progress'])
    assert rc == 0
    assert _files(out) == {'residuals.json'}


def test_residuals_interrupted_puts_the_earlier_result_back(fake_loop, tmp_path, capsys):
    fake_loop['interrupt'] = True
    out = tmp_path / 'o'
    _fill(out, OLD_RESID)
    rc = analyze(['residuals', '--bench', str(tmp_path / 'b'), '--robot', str(tmp_path / 'r'),
                  '--out', str(out), '--no-progress'])
    assert rc == 130
    assert _files(out) == set(OLD_RESID) and (out / 'residuals.json').read_text() == 'old'


def test_a_refused_re_run_keeps_the_earlier_result(robot_bag, tmp_path, capsys):
    """Review D: the earlier result was removed before any bag was read, so a re-run refused
    for a bag lacking a topic left an empty folder. It is now set aside and put back."""
    out = tmp_path / 'o'
    _fill(out, OLD_ENERGY + ['notes.txt'])
    (tmp_path / 'empty').mkdir()
    rc = analyze(['energy', '--robot', str(tmp_path / 'empty'), '--out', str(out),
                  '--robot-mass', '2.183', '--no-progress'])
    assert rc == 2
    assert _files(out) == set(OLD_ENERGY) | {'notes.txt'}
    assert (out / 'energy.json').read_text() == 'old'
    rc = analyze(['energy', '--robot', str(robot_bag), '--out', str(out), '--robot-mass',
                  '2.183', '--no-progress'])
    assert rc == 0 and (out / 'energy.json').read_text() != 'old'
    assert not any(n.startswith('.') for n in _files(out))   # nothing set aside is left


# ---------------------------------------------------------------------- the helpers

def test_remove_outputs_removes_one_commands_files_only(tmp_path):
    names = OLD_ENERGY + OLD_SLIP + OLD_RESID + ['demo.json', 'stray.png', 'report.html']
    _fill(tmp_path, names)
    remove_outputs(tmp_path, 'slip.json')
    assert _files(tmp_path) == set(names) - set(OLD_SLIP)
    remove_outputs(tmp_path, 'energy.json')
    remove_outputs(tmp_path, 'residuals.json')
    assert _files(tmp_path) == {'demo.json', 'stray.png', 'report.html'}
    assert set(OUTPUTS) == {'energy.json', 'slip.json', 'residuals.json'}


def test_write_text_atomic_never_leaves_half_a_file(tmp_path, monkeypatch):
    target = tmp_path / 'slip.json'
    target.write_text('{"old": 1}')
    real_replace = os.replace

    def cut(src, dst):
        raise KeyboardInterrupt

    monkeypatch.setattr(os, 'replace', cut)
    with pytest.raises(KeyboardInterrupt):
        write_text_atomic(target, '{"new": 2}')
    assert _files(tmp_path) == {'slip.json'} and target.read_text() == '{"old": 1}'
    monkeypatch.setattr(os, 'replace', real_replace)
    old_mask = os.umask(0o022)
    try:
        write_text_atomic(target, '{"new": 2}')
    finally:
        os.umask(old_mask)
    assert target.read_text() == '{"new": 2}' and _files(tmp_path) == {'slip.json'}
    assert target.stat().st_mode & 0o777 == 0o644   # as a plain write, not mkstemp's 0600


# ---------------------------------------------------------------------------- report

def test_report_fails_when_no_result_can_be_read(tmp_path, capsys):
    """F9: a cut slip.json alone: exit 0 and 'wrote report.html', nothing on stderr."""
    (tmp_path / 'slip.json').write_text('{"schema": "slip/1", "stances": [')
    rc = analyze(['report', str(tmp_path)])
    cap = capsys.readouterr()
    assert rc == 2
    assert 'slip.json unreadable' in cap.err and 'no result' in cap.err
    assert 'wrote' not in cap.out
    page = (tmp_path / 'report.html').read_text()
    assert page.index('class="banner"') < page.index('<h2>')


def test_report_warns_about_an_unreadable_result_beside_readable_ones(tmp_path, capsys):
    (tmp_path / 'slip.json').write_text('{')
    (tmp_path / 'residuals.json').write_text(json.dumps({'summary': 'fine'}))
    assert analyze(['report', str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert 'warning: slip.json unreadable' in cap.err and 'wrote' in cap.out


@pytest.mark.parametrize('status', ['incomplete', 'complete'])
def test_report_of_an_unfinished_demo_says_so_at_the_top(tmp_path, status, capsys):
    """F10: an interrupted demo's report showed its sections with no word of it (only the
    folded demo.json said "status": "incomplete")."""
    (tmp_path / 'demo.json').write_text(json.dumps({'out': str(tmp_path), 'status': status}))
    (tmp_path / 'energy').mkdir()
    (tmp_path / 'energy' / 'energy.json').write_text(json.dumps({'plots': []}))
    assert analyze(['report', str(tmp_path)]) == 0
    page = (tmp_path / 'report.html').read_text()
    err = capsys.readouterr().err
    if status == 'incomplete':
        assert page.index('class="banner"') < page.index('<h2>')
        assert 'did not finish' in page[:page.index('<h2>')] and 'did not finish' in err
    else:
        assert 'class="banner"' not in page and not err


def test_report_gives_energy_json_only_its_own_plots(tmp_path):
    """A PNG no command writes is not captioned as energy.json's (it owned every name the
    other results did not); it is listed under 'Other plots'."""
    (tmp_path / 'energy.json').write_text(json.dumps({'plots': []}))
    _fill(tmp_path, ['prediction.png', 'stray.png'])
    from hexapod_common.report import write_report

    page = write_report(tmp_path).read_text()
    other = page.index('<h2>Other plots</h2>')
    assert page.index('<code>prediction.png</code>') < other < page.index('<code>stray.png')
