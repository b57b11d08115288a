"""Full joint frames from JointState messages split over several name groups (numpy only).

Many robots publish one ``sensor_msgs/JointState`` per servo bus or per leg (hips L1-L3 in
one message and R1-R3 in another, or one message per joint, each with its own stamp, possibly
at slightly different rates). The SLIP analysis needs every hip at one time, so:

- :func:`assemble_joint_frames` (offline, vectorised): samples are grouped by name set; when
  every sample carries the same name set (in any order) the frames are the samples themselves,
  put in the first sample's name order (the fast path: bit-identical to reading full frames).
  Otherwise each joint's series (all samples naming it, in stamp order; at an equal stamp the
  later message wins, so joints named by two groups take the most recent value) is linearly
  interpolated onto the stamps of the densest group inside the span every joint covers (never
  extrapolated); a frame that falls in a gap of any joint longer than ``max_gap_periods`` of
  that joint's median period is dropped. Name sets that never cover the joint set (the
  contract's ``L1..Lk``/``R1..Rk`` legs for every joint suffix seen, plus ``required``) raise
  :class:`~slip_identification.errors.SlipDataError` naming the missing joints.
- :class:`JointFrameAssembler` (online, O(J) per message with J joints, no growth with time):
  the same rule incrementally. Full frames pass straight through; with split messages it first
  learns the joint set (until the union is complete and every joint has been seen twice) and
  the densest group, then emits a frame at each of that group's stamps as soon as every
  joint has a sample at or after it (a delay of at most one period of the slowest group).

Two more habits of other labs' drivers are undone on both paths:

- **Wrapped angles.** Continuously rotating (RHex-class) hips are often logged wrapped into
  ``[-pi, pi)`` or ``[0, 2 pi)``. Each joint's positions are unwrapped in time
  (:func:`unwrap_positions`: every sample takes the ``2 pi`` representative nearest the
  joint's previous finite sample; online the same rule incrementally per joint), before any
  interpolation or spline. The first sample keeps its branch, so the result may differ from
  the robot's own count of turns by a multiple of ``2 pi`` (the leg geometry is periodic).
  Undoing a wrap adds a note (:func:`wrap_note`). A joint that truly turns by more than
  ``pi`` between two samples (a dropout at speed) cannot be told from a wrap.
- **No velocities.** When no sample carries velocities but positions are there, the speeds
  are derived from the unwrapped positions (:func:`derive_velocity`: NumPy's second-order
  central differences on the stamps, one-sided at the ends; no lag, unlike a backward
  difference, which lags by half a sample period), with the note :data:`DERIVED_NOTE`.
  They average the speed over two sample periods, which smooths the sharp stance/swing speed
  switches of a Buehler clock: on a simulated EduBot running bag the geometric stance edges
  stay within 0.2 ms, but the paper's shifted-clock edges move by about +1.4 ms (the clock
  shift, fitted by mean absolute deviation on 100 Hz samples, is 4.3 instead of 2.95 ms;
  jogging +1.6 ms, walk and pace within 0.4 ms), 1.4 ms closer to the simulator's true
  touchdowns, which these edges precede by about 20 ms in any case.
  Online the same central difference needs the next sample: frames come out one joint-state
  period late (10 ms at 100 Hz; :data:`DERIVED_NOTE_ONLINE`). Samples with positions but no
  velocities among samples with velocities are still dropped (as before).

A third habit is refused on both offline paths: a sample whose stamp equals or precedes the
previous stamp of its name group while its values differ (a driver stamping with the last bus
read's time when a read is skipped). Without receive times it cannot be placed, so it is
dropped, noted (:func:`.stamps.repeat_note`); ``read_run`` has already re-stamped such samples
from the bag's receive times (:mod:`.stamps`), so this catches other callers only. Exact repeats
(the same values at the same stamp) are kept as before.

Full-frame bags that carry velocities and no wrapped angles give bit-identical frames.

Joint names follow DESIGN section 4: ``<leg>_<joint>`` with legs ``L1..Lk`` and ``R1..Rk``.
"""

from __future__ import annotations

import dataclasses
import math
import re
from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .errors import SlipDataError
from .stamps import StampMemory, repeat_note

__all__ = [
    'DERIVED_NOTE',
    'DERIVED_NOTE_ONLINE',
    'AssembledJoints',
    'JointFrame',
    'JointFrameAssembler',
    'assemble_joint_frames',
    'command_columns',
    'commands_in_order',
    'derive_velocity',
    'in_order',
    'missing_joints',
    'note_out_of_order',
    'rotation_signs',
    'stamp_order',
    'unwrap_positions',
    'wrap_note',
]

_LEG_JOINT = re.compile(r'^([LR])(\d+)_(\w+)$')
_TWO_PI = 2.0 * math.pi

#: note when the joint speeds are derived from the positions (offline)
DERIVED_NOTE = ('no joint velocities: from position differences (central differences of the '
                'unwrapped angles on their stamps, one-sided at the ends)')
