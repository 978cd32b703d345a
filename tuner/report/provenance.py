"""Where a result comes from: the git commit of the file that produced it."""

from __future__ import annotations

from pathlib import Path

__all__ = ["commit_of"]


def commit_of(path: str) -> str:
    """' (commit abc1234)' when the study file sits in a git checkout ('+ local changes' if it
    differs from that commit), else ''."""
    import subprocess
    try:
        folder = str(Path(path).resolve().parent)
        head = subprocess.run(["git", "-C", folder, "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=10)
        if head.returncode != 0:
            return ""
        dirty = subprocess.run(["git", "-C", folder, "status", "--porcelain", "--", str(Path(path).resolve())],
                               capture_output=True, text=True, timeout=10).stdout.strip()
        return f" (commit {head.stdout.strip()}{' + local changes' if dirty else ''})"
    except (OSError, subprocess.SubprocessError):
        return ""
