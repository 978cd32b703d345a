"""Figures written by the command line (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gaits import GaitTrajectory  # noqa: E402

__all__ = ["plot_references", "plot_pitch", "plot_zmp"]


def plot_references(traj: GaitTrajectory, path: str | Path, title: str = "") -> Path:
    """CoM, ZMP reference, feet and left-leg joint targets against time, one PNG."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    t = traj.t
    zlabel = "ZMP ref" if traj.zmp_source == "model" else "ZMP (cart-table of CoM)"
    ax = axes[0]
    ax.plot(t, traj.p_world_com[:, 0] * 100, label="CoM x")
    ax.plot(t, traj.p_world_zmp_ref[:, 0] * 100, "--", label=f"{zlabel} x")
    ax.plot(t, traj.p_world_foot_l[:, 0] * 100, ":", label="left foot x")
    ax.plot(t, traj.p_world_foot_r[:, 0] * 100, ":", label="right foot x")
    ax.set_ylabel("sagittal [cm]")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[1]
    ax.plot(t, traj.p_world_com[:, 1] * 100, label="CoM y")
    ax.plot(t, traj.p_world_zmp_ref[:, 1] * 100, "--", label=f"{zlabel} y")
    ax.plot(t, traj.p_world_foot_l[:, 1] * 100, ":", label="left foot y")
    ax.plot(t, traj.p_world_foot_r[:, 1] * 100, ":", label="right foot y")
    ax.set_ylabel("lateral [cm]")
    ax.legend(loc="upper left", fontsize=8)
    if traj.zmp_source != "model":
        lim = np.nanpercentile(np.abs(traj.p_world_com[:, :2]), 100) * 100 * 1.5 + 1
        axes[1].set_ylim(-lim, lim)
    ax = axes[2]
    ax.plot(t, traj.p_world_foot_l[:, 2] * 100, label="left foot z")
    ax.plot(t, traj.p_world_foot_r[:, 2] * 100, label="right foot z")
    ax.plot(t, (traj.p_world_pelvis[:, 2] - traj.p_world_pelvis[0, 2]) * 100, label="pelvis z (rel.)")
    ax.set_ylabel("height [cm]")
    ax.legend(loc="upper left", fontsize=8)
    ax = axes[3]
    for name in ("l_hip_roll", "l_hip_pitch", "l_knee", "l_ankle_pitch", "l_ankle_roll"):
        ax.plot(t, np.degrees(traj.joint(name)), label=name)
    ax.set_ylabel("left leg [deg]")
    ax.set_xlabel("time [s]")
    ax.legend(loc="upper left", fontsize=8)
    fig.suptitle(title or f"{traj.family} references")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_pitch(traces: dict, path: str | Path, title: str = "") -> Path:
    """Torso pitch against time and against distance walked (EROS paper, Figs 24-28)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 7))
    for label, tr in traces.items():
        deg = np.degrees(tr.pitch)
        a1.plot(tr.t, deg, label=label)
        a2.plot((tr.p_torso[:, 0] - tr.p_torso[0, 0]) * 1000, deg, label=label)
        if tr.fell:
            a1.plot(tr.t[-1], deg[-1], "kx", ms=10)
            a2.plot((tr.p_torso[-1, 0] - tr.p_torso[0, 0]) * 1000, deg[-1], "kx", ms=10)
    a1.set_xlabel("time [s]")
    a2.set_xlabel("distance walked [mm]")
    for a in (a1, a2):
        a.set_ylabel("torso pitch [deg]")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle(title or "torso pitch (x: fall)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_zmp(trace, path: str | Path, foot_size: tuple[float, float], title: str = "") -> Path:
    """Measured ZMP against the reference, relative to the support foot, with the sole's
    boundaries (TLIPFM paper, Figs 14-16)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    for axis, (ax, label, half) in enumerate(zip(axes, ("sagittal", "lateral"),
                                                 (foot_size[0] / 2, foot_size[1] / 2))):
        ax.plot(trace.t, trace.zmp_ref_local[:, axis] * 100, "-.", label="ZMP reference")
        ax.plot(trace.t, trace.zmp_local[:, axis] * 100, "-", lw=1, label="measured ZMP (sole sensors)")
        ax.axhline(half * 100, ls="--", c="gray", lw=0.8)
        ax.axhline(-half * 100, ls="--", c="gray", lw=0.8, label="sole boundary (single support)")
        ax.set_ylabel(f"{label} [cm]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[1].set_xlabel("time [s]")
    fig.suptitle(title or "ZMP response, relative to the support foot")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
