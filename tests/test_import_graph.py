"""gaits/ is pure math: it never imports the simulator, the optimisers or tuner/."""

import ast
import subprocess
import sys
from pathlib import Path

FORBIDDEN = ("mujoco", "optuna", "casadi", "tuner", "matplotlib", "click")
GAITS = Path(__file__).resolve().parents[1] / "gaits"


def test_no_forbidden_import_statements():
    offenders = []
    for path in GAITS.rglob("*.py"):
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            offenders += [f"{path.name}: {n}" for n in names if n.split(".")[0] in FORBIDDEN]
    assert offenders == []


def test_importing_gaits_loads_no_forbidden_module():
    code = ("import sys, gaits; "
            "print(sorted({m.split('.')[0] for m in sys.modules} & set(%r)))" % (FORBIDDEN,))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
