"""The papers' figures walk-through runs and writes its figures."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_papers_figures_walkthrough(tmp_path, run_env):
    r = subprocess.run([sys.executable, str(ROOT / "notebooks" / "papers_figures.py"), str(tmp_path)],
                       capture_output=True, text=True, env=run_env, timeout=300)
    assert r.returncode == 0, r.stderr
    for name in ("tlipfm_com.png", "tlipfm_cycloid.png", "eros_trajectory.png", "eros_pitch_grass50.png",
                 "zmp_lipm.png", "zmp_dlipm.png", "zmp_tlipfm.png"):
        assert (tmp_path / name).stat().st_size > 10_000
    assert "T_TF = 0.1709 s" in r.stdout
