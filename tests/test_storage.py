"""Studies that never lose work: shared budgets, dead workers, crashed locks, torn journals, full
disks, and PostgreSQL through the real CLI (a server from the pgserver wheel on 127.0.0.1).

Each kill test checks the issue's three numbers: trials lost (a finished trial missing after
the resume), stale trials left (RUNNING at the end) and overshoot (finished trials beyond the
budget), all 0.
"""

import json
import os
import resource
import signal
import subprocess
import sys
import time
from pathlib import Path

import optuna
import pytest

from conftest import run_cli

from tuner.errors import UserError
from tuner.store.journal import FlockLock, repair_journal
from tuner.store.storage import StudyStore, normalise_url

# trials of ~0.3-1 s each (two surfaces, 8 s walks): long enough to be killed mid-trial
STUDY = """name: {name}
robot: kidsize
surfaces: {surfaces}
gait: tlipfm
base: tkux-table2
fixed: {{n_steps: 10}}
space:
  period: {{low: 0.5, high: 0.8}}
  h_z: {{low: 0.02, high: 0.06}}
objectives: [pitch_rms]
trials: {trials}
duration: 8.0
enqueue: [casadi, baselines]
sampler_seed: 5
"""
SPACE_SIZE = 2                                     # the parameters of STUDY's space
DONE = (optuna.trial.TrialState.COMPLETE, optuna.trial.TrialState.PRUNED)


SHORT = "[grass50, carpet4]"                        # ~0.3 s trials
LONG = "[grass50, grass30, grass10, carpet4]"       # ~0.7 s: kill tests aim inside a trial


def write_study(folder: Path, name: str, trials: int = 12, surfaces: str = SHORT) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(STUDY.format(name=name, trials=trials, surfaces=surfaces))
    return path


def load(name: str, storage: str | None, runs: Path) -> optuna.Study:
    store = StudyStore.open(name, storage, runs)
    return optuna.load_study(study_name=name, storage=store.optuna_storage())


def tally(study: optuna.Study) -> dict:
    trials = study.get_trials(deepcopy=False)
    return {"done": sum(t.state in DONE for t in trials),
            "running": sum(t.state == optuna.trial.TrialState.RUNNING for t in trials),
            "failed": [t for t in trials if t.state == optuna.trial.TrialState.FAIL],
            "retries": [t for t in trials if t.user_attrs.get("retry_of") is not None],
            "finished": {t.number: t.values for t in trials if t.state == optuna.trial.TrialState.COMPLETE}}


def cli(cmd, *args, env=None, **kw):
    """In this process unless the test asks for a process: an environment of its own, input (conftest.run_cli)."""
    return run_cli(cmd, [str(a) for a in args], env, **kw)


def start(cmd, *args, env=None):
    return subprocess.Popen(cmd + [str(a) for a in args], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=env, start_new_session=True)


def wait_for(pred, timeout=120.0, step=0.1, procs=()):
    deadline = time.time() + timeout
    while time.time() < deadline:
        for p in procs:
            assert p.poll() is None, p.communicate()[1]
        got = pred()
        if got:
            return got
        time.sleep(step)
    raise AssertionError("timed out waiting")


def running_worker(name, storage, runs):
    """(trial number, worker pid) of a trial being walked, or None. No time window: the caller
    stops the worker and checks that its trial is still running before it kills it."""
    try:
        study = load(name, storage, runs)
    except Exception:
        return None
    for t in study.get_trials(deepcopy=False):
        if t.state == optuna.trial.TrialState.RUNNING and "worker" in t.user_attrs \
                and alive(int(t.user_attrs["worker"]["pid"])):
            return t.number, int(t.user_attrs["worker"]["pid"])
    return None


