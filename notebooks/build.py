"""Write each walk-through of this folder as an executed Jupyter notebook.

``python notebooks/build.py [NAME ...] [--check]``: every ``notebooks/*.py`` in the ``# %%``
format (or the ones named) is turned into ``NAME.ipynb`` beside it (jupytext), run top to bottom
in a fresh kernel from the repository's root (nbclient; the figures and files it writes go to a
temporary folder), and written with its outputs. ``--out DIR`` writes the executed notebooks
there instead (the slow test does). Needs the dev extra (jupytext, nbclient, ipykernel).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent


def sources() -> list[Path]:
    """The walk-throughs: the folder's Python files in the ``# %%`` format."""
    return sorted(p for p in HERE.glob("*.py") if p.name != "build.py"
                  and p.read_text(encoding="utf-8").startswith("# %%"))


def notebook_of(source: Path):
    """The notebook (nbformat) of a walk-through, unexecuted."""
    import jupytext
    nb = jupytext.read(source, fmt="py:percent")
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata.pop("jupytext", None)
    return nb


def execute(source: Path, out: Path, timeout: int = 1200) -> Path:
    """Run the walk-through as a notebook and write it, with its outputs, as ``out/NAME.ipynb``."""
    import nbformat
    from nbclient import NotebookClient
    nb = notebook_of(source)
    with tempfile.TemporaryDirectory(prefix=f"{source.stem}-") as scratch:
        env_keys = {"FIGURES_OUT": scratch, "NOTEBOOK_OUT": scratch, "MPLBACKEND": "Agg"}
        saved = {k: os.environ.get(k) for k in env_keys}
        os.environ.update(env_keys)            # the kernel inherits them
        try:
            NotebookClient(nb, timeout=timeout, kernel_name="python3",
                           resources={"metadata": {"path": str(ROOT)}}).execute()
        finally:
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{source.stem}.ipynb"
    nbformat.write(nb, str(path))
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help="walk-throughs to build (default: all)")
    ap.add_argument("--out", type=Path, default=HERE, help="where the executed notebooks go")
    args = ap.parse_args(argv)
    chosen = [p for p in sources() if not args.names or p.stem in args.names]
    if not chosen:
        print(f"no walk-through named {', '.join(args.names)} in {HERE}", file=sys.stderr)
        return 2
    for src in chosen:
        print(f"{src.name} -> {execute(src, args.out)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
