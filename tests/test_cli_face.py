"""The command line is a face (``tuner/cli/``): its root lists the verbs without loading them, so
``gait-tuner --help`` and a refused verb load no simulator, optimiser or gait; each module stays
small; the root's one-line helps are the commands' own."""

from __future__ import annotations

import subprocess
import sys

import click
import pytest

from conftest import ROOT
from tuner.cli import VERBS, cli


def test_the_roots_one_line_helps_are_the_commands_own():
    ctx = click.Context(cli)
    for name, (_, _, short) in VERBS.items():
        cmd = cli.get_command(ctx, name)
        assert cmd is not None, name
        assert cmd.get_short_help_str(limit=400) == short, name
    assert set(VERBS) == set(cli.list_commands(ctx))


def test_help_and_a_refusal_load_no_simulator_optimiser_or_gait():
    code = ("import sys\nfrom tuner.cli import main\n"
            "for args in (['--help'], ['no-such-verb']):\n"
            "    try:\n        main(args)\n    except SystemExit:\n        pass\n"
            "heavy = [m for m in ('numpy', 'mujoco', 'optuna', 'casadi', 'scipy', 'gaits') if m in sys.modules]\n"
            "print('HEAVY', heavy)")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert "HEAVY []" in r.stdout, r.stdout + r.stderr


def test_a_study_verbs_start_loads_no_scipy():
    """What ``tune`` loads before it walks (its verb module, the search, the robots, the scenarios)
    leaves scipy out: scipy.spatial and scipy.special cost ~0.5 s of every process start, and only
    a URDF's rotations and the challenge's pendulum use them (imported there, when they run)."""
    code = "import sys\nimport tuner.cli.study\nprint('SCIPY', sorted(m for m in sys.modules if m.startswith('scipy'))[:3])"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT)
    assert "SCIPY []" in r.stdout, r.stdout + r.stderr


def test_no_cli_module_is_over_400_lines():
    sizes = {p.name: len(p.read_text().splitlines()) for p in (ROOT / "tuner" / "cli").glob("*.py")}
    assert max(sizes.values()) <= 400, sizes


#: The root's own (tuner/cli/main.py): the entry points, the SIGINT handler, the one-line error, the
#: verbs' lines in its help.
ROOT_PLUMBING = {"main": {"cli", "main", "run", "_bad_input", "_on_ctrl_c", "_said", "_short"}}


def _kind_of(node, module: str) -> str | None:
    """What a CLI module's top-level function is: a click command, the root's plumbing, a shared
    option (options.py), a printer (it says something: click.echo or a progress bar) or a refusal
    (it raises UserError); None for anything else (domain code: it belongs in a wing)."""
    import ast
    decorators = [ast.unparse(d) for d in node.decorator_list]
    if any(d.startswith(("click.command", "click.group")) or ".command(" in d for d in decorators):
        return "command"
    if node.name in ROOT_PLUMBING.get(module, ()):
        return "root"
    if module == "options":
        return "option"
    text = ast.unparse(node)
    if "click.echo" in text or "tqdm(" in text or "running_total(" in text:
        return "printer"
    if "raise UserError" in text:
        return "refusal"
    return None


def _cli_functions(folder):
    import ast
    out = {}
    for p in sorted(folder.glob("*.py")):
        tree = ast.parse(p.read_text(encoding="utf-8"))
        for node in tree.body:
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                out[f"{p.stem}.{node.name}"] = _kind_of(node, p.stem)
    return out


def test_every_cli_function_is_a_command_or_a_printer():
    """``tuner/cli/`` holds no function a wing could own: each top-level function is a click command,
    the root's plumbing, a shared option, a printer or a refusal, and no CLI module computes with
    numpy (its arithmetic is a wing's)."""
    found = _cli_functions(ROOT / "tuner" / "cli")
    assert sum(k == "command" for k in found.values()) >= 29
    assert [name for name, kind in found.items() if kind is None] == []
    numeric = [p.name for p in (ROOT / "tuner" / "cli").glob("*.py")
               if "import numpy" in p.read_text(encoding="utf-8")]
    assert numeric == []


def test_the_cli_function_census_can_fail(tmp_path):
    (tmp_path / "fake.py").write_text("import click\n\n@click.command()\ndef verb():\n    click.echo(_sum([1]))\n\n"
                                      "def _sum(xs):\n    return sum(xs)\n")
    assert _cli_functions(tmp_path) == {"fake.verb": "command", "fake._sum": None}


