"""Power breakdown of the simulated AntBot: where the servo power goes, by phase, joint and term.

Diagnostic benchmark for Brodoline et al.'s duty-factor and wave findings. For each run (clean,
no effects, one settling cycle dropped) it prints the robot's P_in, P_out (positive servo output
power), P_loss and CoT/M, then the mean power of one leg while in stance and while in swing,
split into the :class:`~hexapod_bench_drivers.servo_model.ServoModel` loss terms (standby,
copper, bridge braking, Coulomb, load-dependent gear friction, viscous, rotor kinetic, load),
and per joint. Baseline measured in the same run: tripod beta 0.5 at the same speed and
payload; the ratio printed is P_loss(variant) / P_loss(baseline) (the paper: beta 0.7 at
0.26 m/s about 0.90, wave beta 0.83 at 0.1 m/s with load up to 0.92).

It also prints, per run, the peak commanded joint speed against the servo's no-load speed at the
supply voltage (a swing faster than that cannot be followed: the servo saturates), and the
largest possible saving from sharing the body weight over more stance legs: the time-mean
holding copper ``R (tau / k_t)^2`` of the stance joints (no friction helping to hold).

    .venv/bin/python bench/bench_sim_breakdown.py [--joints] [--servo NAME=VALUE ...] [--grid]
        [--budget] [--candidates]

``--grid`` sweeps Coulomb and viscous friction, rotor inertia, friction smoothing and the
compliance slope (40 valid AX-18A variants, about a minute) and prints, for each, the P_loss
change of beta 0.7 and of the wave gait and the 0.6 m/s figures the issue bounds (P_in 35-80 W,
efficiency <= 6 %).

``--budget`` (with any ``--servo`` what-if, a few seconds) splits the two findings into their
terms: the energy of one swing of one leg above standby against the swing duration, the robot's
swing power, the realised stance copper against its holding bound, the stance joints' transmitted
power ``sum |tau| |w|`` (the most that a load-proportional gear friction could dissipate in stance
even at ``mu = 1``), the stance-copper factor that beta 0.7 would need to break even, the swing
duration at which the gait's peak joint speed reaches the no-load speed, and beta 0.7 against
0.5 from 0.1 to 0.26 m/s.

``--candidates`` (about 10 s) prints both findings and every whole-robot band of the issue
(standing, 0.6 m/s power and efficiency, efficiency at 0.1 m/s, CoT/M at 0.84 m/s, 500 g load
sensitivity) for the calibrated servo and six physical variants (dither, gear stiction,
datasheet no-load current, coreless rotor inertia, softer compliance slope).

``--servo`` replaces AX-18A constants for a what-if (for example
``--servo friction_smoothing_rad_s=0.2 --servo coulomb_friction_nm=0.1``).
"""

from __future__ import annotations

import argparse
import contextlib
import math
import time
from collections.abc import Iterator

import numpy as np

from hexapod_bench_drivers.effects import EffectSet
from hexapod_bench_drivers.robot_sim import RobotConfig, RobotSimulator, SampleInput
from hexapod_bench_drivers.servo_model import ServoParams

TERMS = ('standby', 'copper', 'brake', 'coulomb', 'gear', 'viscous', 'kinetic', 'load')
JOINTS = ('coxa', 'femur', 'tibia')


