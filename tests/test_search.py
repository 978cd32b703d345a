"""Tuning studies through the real CLI: run, resume after a kill, export, two workers, bad files."""

import json
import os
import signal
import subprocess
import time

import optuna
import pytest

from conftest import run_cli

STUDY = """name: {name}
robot: kidsize
surfaces: [rigid]
gait: eros
base: eros-x8-with
fixed: {{foot_lift: 0.02, n_steps: 4}}
space:
  heel_gain: {{low: 0.0, high: 4.0}}
  c_dc: {{low: 0.0, high: 3.0}}
  n_areas: {{low: 1, high: 6}}
objectives: [pitch_rms]
trials: 6
duration: 2.0
enqueue: [casadi, baselines]
sampler_seed: 3
"""


def write_study(tmp_path, name="tiny", text=STUDY):
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.format(name=name))
    return path


def run(cmd, args, env, **kw):
    """In this process unless the test asks for a process (conftest.run_cli)."""
    return run_cli(cmd, args, env, **kw)


def load(tmp_path, name):
    from optuna.storages import JournalStorage
    from optuna.storages.journal import JournalFileBackend
    storage = JournalStorage(JournalFileBackend(str(tmp_path / "runs" / f"{name}.journal")))
    return optuna.load_study(study_name=name, storage=storage)


