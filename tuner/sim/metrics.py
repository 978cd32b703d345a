"""Walking metrics from a simulation trace, each defined once, here.

All metrics are computed over the *walking window*: from the gait's first
planned single support to the end of the rollout (or the fall).

* ``pitch_rms_deg``: root mean square of torso pitch about its mean [deg].
* ``pitch_pm_deg``: the EROS paper's "average vibration +-X deg": half the
  peak-to-peak torso pitch within each gait cycle (two steps), averaged over
  the complete cycles of the window [deg]. For pitch = A sin(2 pi t / P) with P
  dividing the cycle it is exactly A.
* ``fell`` / ``t_fall_s``: the rollout stopped on a fall (torso tilt beyond the
  threshold or torso too low, see ``tuner.simulate.FallCriteria``), and when.
* ``distance_m``: forward (x) displacement of the torso from the walk's start to
  the end or the fall [m]; ``speed_mps`` = distance / window duration [m/s].
* ``zmp_error_x_cm`` / ``zmp_error_y_cm``: mean absolute error between the
  measured ZMP (centre of pressure of the eight sole force sensors) and the
  gait's ZMP reference, sagittal and lateral, over the loaded samples [cm].
  Both are taken relative to the support foot (the midpoint of both feet in
  double support): the measured one to the actual foot, the reference to the
  planned one, as force sensors in the soles see it; an open-loop drift of the
  whole walk is not a tracking error.
  The TLIPFM paper's Table 3 calls its figures "sum of absolute error" but
  gives 1.1-1.7 cm for ~9 s of walking, which can only be a per-sample
  (mean) figure; we report the mean and label it so.
* ``vx_mps`` / ``vy_mps`` / ``wz_radps``: the walk's velocity in the torso's heading
  frame: the torso's displacement between control ticks turned into the heading of the
  tick and summed, and the heading change, over the *steady window* of a walk command
  (``gaits.CommandRamp.steady_steps``, whole gait cycles at the held command) or else the
  walking window, divided by its duration. Undefined (null) when the robot fell before
  the steady window ended.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from .centre_of_pressure import centre_of_pressure
from .rollout import Trace

__all__ = ["Metrics", "DEFINITIONS", "distance_budget", "loaded_soles", "heading_velocity", "pitch_rms", "pitch_pm",
           "centre_of_pressure", "zmp_error", "summarize", "tracking", "MIN_PROGRESS", "planned_forward_distance"]

#: A walk that stays up having covered less than this share of its planned forward distance did not
#: walk: a study's trial is infeasible (``search/objective.py``), robustness counts it ``stalled``.
MIN_PROGRESS = 0.5


def planned_forward_distance(traj) -> float:
    """[m] The forward distance a joint table plans: its pelvis's x, last minus first."""
    return float(traj.p_world_pelvis[-1, 0] - traj.p_world_pelvis[0, 0])

DEFINITIONS = {
    "pitch_rms_deg": "RMS of torso pitch about its mean over the walk [deg]",
    "pitch_pm_deg": "half the peak-to-peak torso pitch per gait cycle, averaged (the EROS +- figure) [deg]",
    "fell": "the robot fell (torso tilt > limit or torso too low)",
    "outcome": "how the walk ended: completed, fell, diverged (MuJoCo's warning, or a controller's target "
               "not finite), impossible (a state no "
               "kid-size robot reaches), stopped; only completed and stopped count as survival",
    "t_fall_s": "time of the fall [s]",
    "distance_m": "forward torso displacement over the walk [m]",
    "speed_mps": "distance / walking time [m/s]",
    "zmp_error_x_cm": "mean |measured ZMP - reference|, sagittal [cm]",
    "zmp_error_y_cm": "mean |measured ZMP - reference|, lateral [cm]",
    "walk_time_s": "time from the first step to the end or the fall [s]",
    "vx_mps": "forward velocity in the torso's heading frame, steady window [m/s]",
    "vy_mps": "leftward velocity in the torso's heading frame, steady window [m/s]",
    "wz_radps": "turning rate (counter-clockwise), steady window [rad/s]",
}


