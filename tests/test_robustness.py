"""The robust objective, the robustness command and shipped robust results, through the real CLI."""

import json

import pytest

import gaits
from tuner.errors import UserError
from tuner.search.study import load_study
from conftest import run_cli


def run(cmd, args, env, cwd=None):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, cwd=cwd)


def test_robustness_command_strict_json_and_plot(gait_tuner_cmd, run_env, tmp_path):
    r = run(gait_tuner_cmd, ["robustness", "--params", "tkux-table2", "--surface", "rigid", "--rollouts", "4",
                             "--pushes", "0.5,3", "--push-rollouts", "2", "--seed", "3", "--json",
                             "--plot", str(tmp_path)], run_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)             # strict: no NaN
    assert 0.0 <= doc["survival"] <= 1.0 and doc["rollouts"] == 4
    assert set(doc["push_survival"]) == {"0.5", "3"}
    assert doc["push_survival"]["3"] <= doc["push_survival"]["0.5"]
    assert (tmp_path / "robustness.png").stat().st_size > 10_000
    # the same seed again, with another number of workers: the same numbers
    r2 = run(gait_tuner_cmd, ["robustness", "--params", "tkux-table2", "--surface", "rigid", "--rollouts", "4",
                              "--pushes", "0.5,3", "--push-rollouts", "2", "--seed", "3", "--json",
                              "--workers", "1"], run_env)
    assert json.loads(r2.stdout) == doc


@pytest.mark.parametrize("args,message", [
    (["--pushes", "abc"], "--pushes 'abc': expected comma-separated impulses"),
    (["--pushes", "0,1"], "each impulse must be in (0, 50] N s"),
    (["--stabiliser"], "holds no stabiliser section"),
    (["--randomisation", "RND"], "unknown field 'masses' (allowed: mass_scale"),
])
def test_robustness_bad_input_is_one_line(gait_tuner_cmd, run_env, tmp_path, args, message):
    (tmp_path / "rnd.yaml").write_text("masses: 0.1\n")
    args = [str(tmp_path / "rnd.yaml") if a == "RND" else a for a in args]
    r = run(gait_tuner_cmd, ["robustness", "--params", "tkux-table2", "--rollouts", "1"] + args, run_env)
    assert r.returncode == 2, r.stdout + r.stderr
    assert r.stderr.count("\n") == 1 and message in r.stderr


STUDY = """gait: tlipfm
surfaces: [rigid]
trials: 3
duration: 2.0
base: tkux-table2
enqueue: [baselines]
space:
  t1: {low: 0.12, high: 0.18}
  stabiliser.k_ankle_pitch: {low: 0.0, high: 1.0}
robust:
  rollouts: 2
  risk: cvar25
  min_survival: 0.5
stabiliser: {enabled: true, d_ankle_pitch: 0.05}
"""


