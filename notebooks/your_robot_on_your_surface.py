# %% [markdown]
# # Your robot on your surface, end to end
#
# What a team does with its own robot, in the order it does it, through the same
# command line the README shows (each cell runs `gait-tuner`, so what works here works
# in a terminal). The robot is `examples/robots/kid3kg` (a 3.2 kg kid-size robot of
# its own MJCF file and a short YAML map); the surface is 30 mm artificial grass, the
# RoboCup field. `your_robot_on_your_surface.ipynb` beside this file is it executed.
#
# 1. check the robot: what the tool derived from its file, and a stand test;
# 2. walk the TLIPFM paper's gait on it, untuned;
# 3. tune that gait for this robot on grass30 (a small study);
# 4. export the best set and walk it;
# 5. randomised walks: does it survive what differs between the model and the field?
#
# Run it as `python notebooks/your_robot_on_your_surface.py [OUT_DIR]` or open it in
# Jupyter from the repository's root.

# %%
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

try:
    from IPython import get_ipython
    from IPython.display import Image, display
    IN_NOTEBOOK = get_ipython() is not None
except ImportError:
    IN_NOTEBOOK = False

ROOT = Path.cwd() if (Path.cwd() / "examples").is_dir() else Path(__file__).resolve().parents[1]
_arg = sys.argv[1] if len(sys.argv) > 1 and not IN_NOTEBOOK else None
OUT = Path(_arg or os.environ.get("NOTEBOOK_OUT") or ROOT / "runs" / "your-robot")
OUT.mkdir(parents=True, exist_ok=True)
ROBOT = str(ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml")
EXE = shutil.which("gait-tuner") or str(Path(sys.executable).with_name("gait-tuner"))


def gait_tuner(*args: str) -> str:
    """Run one gait-tuner command as a user would; its output, or the error it printed."""
    r = subprocess.run([EXE, *args], capture_output=True, text=True, cwd=OUT)
    if r.returncode != 0:
        raise RuntimeError(f"gait-tuner {' '.join(args)} exited {r.returncode}: {r.stderr.strip()}")
    return r.stdout


# %% [markdown]
# ## 1. The robot, as the tool reads it
# `robot check` says what it derived (legs from the joint axes, soles from the feet's
# collision geoms, the CoM at the walking crouch, the servos) and where each number came
# from, then stands the robot for 2 s.

# %%
check = json.loads(gait_tuner("robot", "check", ROBOT, "--json"))
print(f"{check['robot']}: {check['mass_kg']:.2f} kg, straight hip height {check['straight_hip_height_mm']:.0f} mm")
print("legs [mm]:", {k: round(v, 1) for k, v in check["leg_mm"].items()})
for what, where in check["sources"].items():
    print(f"  {what:12s} <- {where[:90]}")
stand = check["stand"]
print(f"stand test: {'stays up' if stand['stays_up'] else 'FALLS'}, pitch {stand['pitch_deg']:.1f} deg")

# %% [markdown]
# ## 2. The paper's gait, untuned, on grass30

# %%
before = json.loads(gait_tuner("simulate", "--robot", ROBOT, "--params", "tkux-table2", "--surface", "grass30",
                               "--json", "--plot", "untuned"))["metrics"]
print(f"untuned: {before['outcome']}, pitch RMS {before['pitch_rms_deg']:.2f} deg, "
      f"{before['distance_m']:.3f} m at {before['speed_mps']:.3f} m/s")
if IN_NOTEBOOK and (OUT / "untuned" / "pitch.png").exists():
    display(Image(filename=str(OUT / "untuned" / "pitch.png")))

# %% [markdown]
# ## 3. A study for this robot on grass30
# The quick-start study with `robot:` and `surfaces:` changed: the CasADi seed and the
# paper's set are its first trials, then Optuna's TPE. A real study takes more trials;
# the study is resumable (run the same command again).

# %%
study = OUT / "kid3kg-grass30.yaml"
study.write_text(f"""\
name: kid3kg-grass30
description: "the TLIPFM gait tuned for kid3kg on 30 mm grass (the notebook's small study)"
robot: {ROBOT}
surfaces: [grass30]
gait: tlipfm
base: tkux-table2
fixed: {{n_steps: 12}}
space:
  period: {{low: 0.45, high: 1.0}}
  t1: {{low: 0.05, high: 0.3}}
  t2: {{low: 0.3, high: 0.9}}
  h_z: {{low: 0.02, high: 0.06}}
  z_c: {{low: 0.17, high: 0.215}}
  half_width: {{low: 0.035, high: 0.05}}
objectives: [pitch_rms]
trials: 16
enqueue: [casadi, baselines]
sampler_seed: 0
""")
print(gait_tuner("tune", str(study), "--workers", "2").strip().splitlines()[-2])

# %% [markdown]
# ## 4. The tuned set, exported and walked

# %%
gait_tuner("export", str(study), "--out", "kid3kg-grass30-best.yaml")
after = json.loads(gait_tuner("simulate", "--robot", ROBOT, "--params", "kid3kg-grass30-best.yaml",
                              "--surface", "grass30", "--json", "--plot", "tuned"))["metrics"]
for label, m in (("untuned", before), ("tuned", after)):
    print(f"{label:8s} {m['outcome']:10s} pitch RMS {m['pitch_rms_deg']:6.2f} deg   {m['distance_m']:.3f} m")
if IN_NOTEBOOK and (OUT / "tuned" / "pitch.png").exists():
    display(Image(filename=str(OUT / "tuned" / "pitch.png")))

# %% [markdown]
# ## 5. Randomised walks
# Masses, servos, backlash, latencies, sensor noise, friction, turf and a tilted ground
# drawn afresh each walk (`tuner/sim/randomisation.py` gives the defaults and why).

# %%
rob = json.loads(gait_tuner("robustness", "--robot", ROBOT, "--params", "kid3kg-grass30-best.yaml",
                            "--surface", "grass30", "--rollouts", "10", "--pushes", "", "--json"))
print(f"survival {rob['survival']:.0%} of {rob['rollouts']} randomised walks; "
      f"stalled {rob.get('stalled')}")
print(f"written to {OUT}")
