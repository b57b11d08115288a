"""The gait table gives the fitted stiffness and rest length (median, IQR), and a stance whose
rest length is far from its gait's median is named in its run's notes (the demo's walk: two
converged fits at 340 N/m and 0.197 m beside 2,400 N/m and 0.11 m, shown nowhere)."""
import math

from slip_identification.cli import _note_rest_length_outliers
from slip_identification.energetics import gait_table


def _stance(bag, t, k, l0, gait='walk'):
    return {'bag': bag, 'gait': gait, 'touchdown': t, 'stiffness': k, 'rest_length': l0,
            'nerr': 0.3, 'power_w': 18.0, 'speed_mps': 0.18, 'sr': 3.0}


def test_soft_long_springs_are_named_and_the_table_gives_medians():
    stances = [_stance('walk', 0.5 * i, 2400.0 + 10 * i, 0.110 + 0.001 * i) for i in range(6)]
    stances += [_stance('walk', 3.0, 335.0, 0.1986), _stance('walk', 3.5, 343.0, 0.1961)]
    runs = [{'bag': 'walk', 'notes': []}, {'bag': 'other', 'notes': []}]
    _note_rest_length_outliers(stances, runs)
    [note] = runs[0]['notes']
    assert note.startswith('2 stance(s)') and 't = 3.000 s l0 0.1986 m, k 335 N/m' in note
    assert runs[1]['notes'] == []
    row = gait_table(stances)['walk']
    assert math.isclose(row['rest_length_median'], 0.1135, abs_tol=1e-6)   # 8 stances
    assert 2400 <= row['stiffness_median'] <= 2460 and row['stiffness_iqr'] > 0


def test_a_gait_with_few_stances_is_not_judged():
    stances = [_stance('walk', 0.0, 2400.0, 0.11), _stance('walk', 1.0, 335.0, 0.2)]
    runs = [{'bag': 'walk', 'notes': []}]
    _note_rest_length_outliers(stances, runs)
    assert runs[0]['notes'] == []