#: the same, online (one frame of extra latency)
DERIVED_NOTE_ONLINE = ('no joint velocities: from position differences (central differences '
                       'of the unwrapped angles, each frame one joint-state period late)')


def rotation_signs(position_rad: np.ndarray) -> np.ndarray:
    """Per joint, -1 for a joint that turns continuously backwards over the run, else +1.

    RHex-class hips turn one way while the robot walks forward, and the contract counts that
    way positive. Drivers of robots whose right-side motors are mounted mirrored (or a whole
    robot wired the other way) report some hips turning negatively; taken as they are, the
    SLIP analysis silently fits wrong edges (an EduBot run with its right hips negated: offset
    30.7 ms instead of 25.4, stiffness off by up to 39 %). A joint whose net rotation over the
    run (last minus first finite unwrapped angle) is below -pi is reported -1; joints that do not
    turn continuously (|net| <= pi, e.g. a 3-DOF leg's) are +1.

    Parameters
    ----------
    position_rad : (n, J) array
        Unwrapped joint angles [rad] in time order (NaN allowed).

    Returns
    -------
    (J,) array of +1.0 / -1.0
    """
    q = np.asarray(position_rad, dtype=float)
    if q.ndim == 1:
        q = q[:, None]
    out = np.ones(q.shape[1])
    for j in range(q.shape[1]):
        finite = q[np.isfinite(q[:, j]), j]
        if finite.size >= 2 and finite[-1] - finite[0] < -math.pi:
            out[j] = -1.0
    return out


def unwrap_positions(position_rad: np.ndarray) -> tuple[np.ndarray, int]:
    """Unwrap joint angles in time, per column.

    Every finite sample takes the ``2 pi`` representative nearest the previous finite sample
    of its column (NaN samples are skipped and stay NaN); the first keeps its value.

    Parameters
    ----------
    position_rad : ndarray, shape (n,) or (n, J)
        Angles [rad] in time order (rows).

    Returns
    -------
    position_rad : ndarray, same shape
        Unwrapped angles [rad]; the input object itself when no jump was undone (bit-identical).
    wraps : int
        Number of ``2 pi`` jumps undone (over all columns).
    """
    q = np.asarray(position_rad, dtype=float)
    if q.shape[0] < 2:
        return q, 0
    d = np.diff(q, axis=0)
    big = np.abs(d) > math.pi  # NaN compares False
    if not np.any(big) and np.all(np.isfinite(q)):
        return q, 0
    out = q.copy()
    cols = [out] if q.ndim == 1 else [out[:, j] for j in range(q.shape[1])]
    wraps = 0
    for c in cols:  # views into out
        ok = np.isfinite(c)
        x = c[ok]
        if x.size < 2:
            continue
        k = np.round(np.diff(x) / _TWO_PI)
        if np.any(k != 0):
            wraps += int(np.abs(k).sum())
            c[ok] = x - _TWO_PI * np.concatenate([[0.0], np.cumsum(k)])
    return (out, wraps) if wraps else (q, 0)


def wrap_note(position_rad: np.ndarray, wraps: int, names: Sequence[str]) -> str:
    """The note for ``wraps`` undone jumps; ``position_rad`` the wrapped angles (their range
    names the convention)."""
    q = np.asarray(position_rad, dtype=float)
    q = q[np.isfinite(q)]
    if q.size and q.min() >= -math.pi - 1e-9 and q.max() <= math.pi + 1e-9:
        where = 'at +-pi'
    elif q.size and q.min() >= -1e-9 and q.max() <= _TWO_PI + 1e-9:
        where = 'into [0, 2 pi)'
    else:
        where = 'by 2 pi'
    what = 'hip' if names and all(str(n).endswith('_hip') for n in names) else 'joint'
    return (f'{what} angles wrapped {where}: unwrapped ({wraps} jump(s) of 2 pi undone, each '
            "sample the 2 pi representative nearest the joint's previous one)")


def derive_velocity(t_s: np.ndarray, position_rad: np.ndarray) -> np.ndarray:
    """Joint speeds from unwrapped angles: central differences on the stamps.

    ``np.gradient`` (second order on uneven stamps, first order one-sided at both ends),
    which has no lag. Samples at a repeated stamp take the speed of the last of them.

    Parameters
    ----------
    t_s : ndarray, shape (n,)
        Stamps [s] (any order).
    position_rad : ndarray, shape (n,) or (n, J)
        Unwrapped angles [rad].

    Returns
    -------
    ndarray, same shape as ``position_rad``
        Speeds [rad/s]; NaN when fewer than two distinct stamps.
    """
    t = np.asarray(t_s, dtype=float)
    q = np.asarray(position_rad, dtype=float)
    o = np.argsort(t, kind='stable')
    ts = t[o]
    last = np.append(ts[1:] > ts[:-1], True)  # the last of equal stamps
    tu, qu = ts[last], q[o][last]
    if tu.size < 2:
        return np.full(q.shape, np.nan)
    vu = np.gradient(qu, tu, axis=0)
    if tu.size == t.size and np.all(o == np.arange(t.size)):
        return vu
    idx = np.searchsorted(tu, t)  # every stamp is in tu
    return vu[idx]