def kill_mid_trial(name, storage, runs, procs, sig=signal.SIGKILL) -> tuple[int, int]:
    """SIGKILL a worker while it walks a trial: stop it (SIGSTOP), check that its trial is still
    running, kill; if the trial had just ended, let it go on and aim again. Synchronised on the
    stopped process, not on a moment in wall time. Returns (trial number, pid)."""
    while True:
        number, pid = wait_for(lambda: running_worker(name, storage, runs), procs=procs)
        os.kill(pid, signal.SIGSTOP)
        wait_for(lambda: stopped(pid), timeout=60)
        if holds_a_file_lock(pid):                     # stopped inside a journal write: reading
            os.kill(pid, signal.SIGCONT)               # the study would wait for it; aim again
            continue
        trial = load(name, storage, runs).trials[number]
        if trial.state == optuna.trial.TrialState.RUNNING and len(trial.params) == SPACE_SIZE:
            # walking: its parameters are drawn (a worker samples after reserving the trial)
            os.kill(pid, sig)
            if sig != signal.SIGKILL:
                os.kill(pid, signal.SIGCONT)           # a stopped process takes other signals on waking
            wait_for(lambda: not alive(pid), timeout=60)   # dead before the next aim
            return number, pid
        os.kill(pid, signal.SIGCONT)                   # it had just finished, or not begun: aim again


def stopped(pid: int) -> bool:
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in ("T", "t", "Z", "X")
    except OSError:
        return True


def holds_a_file_lock(pid: int) -> bool:
    """Does ``pid`` hold a kernel file lock (``/proc/locks``; a waiter's line has '->')?"""
    for line in Path("/proc/locks").read_text().splitlines():
        parts = line.split()
        if len(parts) > 4 and parts[1] != "->" and parts[4] == str(pid):
            return True
    return False


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return False
    return state not in ("Z", "X")


def tuned(cmd, env, folder: Path, name: str, trials: int) -> tuple[Path, Path, Path]:
    """A study tuned to its budget on the journal: (study file, runs folder, journal)."""
    study = write_study(folder, name, trials=trials)
    runs = folder / "runs"
    r = cli(cmd, "tune", study, "--workers", "1", "--runs", runs, env=env)
    assert r.returncode == 0, r.stderr
    return study, runs, runs / f"{name}.journal"


# -- the journal ---------------------------------------------------------------------------------

def test_killed_worker_trial_is_failed_and_retried_once_with_same_params(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "wk", trials=10, surfaces=LONG)
    runs = tmp_path / "runs"
    proc = start(gait_tuner_cmd, "tune", study, "--workers", "2", "--runs", runs, env=run_env)
    number, pid = kill_mid_trial("wk", None, runs, [proc])
    _, err = proc.communicate(timeout=300)
    assert proc.returncode == 0, err
    assert "worker" in err and "died" in err
    t = tally(load("wk", None, runs))
    assert t["done"] == 10 and t["running"] == 0                       # overshoot 0, stale 0
    [failed] = [f for f in t["failed"] if f.user_attrs["worker"]["pid"] == pid]
    assert failed.number == number and failed.user_attrs["failed"] == "its worker died"
    [retry] = [r for r in t["retries"] if r.user_attrs["retry_of"] == failed.number]
    assert retry.params == failed.params and retry.state in DONE


def test_workers_killed_again_and_again_are_replaced_and_their_trials_retried(gait_tuner_cmd, run_env, tmp_path):
    """Five workers killed in one run (more than the old limit of 2 per worker): each is replaced,
    each trial retried, its heartbeat file removed; the run ends when the test lowers the budget
    (a budget too large to finish first, so no kill races the end)."""
    from tuner.search.study import load_study
    from tuner.search.workers import prepare_study

    study = write_study(tmp_path, "k5", trials=100, surfaces=LONG)
    runs = tmp_path / "runs"
    proc = start(gait_tuner_cmd, "tune", study, "--trials", 5000, "--workers", "2", "--runs", runs, env=run_env)
    killed = [kill_mid_trial("k5", None, runs, [proc]) for _ in range(5)]
    spec = load_study(str(study))
    store = StudyStore.open("k5", None, runs)
    done = tally(load("k5", None, runs))["done"]
    prepare_study(spec, store, done + 3, 0, log=lambda m: None)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    assert err.count("was killed by SIGKILL; starting another") == 5, (killed, err)
    t = tally(load("k5", None, runs))
    assert t["running"] == 0
    trials = load("k5", None, runs).trials
    for number, pid in killed:
        root = trials[number].user_attrs.get("retry_of", number)      # a retry may be killed too
        retries = [r for r in t["retries"] if r.user_attrs["retry_of"] == root]
        assert retries and all(r.params == trials[number].params for r in retries)
        assert not (runs / "k5.heartbeats" / f"{os.uname().nodename}-{pid}").exists()


