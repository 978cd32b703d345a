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

from gaits.files import write_files_atomic, make_folder

from ..servos.motor import FRICTION_MAGIC
from .servos import EXTENDED, SCALED, ServoFit, unit_of
from ..report.tables import json_finite
from ..report.provenance import commit_of

__all__ = ["servo_overlay", "write_servo_fit", "summary_lines", "fit_json", "write_ground_fit", "ground_lines",
           "sysid_html", "walk_fit_json", "walk_fit_lines", "write_walk_servo_fit"]


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
                 "backlash": ("backlash",),
                 "stribeck": ("friction_model", "stribeck", "stribeck_speed", "stribeck_alpha"),
                 "stribeck_speed": ("friction_model", "stribeck", "stribeck_speed", "stribeck_alpha"),
                 "load_motor": ("friction_model", "load_motor")}


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

    def put(u: str, idx: list[int], f: str, vals: list) -> None:
        def value(v):
            return v if isinstance(v, str) else float(f"{v:.6g}")
        if all(v == vals[0] if isinstance(v, str) else math.isclose(v, vals[0], rel_tol=1e-9, abs_tol=0.0)
               for v in vals):
            out.setdefault(u, {})[f] = value(vals[0])
        else:
            for i, v in zip(idx, vals):
                out.setdefault(fit.joints[i], {})[f] = value(v)

    s = fit.servos
    for u, idx in units.items():
        motors = laws is not None and all(isinstance(laws.get(fit.joints[i]), MotorServo) for i in idx)
        if motors:
            moved = [k for k in _MOTOR_FIELDS if _kept(fit, f"{u}.{k}")]
            # an extended friction that came out as none (no Stribeck, no load term) is the plain form
            extended = any(k in EXTENDED for k in moved) and any(
                fit.values.get(f"{u}.{k}", 0.0) > 1e-9 and _kept(fit, f"{u}.{k}") for k in ("stribeck", "load_motor"))
            if not extended:
                moved = [k for k in moved if k not in EXTENDED]
            fields = list(dict.fromkeys(f for k in moved for f in _MOTOR_FIELDS[k]))
            if fields:
                new = []
                for i in idx:
                    law = laws[fit.joints[i]]
                    servo = law.with_pieces(
                        kp=float(s.kp[i]), torque=float(s.torque[i]), back_emf=float(s.back_emf[i]),
                        damping=float(s.damping[i]), frictionloss=float(s.frictionloss[i]),
                        armature=float(s.armature[i])).replace(backlash=float(s.backlash[i]))
                    if extended and s.friction[i, 0] == FRICTION_MAGIC:
                        servo = servo.with_friction_term(s.terms()[i])
                    new.append(servo)
                for f in fields:
                    put(u, idx, f, [getattr(x, f) for x in new])
        else:
            for f in _FIELDS:
                if _kept(fit, f"{u}.{f}"):
                    put(u, idx, f, list(np.asarray(getattr(s, f))[idx]))
        if fit.identifiable.get("latency", False):
            out.setdefault(u, {})["latency"] = float(f"{fit.servos.latency:.6g}")
    return out