def missing_joints(names: Sequence[str], required: Sequence[str] = ()) -> list[str]:
    """Joints the contract expects beside ``names`` that are absent.

    For every joint suffix seen (``hip``, ``coxa``...), legs ``L1..Lk`` and ``R1..Rk`` with
    ``k`` the largest leg number seen; plus ``required``. Names outside the contract's
    pattern expect nothing.

    Parameters
    ----------
    names : sequence of str
        Joint names seen.
    required : sequence of str
        Names the consumer needs in any case.

    Returns
    -------
    list of str
        Missing names, sorted.
    """
    have = set(names)
    legs: dict[str, int] = {}
    for n in have:
        m = _LEG_JOINT.match(n)
        if m:
            legs[m.group(3)] = max(legs.get(m.group(3), 0), int(m.group(2)))
    expected = {f'{side}{i}_{suffix}' for suffix, k in legs.items()
                for side in 'LR' for i in range(1, k + 1)}
    expected.update(required)
    return sorted(expected - have)


@dataclass(frozen=True)
class AssembledJoints:
    """Full joint frames.

    ``names`` (J,); ``t_s`` (n,) [s]; ``velocity`` (n, J) [rad/s]; ``position`` (n, J) [rad]
    or None (some sample lacks it); ``effort`` (n, J) [N m] or None; ``groups`` the number of
    distinct name sets (1: full frames); ``rate_hz`` the median frame rate; ``dropped`` frames
    dropped in gaps; ``note`` the split line for ``RunData.notes`` ('' for full frames);
    ``notes`` every line for ``RunData.notes`` (the split one, angles unwrapped, velocities
    derived); ``wraps`` the ``2 pi`` jumps undone; ``derived`` True when the velocities come
    from position differences; ``repeats`` samples that repeated their name group's previous
    stamp with new values (dropped; ``repeat_note`` says so, also in ``notes``).
    """

    names: tuple[str, ...]
    t_s: np.ndarray
    velocity: np.ndarray
    position: np.ndarray | None
    effort: np.ndarray | None
    groups: int
    rate_hz: float
    dropped: int = 0
    note: str = ''
    notes: tuple[str, ...] = ()
    wraps: int = 0
    derived: bool = False
    repeats: int = 0
    repeat_note: str = ''


def _derive_mode(samples: Sequence[Any]) -> bool:
    """No sample carries velocities, and some carry positions."""
    return all(s.velocity.size == 0 for s in samples) and \
        any(len(s.names) and s.position.size == len(s.names) for s in samples)


def _field_ok(samples: Sequence[Any], field: str) -> bool:
    return all(getattr(s, field).size == len(s.names) for s in samples)


def _repeat_rows(t: np.ndarray, rows: Sequence[Any]) -> list[int]:
    """Rows (one name group, arrival order, stamps ``t``) that repeat a recent row's stamp
    with new values (:class:`.stamps.StampMemory`; rows received out of stamp order, a stamp
    of their own, are not repeats)."""
    back = np.flatnonzero(t[1:] <= t[:-1]) + 1
    if not back.size:
        return []
    memory = StampMemory()
    return [k for k in range(len(rows)) if memory.check(float(t[k]), rows[k])]


def note_out_of_order(topic: str, t_s: np.ndarray, notes: list[str]) -> None:
    """Add a note counting the samples (arrival order, stamps ``t_s``) stamped before one
    received earlier: they are used in stamp order."""
    t = np.asarray(t_s, dtype=float)
    late = int(np.count_nonzero(t < np.maximum.accumulate(t)))
    if late:
        notes.append(f'{late} {topic} message(s) received out of stamp order (after a later '
                     'stamp): used in stamp order')


def _repeats_note(n: int, topic: str) -> str:
    return repeat_note(n, topic, 'dropped (no receive times to re-stamp them by)')


