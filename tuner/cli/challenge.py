"""The RoboCup Humanoid League's push-recovery challenge (challenge push) and its bound (challenge bound)."""

from __future__ import annotations

from pathlib import Path

import click


from ..errors import UserError
from ..params_io import resolve_drive
from .options import Span, robot_option, surface_option, JSON_OPTION, RECORD_OPTION, STABILISER_OPTION, CONTROLLER_OPTION


@click.group()
def challenge() -> None:
    """RoboCup Humanoid League technical challenges, simulated."""


@challenge.command(name="push")
@click.option("--params", "params_spec", metavar="PATH|NAME",
              help="Parameter YAML file or shipped set (`gait-tuner sets`); or --controller.")
@CONTROLLER_OPTION
@robot_option()
@surface_option("carpet4")
@click.option("--rules", type=click.Choice(["2025", "2019"]), default="2025", show_default=True,
              help="2025: the rules since 2025-02-13 (a 3, 5 or 10 kg bottle; pushes from the front, from behind, "
                   "from either; partial success at two; M). 2019: the old KidSize trial (a 1 kg bottle, three "
                   "random directions, sqrt(H) / (m H_com)), for comparison.")
@click.option("--bottle", type=click.Choice(["3", "5", "10"]), default="3", show_default=True,
              help="The bottle's mass [kg] (2025 rules).")
@click.option("--third", type=click.Choice(["both", "front", "back"]), default="both", show_default=True,
              help="2025 rules: where the third push comes from; both: each D tried with either, the worse counts.")
@click.option("--rope", default=1.5, show_default=True, type=Span(1.0, 2.0),
              help="Rope length L [m] to the bottle's centre of mass: 1.5-2 m by the 2025 rules, 1-2 m by 2019's.")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**31 - 1),
              help="Seed of the pushes: their directions (2019), their timing and a few degrees of direction (2025).")
@click.option("--step", default=0.05, show_default=True, type=Span(0.01, 0.5),
              help="How much D [m] grows from trial to trial.")
@click.option("--by-direction", is_flag=True,
              help="Not the rules' trial: single pushes per direction (--directions), each at 3.0 and 3.1 s, "
                   "D raised from 0.4 m by --step (0.1 with this flag unless given) until one fails: which "
                   "direction binds the rules' random three.")
@click.option("--directions", default="0,45,90,135,180,225,270,315", show_default=True, metavar="DEG,DEG,...",
              help="With --by-direction: the bottle's direction of travel against the robot's heading [deg] "
                   "(0 the way it faces, 90 to its left).")
@STABILISER_OPTION
@JSON_OPTION
@RECORD_OPTION
def challenge_push(params_spec: str | None, controller_file: Path | None, robot_name: str, surface_name: str,
                   rules: str, bottle: str, third: str, rope: float, seed: int, step: float, by_direction: bool,
                   directions: str, stabiliser: bool | None, as_json: bool, record_dir: Path | None) -> None:
    """The push-recovery challenge: a bottle on a rope released from a growing distance D.

    The robot walks in place. By the 2025 rules (the default): a 3, 5 or 10 kg bottle meets the
    robot at its CoM height; a trial is a push from the front, one from behind and one from either
    (--third); a push is absorbed when the robot is still up, stepping, at the next one; fully
    successful at three, partially at two; D (at most 0.75 L) grows by --step while a trial is at
    least partially successful; the largest D of each, the bottle's momentum at impact and M =
    sqrt(H) / h_c * m_B / m_R * h_i / h_c are reported. --rules 2019: a 1 kg bottle, three random
    directions, the rank sqrt(H) / (m_robot H_com). tuner/challenge/rules.py says what is ours.
    """

    from ..robots import load_robot
    from ..challenge.rules import challenge as run_challenge
    from ..sim.rollout import Simulator
    from ..sim.surfaces import load_surface

    if params_spec is None and controller_file is None:
        raise UserError("give --params (a gait set) or --controller (your own)")
    if not by_direction and click.get_current_context().get_parameter_source("directions").name != "DEFAULT":
        raise UserError("--directions is for --by-direction (the rules' trial draws its directions from --seed)")
    ctx = click.get_current_context()
    if rules == "2019":
        given = [o for o in ("bottle", "third") if ctx.get_parameter_source(o).name != "DEFAULT"]
        if given:
            raise UserError(f"--{given[0]} is for the 2025 rules (the 2019 trial has a 1 kg bottle and three random "
                            f"directions)")
    elif rope < 1.5:
        raise UserError(f"--rope {rope:g}: the 2025 rules' rope is 1.5 to 2 m (1 to 2 m with --rules 2019)")
    if rules == "2025" and by_direction:
        raise UserError("--by-direction is an analysis of the 2019 trial's random directions: add --rules 2019")
    drive = resolve_drive(params_spec, None, stabiliser=stabiliser, controller=controller_file)
    from ..sim.scene import BOTTLE_2019, BOTTLES
    sim = Simulator(load_robot(robot_name), load_surface(surface_name), pendulum=rope,
                    bottle=BOTTLE_2019 if rules == "2019" else BOTTLES[int(bottle)])

    def shown(trial: dict) -> None:
        if not as_json:
            J = [p["measured_Ns"] for p in trial["pushes"]]
            click.echo(f"  D {trial['distance_m']:.2f} m: {'fully successful' if trial['success'] else trial['reason']}"
                       f" (pushes {', '.join('-' if j is None else f'{j:.2f}' for j in J)} N s measured)")
    if by_direction:
        if record_dir is not None:
            raise UserError("--record is for the rules' trial (each trial's walk one file), not --by-direction")
        _challenge_by_direction(sim, drive, directions, step, as_json)
        return
    if rules == "2025":
        _challenge_2025(sim, drive, seed, step, third, as_json, record_dir)
        return
    if not as_json:
        click.echo(f"push-recovery challenge: {drive.describe()} on {sim.robot.name} / {sim.surface.name}, rope {rope:g} m")
    report = run_challenge(sim, drive, seed=seed, step=step, progress=shown, record=record_dir)
    if _challenge_said(sim, drive, report, record_dir, as_json):
        return
    if report["best_distance_m"] is None:
        click.echo("no trial fully successful (not even the first)")
    else:
        click.echo(f"best D {report['best_distance_m']:.2f} m: H {report['drop_m'] * 1000:.0f} mm, momentum "
                   f"{report['momentum_Ns']:.2f} N s at impact, rank {report['rank']:.3f} "
                   f"(robot {report['robot_mass_kg']:.2f} kg, CoM {report['com_height_m']:.3f} m)")