def test_a_worker_that_crashes_by_itself_leaves_its_trial_failed(gait_tuner_cmd, run_env, tmp_path):
    """One worker, so its parent is the only one to see it die: a native fault (SIGSEGV here) is a
    crash, its trial failed and not retried; the run goes on with a new worker."""
    study = write_study(tmp_path, "seg", trials=6, surfaces=LONG)
    runs = tmp_path / "runs"
    proc = start(gait_tuner_cmd, "tune", study, "--workers", "1", "--runs", runs, env=run_env)
    number, _ = kill_mid_trial("seg", None, runs, [proc], sig=signal.SIGSEGV)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    assert f"trial {number} crashed its worker (SIGSEGV): failed, not retried" in err, err
    t = tally(load("seg", None, runs))
    assert t["done"] == 6 and [r for r in t["retries"] if r.user_attrs["retry_of"] == number] == []
    assert load("seg", None, runs).trials[number].user_attrs["died"] == "SIGSEGV"


def test_killed_parent_takes_its_workers_and_resume_loses_nothing(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "pk", trials=10)
    runs = tmp_path / "runs"
    proc = start(gait_tuner_cmd, "tune", study, "--workers", "2", "--runs", runs, env=run_env)
    wait_for(lambda: running_worker("pk", None, runs), procs=[proc])
    pids = {int(t.user_attrs["worker"]["pid"]) for t in load("pk", None, runs).get_trials(deepcopy=False)
            if "worker" in t.user_attrs}
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    wait_for(lambda: not any(alive(p) for p in pids), timeout=10)      # no orphaned worker
    before = tally(load("pk", None, runs))["finished"]
    r = cli(gait_tuner_cmd, "tune", study, "--workers", "2", "--runs", runs, env=run_env)
    assert r.returncode == 0, r.stderr
    after = tally(load("pk", None, runs))
    assert {n: v for n, v in after["finished"].items() if n in before} == before   # lost 0
    assert after["done"] == 10 and after["running"] == 0                           # overshoot 0, stale 0


def test_lock_held_by_a_killed_process_is_no_obstacle(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "lk", trials=3)
    runs = tmp_path / "runs"
    runs.mkdir()
    journal = runs / "lk.journal"
    holder = subprocess.Popen([sys.executable, "-c", (
        "import sys, time; from tuner.store.journal import FlockLock; "
        f"a = FlockLock({str(journal)!r}); a.acquire(); "
        f"b = FlockLock({str(journal)!r}, suffix='.budget.lock'); b.acquire(); "
        "print('held', flush=True); time.sleep(600)")], stdout=subprocess.PIPE, text=True)
    assert holder.stdout.readline().strip() == "held"
    os.kill(holder.pid, signal.SIGKILL)
    holder.wait()
    # an optuna-style symlink lock with a relative target (the old spin) is ignored, too
    os.symlink("runs/lk.journal", str(journal) + ".lock")
    t0 = time.time()
    r = cli(gait_tuner_cmd, "tune", study, "--workers", "1", "--runs", os.path.relpath(runs),
            env=run_env, cwd=os.getcwd())
    assert r.returncode == 0, r.stderr
    assert time.time() - t0 < 120
    assert tally(load("lk", None, runs))["done"] == 3


