"""The online walk engine beside the best open-loop set, measured in one run (issue 21's benchmark).

Usage: ``python benchmarks/bench_engine.py [--walks 100] [--workers 2] [--quick] [--also SURFACE=PARAMS]``

For carpet4 and grass50, each figure for the engine set (``kidsize-engine-<surface>``), the best
open-loop set in these walks (``SETS``: the rigid floor's fast table on carpet4, the robust fast
table on grass50; tables planned per step) and the surface's own fast table
(``kidsize-omni-<surface>``):

* survival of ``--walks`` randomised walks (default randomisation, evaluation seeds) of the match
  stream ``examples/streams/match-<surface>.csv`` (segments up to 0.3 m/s forward, 0.2 back, 0.1
  sideways, 1.0 rad/s on carpet4; up to 0.2 m/s forward on grass50);
* survival of randomised sustained walks (0.3 m/s on carpet4, 0.2 on grass50, 8 s);
* velocity tracking in the steady segments of the match stream: per moving segment, the measured
  velocity over its steps from the second on, as a share of the command (median over the walks
  that stayed up, and per kind of segment: forward, backward, sideways, turning), and the RMS
  errors; and the same over the steady steps only (those that start once the engine set's
  rate-limited command, ``accel_*``, has reached the segment's: a 0.45 m/s change at 0.5 m/s^2
  takes 0.9 s of a 2 s segment), for the table too (the same steps, side by side);
* the push-recovery challenge (``gait-tuner challenge push``) on carpet4 and grass30, push seeds
  0, 1, 2 (``--challenge-seeds``): the largest fully successful D and the bottle's momentum at
  impact per seed and the median momentum, the engine sets (the match set ``kidsize-engine-carpet4``
  and the challenge's own, ``PUSH_SET``) beside the best open-loop set in the challenge
  (``CHALLENGE_TABLE``, the slow robust walk with its stabiliser) and the fast carpet4 table, and
  each engine set's median as a multiple of the best open-loop set's;
* every shipped set without an engine in the challenge (``--parts tables``, not in the default
  run, ~40 min with nine seeds): which open-loop set is the best, the one to compare with;
* the engine's cost per tick in Python (median, 99th percentile) beside one tick of physics;
* single pushes by direction (``--parts directions``, not in the default run): the largest D each
  of eight directions survives at two points of a step, engine vs open-loop (which direction binds
  the rules' trial, whose three directions are random);
* which limit binds (``--parts limits``): the engine set's first failing challenge trial on carpet4
  and grass30 walked again, its re-plans counted by the limit their step sat on (reach, the sole's
  edge for the ZMP, a shorter swing, the swing foot's speed) and, per push, the servos at their
  torque or speed limit in the second after it, beside the last successful trial;
* what a forward push hands the robot (``--parts transfer``, not in the default run, ~10 s): the
  CoM's velocity and the capture point's jump per D, the share of the bottle's momentum the CoM
  takes, beside the LIPM's N-step capture bound for the engine set's reach, sole and step, and
  what issue 21's 2x target asks of it.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import gaits  # noqa: E402
from gaits import list_baselines  # noqa: E402
from tuner.params_io import list_results, resolve_params  # noqa: E402
from tuner.challenge.rules import challenge  # noqa: E402
from tuner.sim.metrics import AXES, steady_tracking, tracking_by_axis, tracking_shares  # noqa: E402
from tuner.sim.robustness import evaluate  # noqa: E402
from tuner.sim.rollout import Simulator  # noqa: E402
from tuner.sim.surfaces import load_surface  # noqa: E402
from tuner.streams import load_stream  # noqa: E402
from tuner.robots import load_robot  # noqa: E402

# Per surface: the engine set, the best open-loop set in these walks, the sustained walk's speed
# [m/s], and the fast table named for the surface. The best is not the surface's own: over 50
# walks of evaluation seed 1 (scratch, every shipped fast table; the slow robust ones cannot plan the
# streams' speeds), the rigid floor's table survives carpet4's match stream 38% (its own 22%) and
# the robust table grass50's 34% (its own 20%).
SETS = {"carpet4": ("kidsize-engine-carpet4", "kidsize-omni-rigid", 0.3, "kidsize-omni-carpet4"),
        "grass50": ("kidsize-engine-grass50", "kidsize-omni-robust", 0.2, "kidsize-omni-grass50")}
# The best open-loop set in the push challenge, on carpet4 and on grass30 alike: the slow (0.51 s)
# robust walk with its IMU stabiliser takes the largest median push of every shipped set without an
# engine over push seeds 0-8 (``--parts tables`` surveys them all: 1.70 N s on both surfaces, the
# fast carpet4 table 1.16 / 1.43); the match walks above compare with the fast tables instead, the
# only ones that walk the match stream's speeds.
CHALLENGE_TABLE = "kidsize-robust-fb-grass50"
CHALLENGE_TABLE_NS = 1.70    # [N s] its median on both surfaces over push seeds 0-8 and 9-17 (--parts tables)
# The engine set tuned on the challenge alone (studies/kidsize-engine-push.yaml: stepping in place,
# push seeds 0-2 on carpet4 and grass30), beside the match set in the challenge.
PUSH_SET = "kidsize-engine-push"


def survival(rows) -> float:
    """Completed walks only: a fall, a diverged or an impossible simulation is no survival."""
    return float(np.mean([r["survived"] for r in rows])) if rows else float("nan")


def walks(name: str, surface: str, drive: gaits.Drive, n: int, workers: int, seed: int):
    return evaluate("kidsize", surface, drive, rollouts=n, seed=seed, pushes=(), workers=workers).rollouts


def cost_per_tick(engine_set: str, surface: str) -> tuple[float, float, float]:
    """(engine median, engine p99, physics median) [ms] over a 20 s match walk, timed per tick."""
    from tuner.sim.cache import simulator
    robot = load_robot("kidsize")
    sim = simulator(robot, surface)
    drive = gaits.Drive.of(resolve_params(engine_set, None))
    stream = load_stream(ROOT / "examples" / "streams" / f"match-{surface}.csv")
    ctl = dataclasses.replace(drive, stream=stream).controller(robot, sim.control_period)
    inner = getattr(ctl, "inner", ctl)
    times = []
    orig = inner.step

    def timed(m, c=None):
        t0 = time.perf_counter()
        out = orig(m, c)
        times.append(time.perf_counter() - t0)
        return out
    inner.step = timed
    t0 = time.perf_counter()
    trace = sim.run(ctl, commands=stream, duration=stream.duration)
    total = time.perf_counter() - t0
    t = np.array(times) * 1000
    physics = (total - t.sum() / 1000) / len(trace.t) * 1000      # the loop's rest: physics, sensors, plant
    return float(np.median(t)), float(np.percentile(t, 99)), physics


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--walks", type=int, default=100)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--quick", action="store_true", help="20 walks, no challenge on grass30")
    ap.add_argument("--yaw-feedback", type=float, default=None, metavar="GAIN",
                    help="walk the engine sets with this gyro turn feedback (engine yaw_feedback [1/s]; "
                         "default: the sets' own: 6 in kidsize-engine-carpet4, 0 in kidsize-engine-grass50)")
    ap.add_argument("--also", action="append", default=[], metavar="SURFACE=PARAMS",
                    help="walk this set too, beside the shipped two, on that surface's walks (carpet4 or "
                         "grass50; a carpet4 set also takes the challenge); repeatable")
    ap.add_argument("--surfaces", default="carpet4,grass50", help="the walks' surfaces, comma-separated")
    ap.add_argument("--challenge-seeds", default="0,1,2", metavar="K,K,...",
                    help="the challenge's push-direction seeds (one seed's three pushes per D say little)")
    ap.add_argument("--parts", default="walks,challenge,cost,limits",
                    help="which parts to run, comma-separated (walks, challenge, cost, limits, directions, "
                         "tables, transfer; directions, tables and transfer are not in the default: ~10 and ~40 min); the tick "
                         "cost is best measured "
                         "alone on an idle machine: --parts cost")
    args = ap.parse_args()
    parts = set(args.parts.split(","))
    if not parts <= {"walks", "challenge", "cost", "limits", "directions", "tables", "transfer"}:
        ap.error(f"--parts: {args.parts!r}: the parts are walks, challenge, cost, limits, directions, tables, "
                 f"transfer")
    n = 20 if args.quick else args.walks
    also: dict[str, list[str]] = {k: [] for k in SETS}
    for item in args.also:
        surface, _, spec = item.partition("=")
        if surface not in SETS or not spec:
            ap.error(f"--also: {item!r}: expected SURFACE=PARAMS with SURFACE one of {', '.join(SETS)}")
        also[surface].append(spec)
    if not set(args.surfaces.split(",")) <= set(SETS):
        ap.error(f"--surfaces: {args.surfaces!r}: the surfaces are {', '.join(SETS)}")
    chosen = {k: v for k, v in SETS.items() if k in args.surfaces.split(",")}
    for surface, (engine_set, table_set, top, own) in (chosen.items() if "walks" in parts else ()):
        stream = load_stream(ROOT / "examples" / "streams" / f"match-{surface}.csv")
        sustained = gaits.CommandStream([0.0, 8.0], [[top, 0, 0], [0, 0, 0]], tail=2.0)
        print(f"\n{surface}: {n} randomised walks each (evaluation seed {args.seed})")
        e0 = resolve_params(engine_set, None).engine
        print(f"{'set':28s} {'match %':>8s} {f'{top:g} m/s %':>9s} {'tracking':>10s} {'IQR':>6s} "
              f"{'vx rmse':>8s} {'wz rmse':>8s}")
        for label in (engine_set, table_set, own, *also[surface]):
            gf = resolve_params(label, None)
            if gf.engine is not None and args.yaw_feedback is not None:
                gf = dataclasses.replace(gf, engine=gf.engine.replace(yaw_feedback=args.yaw_feedback))
            drive = gaits.Drive.of(gf, source=label, stream=stream)
            t0 = time.perf_counter()
            match = walks(label, surface, drive, n, args.workers, args.seed)
            steady = walks(label, surface, dataclasses.replace(drive, stream=sustained), n, args.workers, args.seed)
            share, iqr = tracking_shares(match)
            rmse = {k: [r["tracking"][k] for r in match if r["survived"] and r["tracking"][k] is not None]
                    for k in ("vx_rmse_mps", "wz_rmse_radps")}
            vx, wz = (np.median(v) if v else float("nan") for v in rmse.values())
            print(f"{label:28s} {survival(match):8.0%} {survival(steady):9.0%} {share:10.0%} {iqr:6.0%} "
                  f"{vx:8.3f} {wz:8.3f}   ({time.perf_counter() - t0:.0f} s; "
                  f"{'online engine' if gf.engine is not None else 'table planned per step'})", flush=True)
            by = tracking_by_axis(match)
            print(f"{'':28s} tracking by segment: " + ", ".join(f"{k} {v:.0%}" for k, v in by.items()), flush=True)
            st = steady_tracking(match, stream, e0)     # the engine set's settling, for the table too
            print(f"{'':28s} steady steps only: " + ("none measured" if st is None else
                  f"{st['median']:.0%} (IQR {st['iqr']:.0%}); " + ", ".join(
                      f"{k} {'-' if st[k] is None else format(st[k], '.0%')}" for k in AXES)), flush=True)
    seeds = [int(x) for x in args.challenge_seeds.split(",")]
    if "challenge" in parts:
        print(f"\npush-recovery challenge (rope 1.5 m, push seeds {args.challenge_seeds}): best D [m] / momentum "
              f"at impact [N s] per seed, and the median momentum")
    for surface in (("carpet4",) + (() if args.quick else ("grass30",))) if "challenge" in parts else ():
        sim = challenge_sim(surface)
        medians = {}
        engines = ("kidsize-engine-carpet4", PUSH_SET)
        for label in (*engines, CHALLENGE_TABLE, "kidsize-omni-carpet4", *also["carpet4"]):
            medians[label] = challenge_row(sim, surface, label, seeds)
        for label in (*engines, *also["carpet4"]):
            ratio = medians[label] / medians[CHALLENGE_TABLE] if medians[CHALLENGE_TABLE] else math.inf
            print(f"  {surface:8s} {label}'s median / the best open-loop set's ({CHALLENGE_TABLE}): "
                  f"{ratio:.2f}x", flush=True)
    if "tables" in parts:
        print(f"\nthe push challenge for every shipped set without an engine (push seeds {args.challenge_seeds}): "
              "which open-loop set is the best")
    for surface in ("carpet4", "grass30") if "tables" in parts else ():
        sim = challenge_sim(surface)
        sets = {x: resolve_params(x, None) for x in list_results() + list_baselines()}
        medians = {label: challenge_row(sim, surface, label, seeds, gf) for label, gf in sets.items()
                   if gf.engine is None}
        best = max(medians, key=medians.get)
        print(f"  {surface:8s} best: {best} ({medians[best]:.2f} N s)", flush=True)
    if "cost" in parts:
        print("\nthe engine's cost per tick, in Python on this machine (a 20 s match walk)")
    for surface, (engine_set, *_) in (SETS.items() if "cost" in parts else ()):
        med, p99, phys = cost_per_tick(engine_set, surface)
        print(f"  {engine_set:28s} median {med:.3f} ms, p99 {p99:.3f} ms; the rest of the tick (physics, "
              f"sensors, plant) {phys:.3f} ms")
    if "directions" in parts:
        print("\nsingle pushes by direction (ours, not the rules' trial; 0 deg: the bottle moving the way the robot "
              "faces, 90: to its left), each at 3.0 and 3.1 s (two points of a step); the largest D [m] both "
              "survived / momentum [N s], D raised by 0.1 m from 0.4")
        for surface in ("carpet4",) + (() if args.quick else ("grass30",)):
            directions(surface, ("kidsize-engine-carpet4", "kidsize-omni-carpet4", *also["carpet4"]))
    if "transfer" in parts:
        print("\nwhat a forward push hands the robot, and the LIPM's capture bound (single pushes at 3.0 s)")
        for surface in ("carpet4", "grass30"):
            transfer(surface)
    if "limits" in parts:
        print("\nwhich limit binds: kidsize-engine-carpet4's challenge trials walked again (rope 1.5 m, seed 0)")
        for surface in ("carpet4", "grass30"):
            limits(surface)


def challenge_sim(surface: str) -> Simulator:
    """The challenge's scene: the kid-size robot on ``surface`` with the 1.5 m pendulum."""
    return Simulator(load_robot("kidsize"), load_surface(surface), pendulum=1.5)


