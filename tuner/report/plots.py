"""Figures written by the command line (matplotlib, Agg backend, PNG)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from gaits import GaitTrajectory  # noqa: E402
from gaits.files import make_folder  # noqa: E402

__all__ = ["plot_references", "plot_pitch", "plot_zmp", "plot_robustness", "save_figure"]


def save_figure(fig, path: str | Path, dpi: int) -> Path:
    """Write a figure to ``path`` (its format from the suffix) whole or not at all: rendered in
    memory, then put in place, so a full disk or a kill leaves the old picture as it was."""
    import io

    from gaits.files import write_bytes_atomic
    buf = io.BytesIO()
    fig.savefig(buf, format=Path(path).suffix.lstrip(".") or "png", dpi=dpi)
    return write_bytes_atomic(path, buf.getvalue())


def plot_references(traj: GaitTrajectory, path: str | Path, title: str = "") -> Path:
    """CoM, ZMP reference, feet and left-leg joint targets against time, one PNG."""
    path = Path(path)
    make_folder(path.parent)
    fig, axes = plt.subplots(4, 1, figsize=(10, 11), sharex=True)
    t = traj.t
    zlabel = "ZMP ref" if traj.zmp_source == "model" else "ZMP (cart-table of CoM)"
    for i, (c, plane) in enumerate((("x", "sagittal"), ("y", "lateral"))):
        ax = axes[i]
        ax.plot(t, traj.p_world_com[:, i] * 100, label=f"CoM {c}")
        ax.plot(t, traj.p_world_zmp_ref[:, i] * 100, "--", label=f"{zlabel} {c}")
        ax.plot(t, traj.p_world_foot_l[:, i] * 100, ":", label=f"left foot {c}")
        ax.plot(t, traj.p_world_foot_r[:, i] * 100, ":", label=f"right foot {c}")
        ax.set_ylabel(f"{plane} [cm]")
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
    save_figure(fig, path, 110)
    plt.close(fig)
    return path


def plot_pitch(traces: dict, path: str | Path, title: str = "") -> Path:
    """Torso pitch against time and against distance walked (EROS paper, Figs 24-28)."""
    path = Path(path)
    make_folder(path.parent)
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
        a.set_ylabel("torso pitch [deg], + = forward")
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle(title or "torso pitch (x: fall)")
    fig.tight_layout()
    save_figure(fig, path, 110)
    plt.close(fig)
    return path


def plot_zmp(trace, path: str | Path, foot_size: tuple[float, float], title: str = "") -> Path:
    """Measured ZMP against the reference, relative to the support foot, with the sole's
    boundaries (TLIPFM paper, Figs 14-16)."""
    path = Path(path)
    make_folder(path.parent)
    fig, axes = plt.subplots(2, 1, figsize=(10, 7), sharex=True)
    # double support (planned support 0 while the walk runs): the reference moves from one foot
    # to the other there, so its frame switches and the curves jump; shade those spans
    support = np.asarray(trace.support)
    walking = np.zeros(len(support), dtype=bool)
    moving = np.flatnonzero(support != 0)
    if len(moving):
        walking[moving[0]:moving[-1] + 1] = True
    double = walking & (support == 0)
    edges = np.flatnonzero(np.diff(np.r_[0, double.astype(int), 0]))
    for axis, (ax, label, half) in enumerate(zip(axes, ("sagittal", "lateral"),
                                                 (foot_size[0] / 2, foot_size[1] / 2))):
        for k, (a, b) in enumerate(zip(edges[::2], edges[1::2])):
            ax.axvspan(trace.t[a], trace.t[min(b, len(trace.t) - 1)], color="0.9", lw=0,
                       label="double support (frame switches feet)" if k == 0 else None)
        ax.plot(trace.t, trace.zmp_ref_local[:, axis] * 100, "-.", label="ZMP reference")
        ax.plot(trace.t, trace.zmp_local[:, axis] * 100, "-", lw=1, label="measured ZMP (sole sensors)")
        ax.axhline(half * 100, ls="--", c="gray", lw=0.8)
        ax.axhline(-half * 100, ls="--", c="gray", lw=0.8, label="sole boundary (single support)")
        ax.set_ylabel(f"{label}, from the support\nfoot's centre [cm]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8, loc="upper right")
    axes[1].set_xlabel("time [s]")
    fig.suptitle(title or "ZMP response, relative to the support foot")
    fig.tight_layout()
    save_figure(fig, path, 110)
    plt.close(fig)
    return path


def plot_robustness(report, out_dir: str | Path) -> Path:
    """Survival per push size, time to fall and pitch RMS of a robustness report, in one PNG."""
    out_dir = Path(out_dir)
    make_folder(out_dir)
    d = report.to_dict()
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    sizes = [0.0] + [float(k) for k in d["push_survival"]]
    surv = [d["survival"]] + list(d["push_survival"].values())
    axes[0].bar([f"{s:g}" for s in sizes], [100 * v for v in surv], color="tab:blue")
    axes[0].axhline(90, color="k", lw=0.8, ls="--", label="90 %")
    for i, v in enumerate(surv):
        axes[0].text(i, max(100 * v, 2), f"{100 * v:.0f}", ha="center", va="bottom", fontsize=8)
    n_push = sorted({len(rows) for rows in report.pushes.values()})
    axes[0].set_xlabel(f"push impulse [N s] (0: randomisation only, {len(report.rollouts)} rollouts; "
                       f"{'/'.join(map(str, n_push)) or 0} per push size)", fontsize=9)
    axes[0].set_ylabel("survival [%]")
    axes[0].set_ylim(0, 110)
    axes[0].legend(fontsize=8)
    axes[0].set_title("survival")
    falls = [r["t_fall_s"] for r in report.rollouts if r["fell"]]
    if falls:
        axes[1].hist(falls, bins=20, color="tab:red")
    else:
        axes[1].text(0.5, 0.5, "no falls", ha="center", transform=axes[1].transAxes)
    axes[1].set_xlabel("time of the fall [s]")
    axes[1].set_ylabel("rollouts")
    axes[1].set_title(f"time to fall ({len(falls)} of {len(report.rollouts)} fell)")
    pitch = [r["pitch_rms_deg"] for r in report.rollouts if r["survived"]]    # completed walks only
    if pitch:
        axes[2].hist(pitch, bins=20, color="tab:green")
    axes[2].set_xlabel("torso pitch RMS [deg]")
    axes[2].set_ylabel("rollouts")
    axes[2].set_title("pitch vibration of the rollouts that stayed up")
    from matplotlib.ticker import MaxNLocator
    for ax in axes[1:]:
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))     # counts of rollouts
    fig.suptitle(f"robustness: {report.params} on robot {report.robot} / {report.surface}, "
                 f"stabiliser {'on' if report.stabiliser else 'off'}")
    fig.tight_layout()
    path = out_dir / "robustness.png"
    save_figure(fig, path, 100)
    plt.close(fig)
    return path
