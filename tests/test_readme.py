"""Every command of the README's command-line block, run through the command line's entry as written.

The block is read from README.md itself, so an example that stops working fails here. Run in
order in a scratch directory (``studies/`` and ``examples/`` linked in), so that ``export`` finds
what ``tune`` made and ``compare`` what ``export`` wrote. In the default run twelve long commands
get a smaller budget, appended and listed in ``BUDGET`` (the same command, fewer trials,
rollouts or iterations), and ``calibrate`` (~10 minutes) runs only in the slow suite, where every line runs
exactly as written (``pytest -m slow tests/test_readme.py``). ``worker`` joins the study
``tune`` just finished (it says so and stops), and ``view``, on a machine without a display,
must fail in one line with exit 2: the README says it needs one.
"""

import os
import re
import shlex
import subprocess

import pytest

from conftest import ROOT, run_in_process

BUDGET = {"tune": ["--trials", "2"], "robustness": ["--rollouts", "4", "--push-rollouts", "2"],
          "identify servos": ["--max-iters", "3"], "identify ground": ["--max-iters", "3", "--horizon", "1"],
          "versus": ["--walks", "1", "--no-challenge", "--speeds", "0.2,0,0,0"],
          "compare": ["--random-rollouts", "2", "--surfaces", "grass50", "--workers", "1"],
          "render": ["--duration", "2"], "transfer": ["--walks", "1"],
          "excite": ["--no-steps", "--duration", "5"], "experiment eros": ["--steps", "4", "--workers", "1"],
          "challenge push": ["--third", "front", "--step", "0.25"], "bus serve": ["--wait", "1"]}
SLOW_ONLY = {"calibrate"}


def readme_commands() -> list[list[str]]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    section = text.split("## Command line", 1)[1]
    block = re.search(r"```sh\n(.*?)```", section, re.S).group(1)
    commands = []
    for line in block.splitlines():
        line = line.split(" #", 1)[0].strip()
        if line.startswith("gait-tuner"):
            commands.append(shlex.split(line)[1:])
    return commands


def test_the_block_is_found_and_covers_every_verb(gait_tuner_cmd, run_env):
    cmds = readme_commands()
    assert len(cmds) >= 15
    verbs = {c[0] for c in cmds}
    r = subprocess.run(gait_tuner_cmd + ["--help"], capture_output=True, text=True, env=run_env)
    listed = set(re.findall(r"^  ([a-z]+)\s", r.stdout.split("Commands:", 1)[1], re.M))
    assert listed - verbs == set(), f"verbs without a README example: {listed - verbs}"


def _run_block(monkeypatch, tmp_path, literal: bool):
    for name in ("studies", "examples"):
        os.symlink(ROOT / name, tmp_path / name)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    for args in readme_commands():
        verb = args[0]
        if verb in SLOW_ONLY and not literal:
            continue
        if not literal:
            args = args + BUDGET.get(verb, BUDGET.get(" ".join(args[:2]), []))
        # in this process, as the console script calls it (tuner.cli.main); the test above starts
        # the console script itself
        r = run_in_process(args, cwd=tmp_path)
        shown = "gait-tuner " + " ".join(args)
        if verb == "view":
            assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, (shown, r.stderr)
            assert "display" in r.stderr
            continue
        assert r.returncode == 0, (shown, r.stdout[-2000:], r.stderr[-2000:])
    # what the examples say they write is there
    for path in ("runs/tk", "runs/sim/pitch.png", "runs/walk.mp4", "runs/tlipfm-robust/best.yaml",
                 "runs/cmp", "runs/turn", "runs/sweep.csv", "runs/servos/robot.yaml"):
        assert (tmp_path / path).exists(), path


def test_readme_commands_run(monkeypatch, tmp_path):
    _run_block(monkeypatch, tmp_path, literal=False)


@pytest.mark.slow
def test_readme_commands_run_exactly_as_written(monkeypatch, tmp_path):
    _run_block(monkeypatch, tmp_path, literal=True)


def _layout_section() -> str:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return text[text.index("## Layout"):]


def test_the_layout_names_every_module_and_nothing_that_is_not_there():
    """The README's Layout section cannot drift: every module of ``gaits/`` and ``tuner/`` is named there
    (as often as its file name recurs in the house) and every file it names exists."""
    import collections
    section = _layout_section()
    named = collections.Counter(n.split("/")[-1] for n in re.findall(r"`([\w./-]+\.(?:py|c|yaml|toml))`", section))
    modules = [p for d in ("tuner", "gaits") for p in (ROOT / d).rglob("*.py")
               if p.name not in ("__init__.py", "__main__.py")] + list((ROOT / "tuner").rglob("*.c"))
    counts = collections.Counter(p.name for p in modules)
    assert {n: c for n, c in counts.items() if named[n] < c} == {}
    there = set()
    for folder, subfolders, files in os.walk(ROOT):
        subfolders[:] = [d for d in subfolders if d not in (".venv", ".git", "runs", "__pycache__")]
        there.update(subfolders, files)
    assert sorted(n for n in named if n not in there) == []
