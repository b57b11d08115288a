"""The SLIP residual loop analyses ``slip``'s stances with ``slip``'s options, taken from one
place (:func:`slip_identification.cli.default_options`): it had restated them, and once ran
other edges and no clock offset (another 22 stances than slip.json's 23)."""

from __future__ import annotations

from typing import Any

import pytest


def test_default_options_are_what_a_plain_slip_run_uses(monkeypatch, tmp_path) -> None:
    from slip_identification import cli

    seen: list[dict[str, Any]] = []
    monkeypatch.setattr(cli, 'analyze_bag',
                        lambda path, options: seen.append(options) or {'bag': path,
                                                                       'error': 'stub'})
    cli.main([str(tmp_path / 'bag'), '--out', str(tmp_path / 'o'), '--mass', '3.31'])
    assert seen == [cli.default_options()]
    assert cli.default_options(edges='paper')['edges'] == 'paper'
    with pytest.raises(KeyError, match='not slip options'):
        cli.default_options(edge='paper')


def test_the_residual_loop_takes_slips_options(monkeypatch) -> None:
    from slip_identification import cli

    from hexapod_energy.residuals_cli import run_slip_loop

    seen: list[dict[str, Any]] = []

    class Stop(Exception):
        pass

    def analyze(run: Any, options: dict[str, Any]) -> Any:
        seen.append(options)
        raise Stop

    monkeypatch.setattr(cli, 'read_run', lambda path: path)
    monkeypatch.setattr(cli, 'analyze_data', analyze)
    with pytest.raises(Stop):
        run_slip_loop(['b'], mass_kg=3.0, payload_kg=0.5, box=[0, 0, 0, 2, 1, 1])
    assert seen == [cli.default_options(mass_kg=3.5, position_fit=False,
                                        box_lower=[0, 0, 0], box_upper=[2, 1, 1])]