@challenge.command(name="bound")
@robot_option()
@surface_option("carpet4")
@click.option("--bottle", type=click.Choice(["3", "5", "10"]), default="3", show_default=True,
              help="The bottle's mass [kg] (2025 rules).")
@click.option("--rope", default=1.5, show_default=True, type=Span(1.5, 2.0), help="Rope length L [m].")
@click.option("--steps", default=3, show_default=True, type=click.IntRange(1, 4),
              help="Steps the model may take to absorb a push.")
@JSON_OPTION
def challenge_bound(robot_name: str, surface_name: str, bottle: str, rope: float, steps: int, as_json: bool) -> None:
    """The physical bound for this robot: the largest push from behind and from the front that any
    step sequence within its limits absorbs, and the largest sustained forward speed.

    A trajectory optimisation (CasADi) of the linear inverted pendulum that knows the push in
    advance: step places and timings free, the ZMP anywhere on the sole (and within the ankle's
    torque), steps within the reach, each swing no shorter than the hip and knee servos' torque and
    speed allow. An upper bound within what it models; what it leaves out is said
    (tuner/challenge/bound.py)."""
    import json

    from ..robots import load_robot
    from ..challenge.bound import robot_bound
    from ..sim.surfaces import load_surface
    out = robot_bound(load_robot(robot_name), load_surface(surface_name), float(bottle), rope, steps)
    if as_json:
        click.echo(json.dumps(out, indent=2, allow_nan=False))
        return
    m, m_b = out["model"], out["bottle_kg"]
    click.echo(f"bound for {out['robot']} on {out['surface']} (an upper bound of the LIPM within the servos' limits, "
               f"{steps} step(s) at most; {m['mass_kg']:.2f} kg, z_c {m['z_c_m']:.3f} m, ZMP {m['zmp_back_m'] * 1000:.0f} mm "
               f"back / {m['zmp_front_m'] * 1000:.0f} mm ahead, reach {m['reach_m'] * 1000:.0f} mm, lift "
               f"{m['lift_m'] * 1000:.0f} mm)")
    click.echo(f"  from the surface: {out['surface_terms']}")
    for side, label in (("from_behind", "from behind"), ("from_the_front", "from the front")):
        r = out[side]
        where = (f"D {r['distance_m']:.2f} m" + ("" if r["within_rules"] else f" (beyond the rules' 0.75 L = "
                                                                               f"{0.75 * rope:.2f} m)")
                 if r["distance_m"] is not None else "no release reaches it")
        click.echo(f"  a push {label}: Delta v {r['delta_v_mps']:.2f} m/s, a {m_b:g} kg bottle's "
                   f"{r['momentum_Ns']:.2f} N s, {where}" + (f", M {r['M']:.3f}" if r["M"] is not None else "")
                   + "; steps " + ", ".join(f"{p['step_m'] * 1000:.0f} mm in {p['swing_s']:.3f} s"
                                               for p in r["plan"]))
    sp = out["speed"]
    click.echo(f"  forward speed: {sp['speed_mps']:.2f} m/s (steps of {sp['step_m'] * 1000:.0f} mm every "
               f"{sp['period_s']:.3f} s), Froude number {sp['froude']:.2f}")
    click.echo("  left out (so an upper bound only within it): " + "; ".join(out["leaves_out"]))