@dataclass(frozen=True)
class Metrics:
    pitch_rms_deg: float
    pitch_pm_deg: float
    fell: bool
    t_fall_s: float | None
    distance_m: float
    speed_mps: float
    zmp_error_x_cm: float
    zmp_error_y_cm: float
    walk_time_s: float
    reason: str
    vx_mps: float = float("nan")
    vy_mps: float = float("nan")
    wz_radps: float = float("nan")
    outcome: str = "completed"
    #: why the steady window's velocities are not numbers (a fall in it, or a walk that ended before
    #: it); "" when they are
    velocity_note: str = ""

    @property
    def survived(self) -> bool:
        """The walk ended standing (completed or stopped); a fall, a diverged or an impossible
        simulation never counts as survival."""
        return self.outcome in ("completed", "stopped")

    def to_dict(self) -> dict:
        """The metrics for strict JSON: a value that is not a number (the ZMP error of a walk
        with no sample that loads the soles, e.g. an early fall) is null, and ``undefined``
        says why."""
        out = asdict(self)
        note = out.pop("velocity_note")
        out["survived"] = self.survived
        undefined = {k: ((note or "the robot fell before the steady window ended") if k in _VELOCITY else
                         "no sample with at least 10% of the robot's weight on its sole sensors")
                     for k, v in out.items() if isinstance(v, float) and not math.isfinite(v)}
        for k in undefined:
            out[k] = None
        out["undefined"] = undefined
        return out


_VELOCITY = ("vx_mps", "vy_mps", "wz_radps")


def heading_velocity(t: np.ndarray, p: np.ndarray, yaw: np.ndarray, t0: float, t1: float) -> np.ndarray:
    """(vx [m/s], vy [m/s], wz [rad/s]) over [t0, t1] in the heading frame (see the module
    docstring); NaN when the samples do not reach t1."""
    t = np.asarray(t, dtype=float)
    if len(t) < 2 or t[-1] < t1 - 1e-9 or t1 <= t0:
        return np.full(3, np.nan)
    sel = (t >= t0 - 1e-9) & (t <= t1 + 1e-9)
    pw, yw = np.asarray(p, dtype=float)[sel, :2], np.asarray(yaw, dtype=float)[sel]
    d = np.diff(pw, axis=0)
    c, s = np.cos(yw[:-1]), np.sin(yw[:-1])
    dx = np.sum(c * d[:, 0] + s * d[:, 1])
    dy = np.sum(-s * d[:, 0] + c * d[:, 1])
    dur = float(t[sel][-1] - t[sel][0])
    return np.array([dx / dur, dy / dur, (yw[-1] - yw[0]) / dur])


def pitch_rms(pitch: np.ndarray) -> float:
    """RMS about the mean [same unit as ``pitch``]; 0 for fewer than two samples."""
    pitch = np.asarray(pitch, dtype=float)
    if len(pitch) < 2:
        return 0.0
    return float(np.sqrt(np.mean((pitch - pitch.mean()) ** 2)))


def pitch_pm(t: np.ndarray, pitch: np.ndarray, cycle: float) -> float:
    """Mean over complete cycles of (max - min) / 2; the whole window if shorter than a cycle."""
    t = np.asarray(t, dtype=float)
    pitch = np.asarray(pitch, dtype=float)
    if len(t) < 2:
        return 0.0
    if cycle <= 0:
        raise ValueError(f"cycle must be positive, got {cycle}")
    n = int(math.floor((t[-1] - t[0]) / cycle + 1e-9))
    if n == 0:
        return float((pitch.max() - pitch.min()) / 2)
    halves = []
    for i in range(n):
        lo, hi = t[0] + i * cycle, t[0] + (i + 1) * cycle
        sel = (t >= lo - 1e-9) & (t < hi - 1e-9)          # half-open cycles [lo, hi)
        halves.append((pitch[sel].max() - pitch[sel].min()) / 2)
    return float(np.mean(halves))


