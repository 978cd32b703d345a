"""The command line is a face (``tuner/cli/``): its root lists the verbs without loading them, so
``gait-tuner --help`` and a refused verb load no simulator, optimiser or gait; each module stays
small; the root's one-line helps are the commands' own."""

from __future__ import annotations

import subprocess
import sys

import click

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


def test_no_cli_module_is_over_400_lines():
    sizes = {p.name: len(p.read_text().splitlines()) for p in (ROOT / "tuner" / "cli").glob("*.py")}
    assert max(sizes.values()) <= 400, sizes