def test_tune_export_simulate_reproduces(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path)
    runs = str(tmp_path / "runs")
    r = run(gait_tuner_cmd, ["tune", str(study), "--runs", runs], run_env)
    assert r.returncode == 0, r.stderr
    assert "best trial" in r.stdout
    s = load(tmp_path, "tiny")
    done = [t for t in s.trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(done) == 6
    starts = [t.user_attrs.get("start") for t in s.trials[:2]]
    assert starts == ["casadi seed", "baseline 0"]            # the seed and the base go first
    out = tmp_path / "best.yaml"
    r = run(gait_tuner_cmd, ["export", str(study), "--runs", runs, "--out", str(out)], run_env)
    assert r.returncode == 0, r.stderr
    assert out.exists() and (tmp_path / "best.joints.csv").exists()
    number = int(r.stdout.split()[1])
    stored = next(t for t in done if t.number == number).user_attrs["result"]["per_surface"]["rigid"]
    r = run(gait_tuner_cmd, ["simulate", "--params", str(out), "--surface", "rigid", "--duration", "2.0",
                             "--json"], run_env)
    assert r.returncode == 0, r.stderr
    again = json.loads(r.stdout)["metrics"]
    for key in ("pitch_rms_deg", "pitch_pm_deg", "distance_m", "zmp_error_x_cm", "fell"):
        assert again[key] == stored[key]                           # exactly: the simulation is deterministic


def test_a_study_with_no_feasible_trial_says_so_and_offers_no_export(gait_tuner_cmd, run_env, tmp_path):
    """Every draw here ends single support after the step (t2 > period): rejected before it walked.
    No rejected trial is named best (its penalty is not a walk's score): the summary says none walked,
    why, and that there is nothing to export (not `export it with`)."""
    study = tmp_path / "rej.yaml"
    study.write_text("name: rej\nrobot: kidsize\nsurfaces: [rigid]\ngait: tlipfm\nbase: tkux-table2\n"
                     "space:\n  period: {low: 0.2, high: 0.21}\n  t2: {low: 0.3, high: 0.4}\n"
                     "trials: 2\nenqueue: []\nsampler_seed: 0\n")
    r = run(gait_tuner_cmd, ["tune", str(study), "--runs", str(tmp_path / "runs"), "--workers", "1"], run_env)
    assert r.returncode == 0, r.stderr
    last = r.stdout.strip().splitlines()
    assert last[-1].startswith("no trial walked yet: study 'rej': every completed trial was rejected before it "
                               "walked (the first: ") and "t2" in last[-1], r.stdout
    assert not any(line.startswith("best trial") for line in last) and "export it with" not in r.stdout


def test_a_rejected_trial_is_never_the_best_even_when_every_walk_fell():
    """A rejected draw scores a penalty (twice a fall's) that can be lower than a fallen walk's
    score: the walked trial is the best, not the rejected one."""
    from optuna.distributions import FloatDistribution
    from tuner.search.trials import NothingWalked, best_trial
    study = optuna.create_study(direction="minimize")
    dist = {"period": FloatDistribution(0.1, 1.0)}
    rejected = {"fell": True, "fall_constraint": 1.0, "invalid": "t2 0.4 s is past the period 0.2 s"}
    study.add_trial(optuna.trial.create_trial(params={"period": 0.2}, distributions=dist, value=200.0,
                                              user_attrs={"result": rejected}))
    with pytest.raises(NothingWalked, match="rejected before it walked"):
        best_trial(study)
    # a trial that walked and was stopped at its falls (pruned) is said, not hidden behind "rejected"
    pruned = {"fell": True, "fall_constraint": 0.17, "invalid": None, "survival": 0.0, "hopeless": True}
    study.add_trial(optuna.trial.create_trial(params={"period": 0.25}, distributions=dist,
                                              state=optuna.trial.TrialState.PRUNED, user_attrs={"result": pruned}))
    with pytest.raises(NothingWalked, match=r"1 trial\(s\) walked and fell below the minimum survival") as caught:
        best_trial(study)
    assert caught.value.fell == 1
    study.add_trial(optuna.trial.create_trial(params={"period": 0.3}, distributions=dist, value=250.0,
                                              user_attrs={"result": {"fell": True, "fall_constraint": 1.0}}))
    assert best_trial(study).params == {"period": 0.3}


def test_resume_after_kill_keeps_finished_trials(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "killed")
    runs = str(tmp_path / "runs")
    proc = subprocess.Popen(gait_tuner_cmd + ["tune", str(study), "--trials", "200", "--runs", runs],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=run_env,
                            start_new_session=True)
    deadline = time.time() + 120
    n = 0
    while time.time() < deadline:
        time.sleep(0.5)
        try:
            n = len([t for t in load(tmp_path, "killed").trials if t.state.is_finished()])
        except Exception:
            n = 0
        if n >= 4:
            break
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    before = {t.number: t.values for t in load(tmp_path, "killed").trials
              if t.state == optuna.trial.TrialState.COMPLETE}
    assert len(before) >= 4
    total = len(before) + 3
    r = run(gait_tuner_cmd, ["tune", str(study), "--trials", str(total), "--runs", runs], run_env)
    assert r.returncode == 0, r.stderr
    after = load(tmp_path, "killed").trials
    kept = {t.number: t.values for t in after if t.number in before}
    assert kept == before
    assert len([t for t in after if t.state in (optuna.trial.TrialState.COMPLETE,
                                                optuna.trial.TrialState.PRUNED)]) == total


def test_two_workers_finish_exactly_without_duplicates(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "pair")
    r = run(gait_tuner_cmd, ["tune", str(study), "--trials", "10", "--workers", "2",
                             "--runs", str(tmp_path / "runs")], run_env)
    assert r.returncode == 0, r.stderr
    trials = load(tmp_path, "pair").trials
    assert len(trials) == 10
    assert all(t.state == optuna.trial.TrialState.COMPLETE for t in trials)
    assert len({t.number for t in trials}) == 10


@pytest.mark.parametrize("edit,message", [
    (lambda s: s.replace("c_dc: {low: 0.0", "c_dk: {low: 0.0"), "space: unknown or non-numeric parameter 'c_dk'"),
    (lambda s: s.replace("heel_gain: {low: 0.0, high: 4.0}", "heel_gain: {low: 4.0, high: 1.0}"),
     "space: heel_gain bounds reversed or empty: low = 4.0, high = 1.0"),
    (lambda s: s.replace("surfaces: [rigid]", "surfaces: [ice]"), "surfaces: --surface 'ice': not a built-in"),
    (lambda s: s.replace("trials: 6", "trials: many"), "trials must be an integer"),
    (lambda s: s + "colour: red\n", "unknown key 'colour'"),
    (lambda s: s.replace("heel_gain: {low: 0.0, high: 4.0}", "heel_gain: {low: 0.0, high: 40.0}"),
     "leaves the parameter's allowed range [0.0, 10.0] rad/m"),
])
def test_malformed_study_exits_2(gait_tuner_cmd, run_env, tmp_path, edit, message):
    path = tmp_path / "bad.yaml"
    path.write_text(edit(STUDY.format(name="bad")))
    r = run(gait_tuner_cmd, ["tune", str(path), "--runs", str(tmp_path / "runs")], run_env)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert message in r.stderr
    assert r.stderr.strip().count("\n") == 0


def test_export_without_runs_exits_2(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "never")
    r = run(gait_tuner_cmd, ["export", str(study), "--runs", str(tmp_path / "runs")], run_env)
    assert r.returncode == 2 and "run `gait-tuner tune` first" in r.stderr


def test_shipped_studies_load(gait_tuner_cmd, run_env):
    r = run(gait_tuner_cmd, ["studies"], run_env)
    assert r.returncode == 0
    for name in ("quickstart", "eros-grass50", "tlipfm-carpet4", "eros-robust", "eros-paper"):
        assert name in r.stdout


def _default_sigint() -> None:
    """Ctrl-C reaches a program run in a terminal's foreground; a shell without job control
    (a CI script, a background job) starts its children with SIGINT ignored, which Python keeps:
    the child gets what the terminal would give it."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_stops_cleanly_and_keeps_trials(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "interrupted")
    # a budget it cannot finish before the interrupt (its trials take ~0.1 s; 500 could end first)
    proc = subprocess.Popen(gait_tuner_cmd + ["tune", str(study), "--trials", "100000", "--workers", "2",
                                              "--runs", str(tmp_path / "runs")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=run_env,
                            start_new_session=True, preexec_fn=_default_sigint)
    deadline = time.time() + 120
    while time.time() < deadline:
        time.sleep(0.5)
        try:
            if len([t for t in load(tmp_path, "interrupted").trials if t.state.is_finished()]) >= 4:
                break
        except Exception:
            pass
    os.killpg(proc.pid, signal.SIGINT)                  # what Ctrl-C sends to the terminal's group
    out, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert "interrupted: finished trials are kept" in err
    assert "Traceback" not in err
    done = [t for t in load(tmp_path, "interrupted").trials if t.state == optuna.trial.TrialState.COMPLETE]
    assert len(done) >= 4


def test_sqlite_storage_url(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "sq")
    url = f"sqlite:///{tmp_path / 'studies.db'}"
    r = run(gait_tuner_cmd, ["tune", str(study), "--trials", "4", "--workers", "2", "--storage", url], run_env)
    assert r.returncode == 0, r.stderr
    s = optuna.load_study(study_name="sq", storage=url)
    assert len([t for t in s.trials if t.state == optuna.trial.TrialState.COMPLETE]) == 4
    r = run(gait_tuner_cmd, ["export", str(study), "--storage", url, "--out", str(tmp_path / "b.yaml")], run_env)
    assert r.returncode == 0, r.stderr


def test_the_dashboard_shows_the_objectives_names(tmp_path):
    """optuna-dashboard reads the study's metric names: set once, from the study's objectives."""
    import warnings

    from tuner.store.storage import StudyStore
    from tuner.search.study import load_study
    from tuner.search.workers import open_study
    spec = load_study("quickstart")
    store = StudyStore.open(spec.name, None, tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")             # and without a warning shown
        study = open_study(spec, store.optuna_storage(), 0)
    assert study.metric_names == ["pitch score [deg]"]


@pytest.mark.parametrize("study, min_survival", [pytest.param("kidsize-robust-grass50", 0.0, marks=pytest.mark.slow), ("kidsize-robust-grass50", 0.99),
                                                  ("kidsize-engine-carpet4", 0.0), ("kidsize-omni-rigid", None)])
def test_a_trial_on_two_threads_is_the_one_at_a_time_trial(study, min_survival):
    """Threads change only when the walks run: every walk (robust, match, speed), the early stop
    of a hopeless trial (min_survival 0.99 stops this set at its first fall) and the result are
    the same."""
    from dataclasses import replace

    from tuner.search.objective import Evaluator
    from tuner.search.study import load_study
    spec = load_study(study)
    if spec.kind == "robust":
        spec = replace(spec, settings=replace(spec.settings, rollouts=6, min_survival=min_survival))
    if spec.kind == "match":
        spec = replace(spec, surfaces=spec.surfaces[:1], settings=replace(spec.settings, walks=3, min_survival=0.0))
    drive = spec.drive_for({}, source="test")
    one, two = (Evaluator(spec, threads=n).evaluate(drive) for n in (1, 2))
    assert one == two
    if min_survival is not None:
        assert one.hopeless == (min_survival > 0)
    if one.hopeless:    # its first fall stopped it: the constraint says how long it stood too
        total = spec.settings.rollouts * len(spec.surfaces)
        ungraded = min_survival - (1 - 1 / total) + 1e-3
        assert ungraded < one.fall_constraint < ungraded + 1 / (total + 1)


def test_the_progress_bar_counts_feasible_trials_and_trials_with_a_fall():
    """The bar said "falls N" for the trials in which any walk fell, read as falls counted and beside a
    best trial that kept every walk; it says how many trials are feasible and how many had a fall."""
    from optuna.distributions import FloatDistribution
    from tuner.search.trials import progress_note
    study = optuna.create_study(direction="minimize")
    dist = {"period": FloatDistribution(0.1, 1.0)}
    for value, result, state in ((3.0, {"fell": False, "fall_constraint": -0.5}, "COMPLETE"),
                                 (9.0, {"fell": True, "fall_constraint": -0.1}, "COMPLETE"),
                                 (None, {"fell": True, "fall_constraint": 0.4, "invalid": None}, "PRUNED")):
        study.add_trial(optuna.trial.create_trial(params={"period": 0.3}, distributions=dist, value=value,
                                                  state=getattr(optuna.trial.TrialState, state),
                                                  user_attrs={"result": result}))
    assert progress_note(study.get_trials()) == "2 feasible, 2 with a fall"


def test_an_optuna_plot_carries_our_title_alone():
    """Optuna titles its importances plot on the left: ours replaces it (the two were drawn over
    each other in study_importances.png)."""
    import warnings
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import optuna
    import optuna.visualization.matplotlib as ovm
    from tuner.report.compare import retitle
    optuna.logging.set_verbosity(optuna.logging.ERROR)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    study.optimize(lambda t: t.suggest_float("x", 0, 1) ** 2 + t.suggest_float("y", 0, 1), n_trials=12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ax = ovm.plot_param_importances(study)
    assert ax.get_title(loc="left")              # Optuna's own, which would sit beside ours
    retitle(ax, "parameter importances, study s")
    assert [ax.get_title(loc=loc) for loc in ("left", "center", "right")] == ["", "parameter importances, study s", ""]
    plt.close(ax.figure)


def test_a_study_resumed_with_other_scoring_is_refused_a_wider_space_is_not(gait_tuner_cmd, run_env, tmp_path):
    """init re-run into the same folder, or a study file edited, resumed the stored trials scored by
    another robot, surface or scenario beside the new ones, without a word. The scoring parts are
    stored with the study: another surface is one line naming it; a wider space resumes."""
    study = write_study(tmp_path, "scored", STUDY.replace("trials: 6", "trials: 2"))
    runs = str(tmp_path / "runs")
    r = run(gait_tuner_cmd, ["tune", str(study), "--runs", runs], run_env)
    assert r.returncode == 0, r.stderr
    stored = load(tmp_path, "scored").user_attrs["scoring"]
    assert {"robot", "surfaces", "scenario", "objectives", "fixed", "engine"} <= set(stored)
    text = study.read_text()
    study.write_text(text.replace("surfaces: [rigid]", "surfaces: [carpet4]"))
    r = run(gait_tuner_cmd, ["tune", str(study), "--runs", runs, "--trials", "3"], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "scored with another surfaces than" in r.stderr and "give the study a new name" in r.stderr
    assert len(load(tmp_path, "scored").trials) == 2
    study.write_text(text.replace("c_dc: {low: 0.0, high: 3.0}", "c_dc: {low: 0.0, high: 3.5}"))
    r = run(gait_tuner_cmd, ["tune", str(study), "--runs", runs, "--trials", "3"], run_env)
    assert r.returncode == 0, r.stderr
    assert len([t for t in load(tmp_path, "scored").trials if t.state == optuna.trial.TrialState.COMPLETE]) == 3


def test_a_share_of_another_parameter_is_searched_so_every_draw_is_valid():
    """t2: {low, high, of: period}: the sampled share times the sampled period; an enqueued start
    becomes its share; none of 300 draws breaks t1 < t2 < period (as times, a short period drew a t2
    past it and the trial was rejected)."""
    import optuna
    from tuner.search.objective import suggest
    from tuner.search.study import load_study
    from tuner.search.workers import _clip_to_space
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "shares.yaml"
        path.write_text("name: shares\nrobot: kidsize\nsurfaces: [rigid]\ngait: tlipfm\nbase: tkux-table2\n"
                        "space:\n  period: {low: 0.25, high: 0.8}\n  t1: {low: 0.1, high: 0.35, of: period}\n"
                        "  t2: {low: 0.65, high: 0.9, of: period}\nobjectives: [pitch_rms]\ntrials: 2\n")
        spec = load_study(str(path))
        assert [r.label for r in spec.space] == ["period [s]", "t1 [x period]", "t2 [x period]"]
        study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=1))
        for _ in range(300):
            trial = study.ask()
            p = spec.params_for(suggest(trial, spec))
            assert 0 < p.t1 < p.t2 < p.period and (p.t2 - p.t1) >= 0.3 * p.period - 1e-9
            study.tell(trial, 0.0)
        start = _clip_to_space(spec, spec.base)
        assert start["t2 [x period]"] == pytest.approx(spec.base.t2 / spec.base.period)
        bad = path.read_text().replace("of: period}\n  t2", "of: step_length}\n  t2").replace("high: 0.35", "high: 1.5")
        path.write_text(bad)
        with pytest.raises(Exception, match="t1 as a share of step_length: low and high in"):
            load_study(str(path))


def test_a_study_moved_with_its_robot_scores_the_same(tmp_path):
    """The scoring parts stand on the robot's own file and numbers, not on where it lies: a study
    folder moved (or copied to another machine) resumes; the MJCF edited does not."""
    import shutil
    from tuner.search.study import load_study
    from tuner.search.workers import scoring_parts
    from conftest import ROOT
    a = tmp_path / "a"
    a.mkdir()
    for f in ("kid3kg.xml", "kid3kg.yaml"):
        shutil.copy(ROOT / "examples" / "robots" / "kid3kg" / f, a / f)
    (a / "study.yaml").write_text(STUDY.format(name="moved").replace("robot: kidsize", "robot: kid3kg.yaml"))
    before = scoring_parts(load_study(str(a / "study.yaml")))
    shutil.copytree(a, tmp_path / "b")
    assert scoring_parts(load_study(str(tmp_path / "b" / "study.yaml"))) == before
    xml = tmp_path / "b" / "kid3kg.xml"
    xml.write_text(xml.read_text().replace('mass="', 'mass="1', 1))
    after = scoring_parts(load_study(str(tmp_path / "b" / "study.yaml")))
    assert after["robot"] != before["robot"] and after["surfaces"] == before["surfaces"]