def fit_json(fit: ServoFit) -> dict[str, Any]:
    def num(x: float) -> float | None:
        return float(x) if math.isfinite(x) else None
    return {"by": fit.by, "joints": list(fit.joints), "recordings": fit.recordings,
            "parameters": {k: {"value": fit.values[k], "interval95": num(fit.intervals[k]),
                               "unit": "factor of the map's" if unit_of(k) == "x" else unit_of(k),
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
    columns = SCALED + ("backlash",) + tuple(f for f in EXTENDED if any(k.endswith("." + f) for k in fit.fitted))
    head = f"  {'':8s}" + "".join(f"{f:>16s}" for f in columns)
    lines.append(head + "   (factor of the map's +- 95 %; backlash mrad; " +
                 "".join(f"{f} {EXTENDED[f][0]}; " for f in columns if f in EXTENDED) +
                 "~ loose; - not identifiable; (map) not fitted)")
    for u in units:
        cells = []
        for f in columns:
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
        lines.append(f"  ended on its bound (the recordings want it beyond the fit's range: 0.2-5x the map's, an "
                     f"extended friction's own range, fit.json): "
                     f"{', '.join(fit.on_bound)}")
    flat = [k for k in fit.not_identifiable if k not in fit.loose and k not in fit.at_least]
    if flat:
        lines.append(f"  not identifiable from these recordings (the map's value kept): {', '.join(flat)}")
    return lines


def write_servo_fit(fit: ServoFit, robot_map: Path | None, out_dir: Path, noise: float,
                    laws: Mapping[str, Any] | None = None) -> list[Path]:
    """Write ``robot.yaml`` (when the robot came from a map), ``servos.yaml``, ``fit.json`` and
    ``report.txt`` into ``out_dir``, all or none."""
    a = np.sqrt(np.mean(np.square(list(fit.rms_after.values()))))
    files, commit = _servo_files(servo_overlay(fit, laws), fit.recordings,
                                 f"joint angle residual RMS after the fit: {a * 1000:.3f} mrad; per joint in fit.json",
                                 robot_map, out_dir)
    files[out_dir / "fit.json"] = json.dumps(fit_json(fit), indent=1, allow_nan=False) + "\n"
    files[out_dir / "report.txt"] = "\n".join(summary_lines(fit, noise)) + "\n"
    if fit.sysid:
        files[out_dir / "report.html"] = sysid_html(f"gait-tuner identify servos ({commit})", fit.sysid)
    make_folder(out_dir)
    return write_files_atomic(files)


def _servo_files(overlay: Mapping[str, Any], recordings: list[str], residual: str, robot_map: Path | None,
                 out_dir: Path) -> tuple[dict[Path, str], str]:
    """``servos.yaml`` and (from a map) ``robot.yaml`` of an identification's servo overlay, each
    with a header naming the tool's commit, the recordings and the residual; and the commit."""
    import tuner
    commit = commit_of(tuner.__file__).strip(" ()") or "unknown commit"
    header = (f"# servos identified by gait-tuner identify servos ({commit})\n"
              f"# from: {', '.join(recordings)}\n# {residual}\n")
    files: dict[Path, str] = {out_dir / "servos.yaml": header + yaml.safe_dump({"servo": dict(overlay)}, sort_keys=False)}
    if robot_map is not None:
        from ..robots.robot_map import map_with_servo
        doc = map_with_servo(robot_map, out_dir, overlay)
        files[out_dir / "robot.yaml"] = header + yaml.safe_dump(doc, sort_keys=False)
    return files, commit


def walk_fit_json(fit: Any) -> dict[str, Any]:
    """A walk's servo fit (``identify servos`` on walking recordings) as ``--json`` gives it."""
    from .walk_servos import NOT_FROM_A_WALK
    return {"from": "walks", "recordings": fit.recordings,
            "parameters": {k: {"value": v, "interval95": fit.intervals[k] if math.isfinite(fit.intervals[k]) else None,
                               "unit": "factor of the map's", "identifiable": fit.identifiable[k]}
                           for k, v in fit.values.items()},
            "latency": {"ticks": fit.latency_ticks, "identifiable": fit.latency_identified,
                        "misfit": {str(k): v for k, v in fit.latency_misfit.items()}},
            "not_from_a_walk": list(NOT_FROM_A_WALK), "entangled": fit.entangled,
            "rms_before": fit.rms_before, "rms_after": fit.rms_after, "horizon_s": fit.horizon,
            "replays": fit.rollouts, "seconds": round(fit.seconds, 1)}


def walk_fit_lines(fit: Any, dt: float) -> list[str]:
    """The one-screen summary of a walk's servo fit."""
    from .walk_servos import NOT_FROM_A_WALK
    b, a = fit.rms_before, fit.rms_after
    lines = [f"servos identified from {len(fit.recordings)} walk(s), each replayed over its first {fit.horizon:g} s: "
             f"residual RMS in sensor noises, before -> after: "
             + ", ".join(f"{k} {b[k]:.2f} -> {a[k]:.2f}" for k in a) + f"; {fit.rollouts} replays, {fit.seconds:.0f} s"]
    for k, v in fit.values.items():
        state = "" if fit.identifiable[k] else "   not identifiable from these walks (the map's kept)"
        lines.append(f"  {k:12s} x {v:.3f} +- {fit.intervals[k]:.2g}{state}")
    lat = " ".join(f"{k}:{v:.3g}" for k, v in fit.latency_misfit.items())
    lines.append(f"  latency      {fit.latency_ticks} tick(s) = {fit.latency_ticks * dt * 1000:g} ms "
                 + ("" if fit.latency_identified else "(not identifiable: other counts fit within the 95 % band; "
                    "the map's kept) ") + f"(misfit per count: {lat})")
    for group in fit.entangled:
        lines.append(f"  estimates that move together (correlation past 0.995): {', '.join(group)}")
    lines.append(f"  a walk cannot tell (the map's kept; fit them on a sweep hanging, gait-tuner excite): "
                 f"{', '.join(NOT_FROM_A_WALK)}")
    return lines


def write_walk_servo_fit(fit: Any, robot: Any, out_dir: Path) -> list[Path]:
    """Write a walk's servo fit: ``servos.yaml``, ``robot.yaml`` (from a map), ``fit.json`` and
    ``report.txt`` into ``out_dir``, all or none."""
    from .walk_servos import walk_servo_overlay
    robot_map = None if robot.map_path is None else Path(robot.map_path)
    residual = "residual RMS after the fit, in sensor noises: " + ", ".join(f"{k} {v:.2f}" for k, v in fit.rms_after.items())
    files, _ = _servo_files(walk_servo_overlay(fit, robot), fit.recordings, residual, robot_map, out_dir)
    files[out_dir / "fit.json"] = json.dumps(walk_fit_json(fit), indent=1, allow_nan=False) + "\n"
    files[out_dir / "report.txt"] = "\n".join(walk_fit_lines(fit, robot.sim.control_period)) + "\n"
    make_folder(out_dir)
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
    make_folder(out_dir)
    return write_files_atomic(files)