def zmp_error(zmp: np.ndarray, zmp_ref: np.ndarray) -> tuple[float, float]:
    """Mean absolute error (x, y) over samples where the measured ZMP exists [m]."""
    ok = np.all(np.isfinite(zmp), axis=1)
    if not ok.any():
        return float("nan"), float("nan")
    e = np.abs(zmp[ok] - zmp_ref[ok])
    return float(e[:, 0].mean()), float(e[:, 1].mean())


def summarize(trace: Trace) -> Metrics:
    """All metrics of one rollout (see the module docstring for definitions)."""
    w = trace.t >= trace.walk_start
    if not w.any():
        w = np.ones_like(trace.t, dtype=bool)
    t = trace.t[w]
    pitch = np.degrees(trace.pitch[w])
    ex, ey = zmp_error(trace.zmp_local[w], trace.zmp_ref_local[w])
    walk = float(t[-1] - t[0]) if len(t) > 1 else 0.0
    dist = float(trace.p_torso[w][-1, 0] - trace.p_torso[w][0, 0]) if len(t) else 0.0
    t0, t1 = trace.meta.get("steady", (trace.walk_start, float(trace.t[-1])))
    vel = (heading_velocity(trace.t, trace.p_torso, trace.yaw, t0, t1) if trace.yaw is not None
           else np.full(3, np.nan))
    note = ""
    if not np.all(np.isfinite(vel)):
        if trace.fell and trace.t_fall is not None and trace.t_fall < t1:
            note = f"the robot fell at {trace.t_fall:.2f} s, before the steady window ({t0:.2f}-{t1:.2f} s) ended"
        elif float(trace.t[-1]) < t1 or t1 <= t0:
            note = (f"the walk ended at {float(trace.t[-1]):.2f} s, before its steady window ({t0:.2f}-{t1:.2f} s) "
                    f"did: walk longer")
        else:
            note = "no heading was recorded"
    return Metrics(pitch_rms_deg=pitch_rms(pitch), pitch_pm_deg=pitch_pm(t, pitch, trace.cycle_time),
                   fell=trace.fell, t_fall_s=trace.t_fall, distance_m=dist,
                   speed_mps=dist / walk if walk > 0 else 0.0,
                   zmp_error_x_cm=ex * 100, zmp_error_y_cm=ey * 100, walk_time_s=walk,
                   reason=trace.reason, vx_mps=float(vel[0]), vy_mps=float(vel[1]),
                   wz_radps=float(vel[2]), outcome=trace.outcome, velocity_note=note)


#: [s] the windows a walk is cut into when its controller reports no steps (a learned policy, a
#: controller class of a team's own): about two steps of a kid-size walk, so the sway mostly
#: cancels within one (ours)
TRACKING_WINDOW = 1.0


def tracking(trace: Trace, stream, step_starts: np.ndarray | None) -> dict:
    """How well a walk followed a command stream (``gaits.CommandStream``).

    The walk is cut at the step starts ``step_starts`` [s] (the controller's own steps, so the
    torso's sway, which crosses the midline once a step, cancels within each window; None, from a
    controller that reports no steps: every :data:`TRACKING_WINDOW` from the start); in every
    step that lies inside one segment of the stream, after that segment's first step, the torso's
    velocity in its heading frame (:func:`heading_velocity`) is compared with the segment's
    command. Returns the RMS errors ``vx_rmse_mps``, ``vy_rmse_mps``, ``wz_rmse_radps`` over those
    steps (null when no step qualifies, e.g. after an early fall), how many steps were measured,
    and per segment its command, measured mean velocity, number of steps and each measured step
    (``step_velocities``: its start [s] and velocity (vx, vy, wz), for a reader that wants only
    some of them, e.g. the steps after a controller's command ramp has settled).
    """
    t_end = float(trace.t[-1])
    starts = (np.arange(0.0, float(stream.duration) + TRACKING_WINDOW, TRACKING_WINDOW) if step_starts is None
              else np.asarray(step_starts, dtype=float))
    errors, segments = [], []
    for a, b, cmd in stream.segments():
        inside = starts[(starts >= a - 1e-9) & (starts <= b + 1e-9)]
        got, rows = [], []
        for w0, w1 in zip(inside[1:-1], inside[2:]):       # the segment's first step is left out
            if w1 > t_end + 1e-9 or (trace.fell and trace.t_fall is not None and w1 > trace.t_fall):
                break
            v = heading_velocity(trace.t, trace.p_torso, trace.yaw, float(w0), float(w1))
            if np.all(np.isfinite(v)):
                got.append(v)
                rows.append([float(w0)] + [float(x) for x in v])
                errors.append(v - cmd)
        segments.append({"t0_s": a, "t1_s": b, "command": [float(x) for x in cmd], "steps": len(got),
                         "measured": None if not got else [float(x) for x in np.mean(got, axis=0)],
                         "step_velocities": rows})
    e = np.array(errors).reshape(-1, 3)
    rmse = [None if not len(e) else float(np.sqrt(np.mean(e[:, i] ** 2))) for i in range(3)]
    return {"vx_rmse_mps": rmse[0], "vy_rmse_mps": rmse[1], "wz_rmse_radps": rmse[2], "steps": int(len(e)),
            "segments": segments}