def breakdown(label: str, show_joints: bool = False, verbose: bool = True,
              **kw) -> dict[str, float]:
    """Simulate one clean run with the loss breakdown on; print and return its figures.

    Returned keys: ``p_in_w``, ``p_out_w``, ``p_loss_w``, ``cot_per_mass``, ``hold_w`` (the
    holding copper bound of the whole robot), ``t_swing_s``, ``period_s``, ``stance_legs``
    (time mean), ``peak_speed_rad_s`` (commanded), ``w_max_rad_s`` (no-load speed at the
    supply), ``transmitted_w`` (time mean of ``sum |tau| |w|`` over the stance joints: the most
    that a load-proportional gear friction with ``mu = 1`` could dissipate in stance), and per
    leg in each phase ``<phase>_<term>_w`` (``phase`` stance or swing) and ``<phase>_w``.
    """
    cfg = RobotConfig(**kw)
    sim = RobotSimulator(cfg, effects=EffectSet.none())
    sim.servos.record_losses = True
    period = cfg.effective_period_s
    cycles = max(2, math.ceil(4.0 / period))
    dt = 1.0 / cfg.rate_hz
    n = int(round(period * (cycles + 1) * cfg.rate_hz))
    t = dt * np.arange(1, n + 1)
    q, qd, qdd, stance, tipv = sim.gait_inputs(t)
    tau = sim.required_torques(q, qd, qdd, stance, tipv)
    terms = np.zeros((n, len(TERMS), q.shape[1] * 3))
    p_in = np.zeros(n)
    for k in range(n):
        res = sim.step(dt, SampleInput(q[k], qd[k], qdd[k], stance[k], 0.0, 0.0, tipv[k]), tau[k])
        losses = res['servo'].losses
        terms[k] = [losses[name] for name in TERMS]
        p_in[k] = res['power_w']
    keep = t > period + 1e-9
    terms, p_in = terms[keep], p_in[keep]
    st = np.repeat(stance[keep], 3, axis=1)                       # (n, joints)
    p_out = float(np.clip(terms[:, TERMS.index('load')], 0.0, None).sum(axis=1).mean())
    loss = float(p_in.mean()) - p_out
    speed = cfg.speed_mps
    mass = cfg.total_mass_kg
    params = sim.servo_params
    ke = params.back_emf_constant_v_s
    w_max = (cfg.supply_voltage_v - params.winding_resistance_ohm * params.no_load_current_a) / ke
    r_ohm, kt = params.winding_resistance_ohm, params.torque_constant_nm_a
    hold = float((np.where(stance[keep][..., None], r_ohm * (tau[keep] / kt) ** 2, 0.0))
                 .sum(axis=(1, 2)).mean())
    qd_k, tau_k = qd[keep].reshape(len(p_in), -1), tau[keep].reshape(len(p_in), -1)
    transmitted = float((np.abs(tau_k) * np.abs(qd_k) * st).sum(axis=1).mean())
    out = {'p_in_w': float(p_in.mean()), 'p_out_w': p_out, 'p_loss_w': loss,
           'cot_per_mass': loss / (mass * speed), 'hold_w': hold,
           't_swing_s': period * (1 - cfg.duty_factor), 'period_s': period,
           'stance_legs': float(stance[keep].sum(axis=1).mean()),
           'peak_speed_rad_s': float(np.abs(qd[keep]).max()), 'w_max_rad_s': w_max,
           'transmitted_w': transmitted}
    if verbose:
        print(f'\n== {label}: T {period:.3f} s, T_swing {out["t_swing_s"]:.3f} s, '
              f'stance legs {out["stance_legs"]:.2f}; P_in {p_in.mean():.2f} W, '
              f'P_out {p_out:.3f} W, P_loss {loss:.2f} W, CoT/M {loss / (mass * speed):.2f} '
              'J/(m kg)')
        print(f'   peak commanded joint speed {out["peak_speed_rad_s"]:.1f} rad/s (no-load speed '
              f'at {cfg.supply_voltage_v:.1f} V: {w_max:.1f}); holding copper bound '
              f'sum R (tau/k_t)^2 over stance joints {hold:.2f} W; stance sum |tau w| '
              f'{transmitted:.2f} W')
    for name, mask in (('stance', st), ('swing', ~st)):
        per_leg = {term: float((terms[:, j] * mask).sum() / max(mask.sum(), 1) * 3)
                   for j, term in enumerate(TERMS)}
        total = sum(per_leg.values())
        out[f'{name}_w'] = total
        out.update({f'{name}_{term}_w': v for term, v in per_leg.items()})
        if not verbose:
            continue
        print(f'   {name:6s} ({mask.mean():.2f} of the time) one leg {total:5.2f} W: '
              + ' '.join(f'{term} {v:5.2f}' for term, v in per_leg.items()))
        if show_joints:
            for jj, joint in enumerate(JOINTS):
                cols = np.arange(jj, mask.shape[1], 3)
                m = mask[:, cols]
                vals = {term: float((terms[:, j][:, cols] * m).sum() / max(m.sum(), 1))
                        for j, term in enumerate(TERMS)}
                print(f'      {joint:5s} '
                      + ' '.join(f'{term} {v:5.2f}' for term, v in vals.items()))
    return out


@contextlib.contextmanager
def servo_overrides(changes: dict[str, float]) -> Iterator[None]:
    """Within the block, every servo preset the simulators build has ``changes`` applied."""
    original = ServoParams.__dict__['by_name']
    if not changes:
        yield
        return

    def by_name(cls: type[ServoParams], name: str) -> ServoParams:
        return original.__func__(cls, name).with_changes(**changes)

    ServoParams.by_name = classmethod(by_name)  # type: ignore[method-assign,assignment]
    try:
        yield
    finally:
        ServoParams.by_name = original  # type: ignore[method-assign]


