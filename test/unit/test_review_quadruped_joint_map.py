"""The joint map refuses keys it does not know and non-finite offsets. A quadruped review: a
typo in the mirrored side's entries (``dirction: -1``) was ignored, the joint kept direction
+1 and the driver would turn those femurs and tibias the wrong way, without a word."""

from __future__ import annotations

import pytest

from hexapod_bench_drivers.dynamixel_bus import JointMapError, parse_joint_map


@pytest.mark.parametrize('spec, said', [
    ({'id': 8, 'dirction': -1}, 'dirction'),
    ({'id': 8, 'direction': -1, 'offset': 0.3}, 'offset'),
    ({'id': 8, 'offset_rad': float('nan')}, 'offset_rad'),
    ({'id': 8, 'offset_rad': float('inf')}, 'offset_rad'),
])
def test_bad_entry_is_refused_naming_it(spec, said):
    with pytest.raises(JointMapError, match=said) as err:
        parse_joint_map({'joints': {'R1_femur': spec}})
    assert 'R1_femur' in str(err.value)


def test_known_keys_still_read():
    (j,) = parse_joint_map({'joints': {'R1_femur': {'id': 8, 'direction': -1,
                                                    'offset_rad': 0.25}}})
    assert (j.servo_id, j.direction, j.offset_rad) == (8, -1, 0.25)
    (k,) = parse_joint_map({'joints': [{'name': 'R1_femur', 'id': 8, 'direction': -1}]})
    assert (k.name, k.direction) == ('R1_femur', -1)
