# %% [markdown]
# # The papers' figures, regenerated
#
# A walk-through in plain Python (cells in the `# %%` format that Jupyter, VS Code
# and jupytext open as a notebook; `papers_figures.ipynb` beside it is this file
# executed, with its figures). Run it as `python notebooks/papers_figures.py
# [OUT_DIR]`; it writes one PNG per figure and prints what each shows.
#
# * TLIPFM (Wong et al. 2020) Fig. 5: the natural ZMP reference; Figs. 7-8: the
#   CoM trajectory with and without a constant flywheel torque; Fig. 11: the
#   cycloid swing foot.
# * EROS (Pristovani et al.) Figs. 13-14: the quarter-circle walking trajectory,
#   and Fig. 17: the landing with deceleration.
# * Cosine law (Setiono et al. 2012) Tables 1-3: the triangle angles against the
#   printed values.
# * Simulated on the built-in robot: EROS Figs. 24-28 (pitch against distance)
#   and TLIPFM Figs. 14-16 (ZMP responses).

# %%
import os
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gaits import cosine_law as cl  # noqa: E402
from gaits import eros, generate, load_baseline, tlipfm  # noqa: E402

try:                                   # in Jupyter the figures are shown as well as written
    from IPython import get_ipython
    from IPython.display import Image, display
    IN_NOTEBOOK = get_ipython() is not None
except ImportError:
    IN_NOTEBOOK = False

# the output folder: the script's argument, or FIGURES_OUT (Jupyter passes the kernel's own arguments)
_arg = sys.argv[1] if len(sys.argv) > 1 and not IN_NOTEBOOK else None
OUT = Path(_arg or os.environ.get("FIGURES_OUT") or "runs/figures")
OUT.mkdir(parents=True, exist_ok=True)


def save(fig, name: str) -> None:
    """Write the figure as OUT/name (and show it in a notebook)."""
    fig.savefig(OUT / name, dpi=100)
    plt.close(fig)
    if IN_NOTEBOOK:
        display(Image(filename=str(OUT / name)))

# %% TLIPFM Fig. 5 and Figs. 7-8: natural ZMP and CoM, with and without flywheel torque
p = load_baseline("tkux-table2").params
t = np.arange(0, p.t_start + p.n_steps * p.period + p.t_end, 0.005)
zmp = tlipfm.natural_zmp(p, t)
plain = tlipfm.com_trajectory(p, t)
torque = tlipfm.com_trajectory(p.replace(flywheel_accel=10.0), t)
fig, ax = plt.subplots(3, 1, figsize=(9, 9), sharex=True)
ax[0].plot(t, zmp[:, 0] * 100, "k:", label="natural ZMP")
ax[0].plot(t, plain.pos[:, 0] * 100, "--", label="CoM, no flywheel torque")
ax[0].plot(t, torque.pos[:, 0] * 100, label="CoM, constant torque (J phi'' = 0.26 N m)")
ax[0].set_ylabel("sagittal [cm]")
ax[1].plot(t, plain.vel[:, 0] * 100, "--", label="no torque")
ax[1].plot(t, torque.vel[:, 0] * 100, label="constant torque")
ax[1].set_ylabel("sagittal velocity [cm/s]")
ax[2].plot(t, zmp[:, 1] * 100, "k:", label="natural ZMP")
ax[2].plot(t, plain.pos[:, 1] * 100, label="CoM (torque has no lateral effect)")
ax[2].set_ylabel("lateral [cm]")
ax[2].set_xlabel("time [s]")
for a in ax:
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
fig.suptitle("TLIPFM, TKU-X Table 2 (Wong et al. Figs. 5, 7-9)")
fig.tight_layout()
save(fig, "tlipfm_com.png")
print(f"TLIPFM: T_TF = {plain.constants.T:.4f} s; with torque the CoM leads by "
      f"{(torque.pos[:, 0] - plain.pos[:, 0]).max() * 100:.2f} cm at most")

# %% TLIPFM Fig. 11: the cycloid swing foot
s = np.linspace(0, p.period, 200)
f = tlipfm.cycloid_swing(s, p.t1, p.t2, 2 * p.step_length, 0.0, p.h_z)
fig, ax = plt.subplots(1, 2, figsize=(10, 3.5))
ax[0].plot(s, f[:, 0] * 100)
ax[0].set_title("X (theta - sin theta) Amp_x")
ax[1].plot(s, f[:, 2] * 100)
ax[1].set_title("Z (1 - cos theta) H_z / 2")
for a in ax:
    a.set_xlabel("time in the step [s]")
    a.set_ylabel("[cm]")
