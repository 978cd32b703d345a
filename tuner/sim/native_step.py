"""What runs inside every physics step that MuJoCo has no element for, as a native MuJoCo callback
(ours): ``native_step.c``, compiled once. Two parts, each a no-op on a model that does not ask:

* **the servos' extended friction** (``tuner/servos/motor.py``, BAM's m2 to m6): a dry-friction
  budget that follows the joint's speed and load, set as the joint's friction-loss bound every
  step. MuJoCo's friction loss is a model constant; the budget is read from the servo actuator's
  user numbers (``scene`` writes them) and written into the step's constraint row. Without the
  callback such a robot is refused (:func:`require`), not walked with the wrong friction;
* **the grass drag dampers' gate**: on a contact-layer grass each sole corner's drag dampers are
  switched on while the corner is in the blades (``ground.layer.drag_gate``). The tick loop did it in
  Python between control ticks, which kept every grass walk out of MuJoCo's native rollout (1.15x
  its cost). MuJoCo has no native element that gates a damper along x by a height along z. The
  gate reads its numbers from the last :data:`BLOCK` entries of ``mjData.userdata`` (the
  simulator's models add them) and does nothing unless a walk armed them.

This module compiles the C file with the machine's C compiler into a user cache, loads it with
ctypes and installs it as MuJoCo's control callback (``mjcb_control``), which MuJoCo calls inside
every physics step, in ``mj_step`` and in ``mujoco.rollout`` alike. The gate computes the loop's
gate to the bit (the same comparisons and one division, from the same corner heights at the same
instants; tested against the contact layer's Python tick, ``ground/layer.py``, walk by walk); the friction budget is
``motor.friction_budget``'s arithmetic (tested equal). Without a compiler (or with
``GAIT_TUNER_NATIVE_STEP=0``, or when another callback is installed) :func:`install` returns False
and the simulator keeps the Python gate: the same walks, slower.

The compiled library is cached under ``$XDG_CACHE_HOME/gait-tuner`` (default ``~/.cache``) by a
hash of the source and the MuJoCo version (the struct layout it reads), written to a temporary
name and renamed, so concurrent workers never load a half-written file.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import threading
from pathlib import Path

import mujoco
import numpy as np

from ..servos.motor import FRICTION_MAGIC, FRICTION_WIDTH

__all__ = ["BLOCK", "MAGIC", "install", "status", "arm", "disarm", "require", "budget"]

SOURCE = Path(__file__).with_name("native_step.c")
#: The layout of the drag gate's block (mirrors ``native_step.c``).
ARMED, HEIGHT, DEPTH, NSTEP, STEP0, FIRST, NPOINT, HEAD = range(8)
MAXPOINT = 16
BLOCK = HEAD + 2 * MAXPOINT
MAGIC = 24061.0

_state: dict = {"lib": None, "status": None}
_lock = threading.Lock()             # simulators built on several threads at once install it once


def _cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "gait-tuner"


def _compile(target: Path) -> None:
    """Compile ``native_step.c`` into ``target`` (a temporary name, then renamed)."""
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        raise OSError("no C compiler (cc, gcc or clang) on the PATH")
    include = Path(mujoco.__file__).with_name("include")
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=".building-", suffix=".so", dir=target.parent)
    os.close(fd)
    try:
        # no fast-math, no contraction: the gate's arithmetic is the numpy reference's to the bit
        run = subprocess.run([cc, "-O2", "-std=c99", "-fPIC", "-shared", "-ffp-contract=off",
                              f"-I{include}", str(SOURCE), "-o", tmp, "-lm"],
                             capture_output=True, text=True, timeout=120)
        if run.returncode != 0:
            err = run.stderr.strip().splitlines()
            raise OSError(f"{cc} failed: {err[-1] if err else f'exit {run.returncode}'}")
        os.replace(tmp, target)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)


def _load(target: Path) -> ctypes.CDLL:
    lib = ctypes.CDLL(str(target))
    lib.gait_tuner_gate_block.restype = ctypes.c_int
    lib.gait_tuner_gate_magic.restype = ctypes.c_double
    lib.gait_tuner_friction_width.restype = ctypes.c_int
    lib.gait_tuner_friction_magic.restype = ctypes.c_double
    lib.gait_tuner_friction_budget.restype = ctypes.c_double
    lib.gait_tuner_friction_budget.argtypes = [ctypes.POINTER(ctypes.c_double), ctypes.c_double, ctypes.c_double,
                                               ctypes.c_double]
    if (lib.gait_tuner_gate_block() != BLOCK or lib.gait_tuner_gate_magic() != MAGIC
            or lib.gait_tuner_friction_width() != FRICTION_WIDTH or lib.gait_tuner_friction_magic() != FRICTION_MAGIC):
        raise OSError(f"{target} does not match native_step.py's layout")
    return lib


def _build() -> ctypes.CDLL:
    """The compiled callback library: loaded from the cache, built there first when it is missing
    or does not load (a damaged file is rebuilt once)."""
    source = SOURCE.read_bytes()
    key = hashlib.sha256(source + mujoco.__version__.encode()).hexdigest()[:16]
    target = _cache_dir() / f"native_step-{key}.so"
    if target.exists():
        try:
            return _load(target)
        except (OSError, AttributeError):
            target.unlink(missing_ok=True)
    _compile(target)
    return _load(target)


def install() -> bool:
    """Install the native step as MuJoCo's control callback in this process, if it can be: True
    when it is in place (now or before), False when the simulator must gate in Python and cannot
    walk a servo with extended friction (the reason in :func:`status`)."""
    with _lock:
        return _install()


def _install() -> bool:
    if _state["status"] is not None:
        return _state["lib"] is not None and mujoco.get_mjcb_control() is _state["fn"]
    if os.environ.get("GAIT_TUNER_NATIVE_STEP", "1").strip() in ("0", "no", "off", "false"):
        _state["status"] = "off (GAIT_TUNER_NATIVE_STEP=0): the drag gate runs in Python"
        return False
    if mujoco.get_mjcb_control() is not None:
        _state["status"] = "off (another mjcb_control callback is installed): the drag gate runs in Python"
        return False
    try:
        lib = _build()
    except (OSError, subprocess.SubprocessError) as e:
        _state["status"] = f"off ({e}): the drag gate runs in Python"
        return False
    fn = lib.gait_tuner_step
    mujoco.set_mjcb_control(fn)
    _state.update(lib=lib, fn=fn, status="native (native_step.c as mjcb_control)")
    return True


def require(what: str) -> None:
    """Install the native step or refuse, in one line naming ``what`` needs it."""
    if not install():
        from ..errors import UserError
        raise UserError(f"{what} needs the native step (a per-physics-step term MuJoCo has no piece for), "
                        f"which is {status()}; install a C compiler (cc) or use friction_model m1")


def budget(u: np.ndarray, speed: float, motor: float, external: float) -> float:
    """The C library's friction budget of one joint (for the tests against ``motor.friction_budget``)."""
    if not install():
        raise RuntimeError(status())
    arr = np.ascontiguousarray(u, dtype=np.float64)
    return float(_state["lib"].gait_tuner_friction_budget(arr.ctypes.data_as(ctypes.POINTER(ctypes.c_double)),
                                                          speed, motor, external))


def status() -> str:
    """How the drag gate runs in this process (after :func:`install`)."""
    return _state["status"] or "not installed yet"


def arm(model: mujoco.MjModel, data: mujoco.MjData, *, height: float, depth: float, nstep: int,
        first: int, n_points: int) -> None:
    """Arm the callback for a walk starting now: corners' dampers from actuator ``first`` on,
    ``n_points`` corners, blade tips at ``height`` [m], drag depth ``depth`` [m], ``nstep``
    physics steps per control tick."""
    if not 0 < n_points <= MAXPOINT:
        raise ValueError(f"the native drag gate takes 1-{MAXPOINT} corners, not {n_points}")
    u = data.userdata[model.nuserdata - BLOCK:]
    u[:] = 0.0
    u[HEIGHT], u[DEPTH], u[NSTEP] = height, depth, nstep
    u[STEP0] = float(np.rint(data.time / model.opt.timestep))
    u[FIRST], u[NPOINT] = first, n_points
    u[ARMED] = MAGIC


def disarm(model: mujoco.MjModel, data: mujoco.MjData) -> None:
    data.userdata[model.nuserdata - BLOCK + ARMED] = 0.0
