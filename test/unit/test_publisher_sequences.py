"""Several live publishers on one topic, from the messages' publication sequence numbers
(hexapod_common.publishers): the graph's publisher count keeps a crashed node's endpoint for
its DDS lease (a respawned battery monitor read as two), sequence numbers do not."""

from __future__ import annotations

import numpy as np
import pytest

from hexapod_common.publishers import (
    SEQUENCE_UNSUPPORTED,
    PublisherSequences,
    publication_sequence,
)


def _feed(seqs):
    w = PublisherSequences()
    hits = [i for i, s in enumerate(seqs) if w.add(s)]
    return w, hits


def test_one_publisher_with_losses_is_one():
    rng = np.random.default_rng(0)
    seqs = np.flatnonzero(rng.random(5000) > 0.3) + 1     # best effort: 30 % lost
    w, hits = _feed([int(s) for s in seqs])
    assert hits == [] and not w.interleaving and w.live_series == 1


def test_a_respawned_publisher_is_one_not_two():
    """Measured on this machine: the dead writer's last number 255, the new one's first 7."""
    seqs = list(range(144, 256)) + list(range(7, 1500))
    w, hits = _feed(seqs)
    assert hits == [] and not w.interleaving
    assert w.live_series == 1    # the dead series forgotten after a window


def test_two_live_publishers_found_within_a_few_messages_once_per_episode():
    a = list(range(568, 1568))
    b = list(range(109, 1109))
    both = [x for pair in zip(a, b) for x in pair]
    w, hits = _feed(both)
    assert hits == [2] or hits == [3]                      # A, B, A(switch), B(switch)
    assert w.interleaving and w.episodes == 1


def test_two_publishers_that_started_together_with_equal_numbers():
    both = [x for s in range(1, 500) for x in (s, s)]
    w, hits = _feed(both)
    assert len(hits) == 1 and hits[0] < 10


def test_a_second_publisher_at_a_tenth_of_the_rate_is_found_and_its_end_ends_the_episode():
    seqs, b = [], 1
    for a in range(1, 5001):
        seqs.append(a)
        if 1000 <= a < 2000 and a % 10 == 0:
            seqs.append(b)
            b += 1
    w = PublisherSequences()
    hits = [i for i, s in enumerate(seqs) if w.add(s)]
    assert len(hits) == 1 and 1000 < hits[0] < 1040
    assert not w.interleaving            # calm again after the second one stopped
    assert w.episodes == 1


def test_a_second_publisher_at_a_two_hundredth_of_the_rate_is_found():
    """A 0.5 Hz teleop beside a 100 Hz gait node (a review: 1 in 150 was never seen)."""
    seqs, b = [], 1
    for a in range(1, 3001):
        seqs.append(a)
        if a % 200 == 0:
            seqs.append(b)
            b += 1
    w, hits = _feed(seqs)
    assert len(hits) == 1 and hits[0] < 700


def test_unnumbered_messages_are_ignored():
    assert publication_sequence(None) is None
    assert publication_sequence({}) is None
    assert publication_sequence({'publication_sequence_number': 0}) is None
    assert publication_sequence({'publication_sequence_number': SEQUENCE_UNSUPPORTED}) is None
    assert publication_sequence({'publication_sequence_number': 7}) == 7
    w = PublisherSequences()
    assert not any(w.add(None) for _ in range(10))
    assert not w.numbered and w.unnumbered == 10


def test_bad_settings_refused():
    with pytest.raises(ValueError):
        PublisherSequences(window=1)