fig.tight_layout()
save(fig, "tlipfm_cycloid.png")

# %% EROS Figs. 13-14 and 17: quarter-circle trajectory, and the decelerated landing
fig, ax = plt.subplots(1, 2, figsize=(11, 4))
for name, style in (("eros-x16-without", "-"), ("eros-x16-with", "--")):
    ref = eros.eros_references(load_baseline(name).params)
    ax[0].plot(ref.state[:, eros.XL] * 1000, ref.state[:, eros.ZL] * 1000, style, label=name)
    ax[1].plot(ref.t, ref.state[:, eros.ZL] * 1000, style, label=name)
ax[0].set_xlabel("left foot x [mm]")
ax[0].set_ylabel("left foot z [mm]")
ax[0].set_title("sagittal path (Fig. 13)")
ax[1].set_xlabel("time [s]")
ax[1].set_ylabel("left foot z [mm]")
ax[1].set_title("landing slowed by deceleration (Fig. 17)")
for a in ax:
    a.legend(fontsize=8)
    a.grid(alpha=0.3)
fig.tight_layout()
save(fig, "eros_trajectory.png")
plain_steps = len(eros.angle_steps(load_baseline("eros-x16-with").params.t_mn))
dec = eros.decelerated_angle_steps(load_baseline("eros-x16-with").params.t_mn, 1.0, 4)
print(f"EROS: a landing takes {plain_steps} ticks plain and {len(dec)} with C_DC = 1, n = 4")

# %% Cosine law, Tables 1-3: the triangle angles against the printed values
pc = cl.CosineLawParams()
tt = np.linspace(0, pc.motion_time, 9)
ms = cl.motion_profiles("starting", tt, pc)
ang = np.degrees(cl.paper_leg_angles(ms.ref_tilted, ms.theta_t, *cl.SETIONO_TABLE_FIT))
table1_hip = np.array([41.3, 48.5, 54.3, 59.1, 63.1, 68.6, 72.9, 76.3, 79.1])
print("cosine law, Table 1 black-leg hip angle [deg], printed vs ours:")
for a, b in zip(table1_hip, ang[:, 0]):
    print(f"   {a:6.1f} {b:6.1f}")

# %% Simulated: EROS Figs. 24-28 (torso pitch against distance, without and with
# the optimisation, 24 mm steps on 50 mm grass) and TLIPFM Figs. 14-16 (ZMP
# response of LIPM, DLIPM and TLIPFM on the rigid floor). These walk the
# built-in robot in MuJoCo (see docs/simulation.md for what the simulation reproduces).
from tuner.report import experiments as ex  # noqa: E402
from tuner.sim.metrics import summarize  # noqa: E402
from tuner.report.plots import plot_pitch, plot_zmp  # noqa: E402
from tuner.robots import load_robot  # noqa: E402
from tuner.sim.rollout import Simulator  # noqa: E402
from tuner.sim.surfaces import SURFACES  # noqa: E402

robot = load_robot("kidsize")
sim = Simulator(robot, SURFACES["grass50"])
traces = {}
for optimised in (False, True):
    pe = ex.eros_params(24, optimised)
    pe = pe.replace(foot_lift=pe.foot_lift * 0.2)
    traces["with optimisation" if optimised else "without"] = sim.rollout(
        generate(pe, robot.leg, sim.control_period))
plot_pitch(traces, OUT / "eros_pitch_grass50.png", "EROS, 24 mm steps on 50 mm grass (cf. Fig. 28)")
if IN_NOTEBOOK:
    display(Image(filename=str(OUT / "eros_pitch_grass50.png")))
for label, tr in traces.items():
    m = summarize(tr)
    print(f"EROS 24 mm on grass50, {label}: +-{m.pitch_pm_deg:.1f} deg, {tr.reason}")
rigid = Simulator(robot, SURFACES["rigid"])
for model in ("lipm", "dlipm", "tlipfm"):
    pt = load_baseline("tkux-table2").params.replace(model=model)
    tr = rigid.rollout(generate(pt, robot.leg, rigid.control_period))
    plot_zmp(tr, OUT / f"zmp_{model}.png", robot.foot_size, f"{model.upper()} ZMP response (cf. Figs. 14-16)")
    if IN_NOTEBOOK:
        display(Image(filename=str(OUT / f"zmp_{model}.png")))
    m = summarize(tr)
    print(f"{model}: ZMP error {m.zmp_error_x_cm:.2f}/{m.zmp_error_y_cm:.2f} cm, {tr.reason}")
print(f"figures in {OUT}")
