"""Identification under a real servo (docs/servos.md): the built-in robot hanging in its harness with
its legs driven by BAM's MX-64 in its M6 form (Stribeck, load-dependent and quadratic friction: our
per-step term), recorded playing what ``gait-tuner excite`` writes (a chirp sweep, then large steps
one joint at a time); ``identify servos``' fit (the M1 law in MuJoCo's pieces, over the map's
MX-64 M1) on the sweep alone, and on the sweep plus the steps; each fit predicting a *second*
sweep and a *second* step train (other seeds) as a recording of them would show.

    python benchmarks/identify_real_servo.py [--duration 20] [--workers 2] [--fits sweep,steps,extended]

``--fits``: which fits to run: ``sweep`` (the M1 law on the sweep alone), ``steps`` (on the sweep
and the steps), ``extended`` (on the sweep and the steps, with the extended friction's fields:
``stribeck``, ``stribeck_speed``, ``load_motor``).

Prints, per fit, the RMS [mrad] of measured minus predicted joint angles over every servo joint
on each held-out recording, and what the fit identified.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tuner.robots import load_robot                       # noqa: E402
from tuner.servos import MotorServo, preset               # noqa: E402
from tuner.identify.harness import Harness, excitation, step_train   # noqa: E402
from tuner.identify.servos import DEFAULT_FIT, EXTENDED, JointLog, identify_servos  # noqa: E402

NOISE = 1e-3       # [rad] the encoders' noise in the recordings (and the fit's unit)


def truth_robot():
    m1 = load_robot("kidsize")
    return dataclasses.replace(m1, name="kidsize-m6", servos={
        j: (preset("MX-64", "m6").replace(voltage=s.voltage) if isinstance(s, MotorServo) and s.preset == "MX-64"
            else s) for j, s in m1.servos.items()})


def record(h: Harness, targets: np.ndarray, seed: int) -> np.ndarray:
    s = h.servo_arrays()
    q = h.run(h.compile(s), targets, s)
    return q + np.random.default_rng([seed, 9]).normal(0.0, NOISE, q.shape)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--duration", type=float, default=20.0, help="the sweep's length [s]")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--fits", default="sweep,steps,extended", help="which fits (the module's docstring)")
    a = ap.parse_args()
    fits = {"sweep": (("sweep",), DEFAULT_FIT), "steps": (("sweep", "steps"), DEFAULT_FIT),
            "extended": (("sweep", "steps"), DEFAULT_FIT + tuple(EXTENDED))}
    chosen = [f.strip() for f in a.fits.split(",") if f.strip()]
    if not chosen or any(f not in fits for f in chosen):
        ap.error(f"--fits: some of {', '.join(fits)}")
    truth = Harness(truth_robot())
    model_h = Harness(load_robot("kidsize"))
    logs = {}
    for seed in (0, 1):
        t, sweep = excitation(model_h, duration=a.duration, seed=seed)
        steps = step_train(model_h, sweep[-1], seed=seed)
        for kind, targets in (("sweep", sweep), ("steps", steps)):
            logs[(kind, seed)] = JointLog(f"{kind}-{seed}", model_h.control_period, tuple(model_h.joint_names),
                                          targets, record(truth, targets, 10 * seed + len(kind)))
    for name in chosen:
        train, fields = fits[name]
        t0 = time.monotonic()
        fit = identify_servos(model_h, [logs[(k, 0)] for k in train], noise=NOISE, threads=a.workers, fit=fields)
        s = fit.servos
        model = model_h.compile(s)
        line = []
        for kind in ("sweep", "steps"):
            log = logs[(kind, 1)]
            q = model_h.run(model, log.targets, s, q0=log.measured[0])
            rms = float(np.sqrt(np.mean((log.measured[1:] - q[1:]) ** 2)))
            line.append(f"second {kind} {1000 * rms:.2f} mrad RMS (max {1000 * np.max(np.abs(log.measured[1:] - q[1:])):.0f})")
        if name == "extended":
            m6 = preset("MX-64", "m6")
            print(f"  the truth (BAM's MX-64 M6): frictionloss {m6.frictionloss:.3g} N m, stribeck {m6.stribeck:.3g} N m "
                  f"at {m6.stribeck_speed:.3g} rad/s, load_motor {m6.load_motor:.3g} (+ {m6.load_motor_stribeck:.3g} near "
                  f"rest, quadratic terms)")
            for g in ("hips", "knees", "ankles"):
                i = model_h.joint_names.index({"hips": "l_hip_pitch", "knees": "l_knee", "ankles": "l_ankle_pitch"}[g])
                print(f"  {g}: frictionloss {s.frictionloss[i]:.3g} N m, stribeck {fit.values[g + '.stribeck']:.3g} N m "
                      f"at {fit.values[g + '.stribeck_speed']:.3g} rad/s, load_motor {fit.values[g + '.load_motor']:.3g}")
        ok = [k for k in fit.fitted if fit.identifiable[k]]
        print(f"{name}: fitted on {' + '.join(train)} ({time.monotonic() - t0:.0f} s, {fit.rollouts} rollouts): "
              + "; ".join(line))
        print(f"  identified: {', '.join(ok)}")
        if fit.on_bound:
            print(f"  on its bound: {', '.join(fit.on_bound)}")
        if fit.at_least:
            print(f"  at least: {', '.join(fit.at_least)}")


if __name__ == "__main__":
    main()