def test_a_small_robust_study_end_to_end(gait_tuner_cmd, run_env, tmp_path):
    study = tmp_path / "tiny-robust.yaml"
    study.write_text(STUDY)
    spec = load_study(str(study))
    assert spec.kind == "robust" and spec.settings.rollouts == 2 and spec.stabiliser.enabled
    r = run(gait_tuner_cmd, ["tune", str(study), "--runs", str(tmp_path / "runs"), "--workers", "2"], run_env)
    assert r.returncode == 0, r.stderr
    r = run(gait_tuner_cmd, ["export", str(study), "--runs", str(tmp_path / "runs"), "--out",
                             str(tmp_path / "best.yaml")], run_env)
    assert r.returncode == 0, r.stderr
    best = gaits.load_gait_file(tmp_path / "best.yaml")
    assert best.stabiliser is not None and best.stabiliser.enabled
    assert best.stabiliser.d_ankle_pitch == pytest.approx(0.05)            # the study's fixed value
    assert 0.0 <= best.stabiliser.k_ankle_pitch <= 1.0                      # a searched gain
    r = run(gait_tuner_cmd, ["robustness", "--params", str(tmp_path / "best.yaml"), "--surface", "rigid",
                             "--rollouts", "2", "--pushes", "", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["stabiliser"] is True


@pytest.mark.parametrize("edit,message", [
    (lambda s: s.replace("rollouts: 2", "rollouts: 0"), "robust.rollouts = 0: expected a whole number in [1, 1000]"),
    (lambda s: s.replace("risk: cvar25", "risk: cvar10"), "robust.risk = 'cvar10': expected one of cvar25, worst, mean"),
    (lambda s: s.replace("min_survival: 0.5", "min_survival: '0.9'"), "robust.min_survival = '0.9': expected a fraction"),
    (lambda s: s.replace("stabiliser.k_ankle_pitch", "stabiliser.k_knee"), "unknown stabiliser gain 'k_knee'"),
    (lambda s: s.replace("high: 1.0}\nrobust", "high: 9.0}\nrobust"), "leaves the allowed range [0.0, 5.0] rad/rad"),
    (lambda s: s.replace("stabiliser: {enabled: true, d_ankle_pitch: 0.05}", ""), "needs a stabiliser: section"),
    (lambda s: s.replace("stabiliser: {enabled: true,", "stabiliser: {enabled: 'yes',"), "stabiliser.enabled = 'yes'"),
    (lambda s: s.replace("  risk: cvar25", "  risk: cvar25\n  randomisation: {tilt_deg: 30}"),
     "robust.randomisation: randomisation.tilt_deg = 30"),
])
def test_robust_study_fields_are_checked(tmp_path, edit, message):
    study = tmp_path / "s.yaml"
    study.write_text(edit(STUDY))
    with pytest.raises(UserError) as err:
        load_study(str(study))
    assert message in str(err.value)


def test_shipped_robust_results_load_and_say_where_they_come_from():
    from tuner.params_io import list_results, resolve_params
    assert {"kidsize-robust-grass50", "kidsize-robust-fb-grass50"} <= set(list_results())
    open_loop = resolve_params("kidsize-robust-grass50", None)
    closed = resolve_params("kidsize-robust-fb-grass50", None)
    assert open_loop.stabiliser is None and closed.stabiliser.enabled
    for gf, study in ((open_loop, "kidsize-robust-grass50"), (closed, "kidsize-robust-fb-grass50")):
        assert gf.description.startswith(f"study {study} trial ") and "(commit " in gf.description
        assert "+ local changes" not in gf.description


@pytest.mark.slow
@pytest.mark.parametrize("name", ["kidsize-robust-grass50", "kidsize-robust-fb-grass50"])
def test_shipped_robust_results_survive_randomisation(gait_tuner_cmd, run_env, name):
    r = run(gait_tuner_cmd, ["robustness", "--params", name, "--surface", "grass50", "--rollouts", "100",
                             "--pushes", "", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["survival"] >= 0.95


def test_trials_lists_a_study_and_exactly_optunas_best(gait_tuner_cmd, run_env, tmp_path):
    import optuna
    from tuner.search.workers import open_storage
    study_file = tmp_path / "listed.yaml"
    study_file.write_text(STUDY.replace("trials: 3", "trials: 4"))
    r = run(gait_tuner_cmd, ["tune", str(study_file), "--runs", str(tmp_path / "runs")], run_env)
    assert r.returncode == 0, r.stderr
    r = run(gait_tuner_cmd, ["trials", str(study_file), "--runs", str(tmp_path / "runs"), "--json",
                             "--sort", "number"], run_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert [row["number"] for row in doc["shown"]] == [0, 1, 2, 3]
    assert all(0.0 <= row["params"]["stabiliser.k_ankle_pitch"] <= 1.0 for row in doc["shown"])
    r = run(gait_tuner_cmd, ["trials", str(study_file), "--runs", str(tmp_path / "runs"), "--json", "--pareto"],
            run_env)
    spec = load_study(str(study_file))
    study = optuna.load_study(study_name=spec.name, storage=open_storage(spec, None, tmp_path / "runs"))
    assert sorted(row["number"] for row in json.loads(r.stdout)["shown"]) == \
        sorted(t.number for t in study.best_trials)
    r = run(gait_tuner_cmd, ["trials", str(study_file), "--runs", str(tmp_path / "none")], run_env)
    assert r.returncode == 2 and "run `gait-tuner tune` first" in r.stderr


def test_a_walk_held_in_place_is_counted_stalled_not_just_survived():
    """Exact: a table's rollout that stays up having covered less than MIN_PROGRESS of its plan is
    stalled; a fall, an online walk (no plan: covered None) and a walk that covered its plan are not."""
    from tuner.sim.metrics import MIN_PROGRESS
    from tuner.sim.robustness import RobustnessReport

    def row(survived, covered):
        return {"survived": survived, "fell": not survived, "outcome": "completed" if survived else "fell",
                "t_fall_s": 1.0, "pitch_rms_deg": 2.0, "speed_mps": 0.1, "covered": covered}
    rows = [row(True, MIN_PROGRESS - 0.01), row(True, -0.002), row(True, MIN_PROGRESS), row(True, 1.1),
            row(False, 0.0), row(True, None)]
    rep = RobustnessReport("kidsize", "grass50", "set", False, rows, {})
    assert rep.stalled == 2
    d = rep.to_dict()
    assert d["stalled"] == 2 and d["survival"] == pytest.approx(5 / 6)
    assert d["covered"][1] == pytest.approx(MIN_PROGRESS - 0.005)      # the median of the four that have one
    assert "stalled         2 of the rollouts that stayed up" in rep.format()
    assert "stalled" not in RobustnessReport("kidsize", "grass50", "set", False, rows[2:4], {}).format()


def test_robustness_says_when_a_ground_holds_the_robot_in_place(gait_tuner_cmd, run_env):
    """The blade layer the calibration chose for 50 mm grass (creeping tips) holds the omni set's
    feet: every walk stays up and none walks. Survival says 100 %; ``stalled`` says why that is not
    a walk. On the built-in grass50 the same walks cover their plan (round one's servos: the calibration's)."""
    from conftest import ROOT
    args = ["robustness", "--params", "kidsize-omni-grass50", "--command", "0.2,0,0", "--rollouts", "2",
            "--pushes", "0.5", "--push-rollouts", "1", "--json", "--robot", "kidsize-pd", "--surface"]
    held = run(gait_tuner_cmd, args + [str(ROOT / "examples/surfaces/calibrated/grass50-blades.yaml")], run_env)
    assert held.returncode == 0, held.stderr
    doc = json.loads(held.stdout)
    assert doc["survival"] == 1.0 and doc["stalled"] == 2 and doc["covered"][2] < 0.1
    free = json.loads(run(gait_tuner_cmd, args + ["grass50"], run_env).stdout)
    assert free["stalled"] == 0 and free["covered"][0] > 0.5