def _fast_path(samples: Sequence[Any], topic: str) -> AssembledJoints:
    """Every sample has the first one's name set: reorder into its order (no resampling)."""
    names = tuple(samples[0].names)
    derive = _derive_mode(samples)
    field = 'position' if derive else 'velocity'
    rows = []
    for s in samples:
        if getattr(s, field).size != len(names):
            continue  # no velocities (no positions to derive them): dropped, as before
        if tuple(s.names) != names:
            s = _reorder(s, names, [s.names.index(n) for n in names])
        rows.append(s)
    if not rows:
        raise SlipDataError(f'no JointState sample has velocities (or positions to derive '
                            f'them from) for {list(names)}')
    t = np.array([s.t_s for s in rows])
    notes: list[str] = []
    bad = _repeat_rows(t, rows)
    if bad:
        drop = set(bad)
        rows = [s for k, s in enumerate(rows) if k not in drop]
        t = np.delete(t, bad)
        notes.append(_repeats_note(len(bad), topic))
    if t.size > 1 and bool(np.any(t[1:] < t[:-1])):   # received out of stamp order
        note_out_of_order(topic, t, notes)
        o = np.argsort(t, kind='stable')
        t, rows = t[o], [rows[k] for k in o]
        # a stale stamp re-sent beyond the repeat check's memory (RECENT_STAMPS): the first
        # sample received at a stamp is kept, the later one dropped, noted
        again = np.flatnonzero(t[1:] == t[:-1]) + 1
        if again.size:
            drop = set(again.tolist())
            rows = [s for k, s in enumerate(rows) if k not in drop]
            t = np.delete(t, again)
            notes.append(repeat_note(int(again.size), topic,
                                     'dropped (a stamp received again long after it)'))
    dt = np.diff(t)
    rate = float(1.0 / np.median(dt)) if dt.size and np.median(dt) > 0 else float('nan')
    pos = np.array([s.position for s in rows]) if _field_ok(rows, 'position') else None
    wraps = 0
    if pos is not None:
        raw = pos
        pos, wraps = unwrap_positions(raw)
        if wraps:
            notes.append(wrap_note(raw, wraps, names))
    if derive:
        assert pos is not None
        vel = derive_velocity(t, pos)
        notes.append(DERIVED_NOTE)
    else:
        vel = np.array([s.velocity for s in rows])
    return AssembledJoints(
        names=names, t_s=t, velocity=vel, position=pos,
        effort=np.array([s.effort for s in rows]) if _field_ok(rows, 'effort') else None,
        groups=1, rate_hz=rate, notes=tuple(notes), wraps=wraps, derived=derive,
        repeats=len(bad), repeat_note=_repeats_note(len(bad), topic) if bad else '')


def _reorder(s: Any, names: tuple[str, ...], idx: list[int]) -> Any:
    return dataclasses.replace(
        s, names=names, **{f: getattr(s, f)[idx] for f in ('position', 'velocity', 'effort')
                           if getattr(s, f).size == len(names)})