def test_torn_last_line_is_cut_with_a_warning_and_never_appended_onto(gait_tuner_cmd, run_env, tmp_path):
    study, runs, journal = tuned(gait_tuner_cmd, run_env, tmp_path, "tj", 3)
    whole = journal.read_bytes()
    with open(journal, "ab") as f:
        f.write(b'{"op_code": 5, "worker_id": "x", "trial_id": 2, "user_at')      # a kill mid-write
    r = cli(gait_tuner_cmd, "tune", study, "--trials", "5", "--workers", "1", "--runs", runs, env=run_env)
    assert r.returncode == 0, r.stderr
    assert "cut a torn last line" in r.stderr
    data = journal.read_bytes()
    assert data.startswith(whole) and data.endswith(b"\n")
    for line in data.splitlines():
        json.loads(line)
    assert list(runs.glob("tj.journal.torn-*"))
    assert tally(load("tj", None, runs))["done"] == 5


def test_corrupt_line_inside_the_journal_is_one_line_error(gait_tuner_cmd, run_env, tmp_path):
    study, runs, journal = tuned(gait_tuner_cmd, run_env, tmp_path, "cj", 2)
    lines = journal.read_bytes().splitlines(keepends=True)
    lines[1] = b"not json at all\n"
    journal.write_bytes(b"".join(lines))
    r = cli(gait_tuner_cmd, "trials", study, "--runs", runs, env=run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1
    assert "corrupt" in r.stderr


def _limit_file_size(limit: int):
    def apply() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)     # the write fails with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return apply


def test_full_disk_is_one_line_and_loses_nothing(gait_tuner_cmd, run_env, tmp_path):
    study, runs, journal = tuned(gait_tuner_cmd, run_env, tmp_path, "fd", 4)
    size = journal.stat().st_size
    before = tally(load("fd", None, runs))["finished"]
    # the "disk" holds 3 kB more: the next trials' writes fail part-way
    r = cli(gait_tuner_cmd, "tune", study, "--trials", "30", "--workers", "2", "--runs", runs, env=run_env,
            preexec_fn=_limit_file_size(size + 3000))
    assert r.returncode == 3, r.stderr
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("gait-tuner: error: disk full"), r.stderr
    assert "Traceback" not in r.stderr
    data = journal.read_bytes()
    assert data.endswith(b"\n") and all(json.loads(x) is not None for x in data.splitlines())
    r = cli(gait_tuner_cmd, "tune", study, "--trials", "8", "--workers", "2", "--runs", runs, env=run_env)
    assert r.returncode == 0, r.stderr
    after = tally(load("fd", None, runs))
    assert {n: v for n, v in after["finished"].items() if n in before} == before
    assert after["done"] == 8 and after["running"] == 0


@pytest.mark.slow   # ~16 s; the journal's full disk stays in the default run
def test_full_disk_on_sqlite_is_one_line_and_every_trial_is_walked_on_resume(gait_tuner_cmd, run_env, tmp_path):
    """SQLite as the journal: one line (exit 3), no worker traceback; on resume every trial the full
    disk interrupted is retried (none left failed without a retry, but one whose parameters were
    never stored: nothing was walked, it says so) and the budget is run exactly."""
    study = write_study(tmp_path, "sq", trials=4)
    db = tmp_path / "sq.db"
    url = f"sqlite:///{db}"
    r = cli(gait_tuner_cmd, "tune", study, "--storage", url, "--workers", "1", env=run_env)
    assert r.returncode == 0, r.stderr
    before = tally(load("sq", url, tmp_path))["finished"]
    r = cli(gait_tuner_cmd, "tune", study, "--storage", url, "--trials", "60", "--workers", "2", env=run_env,
            preexec_fn=_limit_file_size(db.stat().st_size + 16_384))
    assert r.returncode == 3, r.stderr
    lines = [x for x in r.stderr.strip().splitlines() if not x.startswith("[I ")]
    assert lines[-1].startswith("gait-tuner: error: disk full"), r.stderr
    assert "Traceback" not in r.stderr and "internal error" not in r.stderr, r.stderr
    budget = tally(load("sq", url, tmp_path))["done"] + 4
    r = cli(gait_tuner_cmd, "tune", study, "--storage", url, "--trials", budget, "--workers", "2", env=run_env)
    assert r.returncode == 0, r.stderr
    after = tally(load("sq", url, tmp_path))
    assert {n: v for n, v in after["finished"].items() if n in before} == before
    assert after["done"] == budget and after["running"] == 0
    trials = load("sq", url, tmp_path).trials
    retried = {t.user_attrs.get("retry_for") for t in trials}
    assert all(t.number in retried or (not t.params and "before it drew" in t.user_attrs.get("not_retried", ""))
               for t in after["failed"]), [t.user_attrs for t in after["failed"]]


