"""Reading a user's YAML file: every way it can be wrong is one line naming the file.

Directories, missing files, binary or non-UTF-8 content, YAML syntax errors and nesting
deep enough to exhaust the parser all become :class:`UserError`, never a traceback.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .errors import UserError

__all__ = ["read_yaml_file"]


def read_yaml_file(path: Path, what: str) -> Any:
    """The parsed document of a YAML file; ``what`` names the kind of file in messages."""
    path = Path(path)
    if path.is_dir():
        raise UserError(f"{path}: is a directory, expected a {what} YAML file")
    try:
        raw = path.read_bytes()
    except FileNotFoundError:
        raise UserError(f"{path}: no such {what} file") from None
    except OSError as exc:
        raise UserError(f"{path}: cannot read the {what} file ({exc.strerror})") from None
    if b"\x00" in raw:
        raise UserError(f"{path}: is a binary file, expected a {what} YAML file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise UserError(f"{path}: is not UTF-8 text (byte {exc.start})") from None
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
        raise UserError(f"{path}: not valid YAML{where}") from None
    except RecursionError:
        raise UserError(f"{path}: nested too deeply to be a {what} file") from None
