"""Reference trajectories of Rhoban's BAM (better-actuator-models 1.0.2) on its pendulum bench, and
its servos' torque-speed lines: the numbers our servo law (tuner/servos/) is tested against
(tests/test_servo_law.py). Ours: this script only calls BAM's public API; nothing of BAM is copied.

BAM needs Python 3.12 (pyenv's 3.12.1 is on every machine here). From a checkout of BAM's
repository (github.com/Rhoban/bam at 1b5a1ce, the 1.0.2 release's tree):

    python3.12 -m venv /tmp/bam-venv
    /tmp/bam-venv/bin/pip install numpy colorama mujoco==4.0.1 ./bam-checkout
    /tmp/bam-venv/bin/python tests/data/bam/make_reference.py tests/data/bam/reference.npz

Writes one compressed numpy archive: ``meta`` (JSON text: the benches, the targets, and per model its
parameters and full-duty torque-speed line) and, per model, bench and target, the angle trajectories
``MODEL/BENCH/TARGET/mujoco`` and ``.../reference`` (float32, rad), and ``.../fine``: BAM's MuJoCo
simulator at a 0.2 ms step, kept every 2 ms (where its explicit motor torque and MuJoCo's implicit
damping have converged to the same law). For each BAM servo model (MX-64 M1 and M6, MX-106 M1 and M6, XL-320 M1,
XL-330 M1, STS3215 M1) its parameters and its full-duty torque-speed line, and for each bench
(a point mass of 0.567 kg at 0.105 m, and 1.5 kg at 0.2 m; the arm down is 0 rad) and each
target (steps from rest at the arm down to 0.1 and 1 rad; sines of 0.5 rad at 1, 2 and 3 Hz)
the trajectory BAM's MuJoCo simulator (bam.mujoco.Simulator: its firmware law, motor torque and
per-step friction on a MuJoCo pendulum) and its reference simulator (bam.simulate.Simulator,
semi-implicit Euler) produce at the firmware gain BAM's logs used (kp 32 on MX and STS, 400 on
XL-330) and its servos' voltages, every 2 ms for 2 s.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np
from bam.model import load_model
from bam import mujoco as bam_mujoco
from bam.simulate import Simulator as ReferenceSimulator

DT = 0.002            # [s] the angles' grid (and the simulator's physics step)
FINE = 0.0002         # [s] the step the trajectories are also made at (both laws converged: see the test)
DURATION = 2.0
BENCHES = {"light": {"mass": 0.567, "arm_mass": 0.0, "length": 0.105},
           "heavy": {"mass": 1.5, "arm_mass": 0.0, "length": 0.2}}
MODELS = [("mx64", "m1"), ("mx64", "m6"), ("mx106", "m1"), ("mx106", "m6"), ("xl320", "m1"), ("xl330", "m1"),
          ("feetech_sts3215_7_4V", "m1")]


def targets(name: str, t: np.ndarray) -> np.ndarray:
    if name.startswith("step"):
        return np.full_like(t, float(name[4:]))
    f = float(name[3:])
    return 0.5 * np.sin(2 * math.pi * f * t)


TARGETS = ["step0.1", "step1", "sin1", "sin2", "sin3"]


def torque_speed(model) -> dict:
    """Torque left at full duty [N m] at speeds from 0 to the no-load speed (BAM's motor equation)."""
    act = model.actuator
    speeds = np.linspace(0.0, 12.0, 25)
    torque = [float(act.compute_torque(act.vin * act.max_pwm, True, 0.0, w)) for w in speeds]
    return {"vin": act.vin, "max_pwm": act.max_pwm, "error_gain": act.error_gain, "kp": act.kp,
            "speed": speeds.tolist(), "torque": torque}


def main(out: str) -> None:
    doc = {"bam": "better-actuator-models 1.0.2 (Apache-2.0), Rhoban, github.com/Rhoban/bam",
           "dt": DT, "duration": DURATION, "benches": BENCHES, "targets": TARGETS, "models": {}}
    arrays = {}
    t = np.arange(int(round(DURATION / DT))) * DT
    for motor, variant in MODELS:
        model = load_model(motor_name=motor, model=variant)
        key = f"{motor}/{variant}"
        params = {name: p.value for name, p in model.get_parameters().items()}
        params.update({"kt": model.kt.value, "R": model.R.value, "armature": model.armature.value})
        entry = {"actuator": model.actuator_name, "parameters": params, "torque_speed": torque_speed(model)}
        for bench, geometry in BENCHES.items():
            for target in TARGETS:
                goal = targets(target, t)
                log = {"dt": DT, **geometry, "kp": model.actuator.kp, "vin": model.actuator.vin,
                       "entries": [{"position": 0.0, "speed": 0.0, "goal_position": float(g), "torque_enable": True}
                                   for g in goal]}
                sim = bam_mujoco.Simulator(load_model(motor_name=motor, model=variant))
                q_mj, _, _ = sim.rollout_log(log)
                fine_t = np.arange(int(round(DURATION / FINE))) * FINE
                fine_log = dict(log, dt=FINE, entries=[{"position": 0.0, "speed": 0.0, "goal_position": float(g),
                                                        "torque_enable": True} for g in targets(target, fine_t)])
                q_fine, _, _ = bam_mujoco.Simulator(load_model(motor_name=motor, model=variant)).rollout_log(fine_log)
                arrays[f"{key}/{bench}/{target}/fine"] = np.asarray(q_fine, dtype=np.float32)[::int(round(DT / FINE))]
                ref = ReferenceSimulator(load_model(motor_name=motor, model=variant))
                q_ref, _, _ = ref.rollout_log(log, simulate_control=True)
                arrays[f"{key}/{bench}/{target}/mujoco"] = np.asarray(q_mj, dtype=np.float32)
                arrays[f"{key}/{bench}/{target}/reference"] = np.asarray(q_ref, dtype=np.float32)
        doc["models"][key] = entry
        print(key, "done", file=sys.stderr)
    np.savez_compressed(out, meta=np.array(json.dumps(doc)), **arrays)


if __name__ == "__main__":
    main(sys.argv[1])
