"""The turf models side by side: what a walk costs on each, the toe-first landing, the full-lift
EROS tables on the first pedestal, and the turf test methods.

    python benchmarks/bench_turf.py [--repeats 5] [--surfaces rigid,grass50,examples/surfaces/grass50-blades.yaml,...]
                                    [--parts table,foot,variants,jam,distance]

Cost: the same TLIPFM walk (tkux-table2, 10 s) on each surface, the surfaces interleaved in every
repeat (this machine is noisy), the minimum of the repeats, as a ratio to the rigid floor's.
Landing: ``Simulator.landing_test`` (3 deg pitched, 0.1 m/s forward), max and final torso pitch
beside carpet4's. Tables: the EROS experiment's Tables 7 and 8 on the surface as pedestal 1
(stable cells of 10). Turf tests: ``gait-tuner surfaces --test``'s figures.

``foot``: the drop test's force reduction and deformation with a 0.1, 1 and 3 kg test foot (the
apparatus' foot mass is not in our sources: how much the figures hang on it). ``variants``: the
blade layer's example file with one number changed at a time (by a fifth or more), its landing
and Tables 7 and 8 on pedestal 1: how much its figures hang on its numbers. ``jam``: the jam
example (``grass50-blades-jam.yaml``) with its jam speed and pressure changed: the landing speeds
of the EROS walk's sole points with and without the optimisation on it (each point's mean speed over
the tick it entered the blades in, after the first 1.2 s), the toe-first landing at 0.7 m/s, and
Tables 7 and 8 and the pitch vibration on pedestal 1: the window of jam speeds that splits the
tables as the paper's.

``distance`` (not in the default run): why walks cover more than their plan. Three straight table
walks (the TLIPFM paper's Table 2, EROS x16 with its optimisation, ``kidsize-omni-carpet4``'s own
walk) on each surface: the torso's distance as a share of the plan's pelvis, split by
``metrics.distance_budget`` into loaded soles sliding, unloaded soles skidding on the ground, feet
carried through the air, and the torso's sway against the feet; and at each touch-down (a sole's
load rising past 15 % of the weight, after the first steps) the step from the stance foot, real
against planned, and how far the CoM is ahead of its planned place over the stance foot.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import gaits  # noqa: E402
from tuner.report.experiments import eros_matrix, stability_percent  # noqa: E402
from tuner.robots import load_robot  # noqa: E402
from tuner.sim.rollout import Simulator  # noqa: E402
from tuner.sim.surfaces import load_surface  # noqa: E402
from tuner.sim.turf_tests import DropTest, drop_test, rotation_test, sole_roll_stiffness, sole_sink  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ["rigid", "carpet4", "grass50", str(ROOT / "examples/surfaces/grass50-blades.yaml"),
           str(ROOT / "examples/surfaces/grass50-blades-creep.yaml"),
           str(ROOT / "examples/surfaces/grass50-blades-jam.yaml"),
           str(ROOT / "examples/surfaces/grass50-blades-slide.yaml")]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--surfaces", default=",".join(DEFAULT))
    ap.add_argument("--parts", default="table,foot,variants,jam")
    a = ap.parse_args()
    parts = set(a.parts.split(","))
    if not parts <= {"table", "foot", "variants", "jam", "distance"}:
        ap.error(f"--parts {a.parts!r}: the parts are table, foot, variants, jam, distance")
    robot = load_robot("kidsize")
    surfaces = [load_surface(s) for s in a.surfaces.split(",")]
    if "table" in parts:
        table(robot, surfaces, a.repeats)
    if "foot" in parts:
        print("\ndrop test with the test foot's mass: force reduction % / vertical deformation mm")
        for s in surfaces:
            cells = [drop_test(s, DropTest(foot_mass=fm)) for fm in (0.1, 1.0, 3.0)]
            print(f"  {s.name:22s}" + "   ".join(f"{fm:g} kg {c.force_reduction_pct:5.1f} / {c.vertical_deformation_mm:5.2f}"
                                              for fm, c in zip((0.1, 1.0, 3.0), cells)))
    if "variants" in parts:
        variants(robot)
    if "jam" in parts:
        jam(robot)
    if "distance" in parts:
        distance(surfaces)


def distance(surfaces) -> None:
    """The ``distance`` part (module docstring)."""
    from tuner.params_io import resolve_params
    from tuner.sim.cache import simulator
    from tuner.sim.metrics import distance_budget
    print("\nwhere the distance comes from, % of the plan: covered = slide + skid + air + sway; at the touch-downs "
          "(medians): step real / planned [mm], CoM ahead of its plan over the stance foot [mm], torso pitch [deg]")
    sets = (("paper:tkux-table2", gaits.load_baseline("tkux-table2")),
            ("paper:eros-x16-with", gaits.load_baseline("eros-x16-with")),
            ("kidsize-omni-carpet4", resolve_params("kidsize-omni-carpet4", None)))
    for label, params in sets:
        drive = gaits.Drive.of(params, source=label)
        for s in surfaces:
            sim = simulator("kidsize", s)
            traj = drive.table(sim.robot, sim.control_period)
            plan = float(traj.p_world_pelvis[-1, 0] - traj.p_world_pelvis[0, 0])
            tr = sim.run(drive.controller(sim.robot, sim.control_period, table=traj))
            b = distance_budget(tr)
            share = {k: 100 * b[k] / plan for k in ("torso_m", "slide_m", "skid_m", "air_m", "sway_m")}
            td = touchdowns(tr, traj)
            print(f"  {label:22s} {s.name:22s} {'up  ' if tr.survived else 'FELL'} covered {share['torso_m']:4.0f}% = "
                  f"slide {share['slide_m']:+3.0f} skid {share['skid_m']:+3.0f} air {share['air_m']:4.0f} "
                  f"sway {share['sway_m']:+3.0f}" + (f";  steps {td[0]:.1f} / {td[1]:.1f} mm, CoM ahead "
                                                     f"{td[2]:+.1f} mm, pitch {td[3]:+.1f} deg ({td[4]} touch-downs)"
                                                     if td else ""), flush=True)


def touchdowns(tr, traj):
    """Medians over the touch-downs after the first 0.3 s of walking: (real step, planned step [mm],
    CoM ahead of plan over the stance foot [mm], torso pitch [deg], count), or None."""
    from tuner.sim.metrics import loaded_soles
    load_l, load_r = loaded_soles(tr)
    feet = {1: (tr.p_sole_l, load_l, traj.p_world_foot_l), -1: (tr.p_sole_r, load_r, traj.p_world_foot_r)}
    rows = []
    for side, (p, loaded, planned) in feet.items():
        q, _, q_planned = feet[-side]
        for k in np.flatnonzero(~loaded[:-1] & loaded[1:]) + 1:
            if k >= len(planned) or tr.t[k] < tr.walk_start + 0.3:
                continue
            step, step_plan = p[k, 0] - q[k, 0], planned[k, 0] - q_planned[k, 0]
            if abs(step_plan) > 0.005:
                ahead = (tr.p_com[k, 0] - q[k, 0]) - (traj.p_world_com[k, 0] - q_planned[k, 0])
                rows.append((1000 * step, 1000 * step_plan, 1000 * ahead, math.degrees(tr.pitch[k])))
    if not rows:
        return None
    return (*np.median(np.array(rows), axis=0), len(rows))


VARIANTS = ({}, {"blade_modulus": 1.8e7}, {"blade_modulus": 2.6e7}, {"blade_tip_depth": 0.01},
            {"blade_tip_depth": 0.02}, {"blade_tip_modulus": 5e4}, {"drag": 100.0}, {"blade_shear": 3e6},
            {"friction": 1.0}, {"blade_damping": 2e5})


def variants(robot) -> None:
    base = load_surface(str(ROOT / "examples/surfaces/grass50-blades.yaml"))
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, robot.leg).q_ref[0]
    print("\ngrass50-blades, one number changed: landing max / final deg, Table 7 / 8 % on pedestal 1")
    for change in VARIANTS:
        s = base.replace(**change)
        tr = Simulator(robot, s).landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
        t7 = stability_percent(eros_matrix(robot, {1: s}, optimised=False))[1]
        t8 = stability_percent(eros_matrix(robot, {1: s}, optimised=True))[1]
        label = ", ".join(f"{k} {v:g}" for k, v in change.items()) or "as shipped"
        print(f"  {label:26s} {np.degrees(tr.pitch.max()):5.2f} / {np.degrees(tr.pitch[-1]):5.2f}   {t7:3.0f} / {t8:3.0f}",
              flush=True)


def landing_speeds(robot, surface, drives: dict[str, gaits.Drive]) -> dict[str, tuple[float, float]]:
    """Per drive: (median, fastest) [m/s] of its sole points' downward speeds as they enter the
    blades of ``surface`` (``BladeLayer.entry_speed``: over the tick they entered in; the
    surface's jam is set beyond any of them, so none jams), after the first 1.2 s (standing)."""
    from tuner.sim.ground import blades
    sim = Simulator(robot, surface.replace(blade_jam_speed=10.0))
    seen: list[float] = []
    update = blades.BladeLayer.update

    def spy(layer, model, data, p, h, mu):
        entered = (p[:, 2] < h) & ~layer.inside
        load = update(layer, model, data, p, h, mu)
        if data.time > 1.2 and entered.any():
            seen.extend(layer.entry_speed[entered].tolist())
        return load
    out = {}
    blades.BladeLayer.update = spy
    try:
        for label, drive in drives.items():
            seen.clear()
            sim.run(drive.controller(robot, sim.control_period), **{**drive.run_options(), "duration": 6.0})
            out[label] = (float(np.median(seen)), float(np.max(seen)))
    finally:
        blades.BladeLayer.update = update
    return out


JAM_SETS = ("kidsize-omni-grass50", "kidsize-robust-grass50")


def jam(robot) -> None:
    from tuner.params_io import resolve_params
    from tuner.report.experiments import eros_params
    from tuner.sim.robustness import evaluate
    path = str(ROOT / "examples/surfaces/grass50-blades-jam.yaml")
    base = load_surface(path)
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, robot.leg).q_ref[0]
    drives = {f"EROS 8 mm {'with' if o else 'without'} the optimisation":
              gaits.Drive(eros_params(8, o), source="bench") for o in (False, True)}
    drives.update({name: gaits.Drive.of(resolve_params(name, None), source="bench") for name in JAM_SETS})
    speeds = landing_speeds(robot, base, drives)
    print("\nthe sole points' speed entering the blades of grass50-blades (median / fastest m/s), and for the "
          "shipped grass50 table sets the survival of 10 randomised walks on grass50-blades / its jam file:")
    for label, (med, top) in speeds.items():
        extra = ""
        if label in JAM_SETS:
            surv = [float(np.mean([r["survived"] for r in evaluate("kidsize", s, drives[label], rollouts=10, seed=2,
                                                                  pushes=(), workers=1).rollouts]))
                    for s in (str(ROOT / "examples/surfaces/grass50-blades.yaml"), path)]
            extra = f"   survival {surv[0]:.0%} / {surv[1]:.0%}"
        print(f"  {label:40s} {med:.2f} / {top:.2f}{extra}", flush=True)
    print("grass50-blades-jam, jam speed m/s / pressure kPa: landing at 0.7 m/s max / final deg, Table 7 / 8 % "
          "on pedestal 1, pitch +- without / with deg")
    for v, p in ((0.5, 13e3), (0.55, 13e3), (0.57, 13e3), (0.6, 13e3), (0.62, 13e3), (0.65, 13e3), (0.7, 13e3),
                 (0.75, 13e3), (0.6, 6.5e3), (0.6, 26e3), (0.6, 130e3)):
        s = base.replace(blade_jam_speed=v, blade_jam_pressure=p)
        tr = Simulator(robot, s).landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1, sink_speed=0.7)
        cells = {o: eros_matrix(robot, {1: s}, optimised=o) for o in (False, True)}
        t7, t8 = (stability_percent(cells[o])[1] for o in (False, True))
        pm = [float(np.median([c.metrics.pitch_pm_deg for c in cells[o]])) for o in (False, True)]
        print(f"  {v:4.2f} / {p / 1e3:5.1f}   {np.degrees(tr.pitch.max()):5.2f} / {np.degrees(tr.pitch[-1]):6.2f}"
              f"   {t7:3.0f} / {t8:3.0f}   {pm[0]:5.1f} / {pm[1]:4.1f}", flush=True)


