"""Resolve a ``--params`` argument: a YAML file path, a shipped baseline (the papers' sets, in
``gaits/baselines/``) or a shipped tuned result (``studies/results/``: each file says which study,
trial and commit produced it)."""

from __future__ import annotations

import os
from pathlib import Path

from gaits import (Drive, GaitFile, ParamError, all_families, did_you_mean, list_baselines, load_baseline,
                   load_gait_file)

from .errors import UserError

__all__ = ["DEFAULT_BASELINE", "SHIPPED_DIR", "RESULTS_DIR", "list_results", "resolve_params", "resolve_drive"]


def _shipped_dir() -> Path:
    """The shipped studies: ``tuner/shipped/`` in an installed wheel (the checkout's ``studies/``
    packaged under that name, ``pyproject.toml``), else the checkout's ``studies/`` (a source
    tree or an editable install)."""
    here = Path(__file__).resolve().parent
    installed = here / "shipped"
    return installed if installed.is_dir() else here.parent / "studies"


#: The shipped studies (``studies/*.yaml``), with their starting sets (``starts/``).
SHIPPED_DIR = _shipped_dir()
#: Tuned parameter sets shipped with the studies that produced them.
RESULTS_DIR = SHIPPED_DIR / "results"


def list_results() -> list[str]:
    return sorted(p.stem for p in RESULTS_DIR.glob("*.yaml"))

#: The parameter set each family uses when ``--params`` is not given.
DEFAULT_BASELINE = {f.name: f.default_baseline for f in all_families()}


def resolve_params(spec: str | None, family: str | None, what: str = "--params") -> GaitFile:
    """Load ``spec`` (path or baseline name), or the family's default; check the family matches.
    ``what``: how a refusal names it (the option, a verb's argument, or "" where the caller says)."""
    if spec is None:
        if family is None:
            raise UserError("give --gait or --params")
        return load_baseline(DEFAULT_BASELINE[family])
    path = Path(spec)
    if path.suffix in (".yaml", ".yml") or os.path.lexists(path):
        gait_file = load_gait_file(path)
    elif spec in list_baselines():
        gait_file = load_baseline(spec)
    elif spec in list_results():
        gait_file = load_gait_file(RESULTS_DIR / f"{spec}.yaml")
    else:
        raise UserError(f"{what + ' ' if what else ''}{spec!r}: no such file, and not a shipped set"
                        f"{did_you_mean(spec, list_baselines() + list_results())} "
                        f"(baselines: {', '.join(list_baselines())}; tuned: {', '.join(list_results()) or 'none'})")
    if family is not None and gait_file.family != family:
        raise UserError(f"{what + ' ' if what else ''}{spec!r} holds {gait_file.family!r} parameters, "
                        f"but --gait is {family!r}")
    return gait_file


def resolve_drive(spec: str | None, family: str | None, *, stabiliser: bool | None = None,
                  command=None, commands_file: str | Path | None = None, tail: float | None = None,
                  controller: str | Path | None = None, what: str = "--params") -> Drive:
    """What drives the joints of a walk asked for on the command line, resolved once: the set
    (:func:`resolve_params`) or a controller of the user's own (``controller``: its YAML, see
    ``tuner/controllers.py``; its code is imported), its stabiliser (``stabiliser``: None as the
    file says, False off, True required), and a command (a ``gaits.WalkCommand``) or a command
    stream file (``tail`` [s] walked after its last row, default 2)."""
    from .streams import load_stream
    if command is not None and commands_file is not None:
        raise UserError("give --command or --commands, not both")
    stream = None if commands_file is None else load_stream(commands_file, tail)
    if controller is None and spec is not None and _is_controller_file(spec):
        controller, spec = spec, None            # a controller or policy file given as the set
    if controller is not None:
        from .controllers import load_controller
        if spec is not None or family is not None:
            raise UserError("give --params (a gait set) or --controller (your own), not both")
        if stabiliser:
            raise UserError("--stabiliser: a controller of your own brings its own feedback")
        user = load_controller(controller)
        return Drive(None, command=command, stream=stream, source=str(controller), user=user)
    gait_file = resolve_params(spec, family, what)
    label = spec or DEFAULT_BASELINE[gait_file.family]
    try:
        return Drive.of(gait_file, source=label, stabiliser=stabiliser, command=command, stream=stream)
    except ParamError as exc:
        raise UserError(f"--stabiliser: {exc}") from None


def _is_controller_file(spec: str) -> bool:
    """Whether ``spec`` names a controller file (``class:``), a policy file (``policy:``) or a placo file
    (``placo:``) rather than
    a parameter set (``gait:``, ``params:``): a YAML file whose top level says so."""
    path = Path(spec)
    if path.suffix not in (".yaml", ".yml") or not path.is_file() or path.stat().st_size > 1_000_000:
        return False
    try:
        import yaml
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except Exception:  # noqa: BLE001 - not ours to judge here: resolve_params names what is wrong
        return False
    return isinstance(doc, dict) and ("policy" in doc or "class" in doc or "placo" in doc)
