"""``OnlineSlip.warm_up`` (called by the ``slip_fitter`` node at start): the compiled fit
kernels are loaded before any data comes, not in the first live stance's publish latency
(a cold process paid 52 ms in that stance's step against 10 ms at most for the others), and
nothing of the core's state changes. Checked in a fresh interpreter: the kernels' dispatchers
hold no compiled signature before the call and do after it (no timing asserted)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

from slip_identification import _kernels

pytestmark = pytest.mark.skipif(not _kernels.HAVE_NUMBA, reason='numba not installed')

SCRIPT = r'''
import json
from slip_identification import _geometry_kernels, _kernels
from slip_identification.geometry import LegGeometry
from slip_identification.model import SlipModel
from slip_identification.online import OnlineSlip

def loaded():
    return {'fit': len(_kernels._fit_many_serial.signatures),
            'gaps': len(_geometry_kernels._leg_gaps_c.signatures)}

out = {'before': loaded()}
core = OnlineSlip(SlipModel(extensions=('leg_damping',)), geometry=LegGeometry(),
                  ground_m=0.0)
out['seconds'] = core.warm_up()
out['after'] = loaded()
out['state'] = [len(core.latency_s), len(core.warnings), core.stale_samples]
print(json.dumps(out))
'''


@pytest.mark.timeout(300)
def test_warm_up_loads_the_fit_kernels_and_leaves_the_core_as_it_was() -> None:
    done = subprocess.run([sys.executable, '-c', SCRIPT], capture_output=True, text=True,
                          timeout=280)
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out['before'] == {'fit': 0, 'gaps': 0}
    assert out['after']['fit'] >= 1 and out['after']['gaps'] >= 1
    assert out['seconds'] > 0
    assert out['state'] == [0, 0, 0]
