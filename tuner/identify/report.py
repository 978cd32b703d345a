"""What an identification writes: the robot map with its servos identified, the overlay alone, the
fit's numbers (JSON) and a one-screen summary; each names the recordings, the fit's residuals and
the commit of the tool that made it.

The map (``robot.yaml``) is the team's own map with its ``servo:`` section extended by the fitted
groups (hips, knees, ankles, arms, head) or joints (our names), absolute values in SI, and its file
paths rewritten relative to the output folder: pass it as ``--robot`` to any verb. A parameter the
recordings could not tell keeps the map's value and is not written.
"""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from gaits.files import write_files_atomic

from .servos import SCALED, ServoFit
from ..report.tables import json_finite
from ..report.provenance import commit_of

__all__ = ["servo_overlay", "write_servo_fit", "summary_lines", "fit_json", "write_ground_fit", "ground_lines",
           "sysid_html"]


def sysid_html(title: str, sysid: dict) -> str:
    """``mujoco.sysid``'s own HTML report of a fit: its automated insights, the parameter table
    (initial and fitted, with bounds), the parameters' distributions with their 95 % intervals,
    and the covariance and correlation (its sections; the signal and video sections need its own
    rollout, which ours replaces)."""
    from mujoco.sysid.report.builder import ReportBuilder
    from mujoco.sysid.report.sections.covariance import Covariance
    from mujoco.sysid.report.sections.insights import AutomatedInsights
    from mujoco.sysid.report.sections.parameter_distribution import ParameterDistribution
    from mujoco.sysid.report.sections.parameters import ParametersTable
    initial, fitted = sysid["initial"], sysid["fitted"]
    for p in list(fitted.keys()):         # the parameters fitted (a second stage may have freed some)
        initial[p].frozen = fitted[p].frozen
    rb = ReportBuilder(title)
    rb.add_section(AutomatedInsights("Automated Insights", fitted))
    rb.add_section(ParametersTable("Parameters", fitted, initial, anchor="Parameters"))
    rb.add_section(ParameterDistribution(title="Parameter Distribution", opt_params=fitted, initial_params=initial,
                                         confidence_intervals=np.asarray(sysid["half"]), anchor="param_dist"))
    rb.add_section(Covariance(title="Covariance and Correlation", anchor="cov", covariance=np.asarray(sysid["cov"]),
                              parameter_dict=fitted))
    return rb.build()

_FIELDS = ("kp", "damping", "armature", "frictionloss", "torque", "speed", "backlash")
#: a dc-motor servo's map fields each fitted piece moves (the stall torque and back-EMF fix kt and R,
#: which the P register then follows so the gain stays the fitted one)
_MOTOR_FIELDS = {"kp": ("p_gain",), "torque": ("kt", "resistance", "p_gain"), "back_emf": ("kt", "resistance", "p_gain"),
                 "damping": ("damping",), "armature": ("armature",), "frictionloss": ("frictionloss",),
                 "backlash": ("backlash",)}


def _kept(fit: ServoFit, key: str) -> bool:
    return fit.identifiable.get(key, False) or key in fit.loose or key in fit.at_least


def servo_overlay(fit: ServoFit, laws: Mapping[str, Any] | None = None) -> dict[str, dict[str, float]]:
    """The map's ``servo:`` entries the fit sets: per fitted unit (group or joint) the fields it
    identified (a unit whose joints differ in a field gets that field per joint), and the latency.
    ``laws`` (our joint name -> the servo the map gave it): a dc-motor servo's fitted pieces are
    written as its own fields (``MotorServo.with_pieces``: p_gain, kt, resistance, damping,
    frictionloss, armature), a pd servo's as they are."""
    from ..servos import MotorServo
    from .servos import group_of
    units: dict[str, list[int]] = {}
    for i, j in enumerate(fit.joints):
        units.setdefault(group_of(j) if fit.by == "groups" else j, []).append(i)
    out: dict[str, dict[str, float]] = {}

    def put(u: str, idx: list[int], f: str, vals: np.ndarray) -> None:
        if np.allclose(vals, vals[0], rtol=1e-9, atol=0):
            out.setdefault(u, {})[f] = float(f"{vals[0]:.6g}")
        else:
            for i, v in zip(idx, vals):
                out.setdefault(fit.joints[i], {})[f] = float(f"{v:.6g}")

    s = fit.servos
    for u, idx in units.items():
        motors = laws is not None and all(isinstance(laws.get(fit.joints[i]), MotorServo) for i in idx)
        if motors:
            moved = [k for k in _MOTOR_FIELDS if _kept(fit, f"{u}.{k}")]
            fields = list(dict.fromkeys(f for k in moved for f in _MOTOR_FIELDS[k]))
            if fields:
                new = []
                for i in idx:
                    law = laws[fit.joints[i]]
                    new.append(law.with_pieces(
                        kp=float(s.kp[i]), torque=float(s.torque[i]), back_emf=float(s.back_emf[i]),
                        damping=float(s.damping[i]), frictionloss=float(s.frictionloss[i]),
                        armature=float(s.armature[i])).replace(backlash=float(s.backlash[i])))
                for f in fields:
                    put(u, idx, f, np.array([getattr(x, f) for x in new]))
        else:
            for f in _FIELDS:
                if _kept(fit, f"{u}.{f}"):
                    put(u, idx, f, np.asarray(getattr(s, f))[idx])
        if fit.identifiable.get("latency", False):
            out.setdefault(u, {})["latency"] = float(f"{fit.servos.latency:.6g}")
    return out


