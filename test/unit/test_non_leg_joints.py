"""Joints that are not a leg's (a gripper beside the legs) are left out of the gait cycles,
P_out and the SLIP analysis, with a note (an outside review, another lab's bag: two gripper
joints opening every 2 s beside 18 leg joints split one steady 0.80 s gait into 0.80 and
1.60 s cycles, 14 of 24 windows, P_out 7.00 W for the legs' 5.11 W, no note; `slip`
refused the bag saying "/joint_states never names joint(s) ['gripper']")."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hexapod_common.conversions import JointStateSample, LegJointFilter
from hexapod_common.testbags import rewrite_bag
from hexapod_energy.bag_io import read_robot_bag
from test_outside_nogait_bag import simulated_run, write_lab_bag

GRIPPERS = ('gripper_left', 'gripper_right')


def _js(t, names):
    n = len(names)
    return JointStateSample(t, tuple(names), np.arange(n, dtype=float), np.ones(n),
                            np.full(n, 2.0))


def test_the_filter_keeps_leg_joints_and_streams_of_other_names():
    f = LegJointFilter(legs_present=True)
    mixed = f.apply(_js(0.1, ('L1_coxa', 'gripper_left', 'R1_hip')))
    assert mixed.names == ('L1_coxa', 'R1_hip')
    np.testing.assert_array_equal(mixed.position, [0.0, 2.0])
    assert f.apply(_js(0.2, GRIPPERS)) is None and f.samples_dropped == 1
    legs = _js(0.3, ('L1_coxa', 'R1_hip'))
    assert f.apply(legs) is legs
    assert f.dropped == {'gripper_left': 2, 'gripper_right': 1}
    assert f.note().startswith('joint(s) gripper_left, gripper_right are not leg joints')
    # live nodes take the map from the environment, not from --joint-map (a review)
    assert f.note().endswith('(a live node reads the map from HEXAPOD_JOINT_MAP, JSON '
                             '{"recorded": "L1_coxa"})')
    assert 'out of the gait cycles and P_out' in f.note()
    # empty velocity or effort arrays stay empty
    s = JointStateSample(0.4, ('L1_coxa', 'gripper_left'), np.zeros(2), np.zeros(0),
                         np.zeros(0))
    out = f.apply(s)
    assert out.names == ('L1_coxa',) and out.velocity.size == 0 and out.effort.size == 0
    # zero-based leg numbers are legs too (an outside review: L0/R0 had been dropped)
    assert f.apply(_js(0.5, ('L0_coxa', 'R0_hip'))).names == ('L0_coxa', 'R0_hip')
    # a bag of other names (no leg joint anywhere) is read whole
    other = LegJointFilter(legs_present=LegJointFilter.names_have_legs([('j_c1_lf', 'hip_0')]))
    s = _js(0.0, ('j_c1_lf', 'hip_0'))
    assert other.apply(s) is s and not other.dropped


def test_live_a_stream_is_settled_by_its_first_leg_joint_and_never_the_other_way():
    """Undecided (live energy), every sample passes whole until one names a leg joint; from
    then on other joints are left out. A stream of other names is never settled as having no
    legs (a first version held such samples and, after 100, passed every later one whole,
    grippers included, for good)."""
    f = LegJointFilter()
    early = _js(0.0, GRIPPERS)
    assert f.apply(early) is early and f.legs_present is None
    got = f.apply(_js(0.02, ('L1_hip', 'gripper_left')))
    assert got.names == ('L1_hip',) and f.legs_present is True
    assert f.apply(_js(0.03, GRIPPERS)) is None and f.samples_dropped == 1
    other = LegJointFilter()
    for k in range(300):
        s = _js(0.01 * k, ('hip_0', 'hip_1'))
        assert other.apply(s) is s
    assert other.legs_present is None and not other.dropped


def _live(bag, preset=None, *, twice_every=0):
    """DescriptorAccumulator fed a bag's messages as energy_monitor gets them (receive
    order), each ``twice_every``-th joint state delivered twice."""
    from hexapod_common.bags import iter_messages, open_reader
    from hexapod_common.conversions import battery_from_msg, gait_phase_from_msg
    from hexapod_common.conversions import joint_state_from_msg
    from hexapod_energy.descriptors import DescriptorAccumulator

    acc = DescriptorAccumulator(mass_kg=2.0, power_out_source='effort')
    if preset is not None:
        acc.leg_joints_ = LegJointFilter(legs_present=preset)
    out, k = [], 0
    with open_reader(bag) as reader:
        for m in iter_messages(reader, ('/battery_state', '/gait/phase', '/joint_states')):
            msg = reader.deserialize(m.data, m.msgtype)
            if m.topic == '/battery_state':
                out += acc.add_battery(battery_from_msg(msg))
            elif m.topic == '/gait/phase':
                out += acc.add_gait_phase(gait_phase_from_msg(msg))
            else:
                k += 1
                for _ in range(2 if twice_every and k % twice_every == 0 else 1):
                    out += acc.add_joint_state(joint_state_from_msg(msg))
    return acc, out


def test_live_energy_equals_offline_with_a_gripper_first_or_other_names(tmp_path):
    """A review of the hold: (A) a gripper publishing 2.5 s before the legs' driver gave live
    P_out 4.63-4.65 W where offline read 1.03; (D) a 12.5 Hz stream of other names read
    P_out 0 W in the windows that ended while its samples were held. Now live equals the
    offline rule (the whole bag decides) on both."""
    from hexapod_common.testbags import write_foreign_robot_bag

    write_foreign_robot_bag(tmp_path / 'base', legs=6, duration_s=12.0, storage='mcap')

    def gripper_first(topic, msg):
        if topic != '/joint_states':
            return None
        t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        q, v = 0.6 * math.sin(math.pi * t), 0.6 * math.pi * math.cos(math.pi * t)
        e = 1.5 * np.sign(v)
        if t < 2.5:
            msg.name, msg.position = list(GRIPPERS), np.array([q, -q])
            msg.velocity, msg.effort = np.array([v, -v]), np.array([e, -e])
            return None
        msg.name = list(msg.name) + list(GRIPPERS)
        msg.position = np.append(msg.position, [q, -q])
        msg.velocity = np.append(msg.velocity, [v, -v])
        msg.effort = np.append(msg.effort, [e, -e])
        return None

    k = [0]

    def other_names_slow(topic, msg):
        if topic != '/joint_states':
            return None
        k[0] += 1
        if k[0] % 4:
            return False
        msg.name = [n.replace('L', 'left').replace('R', 'right') for n in msg.name]
        return None

    for edit, preset in ((gripper_first, True), (other_names_slow, False)):
        bag = rewrite_bag(tmp_path / 'base', tmp_path / edit.__name__, edit)
        _, got = _live(bag)
        _, want = _live(bag, preset=preset)
        assert len(got) == len(want) >= 3, edit.__name__
        for a, b in zip(got, want):
            assert a.power_out_w == pytest.approx(b.power_out_w, rel=1e-12), edit.__name__
    off = read_robot_bag(tmp_path / 'gripper_first', mass_kg=2.0)
    assert np.mean([d.power_out_w for d in got]) < 2.0 and off.power_out_w < 2.0


def test_live_slip_core_takes_the_legs_after_an_early_gripper_message():
    from slip_identification.online import OnlineSlip
    from slip_identification.preprocess import Box

    core = OnlineSlip(box=Box((-10.0,) * 3, (10.0,) * 3))
    f = LegJointFilter(legs_present=True)    # as slip_fitter: SLIP needs contract hips
    hips = tuple(f'{s}{k}_hip' for s in 'LR' for k in (1, 2, 3))
    for k in range(50):
        msgs = [_js(0.01 * k, GRIPPERS)] if k == 0 else []
        msgs.append(_js(0.01 * k, hips))
        for s in filter(None, map(f.apply, msgs)):
            core.add_joint_state(s.t_s, s.names, s.velocity, s.position)
    assert core.names == hips and len(core._js) == 50


def _with_grippers(src, dst):
    """The bag with two gripper joints in every /joint_states message, opening and closing
    every 2 s with a constant effort (0.5-1.9 W of positive joint power)."""
    def edit(topic, msg):
        if topic != '/joint_states':
            return None
        t = msg.header.stamp.sec + 1e-9 * msg.header.stamp.nanosec
        w = 2 * math.pi / 2.0
        q, v = 0.6 * math.sin(w * t), 0.6 * w * math.cos(w * t)
        msg.name = list(msg.name) + list(GRIPPERS)
        msg.position = np.append(msg.position, [q, -q])
        if len(msg.velocity):
            msg.velocity = np.append(msg.velocity, [v, -v])
        if len(msg.effort):
            msg.effort = np.append(msg.effort, [1.5 * np.sign(v), -1.5 * np.sign(v)])
        return None
    return rewrite_bag(src, dst, edit)


@pytest.fixture(scope='module')
def lab_run():
    return simulated_run(duration_s=10.0)


@pytest.mark.parametrize('gait_phase', [True, False])
def test_grippers_change_neither_cycles_nor_p_out(tmp_path, lab_run, gait_phase):
    """A simulated AntBot run recorded by another lab, with /gait/phase or without it (the
    cycles from the joint positions), and again with two grippers in /joint_states."""
    write_lab_bag(tmp_path / 'legs', lab_run, gait_phase=gait_phase, odom=False, mocap=True)
    _with_grippers(tmp_path / 'legs', tmp_path / 'grip')
    ref = read_robot_bag(tmp_path / 'legs', mass_kg=2.183)
    got = read_robot_bag(tmp_path / 'grip', mass_kg=2.183)
    assert ref.windows >= 5 and got.windows == ref.windows
    assert got.power_out_w == pytest.approx(ref.power_out_w, rel=1e-9)
    assert got.power_in_w == pytest.approx(ref.power_in_w, rel=1e-9)
    assert any(n.startswith('joint(s) gripper_left, gripper_right are not leg joints')
               for n in got.extra['notes'])


def test_slip_reads_a_bag_with_a_gripper_as_without(tmp_path):
    """`slip` refused such a bag ("/joint_commands: /joint_states never names joint(s)
    ['gripper']"); it now reads the hips alone, noted."""
    edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')
    from slip_identification.cli import read_run

    ref_bag = edubot_bag.write_edubot_bag(tmp_path / 'ref', 'jogging', duration_s=2.0, seed=1)
    _with_grippers(ref_bag, tmp_path / 'grip')
    ref, got = read_run(ref_bag), read_run(tmp_path / 'grip')
    assert got.joint_names == ref.joint_names
    np.testing.assert_array_equal(got.joint_t_s, ref.joint_t_s)
    np.testing.assert_array_equal(got.joint_velocity, ref.joint_velocity)
    assert any(n.startswith('/joint_states: joint(s) gripper_left, gripper_right are not leg')
               and 'stance detection' in n for n in got.notes)


def test_a_joint_state_delivered_twice_counts_once_live(tmp_path):
    """An outside review: 10 % of the messages recorded twice (bag_replay publishes them
    twice) moved the live windows' P_out -7.6 to +5.6 %; offline drops duplicates as it
    reads. The accumulator now leaves a joint state out that repeats a recent one exactly."""
    from hexapod_common.testbags import write_foreign_robot_bag

    write_foreign_robot_bag(tmp_path / 'bag', legs=6, duration_s=12.0)
    _, ref = _live(tmp_path / 'bag')
    acc, got = _live(tmp_path / 'bag', twice_every=10)
    assert len(ref) >= 4 and len(got) == len(ref)
    assert acc.duplicate_joint_states_ > 30
    for a, b in zip(got, ref):
        assert a.power_out_w == pytest.approx(b.power_out_w, rel=1e-12)
        assert a.power_in_w == pytest.approx(b.power_in_w, rel=1e-12)


def test_offline_a_gripper_message_before_the_legs(tmp_path):
    """The same bag's first /joint_states message replaced by a gripper's: `slip` had refused
    the bag ("name groups never overlap in time"), `energy` let the sample in unnoted."""
    edubot_bag = pytest.importorskip('hexapod_bench_drivers.edubot_bag')
    from slip_identification.cli import read_run

    ref_bag = edubot_bag.write_edubot_bag(tmp_path / 'ref', 'jogging', duration_s=2.0, seed=1)
    first = [True]

    def edit(topic, msg):
        if topic == '/joint_states' and first[0]:
            first[0] = False
            msg.name = list(GRIPPERS)
            msg.position, msg.velocity = np.zeros(2), np.ones(2)
            msg.effort = np.ones(2)
        return None

    rewrite_bag(ref_bag, tmp_path / 'first', edit)
    ref, got = read_run(ref_bag), read_run(tmp_path / 'first')
    assert got.joint_names == ref.joint_names
    np.testing.assert_array_equal(got.joint_t_s, ref.joint_t_s[1:])
    assert any('gripper_left, gripper_right are not leg joints' in n for n in got.notes)
    run = read_robot_bag(tmp_path / 'first', mass_kg=3.31)
    assert any(n.startswith('joint(s) gripper_left, gripper_right are not leg joints')
               for n in run.extra['notes'])