def test_resume_never_walks_a_parameter_set_twice(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "rs", trials=4)
    runs = tmp_path / "runs"
    for total in (4, 8, 12):
        r = cli(gait_tuner_cmd, "tune", study, "--trials", total, "--workers", "1", "--runs", runs, env=run_env)
        assert r.returncode == 0, r.stderr
    trials = [t for t in load("rs", None, runs).get_trials(deepcopy=False) if t.state in DONE]
    walked = [tuple(sorted(t.params.items())) for t in trials if "duplicate_of" not in t.user_attrs]
    assert len(trials) == 12 and len(walked) == len(set(walked))


def test_flock_lock_is_exclusive_and_released(tmp_path):
    a, b = FlockLock(tmp_path / "j"), FlockLock(tmp_path / "j")
    a.acquire()
    probe = subprocess.run([sys.executable, "-c", (
        "import fcntl, os, sys; fd = os.open(sys.argv[1], os.O_RDWR); "
        "fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)"), a.path], capture_output=True)
    assert probe.returncode != 0                      # held
    a.release()
    b.acquire()
    b.release()


def test_repair_journal_cuts_only_the_tail(tmp_path):
    j = tmp_path / "x.journal"
    j.write_bytes(b'{"a": 1}\n{"b": 2}\n{"c": ')
    assert repair_journal(j) == len(b'{"c": ')
    assert j.read_bytes() == b'{"a": 1}\n{"b": 2}\n'
    assert repair_journal(j) == 0


# -- URLs ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("url, words", [
    ("", "empty URL"),
    ("nonsense", "not a database URL"),
    ("sqlite://", "in-memory"),
    ("sqlite:////no/such/folder/x.db", "does not exist"),
    ("oracle://u@h/db", "unsupported database 'oracle'"),
    ("postgresql+pg8000://u@h/db", "driver 'pg8000' is not supported"),
])
def test_bad_storage_urls(url, words):
    with pytest.raises(UserError, match=words):
        normalise_url(url)


def test_plain_postgresql_url_uses_psycopg3_and_a_missing_driver_says_what_to_install(monkeypatch):
    assert normalise_url("postgresql://u@127.0.0.1:5/db").startswith("postgresql+psycopg://")
    import importlib.util
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None)
    with pytest.raises(UserError, match=r"pip install 'gait-tuner\[postgres\]'"):
        normalise_url("postgresql://u@127.0.0.1:5/db")


# -- PostgreSQL ----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def postgres():
    sys.path.insert(0, str(Path(__file__).parent))
    from postgres_server import PostgresServer
    with PostgresServer() as pg:
        yield pg


@pytest.mark.slow   # ~13 s: a PostgreSQL study of three processes
def test_postgres_two_workers_and_a_tune_share_one_budget(postgres, gait_tuner_cmd, run_env, tmp_path):
    url = postgres.create_database("share")
    study = write_study(tmp_path, "share", trials=14)
    procs = [start(gait_tuner_cmd, "worker", study, "--storage", url, env=run_env) for _ in range(2)]
    procs.append(start(gait_tuner_cmd, "tune", study, "--storage", url, "--workers", "1", env=run_env))
    errs = [p.communicate(timeout=300)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0, 0], errs
    assert not any("Heartbeat of storage" in e or "Warning" in e for e in errs), errs   # none we expect
    study_ = load("share", url, tmp_path)
    t = tally(study_)
    assert t["done"] == 14 and t["running"] == 0 and not t["failed"]
    starts = [x.user_attrs.get("start") for x in study_.get_trials(deepcopy=False) if x.user_attrs.get("start")]
    assert sorted(starts) == sorted(set(starts))                  # seed and baselines once