# --- tracking over many walks (robustness rows: ``survived`` and ``segments`` per walk) ----------

def _segment_shares(rows):
    """(command, dominant axis, measured/commanded along it) of every moving segment of the walks
    that stayed up."""
    for r in rows:
        if not r["survived"]:
            continue
        for seg in r.get("segments") or []:
            c, got = np.array(seg["command"]), seg["measured"]
            if got is None or not np.any(c):
                continue
            axis = int(np.argmax(np.abs(c) * [1, 1, 0.1]))
            if abs(c[axis]) > 1e-9:
                yield c, axis, got[axis] / c[axis]


def settled_after(stream, accel: np.ndarray, t_start: float) -> list[float]:
    """Per segment of ``stream``, the time [s] the engine's rate-limited command (``accel_*``,
    ramping from zero at ``t_start``, its first step) reaches the segment's command (inf when the
    segment ends first): the steps that start from then on are the segment's steady part. Each
    axis ramps on its own at its limit, so the command is reached when the slowest axis is."""
    out, r = [], np.zeros(3)
    for a, b, cmd in stream.segments():
        c, t0 = np.asarray(cmd, dtype=float), max(a, t_start)
        need, span = float(np.max(np.abs(c - r) / accel)), max(b - t0, 0.0)
        if need <= span:
            out.append(t0 + need)
            r = c
        else:
            out.append(float("inf"))
            r = r + np.clip(c - r, -accel * span, accel * span)
    return out


def steady_rows(rows, settled: list[float]):
    """``rows`` with each segment's measured velocity the mean of its steady steps only (those that
    start once the command ramp has settled; a segment with none is left out)."""
    out = []
    for r in rows:
        segs = []
        for seg, t_set in zip(r.get("segments") or [], settled):
            steps = [v[1:] for v in seg.get("step_velocities", []) if v[0] >= t_set - 1e-9]
            segs.append(dict(seg, measured=[float(x) for x in np.mean(steps, axis=0)] if steps else None,
                             steps=len(steps)))
        out.append(dict(r, segments=segs))
    return out


def tracking_shares(rows) -> tuple[float, float]:
    """Median measured/commanded along each moving segment's own axis, and its spread (IQR)."""
    shares = [share for _, _, share in _segment_shares(rows)]
    if not shares:
        return float("nan"), float("nan")
    q = np.percentile(shares, [25, 50, 75])
    return float(q[1]), float(q[2] - q[0])


AXES = ("forward", "backward", "sideways", "turning")


def tracking_by_axis(rows) -> dict[str, float]:
    """The median measured/commanded per kind of segment (forward, backward, sideways, turning: the
    segment's dominant axis): where the shares of :func:`tracking_shares` come from."""
    out: dict[str, list[float]] = {a: [] for a in AXES}
    for c, axis, share in _segment_shares(rows):
        kind = ("forward" if c[0] > 0 else "backward") if axis == 0 else ("sideways" if axis == 1 else "turning")
        out[kind].append(share)
    return {k: float(np.median(v)) if v else float("nan") for k, v in out.items()}


