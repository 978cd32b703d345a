"""The real ``gait-tuner`` CLI, run in a subprocess: outputs, exit codes, one-line errors."""

import csv

import numpy as np
import pytest

from gaits import JOINT_NAMES
from conftest import run_cli


def run(cmd, args, env, cwd=None):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, cwd=cwd)


@pytest.mark.parametrize("family", ["tlipfm", "eros", "cosine"])
def test_trajectory_writes_table_plot_and_params(gait_tuner_cmd, run_env, tmp_path, family):
    out = tmp_path / family
    r = run(gait_tuner_cmd, ["trajectory", "--gait", family, "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    assert (out / "references.png").stat().st_size > 10_000
    with (out / "joints.csv").open() as fh:
        first = fh.readline()
        rows = list(csv.reader(fh))
    assert first.startswith("# gait-tuner joint table for robot kidsize")
    header = rows[0]
    assert header[0] == "t[s]"
    assert [h[:-5] for h in header[1:21]] == list(JOINT_NAMES)
    assert "com_x[m]" in header and "zmp_ref_y[m]" in header and header[-1] == "support[-]"
    assert len(rows) > 100
    # the written params.yaml reproduces the same table
    r2 = run(gait_tuner_cmd, ["trajectory", "--params", str(out / "params.yaml"),
                              "--out", str(tmp_path / "again"), "--no-plot"], run_env)
    assert r2.returncode == 0, r2.stderr
    again = (tmp_path / "again" / "joints.csv").read_text().split("\n", 1)
    assert again[1] == (out / "joints.csv").read_text().split("\n", 1)[1]
    assert again[0].endswith(f"gait {out / 'params.yaml'}: open-loop table, its own walk")


def test_model_override_and_baseline_name(gait_tuner_cmd, run_env, tmp_path):
    r = run(gait_tuner_cmd, ["trajectory", "--params", "tkux-table2", "--model", "lipm",
                             "--out", str(tmp_path), "--no-plot", "--dt", "0.005"], run_env)
    assert r.returncode == 0, r.stderr
    assert "samples every 0.005 s" in r.stdout
    assert "model: lipm" in (tmp_path / "params.yaml").read_text()


@pytest.mark.parametrize("args,message", [
    (["trajectory", "--params", "no-such-set", "--out", "X"], "not a shipped set"),
    (["trajectory", "--gait", "eros", "--params", "tkux-table2", "--out", "X"],
     "holds 'tlipfm' parameters, but --gait is 'eros'"),
    (["trajectory", "--gait", "eros", "--model", "lipm", "--out", "X"], "--model applies to the tlipfm"),
    (["trajectory", "--gait", "tlipfm", "--dt", "2", "--out", "X"], "dt = 2.0 s is out of range"),
    (["trajectory", "--gait", "walker", "--out", "X"], "Invalid value for '--gait'"),
    (["trajectory", "--gait", "eros"], "Missing option '--out'"),
    (["fly"], "No such command 'fly'"),
])
def test_bad_input_exits_2_with_one_line(gait_tuner_cmd, run_env, tmp_path, args, message):
    args = [str(tmp_path / a) if a == "X" else a for a in args]
    r = run(gait_tuner_cmd, args, run_env)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert message in r.stderr
    assert "Traceback" not in r.stderr


def test_malformed_file_and_unreachable_gait(gait_tuner_cmd, run_env, tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("gait: tlipfm\nparams:\n  t1: 0.6\n")
    r = run(gait_tuner_cmd, ["trajectory", "--params", str(bad), "--out", str(tmp_path / "o")], run_env)
    assert r.returncode == 2
    assert r.stderr.strip().count("\n") == 0
    assert "t1 = 0.6 s" in r.stderr
    # hip higher than the straight leg: the IK says which foot, when and why
    far = tmp_path / "far.yaml"
    far.write_text("gait: eros\nparams:\n  hip_height: 0.29\n")
    r = run(gait_tuner_cmd, ["trajectory", "--params", str(far), "--out", str(tmp_path / "o")], run_env)
    assert r.returncode == 2
    assert "out of reach" in r.stderr and "t = 0.000 s" in r.stderr


def test_help_lists_verbs(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["--help"], run_env)
    assert r.returncode == 0
    for verb in ("trajectory", "baselines", "params"):
        assert verb in r.stdout


def test_baselines_and_params_listing(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["baselines"], run_env)
    assert r.returncode == 0 and "tkux-table2" in r.stdout and "eros-x24-with" in r.stdout
    r = run(gait_tuner_cmd, ["params", "tlipfm"], run_env)
    assert r.returncode == 0 and "S_L" in r.stdout and "[0.08, 0.5] m" in r.stdout


@pytest.mark.parametrize("content,message", [
    (b"a: " + b"[" * 20000 + b"]" * 20000 + b"\n", "nested too deeply"),
    (b"\x00\x01binary", "is a binary file"),
    ("mjcf: caf\xe9\n".encode("latin-1"), "is not UTF-8 text"),
    (None, "is a directory"),
])
@pytest.mark.parametrize("verb", [["tune"], ["robot", "check"], ["simulate", "--gait", "tlipfm", "--surface"]])
def test_bad_yaml_files_are_one_line_exit_2(gait_tuner_cmd, run_env, tmp_path, content, message, verb):
    path = tmp_path / "bad.yaml"
    if content is None:
        path.mkdir()
    else:
        path.write_bytes(content)
    r = run(gait_tuner_cmd, verb + [str(path)], run_env)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and message in r.stderr


def test_progress_in_a_log_is_plain_lines(capsys):
    """Off a terminal a bar is never silent for long: a plain line every 15 s, no carriage returns."""
    from tqdm import tqdm

    from tuner.cli.options import bar_options as _bar_options
    opts = _bar_options()
    assert opts["disable"] is False and opts["mininterval"] == 15.0 and opts["delay"] == 15.0
    opts.update(mininterval=0.0, delay=0.0, miniters=1)
    with tqdm(total=3, desc="walks", **opts) as bar:
        for _ in range(3):
            bar.update(1)
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.strip().splitlines()
    assert len(lines) >= 3 and lines[-1].startswith("walks: 100%") and "3/3" in lines[-1]


def test_train_writes_a_set_whose_residual_walks_and_goes_on_from_it(gait_tuner_cmd, run_env, tmp_path):
    """gait-tuner train: one iteration of the random search on the built-in robot's carpet set writes
    a set with its residual (the engine's set otherwise unchanged), the same again from the same seed
    (the workers' timing does not enter), and `train OUT --out OUT` starts from OUT's residual; a zero
    residual walks the engine's walk exactly; what it cannot train is one line, exit 2."""
    import json
    from gaits import load_gait_file
    out = tmp_path / "res.yaml"
    args = ["train", "kidsize-engine-carpet4", "--robot", "kidsize", "--surface", "carpet4", "--iterations", "1",
            "--directions", "1", "--top", "1", "--walks", "1", "--seed", "4", "--json"]
    r = run(gait_tuner_cmd, args + ["--out", out, "--workers", "2"], run_env)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout)
    assert len(got["rewards"]) == 1 and 0.0 <= got["stood"][0] <= 1.0
    trained = load_gait_file(out)
    assert trained.residual is not None and np.abs(trained.residual.matrix).max() > 0
    assert "1 of 1 iterations" in trained.description and "seed 4" in trained.description
    again = tmp_path / "again.yaml"
    assert run(gait_tuner_cmd, args + ["--out", again, "--workers", "1"], run_env).returncode == 0
    assert again.read_text() == out.read_text()
    on = tmp_path / "on.yaml"
    assert run(gait_tuner_cmd, ["train", out] + args[2:] + ["--out", on], run_env).returncode == 0
    first, second = trained.residual.matrix, load_gait_file(on).residual.matrix
    assert not np.array_equal(first, second) and np.abs(second - first).max() < 10 * np.abs(first).max()
    # a zero residual is the engine itself, tick for tick
    zero = tmp_path / "zero.yaml"
    zero.write_text(out.read_text().split("residual:")[0] + "residual: {}\n")
    walks = [json.loads(run(gait_tuner_cmd, ["simulate", "--params", p, "--robot", "kidsize", "--surface", "carpet4",
                                             "--command", "0.2,0,0", "--json"], run_env).stdout)
             for p in ("kidsize-engine-carpet4", zero, out)]
    assert walks[0]["metrics"] == walks[1]["metrics"] and "with its trained residual" in walks[1]["drive"]
    assert walks[2]["metrics"]["pitch_rms_deg"] != walks[0]["metrics"]["pitch_rms_deg"]     # a trained one acts
    for bad, said in ((["--top", "2"], "--top 2: at most --directions (1)"),
                      (["--objective", "run"], "Invalid value for '--objective'"),
                      (["--surface", "carpet4,grass30"], "--surface: 2 surfaces but --walks 1")):
        r = run(gait_tuner_cmd, args + ["--out", tmp_path / "b.yaml"] + bad, run_env)
        assert r.returncode == 2 and said in r.stderr and len(r.stderr.strip().splitlines()) == 1, r.stderr
    (tmp_path / "a-file").write_text("x")
    r = run(gait_tuner_cmd, args + ["--out", tmp_path / "a-file" / "b.yaml"], run_env)     # refused before it trains
    assert r.returncode == 2 and "a file stands where a folder is needed" in r.stderr and "iteration" not in r.stderr, r.stderr
    r = run(gait_tuner_cmd, ["train", "tkux-table2"] + args[2:] + ["--out", tmp_path / "b.yaml"], run_env)
    assert r.returncode == 2 and "tlipfm set with an engine: section" in r.stderr, r.stderr
    held = tmp_path / "held.yaml"          # a held command under the randomisation, as robustness walks it
    r = run(gait_tuner_cmd, args + ["--objective", "command", "--command", "0.25,0,0", "--out", held], run_env)
    assert r.returncode == 0 and "command (1 walk(s) an evaluation, command 0.25,0,0)" in load_gait_file(held).description
