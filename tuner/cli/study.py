"""Studies: run one (tune), join one from another machine (worker), list its trials (trials), write a trial as a set (export)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import click

import gaits
from gaits.files import write_files_atomic, make_folder

from ..errors import EXIT_INTERNAL, UserError
from ..robots.joint_table import joint_table_file
from ..search.workers import runs_of, tuned_study
from ..report.provenance import commit_of
from .walks import _tail
from .options import OutPath, workers_option, JSON_OPTION, RUNS_OPTION, COMMANDS_OPTION, TAIL_OPTION, COMMAND_OPTION, parse_command, JOINT_NAMES_OPTION, FORMAT_OPTION, CLIP_OPTION, bar_options, storage_option


def _study_progress(spec, total: int):
    """A tqdm bar over the study's finished trials, and the callback that refreshes it."""
    from tqdm import tqdm

    from ..search.trials import DONE_STATES, best_trial, progress_note
    # a terminal gets a live bar; a log file (CI, nohup) a line every 15 s rather than every poll
    bar = tqdm(total=total, unit="trial", dynamic_ncols=True, **bar_options())

    def progress(study) -> None:
        done = study.get_trials(deepcopy=False, states=DONE_STATES)
        bar.n = min(len(done), total)
        try:
            best = f"{best_trial(study).values[0]:.2f}"
        except KeyError:
            best = "-"
        bar.set_postfix_str(f"best {best}, {progress_note(done)}", refresh=False)
        bar.update(0)                                  # prints when mininterval has passed
    return bar, progress


def _run_and_report(spec, store, study_file: str, storage: str | None, total: int | None, workers: int,
                    seed: int, verb: str, as_json: bool = False) -> None:
    """Prepare the study, run its workers here with a bar, then say its best trial and how to export it
    (a full disk said in one line). ``as_json``: the words go to stderr and stdout is one JSON object
    (the study, its budget and counts, its best trial or why there is none, the export command)."""
    import optuna

    from ..store.storage import full_disk_in_one_line
    optuna.logging.set_verbosity(optuna.logging.WARNING)
    result: dict = {"study": spec.name, "storage": str(store.where)}

    def say(line: str) -> None:
        click.echo(line, err=as_json)

    with full_disk_in_one_line(store.where):
        _run_and_say(spec, store, study_file, storage, total, workers, seed, verb, say, result)
    if as_json:
        import json
        click.echo(json.dumps(result, indent=2, allow_nan=False))


def _run_and_say(spec, store, study_file: str, storage: str | None, total: int | None, workers: int, seed: int,
                 verb: str, say: Callable[[str], None], result: dict) -> None:
    """:func:`_run_and_report`'s work: its lines through ``say``, its figures into ``result``."""
    from ..search.trials import DONE_STATES, NothingWalked, best_trial, trial_feasible, trial_fell
    from ..search.workers import WorkersDying, prepare_study, run_workers
    study, budget, run = prepare_study(spec, store, total, seed)
    done = len(study.get_trials(deepcopy=False, states=DONE_STATES))
    say(f"study {spec.name}: {spec.gait} on {spec.robot} / {', '.join(spec.surfaces)} "
        f"({spec.aggregate if len(spec.surfaces) > 1 else 'single surface'}), "
        f"budget {budget} trials ({done} finished), {workers} worker(s) here, storage {store.where}")
    if spec.controller is not None:
        say(f"study {spec.name} runs the code of a controller of your own: {spec.controller.source}")
    if done >= budget:
        say(f"study {spec.name} is finished: {done} of {budget} trials "
            f"(raise the budget with `gait-tuner tune {study_file} --trials N`)")
    else:
        if workers > 1:
            say("note: with several workers the trials' order, and so the best trial, depends on "
                "timing; --workers 1 --seed S gives the same study every run")
        bar, progress = _study_progress(spec, budget)
        try:
            study = run_workers(spec, store, study, budget, workers, seed, progress, run=run)
        except KeyboardInterrupt:
            bar.close()
            click.echo(f"interrupted: finished trials are kept in {store.where}; "
                       f"run the same command to resume", err=True)
            raise SystemExit(130) from None
        except WorkersDying as exc:
            bar.close()
            click.echo(f"gait-tuner: error: {exc}", err=True)
            raise SystemExit(EXIT_INTERNAL) from None
        finally:
            bar.close()
    finished = study.get_trials(deepcopy=False, states=DONE_STATES)
    result.update(budget=budget, finished=len(finished), feasible=sum(1 for x in finished if trial_feasible(x)),
                  fell=sum(1 for x in finished if trial_fell(x)), best=None, export=None, why=None)
    if verb == "worker":
        say(f"study {spec.name}: budget reached")
        return
    try:
        t = best_trial(study)
    except NothingWalked as exc:
        if exc.fell:
            result["why"] = (f"no trial kept a walk yet: {exc}; no best trial to export: start from a set that "
                             f"stands its walks, or lower the scenario's min_survival")
        else:
            result["why"] = (f"no trial walked yet: {exc}; no best trial to export: narrow the space "
                             f"to draws that can walk")
        say(result["why"])
        return
    except KeyError:          # every trial was pruned (a randomised trial stopped at its falls) or failed
        states = [x.state.name.lower() for x in study.get_trials(deepcopy=False)]
        counts = ", ".join(f"{states.count(k)} {k}" for k in dict.fromkeys(states))
        result["why"] = (f"no trial of study {spec.name} completed yet ({counts}): no best trial to export; give it "
                         f"more trials (resume with the same command and --trials N), or a wider space")
        say(result["why"])
        return
    n_fell = result["fell"]
    n_infeasible = result["finished"] - result["feasible"]
    say(spec.scenario_room.describe_best(spec.settings, t, fell=trial_fell(t), falls=n_fell,
                                         infeasible=n_infeasible))
    result["best"] = {"trial": t.number, "values": dict(zip(spec.objectives, (float(v) for v in t.values))),
                      "feasible": bool(trial_feasible(t)), "fell": bool(trial_fell(t))}
    if not trial_feasible(t):
        result["why"] = (f"no feasible trial of study {spec.name} yet: nothing worth exporting; give it more trials "
                         f"(resume with the same command and --trials N), or a wider space (`export --trial N` "
                         f"writes one anyway)")
        say(result["why"])
        return
    result["export"] = (f"gait-tuner export {study_file}" + (f" --storage {storage}" if storage else "")
                        + (" --pareto-pick knee" if len(spec.objectives) > 1 else ""))
    say(f"export it with: {result['export']}")