def fit_json(fit: ServoFit) -> dict[str, Any]:
    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None
    return {"by": fit.by, "joints": list(fit.joints), "recordings": fit.recordings,
            "parameters": {k: {"value": fit.values[k], "interval95": num(fit.intervals[k]),
                               "unit": "mrad" if k.endswith(".backlash") else "ticks" if k == "latency"
                               else "factor of the map's",
                               "fitted": k in fit.fitted, "identifiable": fit.identifiable[k],
                               "loose": k in fit.loose, "at_least": k in fit.at_least,
                               "on_bound": k in fit.on_bound} for k in fit.values},
            "rms_before_rad": fit.rms_before, "rms_after_rad": fit.rms_after,
            "entangled": fit.entangled, "rollouts": fit.rollouts, "seconds": round(fit.seconds, 1), "iterations": fit.iterations}


def summary_lines(fit: ServoFit, noise: float) -> list[str]:
    b = np.sqrt(np.mean(np.square(list(fit.rms_before.values()))))
    a = np.sqrt(np.mean(np.square(list(fit.rms_after.values()))))
    lines = [f"servos identified by {fit.by} from {len(fit.recordings)} recording(s): joint angle residual RMS "
             f"{b * 1000:.2f} -> {a * 1000:.2f} mrad ({a / noise:.2f}x the {noise * 1000:g} mrad sensor noise); "
             f"{fit.rollouts} rollouts, {fit.seconds:.0f} s"]
    units = list(dict.fromkeys(k.rsplit(".", 1)[0] for k in fit.values if k != "latency"))
    head = f"  {'':8s}" + "".join(f"{f:>16s}" for f in SCALED + ("backlash",))
    lines.append(head + "   (factor of the map's +- 95 %; backlash mrad; ~ loose; - not identifiable; (map) not fitted)")
    for u in units:
        cells = []
        for f in SCALED + ("backlash",):
            k = f"{u}.{f}"
            if k not in fit.fitted:
                cells.append(f"{'(map)':>16s}")
            elif not fit.identifiable[k] and k not in fit.loose:
                cells.append(f"{'-':>16s}")
            elif k in fit.loose:
                cells.append(f"{fit.values[k]:>8.3g}~+-{fit.intervals[k]:<5.2g}")
            else:
                cells.append(f"{fit.values[k]:>9.3g} +-{fit.intervals[k]:<5.2g}")
        lines.append(f"  {u:8s}" + "".join(cells))
    lat = "latency " + (f"{fit.values['latency']:.2f} ticks +- {fit.intervals['latency']:.2g}"
                        if fit.identifiable["latency"] else "not identifiable" if "latency" in fit.fitted
                        else "not fitted (none)")
    lines.append("  " + lat)
    worst = sorted(fit.rms_after.items(), key=lambda kv: -kv[1])[:3]
    lines.append("  largest residuals after: " + ", ".join(f"{j} {v * 1000:.2f} mrad" for j, v in worst))
    for group in fit.entangled:
        lines.append(f"  estimates that move together (correlation past 0.995; each +- says how well it is fixed "
                     f"alone): {', '.join(group)}")
    if fit.loose:
        lines.append(f"  ~ fixed only loosely (95 % interval over 10 %; kept as fitted, their combination is what "
                     f"the recordings fix): {', '.join(fit.loose)}")
    if fit.at_least:
        lines.append(f"  at least (the fit raised it until it stopped binding; the map's lower value would bind "
                     f"and misfit, so the fitted one is kept): {', '.join(fit.at_least)}")
    if fit.on_bound:
        lines.append(f"  ended on its bound (the recordings want it beyond the fit's range, 0.2-5x the map's): "
                     f"{', '.join(fit.on_bound)}")
    flat = [k for k in fit.not_identifiable if k not in fit.loose and k not in fit.at_least]
    if flat:
        lines.append(f"  not identifiable from these recordings (the map's value kept): {', '.join(flat)}")
    return lines