def _loss_w(**kw) -> tuple[float, float, float]:
    """Clean run: whole-cycle mean P_loss, P_in, P_out [W] after one settling cycle."""
    cfg = RobotConfig(**kw)
    period = cfg.effective_period_s
    cycles = max(2, math.ceil(3.0 / period))
    sim = RobotSimulator(cfg, effects=EffectSet.none())
    tr = sim.run(period * (cycles + 1))
    keep = tr.t_s > period + 1e-9
    p_in = float(np.mean(tr.true_power_in_w[keep]))
    p_out = float(np.mean(np.clip(tr.true_mechanical_power_w[keep], 0.0, None).sum(axis=1)))
    return p_in - p_out, p_in, p_out


def run_grid() -> None:
    """Findings and 0.6 m/s figures over a grid of servo constants."""
    import itertools

    from hexapod_bench_drivers.servo_model import ServoParamsError

    tick = math.radians(0.29)
    print('Coulomb N m, viscous N m s/rad, rotor kg m^2, smoothing rad/s, slope ticks: '
          'P_loss change beta 0.7 (0.26 m/s) and wave (0.1 m/s, 0.5 kg); 0.6 m/s P_in, eta')
    grid = itertools.product((0.05, 0.24, 0.4), (0.002, 0.02), (0.3e-8, 1.2e-8), (0.0, 0.2),
                             (32, 128))
    for c, b, j, w_s, slope in grid:
        changes = dict(coulomb_friction_nm=c, viscous_friction_nm_s=b, rotor_inertia_kgm2=j,
                       friction_smoothing_rad_s=w_s, compliance_slope_rad=slope * tick)
        try:
            ServoParams.ax18a().with_changes(**changes)
        except ServoParamsError:
            continue        # no-load friction beyond what the datasheet points allow
        with servo_overrides(changes):
            b5 = _loss_w(speed_mps=0.26)[0]
            b7 = _loss_w(speed_mps=0.26, duty_factor=0.7)[0]
            tri = _loss_w(speed_mps=0.1, payload_kg=0.5)[0]
            wave = _loss_w(speed_mps=0.1, payload_kg=0.5, gait='wave', duty_factor=0.83)[0]
            _, p_in, p_out = _loss_w(speed_mps=0.6)
        ok = 35.0 <= p_in <= 80.0 and p_out / p_in <= 0.06
        print(f'c {c:.2f} b {b:.3f} J {j:.1e} w_s {w_s:.1f} slope {slope:3d}: beta 0.7 '
              f'{100 * (b7 / b5 - 1):+6.1f} %, wave {100 * (wave / tri - 1):+6.1f} %; '
              f'0.6 m/s {p_in:5.1f} W, eta {100 * p_out / p_in:4.1f} %'
              f'{"" if ok else "  (outside the 0.6 m/s bands)"}', flush=True)


CANDIDATES: tuple[tuple[str, dict[str, float]], ...] = (
    ('calibrated (defaults)', {}),
    ('dither 1 rad/s', dict(friction_smoothing_rad_s=1.0)),
    ('stiction 1.5', dict(static_friction_ratio=1.5)),
    ('datasheet no-load 0.2 A', dict(coulomb_friction_nm=0.07, viscous_friction_nm_s=0.01)),
    ('no-load 0.2 A + dither', dict(coulomb_friction_nm=0.07, viscous_friction_nm_s=0.01,
                                    friction_smoothing_rad_s=1.0)),
    ('+ coreless rotor 0.4e-8', dict(coulomb_friction_nm=0.07, viscous_friction_nm_s=0.01,
                                     friction_smoothing_rad_s=1.0, rotor_inertia_kgm2=0.4e-8)),
    ('+ compliance slope 64', dict(coulomb_friction_nm=0.07, viscous_friction_nm_s=0.01,
                                   friction_smoothing_rad_s=1.0, rotor_inertia_kgm2=0.4e-8,
                                   compliance_slope_rad=64 * math.radians(0.29))),
)


def _standing_w() -> float:
    cfg = RobotConfig(period_s=0.0)
    tr = RobotSimulator(cfg, effects=EffectSet.none()).run(2.0)
    return float(np.mean(tr.true_power_in_w[tr.t_s > 1.0]))