@click.command()
@click.argument("study_file", metavar="STUDY.yaml")
@click.option("--trials", type=click.IntRange(1, 100_000), help="The study's budget: total finished trials "
              "it should hold, shared by every worker (default: the stored budget, else the file's). "
              "Re-running resumes: finished trials are kept.")
@workers_option("Processes running trials of this study on this machine.")
@storage_option
@click.option("--seed", type=click.IntRange(0, 2 ** 31 - 1), help="Sampler seed (default: the file's sampler_seed).")
@RUNS_OPTION
@JSON_OPTION
def tune(study_file: str, trials: int | None, workers: int, storage: str | None, seed: int | None,
         runs_dir: Path, as_json: bool) -> None:
    """Run (or resume) a tuning study: Optuna search seeded by CasADi, against MuJoCo walks.

    The progress bar shows finished trials of the budget, the best score so far
    (torso pitch RMS [deg] of a gait that did not fall), falls so far and the
    time left. Ctrl-C stops cleanly: finished trials stay in the storage. A trial
    whose worker was killed is retried with the same parameters (up to 3 times).
    """
    from ..store.storage import StudyStore
    from ..search.study import load_study

    spec = load_study(study_file)
    store = StudyStore.open(spec.name, storage, runs_of(spec, runs_dir))
    _run_and_report(spec, store, study_file, storage, trials,
                    workers, spec.sampler_seed if seed is None else seed, "tune", as_json)


@click.command()
@click.argument("study_file", metavar="STUDY.yaml")
@storage_option
@workers_option("Processes running trials on this machine.")
@click.option("--seed", type=click.IntRange(0, 2 ** 31 - 1), help="Sampler seed of this machine's processes (default: the file's "
              "sampler_seed plus a number drawn from the host name, so machines sample differently).")
@RUNS_OPTION
def worker(study_file: str, storage: str | None, workers: int, seed: int | None, runs_dir: Path) -> None:
    """Join a study from this machine and run its trials until the study's budget is reached.

    Every machine needs the same STUDY.yaml (and robot file) and the same --storage URL,
    usually PostgreSQL. The budget is the study's (set by `tune --trials`, else the file's
    trials), shared by all workers and `tune` processes: together they run it exactly once.
    The CasADi seed and baselines are enqueued once, by whoever starts first.
    """
    import zlib

    from ..store.storage import StudyStore
    from ..search.study import load_study

    spec = load_study(study_file)
    store = StudyStore.open(spec.name, storage, runs_of(spec, runs_dir))
    if seed is None:
        import socket
        seed = spec.sampler_seed + zlib.crc32(f"{socket.gethostname()}-{os.getpid()}".encode()) % 100_000
    _run_and_report(spec, store, study_file, storage, None, workers, seed, "worker")


@click.command()
@click.argument("study_file", metavar="STUDY")
@storage_option
@RUNS_OPTION
@click.option("--pareto", is_flag=True, help="Only Optuna's best trials (the Pareto front of feasible "
              "trials for two objectives, the best feasible one for one).")