def table(robot, surfaces, repeats: int) -> None:
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, robot.sim.control_period)
    sims = {s.name: Simulator(robot, s) for s in surfaces}
    best = {n: math.inf for n in sims}
    for _ in range(repeats):
        for n, sim in sims.items():
            t0 = time.perf_counter()
            sim.rollout(traj)
            best[n] = min(best[n], time.perf_counter() - t0)
    rigid = best.get("rigid")
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, robot.leg).q_ref[0]
    print(f"{'surface':22s}{'walk s':>8s}{'x rigid':>8s}{'land max':>9s}{'final':>7s}{'T7 %':>6s}{'T8 %':>6s}"
          f"{'FR %':>7s}{'VD mm':>7s}{'RR N m':>7s}{'sink mm':>8s}{'roll':>7s}")
    for s in surfaces:
        tr = sims[s.name].landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
        t7 = stability_percent(eros_matrix(robot, {1: s}, optimised=False))[1]
        t8 = stability_percent(eros_matrix(robot, {1: s}, optimised=True))[1]
        d, r = drop_test(s), rotation_test(s)
        ratio = best[s.name] / rigid if rigid else float("nan")
        print(f"{s.name:22s}{best[s.name]:8.3f}{ratio:8.2f}{np.degrees(tr.pitch.max()):9.2f}"
              f"{np.degrees(tr.pitch[-1]):7.2f}{t7:6.0f}{t8:6.0f}{d.force_reduction_pct:7.1f}"
              f"{d.vertical_deformation_mm:7.1f}{r.rotational_torque_Nm:7.1f}{sole_sink(s):8.2f}"
              f"{sole_roll_stiffness(s):7.0f}")


if __name__ == "__main__":
    main()