def challenge_row(sim, surface: str, label: str, seeds, gf: gaits.GaitFile | None = None) -> float:
    """Print one set's challenge per push seed (best D / momentum) and return its median momentum
    (``gf``: the set already read, else read from ``label``)."""
    drive = gaits.Drive.of(gf or resolve_params(label, None), source=label)
    runs = [challenge(sim, drive, seed=k) for k in seeds]
    cells = [f"{r['best_distance_m'] or 0:.2f} / {r['momentum_Ns'] or 0:.2f}" for r in runs]
    med = float(np.median([r["momentum_Ns"] or 0.0 for r in runs]))
    print(f"  {surface:8s} {label:28s} " + ",  ".join(cells) + f"   median {med:.2f} N s", flush=True)
    return med


def directions(surface: str, labels) -> None:
    """Print, per set, the largest single push per direction (``challenge.push_by_direction``)."""
    from tuner.challenge.rules import push_by_direction
    sim = challenge_sim(surface)
    for label in labels:
        rows = push_by_direction(sim, gaits.Drive.of(resolve_params(label, None), source=label))
        cells = [f"{r['direction_deg']:.0f}: {r['best_distance_m'] or 0:.1f}/{r['momentum_Ns'] or 0:.2f}" for r in rows]
        worst = min(rows, key=lambda r: r["best_distance_m"] or 0.0)
        print(f"  {surface:8s} {label:24s} " + "  ".join(cells) + f"   worst {worst['direction_deg']:.0f} deg",
              flush=True)


