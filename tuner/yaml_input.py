"""Reading a user's YAML file: every way it can be wrong is one line naming the file.

Directories, missing files, binary or non-UTF-8 content, YAML syntax errors and nesting
deep enough to exhaust the parser all become :class:`UserError`, never a traceback.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from gaits.gait_file import read_yaml

from .errors import UserError

__all__ = ["read_yaml_file"]


def read_yaml_file(path: Path, what: str) -> Any:
    """The parsed document of a YAML file (:func:`gaits.gait_file.read_yaml`), errors as
    :class:`UserError`; ``what`` names the kind of file in messages."""
    return read_yaml(path, what, UserError)