@click.option("--sort", "sort_key", type=click.Choice(["number", "score", "speed"]), default="score",
              show_default=True, help="Order of the rows (score best first: ascending for a minimised study, "
                                      "descending for a maximised one; speed descending).")
@click.option("--limit", type=click.IntRange(1, 100_000), default=20, show_default=True)
@JSON_OPTION
def trials(study_file: str, storage: str | None, runs_dir: Path, pareto: bool, sort_key: str, limit: int,
           as_json: bool) -> None:
    """List a study's trials: state, objectives, feasibility, survival, searched parameters.

    score: the pitch score [deg] minimised (see tuner/search/objective.py; a speed study's speed score
    and a challenge study's push distance [m] maximised); speed [m/s] when the study has it; feasible: stayed up (robust: survival >= the study's minimum) and walked at
    least half its plan; survival: robust studies' share of randomised walks that stayed up.
    """
    import json

    from optuna.trial import TrialState

    from ..search.trials import trial_feasible, trial_result

    spec, study = tuned_study(study_file, storage, runs_dir)
    rows_src = study.best_trials if pareto else study.get_trials(deepcopy=False)
    rows = []
    for t in rows_src:
        res = trial_result(t)
        values = list(t.values) if t.values is not None else []
        rows.append({"number": t.number, "state": t.state.name.lower(),
                     "score": values[0] if values else None,
                     "speed": values[1] if len(values) > 1 else None,
                     "feasible": trial_feasible(t), "survival": res.get("survival"),
                     "start": t.user_attrs.get("start"),
                     "params": {r.name: t.params.get(r.label, t.params.get(r.name)) for r in spec.space}})
    maximised = spec.directions[0] == "maximize"
    keys = {"number": lambda r: r["number"],
            "score": lambda r: (r["score"] is None, (-r["score"] if maximised else r["score"])
                                if r["score"] is not None else 0.0),
            "speed": lambda r: (r["speed"] is None, -(r["speed"] or 0.0))}
    rows.sort(key=keys[sort_key])
    shown = rows[:limit]
    if as_json:
        click.echo(json.dumps({"study": spec.name, "trials": len(study.trials), "shown": shown,
                               "pareto": pareto}, indent=2, allow_nan=False))
        return
    done = sum(1 for t in study.trials if t.state in (TrialState.COMPLETE, TrialState.PRUNED))
    click.echo(f"study {spec.name}: {len(study.trials)} trials ({done} finished), showing {len(shown)}"
               + (" of Optuna's best" if pareto else f" by {sort_key}"))
    names = [r.name for r in spec.space]
    head = f"{'#':>5s} {'state':9s} {'score':>8s} " + (f"{'speed':>7s} " if len(spec.objectives) > 1 else "") \
        + f"{'feasible':8s} {'surv.':>5s}  " + " ".join(f"{n:>{max(len(n), 9)}s}" for n in names)
    click.echo(head)
    for r in shown:
        cells = [f"{r['number']:5d}", f"{r['state']:9s}",
                 f"{r['score']:8.3f}" if r["score"] is not None else f"{'-':>8s}"]
        if len(spec.objectives) > 1:
            cells.append(f"{r['speed']:7.4f}" if r["speed"] is not None else f"{'-':>7s}")
        cells.append(f"{'yes' if r['feasible'] else 'no':8s}")
        cells.append(f"{r['survival']:5.0%}" if r["survival"] is not None else f"{'-':>5s}")
        params = " ".join(f"{r['params'][n]:>{max(len(n), 9)}.4g}" if r["params"][n] is not None
                          else f"{'-':>{max(len(n), 9)}s}" for n in names)
        click.echo(" ".join(cells) + "  " + params)


@click.command()
@click.argument("study_file", metavar="STUDY")
@storage_option
@RUNS_OPTION
@click.option("--trial", "number", type=int, help="Export this trial instead of the best one.")
@click.option("--pareto-pick", type=click.Choice(["pitch", "speed", "knee"]),
              help="Two-objective studies: the Pareto point with the lowest pitch, the highest speed, or "
                   "the knee (nearest the best of both, each scaled over the front).")
@click.option("--out", type=OutPath(dir_okay=False),
              help="Parameter file to write (default: RUNS/<study>/best.yaml); the joint table goes "
                   "beside it (<out>.joints.csv).")
