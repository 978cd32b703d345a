"""The papers' figures walk-through runs and writes its figures."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def test_papers_figures_walkthrough(tmp_path, run_env):
    r = subprocess.run([sys.executable, str(ROOT / "notebooks" / "papers_figures.py"), str(tmp_path)],
                       capture_output=True, text=True, env=run_env, timeout=300)
    assert r.returncode == 0, r.stderr
    for name in ("tlipfm_com.png", "tlipfm_cycloid.png", "eros_trajectory.png", "eros_pitch_grass50.png",
                 "zmp_lipm.png", "zmp_dlipm.png", "zmp_tlipfm.png"):
        assert (tmp_path / name).stat().st_size > 10_000
    assert "T_TF = 0.1709 s" in r.stdout


def _build():
    import importlib.util
    spec = importlib.util.spec_from_file_location("notebooks_build", ROOT / "notebooks" / "build.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _errors(nb) -> list[str]:
    return [o.get("ename", "") + ": " + o.get("evalue", "") for c in nb.cells if c.cell_type == "code"
            for o in c.get("outputs", []) if o.output_type == "error"]


def test_the_committed_notebooks_are_their_sources_executed():
    """Each walk-through's .ipynb is its .py, cell for cell, run to the end with no error (rebuild
    with `python notebooks/build.py` after changing a .py)."""
    import nbformat
    build = _build()
    names = [p.stem for p in build.sources()]
    assert set(names) == {"papers_figures", "your_robot_on_your_surface"}
    for source in build.sources():
        committed = nbformat.read(str(source.with_suffix(".ipynb")), as_version=4)
        want = [(c.cell_type, c.source) for c in build.notebook_of(source).cells]
        assert [(c.cell_type, c.source) for c in committed.cells] == want, f"{source.name}: rebuild its notebook"
        code = [c for c in committed.cells if c.cell_type == "code"]
        assert all(c.execution_count for c in code) and not _errors(committed), source.name
        assert any(o.output_type == "display_data" for c in code for o in c.outputs), source.name


@pytest.mark.slow
def test_the_notebooks_run_in_a_kernel(tmp_path):
    import nbformat
    build = _build()
    for source in build.sources():
        nb = nbformat.read(str(build.execute(source, tmp_path)), as_version=4)
        assert not _errors(nb), (source.name, _errors(nb))
    text = "".join(o.get("text", "") for c in nbformat.read(str(tmp_path / "your_robot_on_your_surface.ipynb"),
                                                           as_version=4).cells
                   if c.cell_type == "code" for o in c.outputs)
    assert "stand test: stays up" in text and "survival" in text and "tuned" in text
