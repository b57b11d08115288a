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

``--grid`` sweeps Coulomb and viscous friction, rotor inertia, friction smoothing and the
compliance slope (40 valid AX-18A variants, about a minute) and prints, for each, the P_loss
change of beta 0.7 and of the wave gait and the 0.6 m/s figures the issue bounds (P_in 35-80 W,
efficiency <= 6 %).

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


def breakdown(label: str, show_joints: bool = False, **kw) -> dict[str, float]:
    """Simulate one clean run with the loss breakdown on; print and return its figures."""
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
    print(f'\n== {label}: T {period:.3f} s, T_swing {period * (1 - cfg.duty_factor):.3f} s, '
          f'stance legs {stance[keep].sum(axis=1).mean():.2f}; P_in {p_in.mean():.2f} W, '
          f'P_out {p_out:.3f} W, P_loss {loss:.2f} W, CoT/M {loss / (mass * speed):.2f} J/(m kg)')
    print(f'   peak commanded joint speed {np.abs(qd[keep]).max():.1f} rad/s (no-load speed at '
          f'{cfg.supply_voltage_v:.1f} V: {w_max:.1f}); holding copper bound '
          f'sum R (tau/k_t)^2 over stance joints {hold:.2f} W')
    for name, mask in (('stance', st), ('swing', ~st)):
        per_leg = {term: float((terms[:, j] * mask).sum() / max(mask.sum(), 1) * 3)
                   for j, term in enumerate(TERMS)}
        total = sum(per_leg.values())
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
    return {'p_in_w': float(p_in.mean()), 'p_out_w': p_out, 'p_loss_w': loss,
            'cot_per_mass': loss / (mass * speed), 'hold_w': hold}


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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--joints', action='store_true', help='per-joint rows as well')
    parser.add_argument('--servo', action='append', default=[], metavar='NAME=VALUE',
                        help='replace a ServoParams constant (repeatable)')
    parser.add_argument('--grid', action='store_true',
                        help='sweep servo constants instead (findings and 0.6 m/s bands)')
    args = parser.parse_args()
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