@COMMAND_OPTION
@COMMANDS_OPTION
@TAIL_OPTION
@JOINT_NAMES_OPTION
@FORMAT_OPTION
@CLIP_OPTION
@JSON_OPTION
def export(study_file: str, storage: str | None, runs_dir: Path, number: int | None, pareto_pick: str | None,
           out: Path | None, command: str | None, commands_file: Path | None, duration: float | None,
           joint_names: str, table_format: str, clip: bool, as_json: bool) -> None:
    """Write a study's best (or a chosen) trial as a parameter YAML plus its joint table.

    STUDY is the study file (or shipped study name). The YAML is accepted as it
    is by `simulate` and `trajectory`.
    """
    from ..search.trials import best_trial, pareto_pick as pick, trial_engine, trial_fell, trial_params, trial_stabiliser

    if number is not None and pareto_pick is not None:
        raise UserError("give --trial or --pareto-pick, not both")
    if clip and joint_names != "robot":
        raise UserError("--clip writes the robot's own joints: leave out --joint-names ours")
    spec, study = tuned_study(study_file, storage, runs_dir)
    if out is None:
        out = runs_of(spec, runs_dir) / spec.name / "best.yaml"
    make_folder(out.parent)
    try:
        t = pick(study, pareto_pick) if pareto_pick else best_trial(study, number)
        if spec.controller is not None:
            return _export_controller(spec, t, out, as_json)
        params = trial_params(spec.gait, t)
    except KeyError as exc:
        raise UserError(str(exc.args[0])) from None
    held = (t.user_attrs.get("speed") or {}).get("by_direction")
    desc = (f"study {spec.name} trial {t.number}{commit_of(spec.source)}: score {t.values[0]:.6g}"
            + ("" if not trial_fell(t) or held else " (fell)")
            + ("" if not held else "; highest stairs held: "
               + ", ".join(f"{d} {v:.3g} {'rad/s' if d.startswith('turn') else 'm/s'}" for d, v in held.items()))
            + f"; surfaces {', '.join(spec.surfaces)}; robot {spec.robot}")
    from ..robots import load_robot
    robot = load_robot(spec.robot)
    from ..streams import load_stream
    cmd = parse_command(command)
    if cmd is not None and commands_file is not None:
        raise UserError("give --command or --commands, not both")
    stream = None if commands_file is None else load_stream(commands_file, _tail(duration, commands_file))
    engine = trial_engine(t)
    drive = gaits.Drive(params, trial_stabiliser(t), cmd, stream, source=f"study {spec.name} trial {t.number}",
                        engine=engine)
    what = f"set {out.stem} ({drive.describe()}); surfaces {', '.join(spec.surfaces)}"
    if engine is not None and table_format == "servo":
        # what the engine sends: its targets as it walks the command in the simulator, on the study's
        # first surface (on the robot it re-plans from what it senses there: the same engine, other targets)
        from ..sim.walk import engine_targets
        traj = engine_targets(drive, robot, spec.surfaces[0], note=lambda line: click.echo(line, err=True))
        what += f"; the engine's own targets walking it on {spec.surfaces[0]} in the simulator"
    else:
        traj = gaits.Drive(params, trial_stabiliser(t), cmd, stream).table(robot, robot.sim.control_period)
        if engine is not None:
            what += "; the engine's gait planned per step (--format servo: the engine's own targets)"
    table, table_text, notes = joint_table_file(traj, robot, out.with_suffix(".joints.csv"), joint_names, what,
                                                table_format, clip)
    for line in notes:
        click.echo(f"note: {line}", err=True)
    # the set and its table as one: after a kill at any moment both are new or both old
    write_files_atomic({table: table_text, out: gaits.gait_file_text(params, desc, trial_stabiliser(t), engine)})
    if as_json:
        _exported_json(spec, t, {"params": str(out), "table": str(table)})
    else:
        click.echo(f"trial {t.number} (score {t.values[0]:.4f}) -> {out} and {table}")


def _exported_json(spec, t, files: dict) -> None:
    """export --json: the trial written, its values by objective, and the files."""
    import json

    from ..search.trials import trial_fell
    click.echo(json.dumps({"study": spec.name, "trial": t.number,
                           "values": dict(zip(spec.objectives, (float(v) for v in t.values))),
                           "fell": bool(trial_fell(t)), "surfaces": list(spec.surfaces), "robot": spec.robot,
                           "wrote": files}, indent=2, allow_nan=False))


def _export_controller(spec, t, out: Path, as_json: bool = False) -> None:
    """A controller study's trial as a controller file (its class, the tuned values, the ranges)."""
    from ..controllers import save_controller
    from ..search.trials import trial_fell
    values = (t.user_attrs.get("params") or {}).get("controller")
    if values is None:
        raise UserError(f"trial {t.number} recorded no controller parameters")
    user = spec.controller.with_params(values)
    desc = (f"study {spec.name} trial {t.number}{commit_of(spec.source)}: score {t.values[0]:.6g}"
            + (" (fell)" if trial_fell(t) else "") + f"; surfaces {', '.join(spec.surfaces)}; robot {spec.robot}")
    save_controller(out, user, desc)
    if as_json:
        _exported_json(spec, t, {"controller": str(out)})
        return
    click.echo(f"trial {t.number} (score {t.values[0]:.4f}) -> {out} (a controller file: "
               f"gait-tuner simulate --controller {out})")

