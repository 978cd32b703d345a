"""Every command of the README's command-line block, run through the command line's entry as written.

The block is read from README.md itself, so an example that stops working fails here. Run in
order in a scratch directory (``studies/`` and ``examples/`` linked in), so that ``export`` finds
what ``tune`` made and ``compare`` what ``export`` wrote. In the default run twelve long commands
get a smaller budget, appended and listed in ``BUDGET`` (the same command, fewer trials, sets,
rollouts or iterations), ``calibrate`` (~10 minutes) runs only in the slow suite and two EROS matrices
are left to the tests that check what they print (``ELSEWHERE``); the slow suite runs every line
exactly as written (``pytest -m slow tests/test_readme.py``). The block is cut into chains that
share no file (what ``export`` reads ``tune`` wrote in the same chain), one test each, so the suite's
workers run them side by side. ``worker`` joins the study
``tune`` just finished (it says so and stops), and ``view``, on a machine without a display,
must fail in one line with exit 2: the README says it needs one.
"""

import functools
import os
import re
import shlex
import subprocess

import pytest

from conftest import ROOT, run_in_process

BUDGET = {"tune": ["--trials", "2"], "robustness": ["--rollouts", "4", "--push-rollouts", "2"],
          "identify servos": ["--max-iters", "3"], "identify ground": ["--max-iters", "3", "--horizon", "1"],
          "versus": ["--walks", "1", "--no-challenge", "--speeds", "0.2,0,0,0"],
          "compare": ["--random-rollouts", "2", "--surfaces", "grass50", "--workers", "1", "--no-baselines"],
          "render": ["--duration", "2"], "transfer": ["--walks", "1"],
          "train": ["--iterations", "1", "--directions", "1", "--top", "1", "--walks", "1"],
          "excite": ["--no-steps", "--duration", "5"],
          "challenge push": ["--third", "front", "--step", "0.25"], "bus serve": ["--wait", "1"]}
SLOW_ONLY = {"calibrate"}


#: Lines a test of the default run walks with more options and checks what they print and write: the
#: default run leaves them to it (each a whole EROS matrix, ~15 s); the slow run walks them as written.
ELSEWHERE = {
    ("experiment", "eros"): "test_cli_simulate.py::test_experiment_eros_matrix_as_json_and_as_its_report",
    ("experiment", "eros", "--pedestal", "1=examples/surfaces/grass50-blades.yaml"):
        "test_blades.py::test_the_eros_experiment_walks_a_pedestal_on_a_surface_file",
}


@functools.cache
def _readme_text() -> str:
    return (ROOT / "README.md").read_text(encoding="utf-8")


def readme_commands() -> list[list[str]]:
    text = _readme_text()
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


#: What the examples say they write, each checked after the chain of commands that names it.
WRITTEN = ("runs/tk", "runs/sim/pitch.png", "runs/walk.mp4", "runs/tlipfm-robust/best.yaml",
           "runs/cmp", "runs/turn", "runs/sweep.csv", "runs/servos/robot.yaml", "runs/push-res.yaml")


def _resources(args: list[str]) -> set[str]:
    """What a command shares with others of the block: a folder or file under ``runs/`` (by its first
    two parts) and a study file (tune, worker, trials, export and compare meet in its journal)."""
    out = set()
    for a in args:
        for token in a.split("="):
            if token.startswith("runs/"):
                out.add("/".join(token.split("/")[:2]))
            elif token.endswith(".yaml") and (token.startswith("studies/") or token.endswith("-study.yaml")):
                out.add(token)
    return out


def readme_chains() -> list[list[list[str]]]:
    """The block's commands cut into chains that share nothing: a command joins every earlier chain
    it shares a resource with (merged, in the block's order), so what one reads another wrote before
    it in the same chain, and the chains run side by side on the suite's workers."""
    commands = readme_commands()
    chains: list[tuple[set[str], list[list[str]]]] = []
    for args in commands:
        res = _resources(args)
        joined = [c for c in chains if c[0] & res]
        merged_res = set(res).union(*(c[0] for c in joined))
        merged_cmds = sorted((a for c in joined for a in c[1]), key=commands.index) + [args]
        chains = [c for c in chains if c not in joined] + [(merged_res, merged_cmds)]
    return sorted((c[1] for c in chains), key=lambda cmds: commands.index(cmds[0]))


def _chain_id(cmds: list[list[str]]) -> str:
    first = cmds[0]
    words = first[:2] if len(first) > 1 and first[1].isalpha() else first[:1]
    return "-".join(words + [str(readme_commands().index(first))])


def _in_default_run(args: list[str]) -> bool:
    return args[0] not in SLOW_ONLY and tuple(args) not in ELSEWHERE


def _default_chains() -> list[list[list[str]]]:
    """The chains the default run walks: all but those of slow-only lines and lines run elsewhere."""
    return [c for c in readme_chains() if any(map(_in_default_run, c))]


def test_the_lines_left_to_other_tests_are_run_there():
    """Each line of ELSEWHERE is in the block, and its test is in the default run and runs every word
    of it (a file by its name)."""
    import ast
    commands = [tuple(a) for a in readme_commands()]
    for line, where in ELSEWHERE.items():
        assert line in commands, line
        module, name = where.split("::")
        tree = ast.parse((ROOT / "tests" / module).read_text(encoding="utf-8"))
        [fn] = [n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == name]
        assert not any("slow" in ast.unparse(d) for d in fn.decorator_list), where
        source = ast.unparse(fn)
        for word in line:
            assert word.split("=")[-1].split("/")[-1] in source, (where, word)


def test_the_chains_hold_every_command_once_in_order():
    commands = readme_commands()
    chains = readme_chains()
    assert sorted(commands) == sorted(a for c in chains for a in c)
    for cmds in chains:
        assert [commands.index(a) for a in cmds] == sorted(commands.index(a) for a in cmds)
    # what one command writes, the next one reads in the same chain
    tune = next(c for c in chains if ["tune", "studies/tlipfm-robust.yaml", "--workers", "2"] in c)
    assert [a[0] for a in tune] == ["tune", "worker", "trials", "export", "compare"]
    assert len(chains) > 20
    assert [c for c in chains if c not in _default_chains()] == \
        [c for c in chains if all(a[0] in SLOW_ONLY or tuple(a) in ELSEWHERE for a in c)]
    for path in WRITTEN:
        assert sum(any(path.startswith(r) for r in set().union(*map(_resources, c))) for c in chains) == 1, path


def _run_chain(monkeypatch, tmp_path, cmds, literal: bool):
    for name in ("studies", "examples"):
        os.symlink(ROOT / name, tmp_path / name)
    (tmp_path / "runs").mkdir()         # as after the quick start's `make run` (bus serve makes no folder)
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    for args in cmds:
        verb = args[0]
        if not literal and not _in_default_run(args):
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
    named = set().union(*map(_resources, cmds))
    for path in WRITTEN:
        if any(path.startswith(r) for r in named):
            assert (tmp_path / path).exists(), path


@pytest.mark.parametrize("cmds", _default_chains(), ids=_chain_id)
def test_readme_commands_run(monkeypatch, tmp_path, cmds):
    _run_chain(monkeypatch, tmp_path, cmds, literal=False)


@pytest.mark.slow
@pytest.mark.parametrize("cmds", readme_chains(), ids=_chain_id)
def test_readme_commands_run_exactly_as_written(monkeypatch, tmp_path, cmds):
    _run_chain(monkeypatch, tmp_path, cmds, literal=True)


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