def _challenge_said(sim, drive, report: dict, record_dir: Path | None, as_json: bool) -> bool:
    """Say where a challenge's trials were recorded; with ``as_json`` print the report (True: done)."""
    import json
    if record_dir is not None:
        click.echo(f"recorded {len(report['trials'])} trial(s) into {record_dir}", err=True)
    if as_json:
        click.echo(json.dumps({"robot": sim.robot.name, "surface": sim.surface.name, "params": drive.source,
                               "drive": drive.describe(), **report}, indent=2, allow_nan=False))
    return as_json


def _challenge_2025(sim, drive, seed: int, step: float, third: str, as_json: bool, record_dir: Path | None) -> None:
    """``challenge push`` by the 2025 rules (``challenge.challenge_2025``)."""
    import math

    from ..challenge.rules import challenge_2025

    def shown(trial: dict) -> None:
        if as_json:
            return
        # a push from the front: the bottle moving backward against the heading (cos < 0)
        cells = ", ".join(f"{'front' if math.cos(math.radians(p['direction_deg'])) < 0 else 'back'} "
                          f"{'-' if p['measured_Ns'] is None else format(p['measured_Ns'], '.2f')} N s "
                          f"{'absorbed' if p['absorbed'] else 'not absorbed'}" for p in trial["pushes"])
        verdict = "fully successful" if trial["success"] else "partially successful" if trial["partial"] else \
            f"failed ({trial['reason']})"
        click.echo(f"  D {trial['distance_m']:.2f} m, third from the {trial['third']}: {verdict} ({cells})")
    if not as_json:
        click.echo(f"push-recovery challenge (2025 rules): {drive.describe()} on {sim.robot.name} / {sim.surface.name}, "
                   f"{sim.bottle.mass:g} kg bottle, rope {sim.rope:g} m, D up to {0.75 * sim.rope:.3g} m")
    report = challenge_2025(sim, drive, seed=seed, step=step, third=third, progress=shown, record=record_dir)
    if _challenge_said(sim, drive, report, record_dir, as_json):
        return
    for kind in ("full", "partial"):
        f = report[kind]
        if f["distance_m"] is None:
            click.echo(f"{'fully' if kind == 'full' else 'partially'} successful: no D (not even the first)")
        else:
            click.echo(f"{'fully' if kind == 'full' else 'partially'} successful up to D {f['distance_m']:.2f} m: H "
                       f"{f['drop_m'] * 1000:.0f} mm, {f['momentum_Ns']:.2f} N s at impact, M {f['M']:.3f}")
    click.echo(f"  (M = sqrt(H) / h_c * m_B / m_R * h_i / h_c: h_c = h_i = {report['com_height_m']:.3f} m, m_B "
               f"{report['bottle_kg']:g} kg, m_R {report['robot_mass_kg']:.2f} kg)")


def _challenge_by_direction(sim, drive, directions: str, step: float, as_json: bool) -> None:
    """``challenge push --by-direction``: single pushes per direction (``challenge.push_by_direction``)."""
    import json

    from ..challenge.rules import push_by_direction

    try:
        dirs = tuple(float(v) for v in directions.split(",") if v.strip())
    except ValueError:
        raise UserError(f"--directions {directions!r}: expected comma-separated angles in degrees, e.g. 90,270") from None
    if not dirs or not all(-360.0 <= d <= 360.0 for d in dirs):
        raise UserError(f"--directions {directions!r}: give one or more angles in [-360, 360] deg")
    seen: dict[float, float] = {}
    for d in dirs:
        key = round(d % 360.0, 9) % 360.0
        if key in seen:
            same = seen[key]
            raise UserError(f"--directions {directions!r}: {d:g} deg is the direction of {same:g} deg, given "
                            "already (each direction is walked once)")
        seen[key] = d
    step = step if click.get_current_context().get_parameter_source("step").name != "DEFAULT" else 0.1

    def shown(row: dict) -> None:
        if not as_json:
            f = row["first_failure"]
            best = "none" if row["best_distance_m"] is None else \
                f"{row['best_distance_m']:.2f} m ({row['momentum_Ns']:.2f} N s)"
            click.echo(f"  {row['direction_deg']:5.0f} deg: best D {best}" +
                       (f"; fails at {f['distance_m']:.2f} m pushed at {f['push_s']:.1f} s: {f['reason']}" if f else ""))
    if not as_json:
        click.echo(f"single pushes by direction (not the rules' trial): {drive.describe()} on {sim.robot.name} / "
                   f"{sim.surface.name}, rope {sim.rope:g} m")
    rows = push_by_direction(sim, drive, directions=dirs, step=step, progress=shown)
    if as_json:
        click.echo(json.dumps({"robot": sim.robot.name, "surface": sim.surface.name, "params": drive.source,
                               "drive": drive.describe(), "rope_m": sim.rope, "by_direction": rows},
                              indent=2, allow_nan=False))
        return
    worst = min(rows, key=lambda r: r["best_distance_m"] or 0.0)
    click.echo(f"worst direction {worst['direction_deg']:.0f} deg: best D "
               + ("none" if worst["best_distance_m"] is None else f"{worst['best_distance_m']:.2f} m"))

