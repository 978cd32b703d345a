"""The simulate / experiment / surfaces verbs through the real CLI."""

import json

import pytest
from conftest import run_cli


def run(cmd, args, env):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env)


def test_simulate_prints_metrics_json_and_plots(gait_tuner_cmd, run_env, tmp_path):
    r = run(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--surface", "carpet4", "--json",
                             "--plot", str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["surface"] == "carpet4" and doc["gait"] == "tlipfm"
    assert set(doc["definitions"]) <= set(doc["metrics"])
    assert doc["metrics"]["fell"] is False
    assert (tmp_path / "pitch.png").stat().st_size > 10_000
    assert (tmp_path / "zmp.png").stat().st_size > 10_000
    r = run(gait_tuner_cmd, ["simulate", "--gait", "eros", "--duration", "1.0"], run_env)
    assert r.returncode == 0, r.stderr
    assert "pitch_pm_deg" in r.stdout and "half the peak-to-peak" in r.stdout


def test_user_surface_file(gait_tuner_cmd, run_env, tmp_path):
    good = tmp_path / "turf.yaml"
    good.write_text("layer_height: 0.02\nlayer_timeconst: 0.03\ndrag: 40\nfriction: 0.8\n")
    r = run(gait_tuner_cmd, ["simulate", "--surface", str(good), "--gait", "tlipfm", "--duration", "1"], run_env)
    assert r.returncode == 0, r.stderr
    assert "/ turf:" in r.stdout


@pytest.mark.parametrize("text,message", [
    ("layer_height: 0.2\n", "surface.layer_height = 0.2 m is out of range [0, 0.1] m"),
    ("blades: 3\n", "unknown surface field 'blades'"),
    ("drag: 10\n", "drag = 10 N s/m needs a layer"),
    ("[1, 2\n", "not valid YAML"),
])
def test_bad_surface_files_exit_2(gait_tuner_cmd, run_env, tmp_path, text, message):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    r = run(gait_tuner_cmd, ["simulate", "--surface", str(path), "--gait", "tlipfm"], run_env)
    assert r.returncode == 2
    assert message in r.stderr and r.stderr.strip().count("\n") == 0


def test_unknown_surface_and_robot_exit_2(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["simulate", "--surface", "ice", "--gait", "tlipfm"], run_env)
    assert r.returncode == 2 and "not a built-in surface (rigid, carpet4" in r.stderr
    r = run(gait_tuner_cmd, ["simulate", "--robot", "nao", "--gait", "tlipfm"], run_env)
    assert r.returncode == 2 and "not a built-in robot (kidsize, kidsize-pd)" in r.stderr
    r = run(gait_tuner_cmd, ["simulate", "--gait", "tlipfm", "--duration", "-1"], run_env)
    assert r.returncode == 2 and "--duration must be in (0, 600] s" in r.stderr


def test_experiment_tlipfm_table3(gait_tuner_cmd, run_env, tmp_path):
    r = run(gait_tuner_cmd, ["experiment", "tlipfm", "--out", str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    assert "1.487/" in r.stdout and "1.107/" in r.stdout       # the paper's numbers beside ours
    assert (tmp_path / "report.md").exists()


def test_experiment_eros_matrix_as_json_and_as_its_report(gait_tuner_cmd, run_env, tmp_path):
    """One run of the matrix: strict JSON on stdout, the text report in report.md (--out is kept
    with --json: it was dropped)."""
    import json
    r = run(gait_tuner_cmd, ["experiment", "eros", "--json", "--steps", "6", "--workers", "1", "--out", str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "report.md").read_text()
    assert "Table 7 (without optimisation)" in text and "Table 8 (with optimisation)" in text
    assert text.count("stability %") == 2
    assert "cells agreeing with the paper:" in text
    assert "foot lift: the paper's Z x 1;" in text and "double support 40% of each step" in text
    assert "paper's table      30             30             50             90" in text
    assert "distance to fall on grass50" in text and "* = our cell differs" in text
    doc = json.loads(r.stdout)
    assert doc["lift_scale"] == 1.0 and doc["double_support"] == 0.4
    names = {"grass50", "grass30", "grass10", "carpet4"}
    for key in ("without", "with"):
        assert set(doc["stability"][key]) == names
        assert all(0.0 <= v <= 1.0 for v in doc["stability"][key].values())
        stable = [c["stable"] for c in doc["cells"] if c["optimised"] == (key == "with")
                  and c["surface"] == "carpet4"]
        assert doc["stability"][key]["carpet4"] == pytest.approx(sum(stable) / 10)
    assert doc["paper_stability"]["without_table"]["grass50"] == 0.3
    assert doc["paper_stability"]["without_text"]["grass50"] == 0.1
    assert doc["paper_stability"]["with"]["carpet4"] == 1.0
    assert set(doc["distance_to_fall_m"]) == {"8", "16", "24"} and len(doc["cells"]) == 80


def test_experiment_eros_literal_cycle_falls(gait_tuner_cmd, run_env):
    """double_support 0 is the paper's literal cycle: at its full lift it falls on every pedestal."""
    import json
    r = run(gait_tuner_cmd, ["experiment", "eros", "--json", "--double-support", "0", "--steps", "4"], run_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["double_support"] == 0.0
    assert doc["mean_stability"]["without"] == 0.0 and doc["mean_stability"]["with"] == 0.0


def test_surfaces_listing(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["surfaces"], run_env)
    assert r.returncode == 0
    for name in ("rigid", "carpet4", "grass10", "grass30", "grass50"):
        assert name in r.stdout
    assert r.stdout.strip().splitlines()[-1].startswith("grass drag gate on this machine: ")
    r = run(gait_tuner_cmd, ["surfaces", "--surface", "carpet4"], run_env)
    assert r.returncode == 0 and "drag gate" not in r.stdout


def test_compare_writes_report(gait_tuner_cmd, run_env, tmp_path):
    r = run(gait_tuner_cmd, ["compare", "tkux-table2", "--surfaces", "rigid", "--random-rollouts", "2", "--workers",
                                  "1", "--out", str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("| tkux-table2 | rigid |") == 1        # the baseline is not listed twice
    assert (tmp_path / "compare.md").exists() and (tmp_path / "compare.png").stat().st_size > 10_000
    r = run(gait_tuner_cmd, ["compare", "nothing.yaml", "--out", str(tmp_path)], run_env)
    assert r.returncode == 2 and "no such parameter file" in r.stderr


def test_compare_reports_the_stair_held_per_direction(tmp_path):
    """The speed column: the shipped carpet4 set holds every stair of the speed studies' staircases on
    carpet4; EROS walks the stairs its step period allows; the cosine law gets '-' sideways and
    turning (it walks forward and backward only)."""
    import re

    from tuner.report.compare import run_compare
    # on round one's servos, the sets' own (on the real ones the omni set holds no backward stair)
    text = run_compare(["kidsize-omni-carpet4", "eros-x8-without", "cosine-setiono"], "kidsize-pd", ["carpet4"],
                       False, None, tmp_path / "runs", tmp_path / "out", workers=1, random_rollouts=0)
    rows = {line.split("|")[1].strip(): line.split("|")[-2].strip() for line in text.splitlines()
            if line.startswith(("| kidsize", "| eros", "| cosine")) and line.count("|") > 10}
    assert rows["kidsize-omni-carpet4"] == "0.48 / 0.32 / 0.16 / 1.60"
    assert re.fullmatch(r"\d\.\d\d / \d\.\d\d / \d\.\d\d / \d\.\d\d", rows["eros-x8-without"])
    assert re.fullmatch(r"\d\.\d\d / \d\.\d\d / - / -", rows["cosine-setiono"])
    assert re.search(r"Stair held: per direction", text)


@pytest.mark.slow   # ~15 s: two whole compares
def test_compare_rows_do_not_depend_on_workers(tmp_path):
    from tuner.report.compare import run_compare
    args = (["tkux-table2"], "kidsize", ["rigid", "carpet4"], False, None, tmp_path / "runs")
    one = run_compare(*args, tmp_path / "w1", workers=1, random_rollouts=2)
    done = []
    two = run_compare(*args, tmp_path / "w2", workers=2, progress=done.append, random_rollouts=2)
    assert one.replace("w1", "w2") == two and len(done) == 2


def test_simulate_json_is_strict_when_a_metric_is_undefined(gait_tuner_cmd, run_env):
    import json as _json
    r = run_cli(gait_tuner_cmd, ["simulate", "--params", "tkux-table2", "--surface", "grass50",
                                         "--duration", "0.01", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    assert "NaN" not in r.stdout
    m = _json.loads(r.stdout)["metrics"]
    assert m["zmp_error_x_cm"] is None and "sole sensors" in m["undefined"]["zmp_error_x_cm"]