def write_servo_fit(fit: ServoFit, robot_map: Path | None, out_dir: Path, noise: float,
                    laws: Mapping[str, Any] | None = None) -> list[Path]:
    """Write ``robot.yaml`` (when the robot came from a map), ``servos.yaml``, ``fit.json`` and
    ``report.txt`` into ``out_dir``, all or none."""
    import tuner
    commit = commit_of(tuner.__file__).strip(" ()") or "unknown commit"
    overlay = servo_overlay(fit, laws)
    a = np.sqrt(np.mean(np.square(list(fit.rms_after.values()))))
    header = (f"# servos identified by gait-tuner identify servos ({commit})\n"
              f"# from: {', '.join(fit.recordings)}\n"
              f"# joint angle residual RMS after the fit: {a * 1000:.3f} mrad; per joint in fit.json\n")
    files: dict[Path, str] = {}
    files[out_dir / "servos.yaml"] = header + yaml.safe_dump({"servo": overlay}, sort_keys=False)
    if robot_map is not None:
        from ..robots.robot_map import map_with_servo
        doc = map_with_servo(robot_map, out_dir, overlay)
        files[out_dir / "robot.yaml"] = header + yaml.safe_dump(doc, sort_keys=False)
    files[out_dir / "fit.json"] = json.dumps(fit_json(fit), indent=1, allow_nan=False) + "\n"
    files[out_dir / "report.txt"] = "\n".join(summary_lines(fit, noise)) + "\n"
    if fit.sysid:
        files[out_dir / "report.html"] = sysid_html(f"gait-tuner identify servos ({commit})", fit.sysid)
    out_dir.mkdir(parents=True, exist_ok=True)
    return write_files_atomic(files)


def ground_lines(fit: Any) -> list[str]:
    """The one-screen summary of a ground identification."""
    b = fit.rms_before
    a = fit.rms_after
    lines = [f"ground identified on {fit.start.name} from {len(fit.recordings)} recording(s): residual RMS in sensor "
             f"noises, before -> after: " + ", ".join(f"{k} {b[k]:.2f} -> {a[k]:.2f}" for k in a)
             + f"; {fit.rollouts} replays, {fit.seconds:.0f} s"]
    for f, v in fit.values.items():
        start = getattr(fit.start, f)
        if fit.identifiable[f]:
            lines.append(f"  {f:16s} {start:10.4g} -> {getattr(fit.surface, f):10.4g}   (x {v:.3f} +- {fit.intervals[f]:.2g})")
        else:
            lines.append(f"  {f:16s} {start:10.4g}    kept: the recordings cannot tell it (x {v:.3f} +- "
                         f"{fit.intervals[f]:.2g}){f' (a loaded sole slips {fit.slips} tick(s) in them)' if f == 'friction' else ''}")
    for group in fit.entangled:
        lines.append(f"  cannot be told apart (estimates correlated past 0.995): {', '.join(group)}")
    rec, bef, aft = fit.stats["recorded"], fit.stats["before"], fit.stats["after"]
    lines.append(f"  {'':20s}{'recorded':>10s}{'before':>10s}{'after':>10s}")
    for k in rec:
        lines.append(f"  {k:20s}{rec[k]:10.3f}{bef.get(k, math.nan):10.3f}{aft.get(k, math.nan):10.3f}")
    return lines


def write_ground_fit(fit: Any, out_dir: Path) -> list[Path]:
    """Write ``surface.yaml`` (the fitted surface: pass it as ``--surface``), ``fit.json`` and
    ``report.txt`` into ``out_dir``, all or none."""
    import tuner

    from ..report.calibration import surface_yaml
    commit = commit_of(tuner.__file__).strip(" ()") or "unknown commit"
    a = fit.rms_after
    header = (f"{fit.surface.name}: {fit.start.name} with its ground identified by gait-tuner identify ground "
              f"({commit})\nfrom: {', '.join(fit.recordings)}\nresidual RMS after the fit, in sensor noises: "
              + ", ".join(f"{k} {v:.2f}" for k, v in a.items())
              + ("\nnot identifiable (kept as on " + fit.start.name + "): " + ", ".join(fit.not_identifiable)
                 if fit.not_identifiable else ""))
    surface = dataclasses.replace(fit.surface, description=f"identified from {len(fit.recordings)} recording(s) "
                                                           f"({commit}); see fit.json")
    doc = {"surface": fit.surface.name, "start": fit.start.name, "recordings": fit.recordings,
           "parameters": {f: {"factor": v, "interval95": (fit.intervals[f] if math.isfinite(fit.intervals[f]) else None),
                              "start": getattr(fit.start, f), "fitted": getattr(fit.surface, f),
                              "identifiable": fit.identifiable[f]} for f, v in fit.values.items()},
           "entangled": fit.entangled, "rms_before": fit.rms_before, "rms_after": fit.rms_after,
           "statistics": fit.stats, "slip_ticks": fit.slips, "replays": fit.rollouts, "seconds": round(fit.seconds, 1)}
    files = {out_dir / "surface.yaml": surface_yaml(surface, header),
             out_dir / "fit.json": json.dumps(json_finite(doc), indent=1, allow_nan=False) + "\n",
             out_dir / "report.txt": "\n".join(ground_lines(fit)) + "\n"}
    if fit.sysid:
        files[out_dir / "report.html"] = sysid_html(f"gait-tuner identify ground ({commit})", fit.sysid)
    out_dir.mkdir(parents=True, exist_ok=True)
    return write_files_atomic(files)