def test_postgres_budget_lock_excludes_another_process_and_is_released_on_error(postgres, tmp_path):
    """The budget lock (a session advisory lock, ``advisory_key``): while one store holds it
    another session cannot take it; after the block, and after a block that raised, it can; the
    same store takes it again (nothing left held)."""
    import sqlalchemy

    from tuner.store.storage import advisory_key
    url = postgres.create_database("lock")
    a = StudyStore.open("lock", normalise_url(url), tmp_path / "runs")
    other = sqlalchemy.create_engine(normalise_url(url), poolclass=sqlalchemy.pool.NullPool)
    k = advisory_key("budget-lock")

    def free() -> bool:
        with other.connect() as conn:
            got = conn.execute(sqlalchemy.text("SELECT pg_try_advisory_lock(:k)"), {"k": k}).scalar()
            if got:
                conn.execute(sqlalchemy.text("SELECT pg_advisory_unlock(:k)"), {"k": k})
            return bool(got)
    for _ in range(2):
        with a.budget_lock("lock"):
            assert not free()
        assert free()
    with pytest.raises(RuntimeError):
        with a.budget_lock("lock"):
            raise RuntimeError("a worker's error inside the lock")
    assert free()
    other.dispose()


@pytest.mark.slow   # ~14 s; the journal's stays in the default run
def test_postgres_killed_worker_trial_is_failed_and_retried(postgres, gait_tuner_cmd, run_env, tmp_path):
    url = postgres.create_database("retry")
    study = write_study(tmp_path, "retry", trials=10, surfaces=LONG)
    procs = [start(gait_tuner_cmd, "worker", study, "--storage", url, env=run_env) for _ in range(2)]
    number, pid = kill_mid_trial("retry", url, tmp_path, procs)   # a process the worker verb forked
    errs = [p.communicate(timeout=300)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errs
    t = tally(load("retry", url, tmp_path))
    assert t["done"] == 10 and t["running"] == 0
    [failed] = [f for f in t["failed"] if f.user_attrs["worker"]["pid"] == pid]
    assert failed.number == number
    [retry] = [r for r in t["retries"] if r.user_attrs["retry_of"] == failed.number]
    assert retry.params == failed.params and retry.state in DONE


@pytest.mark.parametrize("kind, n", [pytest.param("postgresql", 5, marks=pytest.mark.slow), ("sqlite", 4)])
def test_many_processes_meeting_a_fresh_database(kind, n, request, gait_tuner_cmd, run_env, tmp_path):
    url = (request.getfixturevalue("postgres").create_database("fresh") if kind == "postgresql"
           else f"sqlite:///{tmp_path / 'fresh.db'}")
    study = write_study(tmp_path, "fresh", trials=6)
    procs = [start(gait_tuner_cmd, "worker", study, "--storage", url, env=run_env) for _ in range(n)]
    errs = [p.communicate(timeout=300)[1] for p in procs]
    assert [p.returncode for p in procs] == [0] * n, errs
    t = tally(load("fresh", url, tmp_path))
    assert t["done"] == 6 and t["running"] == 0


def test_fall_constraint_is_where_optuna_and_the_dashboard_read_it(gait_tuner_cmd, run_env, tmp_path):
    _, runs, _ = tuned(gait_tuner_cmd, run_env, tmp_path, "cons", 6)
    trials = [t for t in load("cons", None, runs).get_trials(deepcopy=False) if t.state in DONE]
    for t in trials:
        value = t.user_attrs["result"]["fall_constraint"]
        assert t.system_attrs["constraints"] == [value]          # optuna-dashboard's key
        assert t.constraints == {"0": value}                     # Optuna 5's view of it
    assert any(t.constraints["0"] > 0 for t in trials) and any(t.constraints["0"] <= 0 for t in trials)
    # parameter names carry their SI unit where the dashboard and Optuna's plots read them
    names = set(trials[0].distributions)
    assert names and all(n.endswith(("[m]", "[s]", "[rad]", "[rad/m]", "[N s/m]")) or "[" not in n for n in names)
    assert any(n.endswith(" [m]") or n.endswith(" [s]") for n in names), names


def test_two_tunes_of_one_study_at_once_never_walk_a_set_twice(gait_tuner_cmd, run_env, tmp_path):
    """Both start from the file's sampler seed; each start is counted in the storage under the
    budget lock, so their samplers differ. Holds however the two overlap in time (both may even
    run one after the other): the assertion is on what was walked, not on a moment."""
    study = write_study(tmp_path, "twin", trials=16)
    runs = tmp_path / "runs"
    procs = [start(gait_tuner_cmd, "tune", study, "--workers", "1", "--runs", runs, env=run_env) for _ in range(2)]
    for p in procs:
        assert p.wait(timeout=900) == 0, p.communicate()[1]
    trials = [t for t in load("twin", None, runs).get_trials(deepcopy=False) if t.state in DONE]
    copies = [t.number for t in trials if "duplicate_of" in t.user_attrs]
    sampled = [tuple(sorted(t.params.items())) for t in trials
               if "duplicate_of" not in t.user_attrs and t.user_attrs.get("retry_of") is None]
    assert len(trials) == 16 and copies == [] and len(sampled) == len(set(sampled))
    assert load("twin", None, runs).user_attrs["starts"] == 2


def test_the_budget_changes_only_by_trials_and_says_so(gait_tuner_cmd, run_env, tmp_path):
    study = write_study(tmp_path, "bud", trials=3)
    runs = tmp_path / "runs"
    r = cli(gait_tuner_cmd, "tune", study, "--trials", 4, "--workers", "1", "--runs", runs, env=run_env)
    assert r.returncode == 0 and "budget" not in r.stderr, r.stderr
    # a plain re-run keeps the stored budget (4), not the file's 3, and changes nothing
    r = cli(gait_tuner_cmd, "tune", study, "--workers", "1", "--runs", runs, env=run_env)
    assert r.returncode == 0 and "is finished: 4 of 4" in r.stdout and "budget" not in r.stderr, r.stdout
    r = cli(gait_tuner_cmd, "tune", study, "--trials", 6, "--workers", "1", "--runs", runs, env=run_env)
    assert r.returncode == 0 and "raised from 4 to 6 trials (--trials)" in r.stderr, r.stderr
    assert tally(load("bud", None, runs))["done"] == 6


def test_a_running_worker_reads_a_lowered_budget(tmp_path):
    """The budget is read from the storage before each trial: a second `tune --trials` that
    lowers it stops a run already going at the same number (no run goes on to its own)."""
    from tuner.search.study import load_study
    from tuner.search.workers import prepare_study, work

    spec = load_study(str(write_study(tmp_path, "low", trials=40)))
    store = StudyStore.open("low", None, tmp_path / "runs")
    study, budget, run = prepare_study(spec, store, None, 0, log=lambda m: None)
    assert (budget, run) == (40, 0)
    notes = []
    _, budget, run = prepare_study(spec, store, 3, 0, log=notes.append)
    assert (budget, run) == (3, 1) and notes == ["budget of study low lowered from 40 to 3 trials (--trials); "
                                                 "every process on it stops at 3"]
    assert work(spec, store, 40, 0, log=lambda m: None) == 3      # started with 40, stops at the stored 3
    assert tally(load("low", None, tmp_path / "runs"))["done"] == 3


def test_one_worker_and_a_seed_give_the_same_study_and_pareto_lists_optunas_best(gait_tuner_cmd, run_env,
                                                                                   tmp_path):
    study = tmp_path / "par.yaml"
    study.write_text(STUDY.format(name="par", trials=8, surfaces=SHORT).replace("objectives: [pitch_rms]",
                                                                "objectives: [pitch_rms, speed]"))
    runs = []
    for i in (1, 2):
        r = cli(gait_tuner_cmd, "tune", study, "--workers", "1", "--seed", "7", "--runs", tmp_path / f"r{i}",
                env=run_env)
        assert r.returncode == 0, r.stderr
        runs.append([(t.params, t.values) for t in load("par", None, tmp_path / f"r{i}").trials])
    assert runs[0] == runs[1]
    r = cli(gait_tuner_cmd, "trials", study, "--pareto", "--json", "--runs", tmp_path / "r1", env=run_env)
    assert r.returncode == 0, r.stderr
    listed = sorted(row["number"] for row in json.loads(r.stdout)["shown"])
    assert listed == sorted(t.number for t in load("par", None, tmp_path / "r1").best_trials)


def test_pareto_pick_chooses_on_the_front(gait_tuner_cmd, run_env, tmp_path):
    from tuner.search.trials import pareto_pick
    study = tmp_path / "pp.yaml"
    study.write_text(STUDY.format(name="pp", trials=10, surfaces=SHORT).replace("objectives: [pitch_rms]",
                                                                 "objectives: [pitch_rms, speed]"))
    runs = tmp_path / "runs"
    assert cli(gait_tuner_cmd, "tune", study, "--workers", "1", "--runs", runs, env=run_env).returncode == 0
    s = load("pp", None, runs)
    front = [t for t in s.best_trials if t.constraints["0"] <= 0]
    assert pareto_pick(s, "pitch").values[0] == min(t.values[0] for t in front)
    assert pareto_pick(s, "speed").values[1] == max(t.values[1] for t in front)
    assert pareto_pick(s, "knee") in front
    r = cli(gait_tuner_cmd, "export", study, "--runs", runs, "--pareto-pick", "speed", env=run_env)
    assert r.returncode == 0, r.stderr
    assert (runs / "pp" / "best.yaml").exists()                # the default lands under runs/
    assert f"trial {pareto_pick(s, 'speed').number} " in r.stdout


KILL_AFTER_POP = """
import os, signal, sys
from pathlib import Path
from tuner.store import history
reserve = history.TrialIndex.reserve
mark = Path(os.environ["KILL_MARK"])
def killing(self, study, user_attrs=None):
    waiting = {t.number for t in self.waiting}
    trial = reserve(self, study, user_attrs)
    if trial.number in waiting and not mark.exists():      # popped an enqueued trial: die before its params
        mark.write_text(str(trial.number))
        os.kill(os.getpid(), signal.SIGKILL)
    return trial
history.TrialIndex.reserve = killing
from tuner.cli import run
sys.argv = ["gait-tuner"] + sys.argv[1:]
run()
"""


@pytest.mark.parametrize("kind", ["journal", "postgresql"])
def test_an_enqueued_trial_popped_by_a_worker_killed_before_its_params_is_walked_again(
        request, run_env, tmp_path, kind):
    """The CasADi seed and a baseline are enqueued; the worker that pops the first is killed (from inside, right after the
    pop: no timing) before it stores the seed's parameters. The seed is enqueued again with its own
    parameters and walked (it was dropped: its trial had no parameters, and the budget ran out)."""
    url = request.getfixturevalue("postgres").create_database("popped") if kind == "postgresql" else None
    study = tmp_path / "popped.yaml"
    study.write_text(STUDY.format(name="popped", trials=4, surfaces=SHORT))      # enqueues the seed and a baseline
    runs = tmp_path / "runs"
    env = {**run_env, "KILL_MARK": str(tmp_path / "killed")}
    args = ["tune", study, "--workers", "2", "--runs", runs] + (["--storage", url] if url else [])
    r = subprocess.run([sys.executable, "-c", KILL_AFTER_POP, *map(str, args)], capture_output=True, text=True,
                       env=env, timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    popped = int((tmp_path / "killed").read_text())
    trials = load("popped", url, runs).get_trials(deepcopy=False)
    dead = trials[popped]
    assert dead.state == optuna.trial.TrialState.FAIL and dead.params == {}
    seed = dead.system_attrs["fixed_params"]
    again = [t for t in trials if t.user_attrs.get("retry_for") == popped]
    assert len(again) == 1 and again[0].state in DONE, [(t.number, t.state, t.user_attrs) for t in trials]
    assert again[0].params == seed and again[0].user_attrs.get("start") == dead.user_attrs.get("start") is not None