def run_candidates() -> None:
    """Both findings and every whole-robot band of the issue for a few physical variants."""
    print('variant: no-load current, gear efficiency | P_loss change beta 0.7 (0.26 m/s), wave '
          '(0.1 m/s, 0.5 kg) | standing P_in (8-20 W) | 0.6 m/s P_in (35-80 W), eta (<= 6 %) | '
          'eta at 0.1 m/s (>= 0.5 %) | CoT/M at 0.84 m/s, 140 mm (25-50) | +0.5 kg at 0.3 m/s')
    for name, changes in CANDIDATES:
        with servo_overrides(changes):
            p = ServoParams.by_name('ax18a')
            b5 = _loss_w(speed_mps=0.26)[0]
            b7 = _loss_w(speed_mps=0.26, duty_factor=0.7)[0]
            tri = _loss_w(speed_mps=0.1, payload_kg=0.5)[0]
            wave = _loss_w(speed_mps=0.1, payload_kg=0.5, gait='wave', duty_factor=0.83)[0]
            _, p6, o6 = _loss_w(speed_mps=0.6)
            _, p1, o1 = _loss_w(speed_mps=0.1)
            l84 = _loss_w(speed_mps=0.84, step_length_m=0.14)[0]
            light, heavy = _loss_w(speed_mps=0.3)[1], _loss_w(speed_mps=0.3, payload_kg=0.5)[1]
            stand = _standing_w()
        cot84 = l84 / (RobotConfig().total_mass_kg * 0.84)
        bands = (8 <= stand <= 20 and 35 <= p6 <= 80 and o6 / p6 <= 0.06 and o1 / p1 >= 0.005
                 and 25 <= cot84 <= 50)
        print(f'{name:26s}: {p.no_load_current_a:.2f} A, {p.gear_efficiency:.2f} | '
              f'{100 * (b7 / b5 - 1):+5.1f} %, {100 * (wave / tri - 1):+5.1f} % | '
              f'{stand:4.1f} W | {p6:4.1f} W, {100 * o6 / p6:4.1f} % | {100 * o1 / p1:4.2f} % | '
              f'{cot84:4.1f} | {heavy - light:+4.2f} W'
              f'{"" if bands else "  (outside a band)"}', flush=True)