def assemble_joint_frames(samples: Sequence[Any], *, required: Sequence[str] = (),
                          max_gap_periods: float = 5.0,
                          topic: str = '/joint_states') -> AssembledJoints:
    """Full frames from JointState samples that may each carry a subset of the joints.

    Parameters
    ----------
    samples : sequence of JointStateSample-like
        Objects with ``t_s`` [s], ``names``, ``position``, ``velocity``, ``effort`` (arrays
        with one entry per name, or empty), in arrival order. Samples without velocities are
        dropped, unless no sample has velocities: then they are derived from the positions
        (module docs). Positions are unwrapped per joint in time. A sample whose stamp
        equals or precedes its name group's previous one while its values differ is dropped
        and noted (module docs).
    required : sequence of str
        Joint names that must be present in any case.
    max_gap_periods : float
        A frame whose bracketing samples of some joint are further apart than this many of
        that joint's median sample periods is dropped (no interpolation over dropouts).
    topic : str
        The samples' topic, for the notes.

    Returns
    -------
    AssembledJoints

    Raises
    ------
    SlipDataError
        No samples, name sets that never cover the joint set (the message names the missing
        joints), or groups whose stamps never overlap.
    """
    if not samples:
        raise SlipDataError('no JointState sample to assemble')
    first = set(samples[0].names)
    if all(len(s.names) == len(first) and set(s.names) == first for s in samples):
        missing = missing_joints(tuple(first), required)
        if missing:
            raise SlipDataError(f'/joint_states never names joint(s) {missing}: every message '
                                f'names {sorted(first)} only (the joint set is legs L1..Lk and '
                                'R1..Rk for every joint)')
        return _fast_path(samples, topic)
    derive = _derive_mode(samples)
    field = 'position' if derive else 'velocity'
    usable = [s for s in samples if getattr(s, field).size == len(s.names) and len(s.names)]
    # new values under a name group's previous stamp: dropped (the later message used to win
    # at an equal stamp, silently)
    memory: dict[frozenset[str], StampMemory] = {}
    repeats = 0
    kept = []
    for s in usable:
        key = frozenset(s.names)
        if memory.setdefault(key, StampMemory()).check(s.t_s, s):
            repeats += 1
            continue
        kept.append(s)
    usable = kept
    # group by name set, in order of first appearance; joint order: first appearance
    groups: dict[frozenset[str], list[float]] = {}
    order: dict[str, None] = {}
    for s in usable:
        groups.setdefault(frozenset(s.names), []).append(s.t_s)
        order.update(dict.fromkeys(s.names))
    names = tuple(order)
    missing = missing_joints(names, required)
    if missing:
        sets = sorted(sorted(g) for g in groups)
        raise SlipDataError(
            f'/joint_states never names joint(s) {missing}: its {len(groups)} name group(s) '
            f'{sets} do not cover the joint set (legs L1..Lk and R1..Rk for every joint)')
    has_pos = all(s.position.size == len(s.names) for s in usable)
    has_eff = all(s.effort.size == len(s.names) for s in usable)
    # one series per joint: every sample naming it, stamp order, the later message winning
    # at an equal stamp
    col = {n: j for j, n in enumerate(names)}
    per_t: list[list[float]] = [[] for _ in names]
    per_k: list[list[int]] = [[] for _ in names]
    per_v: list[list[float]] = [[] for _ in names]
    per_q: list[list[float]] = [[] for _ in names]
    per_e: list[list[float]] = [[] for _ in names]
    for k, s in enumerate(usable):
        for i, n in enumerate(s.names):
            j = col[n]
            per_t[j].append(s.t_s)
            per_k[j].append(k)
            if not derive:
                per_v[j].append(float(s.velocity[i]))
            if has_pos:
                per_q[j].append(float(s.position[i]))
            if has_eff:
                per_e[j].append(float(s.effort[i]))
    series = []
    wraps = 0
    raw_q: list[np.ndarray] = []
    for j in range(len(names)):
        t = np.asarray(per_t[j])
        o = np.lexsort((np.asarray(per_k[j]), t))
        t = t[o]
        keep = np.append(t[1:] > t[:-1], True)  # the last of equal stamps (most recent)
        sel = o[keep]
        q = None
        if has_pos:
            raw_q.append(np.asarray(per_q[j])[sel])
            q, w = unwrap_positions(raw_q[-1])
            wraps += w
        if derive:
            assert q is not None
            v = derive_velocity(t[keep], q)
        else:
            v = np.asarray(per_v[j])[sel]
        series.append((t[keep], v, q, np.asarray(per_e[j])[sel] if has_eff else None))
    lo = max(s[0][0] for s in series)
    hi = min(s[0][-1] for s in series)
    if not hi > lo:
        raise SlipDataError(f'/joint_states name groups never overlap in time (common span '
                            f'{lo:.3f}..{hi:.3f} s): cannot assemble full frames')
    # the densest group's stamps inside the common span are the time base
    base = None
    for ts in groups.values():
        t = np.unique(np.asarray(ts))
        t = t[(t >= lo) & (t <= hi)]
        if base is None or t.size > base.size:
            base = t
    assert base is not None
    ok = np.ones(base.size, dtype=bool)
    vel = np.empty((base.size, len(names)))
    pos = np.empty((base.size, len(names))) if has_pos else None
    eff = np.empty((base.size, len(names))) if has_eff else None
    for j, (t, v, q, e) in enumerate(series):
        dt = np.diff(t)
        if dt.size:
            i = np.clip(np.searchsorted(t, base, side='right'), 1, t.size - 1)
            ok &= (t[i] - t[i - 1] <= max_gap_periods * float(np.median(dt))) | (base == t[i - 1])
        vel[:, j] = np.interp(base, t, v)
        if pos is not None and q is not None:
            pos[:, j] = np.interp(base, t, q)
        if eff is not None and e is not None:
            eff[:, j] = np.interp(base, t, e)
    base = base[ok]
    dt = np.diff(base)
    rate = float(1.0 / np.median(dt)) if dt.size else float('nan')
    note = (f'joint states split over {len(groups)} name groups: assembled at {rate:.0f} Hz '
            f'({base.size} frames, linear interpolation onto the densest group\'s stamps'
            + (f', {int((~ok).sum())} frame(s) in joint gaps dropped' if (~ok).any() else '')
            + ')')
    notes = [note]
    rnote = _repeats_note(repeats, topic) if repeats else ''
    if rnote:
        notes.append(rnote)
    if wraps:
        notes.append(wrap_note(np.concatenate(raw_q), wraps, names))
    if derive:
        notes.append(DERIVED_NOTE)
    return AssembledJoints(names=names, t_s=base, velocity=vel[ok],
                           position=None if pos is None else pos[ok],
                           effort=None if eff is None else eff[ok], groups=len(groups),
                           rate_hz=rate, dropped=int((~ok).sum()), note=note,
                           notes=tuple(notes), wraps=wraps, derived=derive, repeats=repeats,
                           repeat_note=rnote)



def stamp_order(topic: str, notes: list[str], t_s: np.ndarray,
                 *rows: np.ndarray) -> tuple[np.ndarray, ...]:
    """``t_s`` and ``rows`` in stamp order (stable), with a note when samples came out of it
    (another lab's recorder: 20 % of /joint_states received 15 ms late were re-stamped as
    repeats, then used in arrival order; an outside review)."""
    t = np.asarray(t_s, dtype=float)
    if t.size < 2 or not bool(np.any(t[1:] < t[:-1])):
        return (t, *rows)
    note_out_of_order(topic, t, notes)
    o = np.argsort(t, kind='stable')
    return (t[o], *(np.asarray(r)[o] for r in rows))


