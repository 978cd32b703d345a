"""A robot map's URDF, made into the MJCF the rest of the tool reads (the URDF border's adapter).

ROS teams describe their robots as URDF. MuJoCo's own URDF import fuses every body hung on a
fixed joint into its parent (and the root link into the world), and gives the robot no free
joint; here, on the other hand (our choices, each said by ``robot check``):

* bodies joined by fixed joints stay bodies of their own (MuJoCo's ``fusestatic`` off), so a map
  can name a sole, a cleat or the torso frame; the map's torso gets the free joint: the URDF's
  root link, or a link fixed to it (ROS's ``base_link`` pattern: the fixed joints between them are
  turned round, parent and child swapped and the origin inverted, so the torso becomes the root);
* the collision geometry is the URDF's ``<collision>`` elements (meshes, boxes, cylinders,
  spheres), as MuJoCo imports them; ``<visual>`` elements are left out (the simulation and the
  videos show the collision geometry), so a missing visual mesh is a note, a missing collision
  mesh one line naming the link and the file;
* mesh paths: ``package://NAME/rest`` resolves through the map's ``packages: {NAME: folder}``
  (relative to the map file), else through a folder called NAME (or holding a ``package.xml``
  naming NAME) beside the URDF or above it, as a ROS workspace is laid out; ``package:///FILE``
  (no name, as onshape-to-robot exports) is the URDF's folder; ``file://`` and plain paths are
  the file system's (plain ones relative to the URDF);
* a ``continuous`` joint (no limits) needs a range in the map (``ranges: {JOINT: [low, high]}``
  [rad]); a ``<mimic>`` joint is refused by name (our servos drive joints one by one);
* servo limits: ``<limit effort velocity>`` [N m, rad/s] of each joint, used where the map's
  ``servo:`` section does not set the field (``robot_map._servos``);
* an inertia MuJoCo refuses (principal moments A + B < C, which no rigid body has: Darwin-OP's
  public URDF has one at its neck) is one line naming the link, unless the map says
  ``balance_inertia: true`` (MuJoCo's ``balanceinertia``: the moments are raised until they hold);
  either way ``robot check`` names the links (:func:`unbalanced_bodies`).

Nothing here runs physics; errors are :class:`tuner.errors.UserError`, one line.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import mujoco
import numpy as np

from gaits import did_you_mean
from gaits.files import MAX_BYTES, read_bytes_checked

from ..errors import UserError

__all__ = ["UrdfRobot", "urdf_to_mjcf", "resolve_package", "unbalanced_bodies", "compile_checked"]

#: The compiler settings injected into the URDF before MuJoCo reads it (see the module docstring).
COMPILER = {"fusestatic": "false", "discardvisual": "true", "strippath": "false", "angle": "radian"}
#: The most links and collision meshes a robot file may have before MuJoCo is asked (ours: a kid-size
#: robot has 20-60 links; MuJoCo's arena runs out on some ten thousand).
MAX_LINKS = 1000
MAX_MESHES = 1000


@dataclass
class UrdfRobot:
    """What :func:`urdf_to_mjcf` gives: the MJCF text, each joint's ``<limit effort velocity>``
    (None where the URDF states none or zero) and what was changed, for ``robot check``."""

    xml: str
    effort: dict[str, float | None] = field(default_factory=dict)     # [N m]
    velocity: dict[str, float | None] = field(default_factory=dict)   # [rad/s]
    notes: list[str] = field(default_factory=list)


def _package_dirs(name: str, urdf: Path) -> list[Path]:
    """Folders that may be ROS package NAME: beside the URDF or above it, named NAME or holding a
    package.xml that names it."""
    out = []
    for d in [urdf.parent, *urdf.parent.parents][:6]:
        for cand in (d, d / name):
            if cand.name == name and cand.is_dir():
                out.append(cand)
            px = cand / "package.xml"
            if px.is_file():
                try:
                    text = px.read_text(errors="replace")
                except OSError:
                    continue
                if f"<name>{name}</name>" in text.replace(" ", ""):
                    out.append(cand)
    seen, uniq = set(), []
    for d in out:
        if d.resolve() not in seen:
            seen.add(d.resolve())
            uniq.append(d)
    return uniq


def resolve_package(uri: str, urdf: Path, packages: Mapping[str, Path]) -> tuple[Path | None, str]:
    """A mesh ``filename`` of ``urdf`` -> (path or None, where it was looked for)."""
    if uri.startswith("package://"):
        rest = uri[len("package://"):]
        name, _, sub = rest.partition("/")
        if name == "":                       # package:///FILE (as onshape-to-robot writes): beside the URDF
            p = urdf.parent / sub
            return (p if os.path.lexists(p) else None), "package:/// is read as the URDF's folder"
        if name in packages:
            p = packages[name] / sub
            return (p if os.path.lexists(p) else None), f"packages.{name} = {packages[name]}"
        dirs = _package_dirs(name, urdf)
        for d in dirs:
            if os.path.lexists(d / sub):
                return d / sub, str(d)
        return None, (f"no folder for package {name!r} beside or above the URDF (give packages: {{{name}: FOLDER}} "
                      f"in the map)" if not dirs else f"package {name!r} at {', '.join(map(str, dirs))}")
    if uri.startswith("file://"):
        p = Path(uri[len("file://"):])
        return (p if os.path.lexists(p) else None), "file:// path"
    p = Path(uri) if os.path.isabs(uri) else urdf.parent / uri
    return (p if os.path.lexists(p) else None), "relative to the URDF"


def unbalanced_bodies(spec: mujoco.MjSpec) -> list[tuple[str, np.ndarray]]:
    """Bodies of ``spec`` whose explicit inertia breaks the triangle inequality of principal moments
    (A + B >= C, as MuJoCo's compiler checks it): (name, sorted principal moments [kg m^2])."""
    out = []
    for b in spec.bodies:
        if not b.explicitinertial or b.mass <= 0:
            continue
        f = np.asarray(b.fullinertia, dtype=float)
        if np.isnan(f[0]):
            moments = np.sort(np.asarray(b.inertia, dtype=float))
        else:                                    # (ixx, iyy, izz, ixy, ixz, iyz)
            moments = np.linalg.eigvalsh(np.array([[f[0], f[3], f[4]], [f[3], f[1], f[5]], [f[4], f[5], f[2]]]))
        if moments[0] + moments[1] < moments[2] * (1 - 1e-9):
            out.append((b.name, moments))
    return out


def _moments(m: np.ndarray) -> str:
    return ", ".join(f"{v:.3g}" for v in m) + " kg m^2"


def compile_checked(spec: mujoco.MjSpec, *, balance_inertia: bool, kind: str, fname: str, source: str,
                    notes: list[str]) -> mujoco.MjModel:
    """Compile a robot file's spec: an inertia MuJoCo would refuse is one line naming the
    ``kind`` (link or body) unless ``balance_inertia`` (then a note names what was balanced); any
    other compiler error is one line with the element MuJoCo names."""
    bad = unbalanced_bodies(spec)
    if bad and not balance_inertia:
        name, m = bad[0]
        more = f" (and {len(bad) - 1} more: {', '.join(n for n, _ in bad[1:])})" if len(bad) > 1 else ""
        raise UserError(f"{source}: {kind} {name!r} of {fname} has an inertia no rigid body has: principal moments "
                        f"{_moments(m)}, A + B < C{more}; correct its <inertia>, or set balance_inertia: true in "
                        f"the map to let MuJoCo raise the moments until A + B >= C (its balanceinertia)")
    if balance_inertia:
        spec.compiler.balanceinertia = True
        notes.append("balance_inertia: " + ("; ".join(f"{kind} {n!r} balanced by MuJoCo (principal moments "
                                                     f"{_moments(m)} in the file, A + B < C)" for n, m in bad)
                                            if bad else "no inertia in the file needed balancing"))
    try:
        return spec.compile()
    except Exception as exc:  # mujoco raises ValueError with the compiler's message
        raise UserError(f"{source}: {fname} does not load in MuJoCo: {mujoco_message(exc)}") from None


def mujoco_message(exc: BaseException) -> str:
    """MuJoCo's error as one line: its first line, and the element it names if it names one."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    if not lines:
        return type(exc).__name__
    head = lines[0]
    element = next((ln for ln in lines[1:] if ln.startswith("Element name")), None)
    return f"{head} ({element})" if element else head


def _number(text: str | None, what: str, source: str) -> float | None:
    if text is None:
        return None
    try:
        v = float(text)
    except ValueError:
        raise UserError(f"{source}: {what} = {text!r}: not a number") from None
    if not math.isfinite(v):
        raise UserError(f"{source}: {what} = {text!r}: not a finite number")
    return v


def _triple(text: str, what: str, source: str) -> list[float]:
    """Three finite numbers of an attribute (one line naming it otherwise)."""
    parts = text.split()
    try:
        values = [float(v) for v in parts]
    except ValueError:
        raise UserError(f"{source}: {what} = {text!r}: not a number") from None
    if len(values) != 3 or not all(math.isfinite(v) for v in values):
        raise UserError(f"{source}: {what} = {text!r}: expected three finite numbers")
    return values


def _origin(j: ET.Element, source: str = "") -> tuple[np.ndarray, np.ndarray]:
    """A joint's ``<origin xyz rpy>`` as (R_parent_child (3, 3), p_parent_child (3,))."""
    o = j.find("origin")
    where = f"joint {j.get('name')!r} <origin>"
    xyz = _triple(o.get("xyz", "0 0 0") if o is not None else "0 0 0", f"{where} xyz", source)
    rpy = _triple(o.get("rpy", "0 0 0") if o is not None else "0 0 0", f"{where} rpy", source)
    from scipy.spatial.transform import Rotation       # here: scipy.spatial costs a second of every start
    return Rotation.from_euler("xyz", rpy).as_matrix(), np.array(xyz)


def _check_tree(root: ET.Element, source: str, name: str) -> None:
    """The URDF's links and joints make one tree of a sane size: no more than :data:`MAX_LINKS` links
    and :data:`MAX_MESHES` collision meshes, names unique, every joint naming a parent and a child
    that are links of the file, no link the child of two joints, no cycle, every joint's origin
    and limits numbers (a lower limit above the upper one named). One line for the first fault."""
    links = [ln.get("name") for ln in root.findall("link")]
    joints = root.findall("joint")
    meshes = len(root.findall("link/collision/geometry/mesh"))
    if len(links) > MAX_LINKS or meshes > MAX_MESHES:
        raise UserError(f"{source}: {name} has {len(links)} links and {meshes} collision meshes: more than the "
                        f"{MAX_LINKS} links and {MAX_MESHES} meshes a robot file may have here")
    for kind, names in (("link", links), ("joint", [j.get("name") for j in joints])):
        if None in names:
            raise UserError(f"{source}: a <{kind}> of {name} has no name")
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise UserError(f"{source}: {name} names more than one {kind} {dup[0]!r}")
    known = set(links)
    parent_of: dict[str, tuple[str, str]] = {}
    for j in joints:
        jname = j.get("name")
        ends = {}
        for end in ("parent", "child"):
            el = j.find(end)
            ends[end] = el.get("link") if el is not None else None
            if ends[end] is None:
                raise UserError(f"{source}: joint {jname!r} of {name} has no <{end} link=...>")
            if ends[end] not in known:
                raise UserError(f"{source}: joint {jname!r} of {name}: its {end} link {ends[end]!r} is not a link of "
                                f"the file{did_you_mean(ends[end], known)}")
        child = ends["child"]
        if child in parent_of:
            raise UserError(f"{source}: link {child!r} of {name} is the child of two joints, {parent_of[child][1]!r} "
                            f"and {jname!r}: a URDF robot is one tree")
        parent_of[child] = (ends["parent"], jname)
        _origin(j, source)
        lim = j.find("limit")
        if lim is not None and j.get("type") in ("revolute", "prismatic"):
            lo = _number(lim.get("lower"), f"joint {jname!r} <limit> lower", source)
            hi = _number(lim.get("upper"), f"joint {jname!r} <limit> upper", source)
            if lo is not None and hi is not None and lo > hi:
                raise UserError(f"{source}: joint {jname!r} of {name}: <limit> lower = {lo:g} is above upper = "
                                f"{hi:g} rad: swap them (an inverted range is not read as no range)")
    for start in links:                   # every walk up the tree ends at a root
        seen, link = [start], start
        while link in parent_of:
            link = parent_of[link][0]
            if link in seen:
                loop = seen[seen.index(link):] + [link]
                raise UserError(f"{source}: the links of {name} go round in a cycle: "
                                f"{' -> '.join(reversed(loop))} (each the parent of the next): a URDF robot is one "
                                f"tree")
            seen.append(link)


def _reroot(joints: list[ET.Element], root: str, torso: str, source: str, name: str) -> None:
    """Turn round the fixed joints from the URDF's root link down to ``torso``, so that ``torso``
    becomes the root (each joint's parent and child swapped, its origin inverted: T -> T^-1)."""
    parent_of = {j.find("child").get("link"): j for j in joints if j.find("child") is not None}
    path, link = [], torso
    while link != root:
        j = parent_of.get(link)
        if j is None:
            raise UserError(f"{source}: torso link {torso!r} does not hang from the root link {root!r} of {name}")
        if j.get("type") != "fixed":
            raise UserError(f"{source}: torso link {torso!r} hangs from the root link {root!r} of {name} through "
                            f"the {j.get('type')} joint {j.get('name')!r}: name the root link (or a link fixed to "
                            f"it) as the torso")
        path.append(j)
        link = j.find("parent").get("link")
    for j in path:
        R, p = _origin(j, source)
        Ri = R.T
        pi = -Ri @ p
        o = j.find("origin")
        if o is None:
            o = ET.SubElement(j, "origin")
        o.set("xyz", " ".join(repr(float(v)) for v in pi))
        from scipy.spatial.transform import Rotation
        o.set("rpy", " ".join(repr(float(v)) for v in Rotation.from_matrix(Ri).as_euler("xyz")))
        par, chi = j.find("parent"), j.find("child")
        a, b = par.get("link"), chi.get("link")
        par.set("link", b)
        chi.set("link", a)


def urdf_to_mjcf(path: Path, raw: bytes, *, torso: str, packages: Mapping[str, Path],
                 ranges: Mapping[str, tuple[float, float]], source: str,
                 balance_inertia: bool = False) -> UrdfRobot:
    """Read the URDF text ``raw`` (of ``path``) into MJCF (module docstring)."""
    name = path.name
    try:
        root = ET.fromstring(raw)
    except ET.ParseError as exc:
        raise UserError(f"{source}: {name} is not well-formed XML: {exc}") from None
    if root.tag != "robot":
        raise UserError(f"{source}: {name}: expected a URDF (<robot> at the top), found <{root.tag}>")
    _check_tree(root, source, name)
    out = UrdfRobot(xml="")
    links = {ln.get("name") for ln in root.findall("link")}
    joints = root.findall("joint")
    for r in ranges:
        if r not in {j.get("name") for j in joints}:
            raise UserError(f"{source}: ranges: {r!r} is not a joint of {name}")
    children = set()
    for j in joints:
        jname, jtype = j.get("name"), j.get("type")
        children.add((j.find("child").get("link") if j.find("child") is not None else None))
        if j.find("mimic") is not None:
            raise UserError(f"{source}: joint {jname!r} of {name} mimics {j.find('mimic').get('joint')!r}: mimic "
                            f"joints are not supported (each joint gets its own servo); make it a revolute "
                            f"joint of its own or fix it")
        if jtype in ("floating", "planar", "prismatic"):
            raise UserError(f"{source}: joint {jname!r} of {name} is {jtype}: only revolute, continuous and "
                            f"fixed joints are supported (the robot's free joint is added at its torso)")
        lim = j.find("limit")
        if jtype == "continuous":
            if jname not in ranges:
                raise UserError(f"{source}: joint {jname!r} of {name} is continuous (no limits): give it a range "
                                f"in the map, ranges: {{{jname}: [LOW, HIGH]}} [rad]")
            j.set("type", "revolute")
        if jname in ranges:
            if lim is None:
                lim = ET.SubElement(j, "limit")
            lo, hi = ranges[jname]
            lim.set("lower", repr(float(lo)))
            lim.set("upper", repr(float(hi)))
            out.notes.append(f"{'continuous ' if jtype == 'continuous' else ''}joint {jname!r}: range "
                             f"[{lo:g}, {hi:g}] rad from the map" + ("" if jtype == "continuous" else
                                                                    " (over the URDF's)"))
        if jtype in ("revolute", "continuous"):
            where = f"joint {jname!r} <limit>"
            effort = _number(lim.get("effort") if lim is not None else None, f"{where} effort", source)
            velocity = _number(lim.get("velocity") if lim is not None else None, f"{where} velocity", source)
            out.effort[jname] = effort if effort is not None and effort > 0 else None
            out.velocity[jname] = velocity if velocity is not None and velocity > 0 else None
    roots = sorted(links - children - {None})
    if torso not in links:
        raise UserError(f"{source}: torso link {torso!r} not in {name} (its root link: "
                        f"{', '.join(map(repr, roots)) or 'none'})")
    if len(roots) != 1:
        raise UserError(f"{source}: {name} has {len(roots)} root links ({', '.join(map(repr, roots))}); a URDF "
                        f"robot is one tree")
    if roots != [torso]:
        _reroot(joints, roots[0], torso, source, name)
        out.notes.append(f"the URDF's root link {roots[0]!r} hangs from the torso {torso!r} (its fixed joints "
                         f"turned round), so that the torso carries the free joint")
    missing_visual = 0
    for link in root.findall("link"):
        for kind in ("visual", "collision"):
            for el in link.findall(kind):
                mesh = el.find("geometry/mesh")
                if mesh is None:
                    continue
                uri = mesh.get("filename", "")
                found, where = resolve_package(uri, path, packages)
                if kind == "visual":
                    missing_visual += found is None
                    continue
                if found is None:
                    raise UserError(f"{source}: link {link.get('name')!r}: collision mesh {uri!r} not found "
                                    f"({where})")
                try:
                    read_bytes_checked(found, "mesh", MAX_BYTES["mesh"], UserError)
                except UserError as exc:
                    raise UserError(f"{source}: link {link.get('name')!r}: collision mesh {uri!r}: {exc}") from None
                mesh.set("filename", str(found.resolve()))
        for el in link.findall("visual"):
            link.remove(el)
    out.notes.append("the URDF's <visual> elements are left out: the simulation and the videos show its "
                     "<collision> geometry" + (f" ({missing_visual} visual mesh(es) not found, so no loss)"
                                               if missing_visual else ""))
    for old in root.findall("mujoco"):
        root.remove(old)
    ext = ET.Element("mujoco")
    ET.SubElement(ext, "compiler", COMPILER)
    root.insert(0, ext)
    text = ET.tostring(root, encoding="unicode")
    try:
        spec = mujoco.MjSpec.from_string(text)
        spec.body(torso).add_freejoint()
    except Exception as exc:  # mujoco raises ValueError with the parser's message
        raise UserError(f"{source}: {name} does not load in MuJoCo: {mujoco_message(exc)}") from None
    compile_checked(spec, balance_inertia=balance_inertia, kind="link", fname=name, source=source, notes=out.notes)
    out.xml = spec.to_xml()
    return out