def run_budget() -> None:
    """Per-swing energy, stance sharing and transmitted stance power behind the two findings."""
    runs = {
        'tripod 0.1 m/s': dict(speed_mps=0.1),
        'tripod 0.26 m/s': dict(speed_mps=0.26),
        'beta 0.7 0.26 m/s': dict(speed_mps=0.26, duty_factor=0.7),
        'tripod 0.1 m/s 0.5 kg': dict(speed_mps=0.1, payload_kg=0.5),
        'wave 0.1 m/s 0.5 kg': dict(speed_mps=0.1, payload_kg=0.5, gait='wave',
                                    duty_factor=0.83),
        'tripod 0.6 m/s': dict(speed_mps=0.6),
    }
    res = {name: breakdown(name, verbose=False, **kw) for name, kw in runs.items()}
    legs = RobotConfig().leg_count
    print('run: T_swing s, peak commanded / no-load speed | one swing of one leg above standby '
          'J | robot swing power above standby W | stance copper of the robot W (holding bound) '
          '| stance sum |tau w| W')
    for name, r in res.items():
        e_swing = (r['swing_w'] - r['swing_standby_w']) * r['t_swing_s']
        r['swing_robot_w'] = e_swing * legs / r['period_s']
        r['stance_copper_robot_w'] = r['stance_copper_w'] * r['stance_legs']
        print(f'{name:22s}: {r["t_swing_s"]:.3f} s, {r["peak_speed_rad_s"]:4.1f}/'
              f'{r["w_max_rad_s"]:4.1f} rad/s | {e_swing:5.3f} J | {r["swing_robot_w"]:5.2f} W | '
              f'{r["stance_copper_robot_w"]:5.2f} W ({r["hold_w"]:5.2f}) | '
              f'{r["transmitted_w"]:.2f} W')
    for base, var in (('tripod 0.26 m/s', 'beta 0.7 0.26 m/s'),
                      ('tripod 0.1 m/s 0.5 kg', 'wave 0.1 m/s 0.5 kg')):
        b, v = res[base], res[var]
        d_loss = v['p_loss_w'] - b['p_loss_w']
        d_cu = b['stance_copper_robot_w'] - v['stance_copper_robot_w']
        parity = 1.0 + d_loss / d_cu if d_cu > 0 and d_loss > 0 else float('nan')
        d_sw = v['swing_robot_w'] - b['swing_robot_w']
        print(f'-> {var} vs {base}: P_loss {d_loss:+.2f} W = swing {d_sw:+.2f} W, stance copper '
              f'{-d_cu:+.2f} W (holding bound {v["hold_w"] - b["hold_w"]:+.2f} W), P_out '
              f'{v["p_out_w"] - b["p_out_w"]:+.2f} W (subtracted), rest '
              f'{d_loss - d_sw + d_cu:+.2f} W; break-even needs the stance copper x{parity:.1f}')
    r7 = res['beta 0.7 0.26 m/s']
    print(f'-> the gait swing reaches the no-load speed at T_swing '
          f'{r7["t_swing_s"] * r7["peak_speed_rad_s"] / r7["w_max_rad_s"]:.3f} s '
          '(the paper: 0.16 s is the servo limit)')
    row = []
    for v in (0.1, 0.15, 0.2, 0.26):
        b5, b7 = _loss_w(speed_mps=v)[0], _loss_w(speed_mps=v, duty_factor=0.7)[0]
        row.append(f'{v:.2f} m/s {100 * (b7 / b5 - 1):+.1f} %')
    print('-> P_loss change of beta 0.7 against 0.5: ' + ', '.join(row))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--joints', action='store_true', help='per-joint rows as well')
    parser.add_argument('--servo', action='append', default=[], metavar='NAME=VALUE',
                        help='replace a ServoParams constant (repeatable)')
    parser.add_argument('--grid', action='store_true',
                        help='sweep servo constants instead (findings and 0.6 m/s bands)')
    parser.add_argument('--candidates', action='store_true',
                        help='findings and every whole-robot band for a few physical variants')
    parser.add_argument('--budget', action='store_true',
                        help='per-swing energy, stance sharing and transmitted stance power '
                        '(with --servo what-ifs)')
    args = parser.parse_args()
    if args.candidates:
        start = time.perf_counter()
        run_candidates()
        print(f'\nwall time {time.perf_counter() - start:.1f} s')
        return
    if args.grid:
        start = time.perf_counter()
        run_grid()
        print(f'\nwall time {time.perf_counter() - start:.1f} s')
        return
    changes = {}
    for item in args.servo:
        name, _, value = item.partition('=')
        changes[name.strip()] = float(value)
    if changes:
        print(f'servo constants replaced: {changes}')
    with servo_overrides(changes):
        if args.budget:
            run_budget()
        else:
            run_cases(args.joints)


def run_cases(show_joints: bool) -> None:
    """The duty-factor, wave and load cases, each against its baseline."""
    start = time.perf_counter()
    cases = (
        ('beta 0.7 vs 0.5 at 0.26 m/s',
         dict(speed_mps=0.26, duty_factor=0.5), dict(speed_mps=0.26, duty_factor=0.7)),
        ('wave 0.83 vs tripod 0.5 at 0.1 m/s, 0.5 kg',
         dict(speed_mps=0.1, payload_kg=0.5),
         dict(speed_mps=0.1, payload_kg=0.5, gait='wave', duty_factor=0.83)),
    )
    for title, base_kw, var_kw in cases:
        base = breakdown(f'{title}: baseline', show_joints, **base_kw)
        var = breakdown(f'{title}: variant', show_joints, **var_kw)
        print(f'-> {title}: P_loss {var["p_loss_w"]:.2f} vs {base["p_loss_w"]:.2f} W, ratio '
              f'{var["p_loss_w"] / base["p_loss_w"]:.3f}; CoT/M ratio '
              f'{var["cot_per_mass"] / base["cot_per_mass"]:.3f}; holding bound saving '
              f'{base["hold_w"] - var["hold_w"]:.2f} W')
    light = breakdown('load sensitivity: tripod 0.3 m/s, no payload', **dict(speed_mps=0.3))
    heavy = breakdown('load sensitivity: tripod 0.3 m/s, 0.5 kg', **dict(speed_mps=0.3,
                                                                          payload_kg=0.5))
    print(f'-> +0.5 kg payload at 0.3 m/s: P_in {heavy["p_in_w"] - light["p_in_w"]:+.2f} W '
          '(paper: about +4 W on average over speeds)')
    print(f'\nwall time {time.perf_counter() - start:.1f} s')


if __name__ == '__main__':
    main()