def commands_in_order(samples: Any, names: tuple[str, ...]) -> tuple[np.ndarray, np.ndarray]:
    """Stamps and commanded velocities of the ``/joint_commands`` samples (each naming the
    joints of ``names`` in some order) in the order of ``names``; samples without a velocity
    per joint are left out."""
    t_s: list[float] = []
    velocity = np.empty((len(samples), len(names)))
    for s in samples:
        r = in_order(s, names)
        if r.velocity.size == len(names):
            velocity[len(t_s)] = r.velocity
            t_s.append(r.t_s)
    if not t_s:
        return np.array([]), np.array([])
    return np.array(t_s), velocity[:len(t_s)].copy()


def in_order(sample: Any, names: tuple[str, ...]) -> Any:
    """``sample`` (a JointStateSample) with its arrays in the order of ``names``; a sample
    whose names are not a permutation of ``names`` comes back with empty velocities (dropped
    by the caller)."""
    if sample.names == names:
        return sample
    if len(sample.names) != len(names) or set(sample.names) != set(names):
        return dataclasses.replace(sample, velocity=np.zeros(0))
    idx = [sample.names.index(n) for n in names]
    return dataclasses.replace(
        sample, names=names,
        **{f: getattr(sample, f)[idx] if getattr(sample, f).size == len(names)
           else getattr(sample, f) for f in ('position', 'velocity', 'effort')})