def limits(surface: str) -> None:
    """Print, for the engine set's last successful and first failing challenge trial on ``surface``,
    the re-plans per limit and the servos at a limit in the second after each push."""
    from tuner.challenge.rules import PUSH_TIMES_S, push_trial
    from tuner.sim.walk_speed import saturation
    sim = challenge_sim(surface)
    drive = gaits.Drive.of(resolve_params("kidsize-engine-carpet4", None), source="kidsize-engine-carpet4")
    r = challenge(sim, drive)
    failing = r["trials"][-1]["distance_m"] if not r["trials"][-1]["success"] else None
    for D in (r["best_distance_m"], failing):
        if D is None:
            continue
        trial = push_trial(sim, drive, D, 0, keep_trace=True)
        tr = trial["trace"]
        b = tr.meta.get("binding", {})
        n = max(b.get("replans", 0), 1)
        on = ", ".join(f"{k} {b.get(k, 0) / n:.0%}" for k in ("reach", "sole", "timing", "speed"))
        print(f"  {surface:8s} D {D:.2f} m ({'up' if trial['success'] else 'fell at %.1f s' % tr.t_fall}): "
              f"{b.get('replans', 0)} re-plans; on a limit: {on}")
        for t_push in PUSH_TIMES_S:
            if tr.t[-1] < t_push:
                break
            sat = saturation(sim, tr, t_push, min(t_push + 1.0, float(tr.t[-1])))[:3]
            print(f"  {'':8s}   push at {t_push:.0f} s, servos at a limit in the next second: " +
                  "; ".join(f"{x['joint']} torque {x['torque_share']:.0%} speed {x['speed_share']:.0%}" for x in sat))