def steady_tracking(rows, stream, engine=None) -> dict | None:
    """How much of its command a set walked over many walks of ``stream``, in steady steps: per
    moving segment the mean of its steps that start once the command has settled (an online
    engine's ``accel_*`` ramp, from its first step at ``t_stand``; a table planned per step has
    no ramp: every step from the segment's second), as a share of the command along the
    segment's own axis; the median over the segments of the walks that stayed up, its IQR, and
    the median per kind of segment (forward, backward, sideways, turning; null where none).
    These shares are what a stride calibration inverts (``EngineParams.stride_*``). None when no
    segment was measured."""
    if engine is not None:
        settled = settled_after(stream, np.array([engine.accel_vx, engine.accel_vy, engine.accel_wz]),
                                engine.t_stand)
    else:
        settled = [a for a, _, _ in stream.segments()]
    rows = steady_rows(rows, settled)
    median, iqr = tracking_shares(rows)
    if not np.isfinite(median):
        return None
    by = tracking_by_axis(rows)
    return {"median": median, "iqr": iqr, **{k: (v if np.isfinite(v) else None) for k, v in by.items()}}


def loaded_soles(trace: Trace, load_share: float = 0.15) -> tuple[np.ndarray, np.ndarray]:
    """(left, right) (K,) bool: the sole's four sensors carry more than ``load_share`` of the
    standing weight (the mean total force over the trace's first 0.2 s)."""
    weight = float(np.mean(trace.force[trace.t <= trace.t[0] + 0.2].sum(axis=1)))
    return (trace.force[:, :4].sum(axis=1) > load_share * weight,
            trace.force[:, 4:].sum(axis=1) > load_share * weight)


def distance_budget(trace: Trace, load_share: float = 0.15, ground: float = 0.003) -> dict[str, float]:
    """Where a straight walk's forward distance comes from (ours; issue 25 asks whether walks that
    cover more than their plan do it by sliding soles or by the torso swaying beyond the plan).

    Along the world's x axis (a walk planned straight ahead from the start pose), from the trace's
    first tick to its last (or the fall), each sole's displacement per tick is put in one of three
    parts: a **slide** when the sole is loaded at both ends of the tick (its four sensors carrying
    more than ``load_share`` of the standing weight: :func:`loaded_soles`); a
    **skid** when it is not, but stays within ``ground`` [m] of its lowest height (a foot dragged
    or sliding on the surface as it lands or lifts); **air** otherwise (where the foot was carried
    and put down). Half the sum over both feet is exactly the feet's midpoint displacement, and the
    torso's is that plus the **sway** (the torso's move relative to the feet's midpoint, which does
    not grow with the walk). Returns metres: ``torso_m``, ``feet_m``, ``slide_m``, ``skid_m``,
    ``air_m``, ``sway_m`` (``feet_m = slide_m + skid_m + air_m``, ``torso_m = feet_m + sway_m``)."""
    keys = ("torso_m", "feet_m", "slide_m", "skid_m", "air_m", "sway_m")
    if len(trace.t) < 2:
        return dict.fromkeys(keys, 0.0)
    parts = dict.fromkeys(("slide_m", "skid_m", "air_m"), 0.0)
    for p, loaded in zip((trace.p_sole_l, trace.p_sole_r), loaded_soles(trace, load_share)):
        low = p[:, 2] < float(np.min(p[:, 2])) + ground
        both = loaded[:-1] & loaded[1:]
        skid = ~both & low[:-1] & low[1:]
        dx = np.diff(p[:, 0])
        parts["slide_m"] += 0.5 * float(dx[both].sum())
        parts["skid_m"] += 0.5 * float(dx[skid].sum())
        parts["air_m"] += 0.5 * float(dx[~both & ~skid].sum())
    torso = float(trace.p_torso[-1, 0] - trace.p_torso[0, 0])
    feet = sum(parts.values())
    return {"torso_m": torso, "feet_m": feet, **parts, "sway_m": torso - feet}