def command_columns(samples: Any, names: tuple[str, ...], notes: list[str]
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Stamps and commanded velocities (in the order of ``names``) of ``/joint_commands``
    samples (JointStateSample-like, in arrival order; ``distinct('names')`` used when the
    container has it): each naming every joint in some order, or split over several messages
    (assembled). Lines for ``RunData.notes`` are appended to ``notes``. Used by the offline
    reader and by the live node's self-calibration (:mod:`.calibration`). Raises
    SlipDataError when split commands cannot be assembled."""
    if not len(samples):
        notes.append('no usable /joint_commands (the Buehler clock\'s target speeds): the '
                     "paper's shifted-clock edges are not available, stance edges from the "
                     'leg geometry only')
        return np.zeros(0), np.zeros((0, len(names)))
    sets = (samples.distinct('names') if hasattr(samples, 'distinct')
            else list(dict.fromkeys(s.names for s in samples)))
    if all(len(g) == len(names) and set(g) == set(names) for g in sets):
        # drivers need not keep one name order: every sample is put in the joints' order
        return commands_in_order(samples, names)
    cmd = assemble_joint_frames(samples, required=names, topic='/joint_commands')
    notes.append(f'/joint_commands: {cmd.note}')
    if cmd.repeat_note:
        notes.append(cmd.repeat_note)
    return cmd.t_s, cmd.velocity[:, [cmd.names.index(n) for n in names]]

@dataclass(frozen=True)
class JointFrame:
    """One full frame: ``t_s`` [s], ``names`` (J,), ``velocity`` (J,) [rad/s], ``position``
    (J,) [rad] or None, ``effort`` (J,) [N m] or None."""

    t_s: float
    names: tuple[str, ...]
    velocity: np.ndarray
    position: np.ndarray | None
    effort: np.ndarray | None = None


def _central(prev: tuple[float, Any] | None, mid: tuple[float, Any],
             nxt: tuple[float, Any]) -> Any:
    """Speed at ``mid`` from its neighbours ((t_s, q) pairs): ``np.gradient``'s second-order
    formula on uneven stamps, or the forward difference without ``prev`` (the first sample).
    The angles are floats or (J,) arrays [rad]; the speed has their shape [rad/s]."""
    t1, q1 = mid
    t2, q2 = nxt
    if prev is None:
        return (q2 - q1) / (t2 - t1)
    t0, q0 = prev
    hs, hd = t1 - t0, t2 - t1
    return (-hd / (hs * (hs + hd)) * q0 + (hd - hs) / (hs * hd) * q1
            + hs / (hd * (hs + hd)) * q2)


def _online_wrap_note(names: Sequence[str]) -> str:
    what = 'hip' if names and all(str(n).endswith('_hip') for n in names) else 'joint'
    return (f'{what} angles wrapped (jumps of 2 pi between samples): unwrapped (each sample '
            "the 2 pi representative nearest the joint's previous one)")


class JointFrameAssembler:
    """Online assembly of full frames, O(J) per message (J joints).

    Positions are unwrapped per joint (each sample the ``2 pi`` representative nearest the
    joint's previous one; :attr:`wraps` counts the jumps undone). When the first message has
    positions but no velocities, every message's velocities are derived from the positions by
    central differences (module docs): each frame is returned one sample later (full frames:
    when the next message arrives; split messages: when every joint has a sample after the
    frame's stamp), its speed from the samples before and after it.

    Parameters
    ----------
    required : sequence of str
        Joint names that must be present in any case.
    history : int
        Samples kept per joint (bounds memory; pending frames older than a joint's oldest
        kept sample are dropped, never extrapolated).
    learn_repeats : int
        In split mode, samples of every joint needed before the joint set and the densest
        group are fixed; if the set is still incomplete then, :meth:`add` raises once.

    Attributes
    ----------
    names : tuple of str
        The joint set once known (empty before).
    groups : int
        Distinct name sets seen (1: full frames).
    dropped : int
        Pending frames dropped (a joint's data too old or out of order; in derived mode also
        full frames out of stamp order).
    wraps : int
        ``2 pi`` jumps undone.
    derived : bool
        True when the velocities are derived from the positions.
    notes : list of str
        One line per input fallback (angles unwrapped, velocities derived), each added once.
    """

    def __init__(self, *, required: Sequence[str] = (), history: int = 16,
                 learn_repeats: int = 2) -> None:
        self.required = tuple(required)
        self.history = history
        self.learn_repeats = learn_repeats
        self.names: tuple[str, ...] = ()
        self.groups = 0
        self.dropped = 0
        self._split = False
        self._reported = False
        self._perm: dict[tuple[str, ...], np.ndarray] = {}
        # learning (split mode): name sets -> counts, per-joint counts, buffered messages
        self._sets: dict[frozenset[str], int] = {}
        self._counts: dict[str, int] = {}
        self._order: dict[str, None] = {}
        self._learn: list[tuple[float, tuple[str, ...], np.ndarray, np.ndarray | None]] = []
        self._clock: frozenset[str] | None = None
        self._hist: list[deque[tuple[float, float, float]]] = []
        self._col: dict[str, int] = {}
        self._pending: deque[float] = deque()
        self._has_pos = True
        self.wraps = 0
        self.notes: list[str] = []
        self._derive: bool | None = None  # decided by the first message
        self._last_q: np.ndarray | None = None  # full frames: last unwrapped angles
        self._turns: np.ndarray | None = None  # 2 pi turns undone so far, per joint
        self._mid: tuple[float, np.ndarray] | None = None  # derived: frame awaiting its next
        self._prev: tuple[float, np.ndarray] | None = None  # derived: the frame before it

    @property
    def derived(self) -> bool:
        """True when the velocities are derived from the positions."""
        return bool(self._derive)

    def _wrapped(self, n: int) -> None:
        if n and not self.wraps:
            self.notes.append(_online_wrap_note(self.names))
        self.wraps += n

    @property
    def split(self) -> bool:
        """True once the messages are known to be split over several name groups."""
        return self._split

    def add(self, t_s: float, names: Sequence[str], velocity: np.ndarray,
            position: np.ndarray | None = None) -> list[JointFrame]:
        """One JointState message; returns the frames completed by it (possibly none).

        Raises
        ------
        SlipDataError
            Array lengths disagree with the names, a name outside the learned joint set, or
            (once) a joint set that stays incomplete.
        """
        names = tuple(names)
        v = np.asarray(velocity, dtype=float)
        q = None if position is None or len(position) == 0 else np.asarray(position, float)
        if self._derive is None:  # the first message decides: no velocities, positions
            self._derive = v.size == 0 and q is not None and len(names) > 0
            if self._derive:
                self.notes.append(DERIVED_NOTE_ONLINE)
        if self._derive:
            if q is None or q.size != len(names):
                raise SlipDataError(f'JointState with {len(names)} names has '
                                    f'{0 if q is None else q.size} positions (velocities are '
                                    'derived from the positions: every message needs them)')
            v = np.full(len(names), np.nan)
        if v.size != len(names) or (q is not None and q.size != v.size):
            raise SlipDataError(f'JointState with {len(names)} names has {v.size} velocities '
                                f'and {0 if q is None else q.size} positions')
        if not self._split:
            if names == self.names:
                return self._full(t_s, v, q)
            if self.names:
                perm = self._perm.get(names)
                if perm is None:
                    if len(names) != len(self.names) or set(names) != set(self.names):
                        raise SlipDataError(f'JointState names {list(names)} are not the '
                                            f'joint set {list(self.names)}')
                    perm = np.array([names.index(n) for n in self.names])
                    self._perm[names] = perm
                return self._full(t_s, v[perm], None if q is None else q[perm])
            if not self._sets and not missing_joints(names, self.required):
                self.names = names  # a complete first message: full frames
                self.groups = 1
                return self._full(t_s, v, q)
            return self._learning(t_s, names, v, q)
        return self._push(t_s, names, v, q)

    # -- full frames -------------------------------------------------------------------
    def _full(self, t_s: float, v: np.ndarray, q: np.ndarray | None) -> list[JointFrame]:
        """One full frame in the joint order: angles unwrapped; in derived mode the
        previous frame is returned with its central-difference speed."""
        mid = self._mid
        if self._derive and mid is not None and t_s < mid[0]:
            self.dropped += 1  # out of stamp order: no speed can be formed
            return []
        if q is not None:
            last = self._last_q
            if last is not None:
                d = q - last
                if np.any(np.abs(d) > math.pi):  # NaN compares False
                    k = np.round(d / _TWO_PI)  # turns undone so far, per joint
                    k[~np.isfinite(k)] = 0.0
                    q = q - _TWO_PI * k
                    turns = self._turns if self._turns is not None else np.zeros(k.size)
                    self._wrapped(int(np.abs(k - turns).sum()))
                    self._turns = k
                self._last_q = np.where(np.isfinite(q), q, last)
            else:
                self._last_q = q.copy()
        if not self._derive:
            return [JointFrame(t_s, self.names, v, q)]
        assert q is not None
        if mid is not None and t_s == mid[0]:
            self._mid = (t_s, q)  # the most recent message wins at an equal stamp
            return []
        self._mid = (t_s, q)
        if mid is None:
            return []
        speed = _central(self._prev, mid, (t_s, q))
        self._prev = mid
        return [JointFrame(mid[0], self.names, speed, mid[1])]

    # -- split mode --------------------------------------------------------------------
    def _learning(self, t_s: float, names: tuple[str, ...], v: np.ndarray,
                  q: np.ndarray | None) -> list[JointFrame]:
        key = frozenset(names)
        self._sets[key] = self._sets.get(key, 0) + 1
        self._order.update(dict.fromkeys(names))
        for n in names:
            self._counts[n] = self._counts.get(n, 0) + 1
        self._learn.append((t_s, names, v, q))
        if len(self._learn) > 64 * max(1, len(self._order)):
            del self._learn[0]
        if min(self._counts.values()) < self.learn_repeats:
            return []
        union = tuple(self._order)
        missing = missing_joints(union, self.required)
        if missing:
            if self._reported:
                return []
            self._reported = True
            raise SlipDataError(f'joint states never name joint(s) {missing} (name groups '
                                f'{sorted(sorted(g) for g in self._sets)})')
        self._split = True
        self.names = union
        self.groups = len(self._sets)
        self._col = {n: j for j, n in enumerate(union)}
        self._clock = max(self._sets, key=lambda k: self._sets[k])  # first seen on ties
        self._hist = [deque(maxlen=self.history) for _ in union]
        self._has_pos = all(x[3] is not None for x in self._learn)
        out: list[JointFrame] = []
        for x in self._learn:
            out.extend(self._push(*x))
        self._learn.clear()
        return out

    def _push(self, t_s: float, names: tuple[str, ...], v: np.ndarray,
              q: np.ndarray | None) -> list[JointFrame]:
        for i, n in enumerate(names):
            j = self._col.get(n)
            if j is None:
                raise SlipDataError(f'joint {n!r} is not in the assembled joint set '
                                    f'{list(self.names)}')
            h = self._hist[j]
            qi = float(q[i]) if q is not None else float('nan')
            if h and t_s < h[-1][0]:
                self.dropped += 1  # out of order for this joint: dropped
                continue
            if h and t_s == h[-1][0]:
                h.pop()  # the most recent value wins at an equal stamp
            if h and q is not None and np.isfinite(h[-1][2]) and np.isfinite(qi):
                k = round((qi - h[-1][2]) / _TWO_PI)  # turns undone so far
                if k:
                    qi -= _TWO_PI * k  # unwrapped: the representative nearest the last one
                if self._turns is None:
                    self._turns = np.zeros(len(self.names))
                if k != self._turns[j]:
                    self._wrapped(abs(k - int(self._turns[j])))
                    self._turns[j] = k
            vi = float(v[i])
            if self._derive and h:
                # the previous sample's speed, now that its next neighbour is here
                t1, _, q1 = h[-1]
                prev = (h[-2][0], h[-2][2]) if len(h) >= 2 else None
                h[-1] = (t1, float(_central(prev, (t1, q1), (t_s, qi))), q1)
            h.append((t_s, vi, qi))
        if frozenset(names) == self._clock:
            self._pending.append(t_s)
        out: list[JointFrame] = []
        last = -2 if self._derive else -1  # derived: the newest sample has no speed yet
        while self._pending:
            tp = self._pending[0]
            if any(len(h) < -last or h[last][0] < tp for h in self._hist):
                break  # some joint has no sample (with a speed) at or after tp yet
            self._pending.popleft()
            frame = self._interp(tp)
            if frame is None:
                self.dropped += 1
            else:
                out.append(frame)
        return out

    def _interp(self, tp: float) -> JointFrame | None:
        vel = np.empty(len(self.names))
        pos = np.empty(len(self.names)) if self._has_pos else None
        for j, h in enumerate(self._hist):
            if h[0][0] > tp:
                return None  # never extrapolate
            k = len(h) - (2 if self._derive else 1)  # derived: the newest has no speed
            while k > 0 and h[k - 1][0] >= tp:
                k -= 1
            t1, v1, q1 = h[k]
            if t1 == tp or k == 0:
                vel[j] = v1
                if pos is not None:
                    pos[j] = q1
                continue
            t0, v0, q0 = h[k - 1]
            w = (tp - t0) / (t1 - t0)
            vel[j] = v0 + w * (v1 - v0)
            if pos is not None:
                pos[j] = q0 + w * (q1 - q0)
        return JointFrame(tp, self.names, vel, pos)