def capture_bound(r: float, reach: float, T: float, omega: float, n: int | None) -> float:
    """[m] The largest capture-point offset ahead of the stance sole's centre that a linear inverted
    pendulum can still stop in ``n`` steps (``None``: any number), each step taking ``T`` [s] and
    landing at most ``reach`` [m] ahead of the stance foot, the ZMP at most ``r`` [m] ahead of the
    sole's centre (N-step capturability, Koolen et al. 2012, eq. 11's recursion in one dimension):
    d_0 = r, d_N = r + (d_(N-1) + reach - r) e^(-omega T); d_inf = r + reach / (e^(omega T) - 1)."""
    if n is None:
        return r + reach / math.expm1(omega * T)
    d = r
    for _ in range(n):
        d = r + (d + reach - r) * math.exp(-omega * T)
    return d


def transfer(surface: str, label: str = "kidsize-engine-carpet4") -> None:
    """Print what a forward push hands the robot (single pushes at 3.0 s, the bottle moving the way
    the robot faces): the CoM's velocity gained in the 60 ms after the impact (less its mean over
    the 50 ms before), its momentum as a share of the bottle's, and the capture point's jump; then
    the LIPM's N-step capture bound for the set's reach, sole and step, and what issue 21's target
    (twice the best open-loop set's momentum) asks of it at the measured share."""
    from tuner.challenge.rules import impact_momentum, push_trial
    sim = challenge_sim(surface)
    gf = resolve_params(label, None)
    drive = gaits.Drive.of(gf, source=label)
    mass = float(sim.model.body_subtreemass[sim._torso])
    omega = math.sqrt(9.81 / gf.params.z_c)        # the point-mass pendulum at the CoM's height (physics,
    # not the engine's TLIPFM constant, whose natural period is longer)
    print(f"  {surface} {label}: robot {mass:.2f} kg, omega {omega:.2f} 1/s")
    shares = []
    for D in (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2):
        r = push_trial(sim, drive, D, 0, keep_trace=True, pushes=[(3.0, 0.0)])
        tr = r["trace"]
        dt = float(tr.t[1] - tr.t[0])
        yaw = float(tr.yaw[int(round(2.95 / dt))]) if tr.yaw is not None else 0.0
        u = np.array([math.cos(yaw), math.sin(yaw)])
        v = (np.diff(tr.p_com[:, :2], axis=0) / dt) @ u
        k = int(round(3.0 / dt))
        dv = float(v[k - 2:k + 6].max() - v[k - 7:k - 2].mean())
        p = impact_momentum(sim.rope, D)
        shares.append(mass * dv / p)
        print(f"    D {D:.1f} m: bottle {p:.2f} N s, CoM +{dv:.3f} m/s ({mass * dv / p:.0%} of the bottle's "
              f"momentum), capture point +{dv / omega * 1000:.0f} mm; {'up' if r['success'] else 'fell'}", flush=True)
    share = float(np.median(shares))
    robot = sim.robot
    limits = gaits.family("tlipfm").step_limits(gf.params, robot)
    sole = robot.foot_size[0] / 2 - gf.engine.zmp_margin
    g = gf.params
    T_short = g.t1 + gf.engine.min_ssp_scale * (g.t2 - g.t1) + (g.period - g.t2)
    target = 2 * CHALLENGE_TABLE_NS
    ask = share * target / mass / omega
    print(f"    LIPM capture bound ahead (ZMP {sole * 1000:.0f} mm ahead of the sole's centre, reach "
          f"{limits.max_forward * 1000:.0f} mm): " + "; ".join(
              f"step {T:.3f} s: " + ", ".join(f"{'inf' if n is None else n} step{'s' if n != 1 else ''} "
                                              f"{capture_bound(sole, limits.max_forward, T, omega, n) * 1000:.0f} mm"
                                              for n in (1, 2, 3, None))
              for T in (g.period, T_short)))
    print(f"    issue 21's 2x ({target:.2f} N s) at the median share {share:.0%}: the capture point +{ask * 1000:.0f} mm",
          flush=True)


if __name__ == "__main__":
    main()