def test_the_tests_helper_runs_the_cli_in_this_process_with_the_tests_environment(run_env, monkeypatch):
    """``conftest.run_cli`` with the ``run_env`` fixture's environment (copied at the test's setup)
    runs the verb in this process: spawning one pays a second of imports per call (it did, for
    every test that passed ``run_env``, until PYTEST_CURRENT_TEST was left out of the comparison)."""
    import conftest

    def spawned(*args, **kwargs):
        raise AssertionError(f"spawned a process: {args}")
    monkeypatch.setattr(conftest.subprocess, "run", spawned)
    r = conftest.run_cli(["gait-tuner"], ["--help"], env=run_env)
    assert r.returncode == 0 and "Commands:" in r.stdout
    with pytest.raises(AssertionError, match="spawned"):          # an environment of its own: a process
        conftest.run_cli(["gait-tuner"], ["--help"], env={**run_env, "OTHER": "1"})


def test_a_verbs_line_in_the_roots_help_is_cut_at_a_word():
    from tuner.cli.main import _short
    assert _short("Walk a gait.", 40) == "Walk a gait."
    cut = _short("Compare parameter sets side by side: stability matrix, stability %, pitch", 40)
    assert cut == "Compare parameter sets side by side..." and len(cut) <= 40


def _strict(text: str):
    """JSON as the standard has it: no NaN or Infinity (Python's json would take them)."""
    import json

    def refuse(constant):
        raise ValueError(f"not strict JSON: {constant}")
    return json.loads(text, parse_constant=refuse)


def test_the_verbs_that_gained_json_print_strict_json_alone(capsys, tmp_path, monkeypatch):
    """studies, baselines, params, trajectory, robot export, init, tune and export had no --json (a
    script read their words): each prints one strict JSON object or list on stdout, its words (the
    progress, the notes) on stderr."""
    from tuner.cli import main
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")

    def json_of(argv):
        assert main(argv + ["--json"]) == 0, capsys.readouterr().err
        return _strict(capsys.readouterr().out)

    studies = json_of(["studies"])
    assert {"quickstart", "kidsize-engine-carpet4"} <= {r["name"] for r in studies}
    assert all(r["trials"] >= 1 and r["surfaces"] for r in studies)
    assert {r["name"] for r in json_of(["baselines"])} >= {"eros-x8-with", "cosine-setiono"}
    p = json_of(["params", "tlipfm"])
    assert p["family"] == "tlipfm" and "period" in {r["name"] for r in p["params"]} and p["commands"]
    t = json_of(["trajectory", "--gait", "tlipfm", "--out", "t", "--no-plot"])
    assert t["wrote"] == ["t/joints.csv", "t/params.yaml"] and t["samples"] > 100 and t["walked_x_m"] > 0.1
    r = json_of(["robot", "export", "kidsize", "--out", "r.yaml"])
    assert r["joints"] == 20 and r["with_servo_id"] == 20 and (tmp_path / "r.yaml").is_file()
    i = json_of(["init", "--robot", "kidsize", "--surface", "rigid", "--out", "ini"])
    assert i["study"] == "ini/kidsize-rigid-match.yaml" and (tmp_path / i["study"]).is_file()
    assert set(i["wrote"]) >= {i["study"], i["start"], i["stream"]} and i["falls_standing"] is None
    assert i["values"]["period"]["value"] > 0 and i["values"]["period"]["from"]
    assert i["next"]["tune"] == "gait-tuner tune ini/kidsize-rigid-match.yaml --workers 2"
    run = json_of(["tune", "quickstart", "--trials", "2", "--workers", "1", "--runs", "runs"])
    assert run["study"] == "quickstart" and run["finished"] == 2 and run["budget"] == 2
    assert run["best"]["feasible"] and run["export"] == "gait-tuner export quickstart" and run["why"] is None
    e = json_of(["export", "quickstart", "--runs", "runs", "--out", "b.yaml"])
    assert e["trial"] == run["best"]["trial"] and e["values"] == run["best"]["values"]
    assert e["wrote"] == {"params": "b.yaml", "table": "b.joints.csv"} and (tmp_path / "b.yaml").is_file()


def test_strict_json_refuses_what_python_would_take():
    with pytest.raises(ValueError, match="NaN"):
        _strict('{"x": NaN}')
    assert _strict('{"x": 1.5}') == {"x": 1.5}
