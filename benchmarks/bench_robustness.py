"""Does robust tuning pay? The quick-start's deterministic best beside the shipped robust sets.

Usage: ``python benchmarks/bench_robustness.py [--rollouts 200] [--push-rollouts 20] [--workers 2]``

1. Tunes the quick-start study afresh (``studies/quickstart.yaml``, 1 worker, its own sampler
   seed: the same trials every time) into a temporary folder and exports its best: a gait
   tuned on one deterministic simulation.
2. Evaluates it and the shipped ``kidsize-robust-grass50`` (open loop) and
   ``kidsize-robust-fb-grass50`` (with the IMU stabiliser, and the same gait with it switched
   off) on every pedestal: ``--rollouts`` randomised walks with evaluation seeds (never used in
   tuning) and the push sweep.
3. Times one trial's evaluation in each study kind (deterministic: 1 walk; robust: K walks),
   side by side in this run.
Prints survival % and the largest push survived in >= 90% per set and pedestal.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import gaits
from tuner.params_io import resolve_params
from tuner.sim.randomisation import DEFAULT_PUSHES
from tuner.sim.robustness import evaluate
from tuner.search.objective import Evaluator
from tuner.search.study import load_study

ROOT = Path(__file__).resolve().parents[1]
PEDESTALS = ("grass50", "grass30", "grass10", "carpet4")


def quickstart_best(folder: Path) -> Path:
    exe = [sys.executable, "-m", "tuner.cli"]
    study = str(ROOT / "studies" / "quickstart.yaml")
    subprocess.run(exe + ["tune", study, "--workers", "1", "--runs", str(folder)], check=True,
                   capture_output=True, text=True)
    out = folder / "quickstart-best.yaml"
    subprocess.run(exe + ["export", study, "--runs", str(folder), "--out", str(out)], check=True,
                   capture_output=True, text=True)
    return out


def trial_cost(study: str, params_spec: str, repeats: int = 3) -> float:
    spec = load_study(str(ROOT / "studies" / f"{study}.yaml"))
    gf = resolve_params(params_spec, None)
    ev = Evaluator(spec)
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        ev.evaluate(gaits.Drive(gf.params, gf.stabiliser if spec.stabiliser is not None else None))
        best = min(best, time.perf_counter() - t0)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rollouts", type=int, default=200)
    ap.add_argument("--push-rollouts", type=int, default=20)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        qs = quickstart_best(Path(tmp))
        print(f"quick-start study re-run and exported in {time.perf_counter() - t0:.1f} s: {qs.name}")
        sets = {"quick-start best (deterministic)": (str(qs), True),
                "kidsize-robust-grass50": ("kidsize-robust-grass50", True),
                "kidsize-robust-fb-grass50": ("kidsize-robust-fb-grass50", True),
                "  the same, stabiliser off": ("kidsize-robust-fb-grass50", False)}
        print(f"\n{args.rollouts} randomised rollouts per pedestal (evaluation seed {args.seed}), "
              f"pushes {', '.join(f'{p:g}' for p in DEFAULT_PUSHES)} N s x {args.push_rollouts}")
        print(f"{'set':34s} " + " ".join(f"{p:>20s}" for p in PEDESTALS) + "   wall")
        for label, (spec, stabilised) in sets.items():
            drive = gaits.Drive.of(resolve_params(spec, None), source=spec, stabiliser=None if stabilised else False)
            cells = []
            t0 = time.perf_counter()
            for surface in PEDESTALS:
                rep = evaluate("kidsize", surface, drive, rollouts=args.rollouts, seed=args.seed,
                               push_rollouts=args.push_rollouts, workers=args.workers)
                lp = rep.largest_push
                cells.append(f"{rep.survival:6.1%} push {'-' if lp is None else format(lp, 'g'):>4s}")
            print(f"{label:34s} " + " ".join(f"{c:>20s}" for c in cells) + f"   {time.perf_counter() - t0:.0f} s")
        print("\ncells: survival of the randomised rollouts, largest push [N s] survived in >= 90% "
              "(and every smaller one)")
        det = trial_cost("quickstart", str(qs))
        rob = trial_cost("kidsize-robust-grass50", "kidsize-robust-grass50")
        k = load_study(str(ROOT / "studies" / "kidsize-robust-grass50.yaml")).settings.rollouts
        print(f"\none trial's evaluation: deterministic {det * 1000:.0f} ms, robust (K = {k}, no early stop) "
              f"{rob * 1000:.0f} ms: {rob / det:.1f}x")


if __name__ == "__main__":
    main()
