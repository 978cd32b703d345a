"""Every bad input is one line on stderr and exit 2, naming what is wrong: a generated suite over
every file kind (study, robot map, gait parameters, surface, randomisation) and every verb.

The cases run the real CLI entry point (:func:`tuner.cli.main`) in this process, which is what
the console script calls, so several hundred cases cost seconds; ``test_cli.py`` and
``test_storage.py`` run the console script in subprocesses. Each case asserts: exit code 2, one
line, the ``gait-tuner: error:`` prefix, no traceback, and the words that name the field.
"""

from __future__ import annotations

import copy
import os
import subprocess
from pathlib import Path

import pytest
import yaml

from tuner.cli import main

from conftest import run_cli

ROOT = Path(__file__).resolve().parents[1]
MAP = ROOT / "examples" / "robots" / "kid3kg" / "kid3kg.yaml"

STUDY = {"name": "bad", "robot": "kidsize", "surfaces": ["rigid"], "gait": "tlipfm",
         "base": "tkux-table2", "fixed": {"n_steps": 4},
         "space": {"period": {"low": 0.5, "high": 0.8}}, "objectives": ["pitch_rms"],
         "trials": 2, "duration": 2.0, "enqueue": [], "sampler_seed": 0}

PARAMS = {"gait": "tlipfm", "params": {"period": 0.64}}
SURFACE = {"layer_height": 0.01, "friction": 0.9}
RANDOM = {"mass_scale": 0.1}

class _Delete:
    """The field removed (a stable name in test ids: two workers must collect the same tests)."""

    def __repr__(self) -> str:
        return "DELETE"


DELETE = _Delete()


def _set(doc: dict, path: str, value) -> dict:
    doc = copy.deepcopy(doc)
    keys = path.split(".")
    node = doc
    for k in keys[:-1]:
        node = node[k]
    if value is DELETE:
        del node[keys[-1]]
    else:
        node[keys[-1]] = value
    return doc


# (field path, bad value, words the message must hold)
STUDY_FIELDS = [
    ("name", "../escape", "name must be"), ("name", "a/b", "name must be"), ("name", 5, "name must be"),
    ("name", "x" * 200, "name must be"), ("name", ["a"], "name must be"), ("name", ".hidden", "name must be"),
    ("robot", 5, "robot"), ("robot", "nope-robot", "robot"), ("robot", "", "robot"),
    ("robot", ["kidsize"], "robot"), ("robot", "missing/map.yaml", "robot"),
    ("surfaces", [], "surfaces"), ("surfaces", ["nope"], "surfaces"), ("surfaces", [1], "surfaces"),
    ("surfaces", {"a": 1}, "surfaces"), ("surfaces", [None], "surfaces"), ("surfaces", 7, "surfaces"),
    ("gait", "nope", "gait"), ("gait", 3, "gait"), ("gait", None, "gait"), ("gait", ["tlipfm"], "gait"),
    ("gait", DELETE, "missing 'gait'"),
    ("sampler_seed", -1, "sampler_seed = -1: allowed 0 to 2147483647"),
    ("sampler_seed", 2 ** 40, "sampler_seed = 1099511627776"), ("sampler_seed", 2.5, "sampler_seed"),
    ("base", "no-such-baseline", "base"), ("base", 5, "base"), ("base", "eros-x8-with", "base"),
    ("fixed", [1, 2], "fixed"), ("fixed", {"nope": 1}, "fixed: unknown parameter 'nope'"),
    ("fixed", {"period": "slow"}, "period"), ("fixed", {"period": float("nan")}, "period"),
    ("fixed", {"period": -1.0}, "period"), ("fixed", {"period": True}, "period"),
    ("fixed", {"n_steps": 2.5}, "n_steps"), ("fixed", {"n_steps": 0}, "n_steps"),
    ("space", {}, "space"), ("space", [], "space"), ("space", None, "space"), ("space", DELETE, "missing 'space'"),
    ("space", {"period": {"low": 0.8, "high": 0.5}}, "period bounds reversed"),
    ("space", {"period": {"low": "a", "high": 0.8}}, "period bounds must be numbers"),
    ("space", {"period": {"low": 0.5}}, "period must be"),
    ("space", {"period": 5}, "period must be"),
    ("space", {"first_support": {"low": -1, "high": 1}}, "first_support takes one of -1, 1: it is not searched"),
    ("space", {"period": {"low": 0.5, "high": 0.8, "extra": 1}}, "period must be"),
    ("space", {"period": {"low": float("nan"), "high": 0.8}}, "period bounds must be finite"),
    ("space", {"period": {"low": 0.5, "high": float("inf")}}, "period bounds must be finite"),
    ("space", {"period": {"low": 0.5, "high": 0.8, "log": "false"}}, "period.log must be true or false"),
    ("space", {"period": {"low": 0.5, "high": 0.8, "log": 1}}, "period.log must be true or false"),
    ("space", {"period": {"low": True, "high": 0.8}}, "period bounds must be numbers"),
    ("space", {"period": {"low": 0.01, "high": 0.8}}, "period range"),
    ("space", {"nope": {"low": 0.0, "high": 1.0}}, "unknown or non-numeric parameter 'nope'"),
    ("space", {"n_steps": {"low": 2, "high": 6}, "period": {"low": 0.5, "high": 0.8}}, "'n_steps' is also fixed"),
    ("space", {"stabiliser.nope": {"low": 0.0, "high": 1.0}}, "stabiliser"),
    ("objectives", [], "objectives"), ("objectives", ["nope"], "objectives"),
    ("objectives", "pitch_rms", "objectives"), ("objectives", ["pitch_rms", "pitch_rms"], "objectives"),
    ("objectives", ["speed"], "objectives"), ("objectives", None, "objectives"),
    ("trials", 0, "trials"), ("trials", -5, "trials"), ("trials", "ten", "trials"), ("trials", 1.5, "trials"),
    ("trials", True, "trials"), ("trials", 10 ** 9, "trials"), ("trials", None, "trials"),
    ("duration", 0, "duration"), ("duration", -1, "duration"), ("duration", "long", "duration"),
    ("duration", float("nan"), "duration"), ("duration", float("inf"), "duration"), ("duration", True, "duration"),
    ("duration", 1e9, "duration"), ("duration", [2], "duration"),
    ("enqueue", ["nope"], "enqueue"), ("enqueue", "casadi", "enqueue"), ("enqueue", 5, "enqueue"),
    ("sampler_seed", "x", "sampler_seed"), ("sampler_seed", 1.5, "sampler_seed"),
    ("sampler_seed", True, "sampler_seed"), ("sampler_seed", None, "sampler_seed"),
    ("aggregate", "nope", "aggregate"), ("aggregate", 3, "aggregate"),
    ("description", ["a"], "description"), ("description", {"a": 1}, "description"),
    ("baselines", ["no-such-set"], "baselines"), ("baselines", 5, "baselines"),
    ("nope", 1, "unknown key 'nope'"), ("robust", 5, "robust"), ("robust", {"rollouts": 0}, "rollouts"),
    ("robust", {"rollouts": "many"}, "rollouts"), ("robust", {"risk": "nope"}, "risk"),
    ("robust", {"min_survival": 2}, "min_survival"), ("robust", {"nope": 1}, "nope"),
    ("robust", {"randomisation": {"mass_scale": -1}}, "mass_scale"),
    ("robust", {"randomisation": {"nope": 1}}, "nope"), ("robust", {"randomisation": 7}, "randomisation"),
    ("stabiliser", 5, "stabiliser"), ("stabiliser", {"nope": 1}, "nope"),
    ("stabiliser", {"enabled": "yes"}, "enabled"), ("stabiliser", {"k_ankle_pitch": float("nan")}, "k_ankle_pitch"),
    ("speed", 5, "speed"), ("speed", {"directions": {}}, "directions"),
    ("speed", {"directions": {"sideways": {"top": 0.1}}}, "sideways"),
    ("speed", {"directions": {"forward": {"top": -0.1}}}, "top"),
    ("speed", {"directions": {"forward": {"top": 0.2}}, "levels": 0}, "levels"),
    ("speed", {"directions": {"forward": {"top": 0.2}}, "tolerance": 2}, "tolerance"),
    ("speed", {"directions": {"forward": {"top": 0.2}}, "mode": "nope"}, "mode"),
]

MAP_DOC = yaml.safe_load(MAP.read_text())
MAP_FIELDS = [
    ("mjcf", DELETE, "mjcf"), ("mjcf", "missing.xml", "missing.xml"), ("mjcf", 5, "mjcf"),
    ("mjcf", ["a.xml"], "mjcf"), ("name", ["x"], "name"), ("name", "../x", "name"),
    ("torso", "nope_body", "nope_body"), ("torso", 5, "torso"), ("torso", DELETE, "torso"),
    ("feet", {"left": "foot_l"}, "feet"), ("feet", "foot_l", "feet"), ("feet", {"left": "nope", "right": "foot_r"}, "nope"),
    ("feet", {"left": "foot_l", "right": "foot_l"}, "feet"),
    ("joints", {}, "joints"), ("joints", [1, 2], "joints"), ("joints.l_knee", "NoSuchJoint", "NoSuchJoint"),
    ("joints.l_knee", DELETE, "l_knee"), ("joints.nope_joint", "Knee_L", "nope_joint"),
    ("joints.l_knee", 5, "l_knee"), ("joints.r_knee", "Knee_L", "Knee_L"),
    ("servo", 5, "servo"), ("servo.legs", {"kp": -1}, "kp"), ("servo.legs", {"kp": float("nan")}, "kp"),
    ("servo.legs", {"kp": "stiff"}, "kp"), ("servo.legs", {"torque": 0}, "torque"),
    ("servo.legs", {"speed": -2}, "speed"), ("servo.legs", {"kp": True}, "kp"),
    ("servo.legs", {"preset": "MX-999"}, "MX-999"), ("servo.legs", "MX-999", "MX-999"),
    ("servo.legs", {"nope": 1}, "nope"), ("servo.tail", {"kp": 10}, "tail"),
    ("servo.legs", {"kp": 1e9}, "kp"), ("servo.legs", {"kv": -1}, "kv"),
    ("pose", 5, "pose"), ("pose", {"NoSuchJoint": 0.1}, "NoSuchJoint"), ("pose", {"ShoRoll_L": "up"}, "ShoRoll_L"),
    ("pose", {"ShoRoll_L": float("nan")}, "ShoRoll_L"),
    ("sim", 5, "sim"), ("sim", {"control_period": 0}, "control_period"), ("sim", {"timestep": -1}, "timestep"),
    ("sim", {"max_tilt_deg": "x"}, "max_tilt_deg"), ("sim", {"nope": 1}, "nope"),
    ("leg", {"thigh": -0.1}, "thigh"), ("leg", {"nope": 1}, "nope"), ("leg", 5, "leg"),
    ("nope", 1, "nope"),
]

PARAMS_FIELDS = [
    ("gait", "nope", "nope"), ("gait", 5, "gait"), ("gait", DELETE, "gait"),
    ("params", [1], "params"), ("params", "x", "params"), ("params.nope", 1, "nope"),
    ("params.period", "slow", "period"), ("params.period", float("nan"), "period"),
    ("params.period", -1, "period"), ("params.period", True, "period"), ("params.period", 100.0, "period"),
    ("params.n_steps", 2.5, "n_steps"), ("params.n_steps", -3, "n_steps"), ("params.h_z", 10.0, "h_z"),
    ("params.t1", 0.6, "t1"), ("stabiliser", 5, "stabiliser"), ("stabiliser", {"nope": 1}, "nope"),
    ("stabiliser", {"k_ankle_pitch": "x"}, "k_ankle_pitch"), ("nope", 1, "nope"),
]

SURFACE_FIELDS = [
    ("layer_height", -0.01, "layer_height"), ("layer_height", 5.0, "layer_height"), ("layer_height", "x", "layer_height"),
    ("layer_height", float("nan"), "layer_height"), ("friction", 0, "friction"), ("friction", True, "friction"),
    ("drag", -1, "drag"), ("layer_timeconst", 0, "layer_timeconst"), ("layer_dmin", 1.5, "layer_dmin"),
    ("layer_dmax", 0, "layer_dmax"), ("soil_friction", "rough", "soil_friction"), ("nope", 1, "nope"),
    ("name", 5, "name"),
]

RANDOM_FIELDS = [
    ("mass_scale", -0.1, "mass_scale"), ("mass_scale", 2.0, "mass_scale"), ("mass_scale", "x", "mass_scale"),
    ("latency_ticks", 1.5, "latency_ticks"), ("latency_ticks", 99, "latency_ticks"), ("push", -1, "push"),
    ("tilt_deg", float("nan"), "tilt_deg"), ("kp_scale", True, "kp_scale"), ("nope", 1, "nope"),
    ("backlash", [0.1], "backlash"),
]


# an engine study's scenario section (tuner/sim/match_walks.py, tuner/search/study.py)
ENGINE_STUDY = {**STUDY, "engine": {}, "scenario": {"walks": 2, "duration": 4.0}}
SCENARIO_FIELDS = [
    ("scenario.walks", 0, "scenario: walks = 0"), ("scenario.walks", 1.5, "whole number"),
    ("scenario.min_survival", 1.5, "scenario: min_survival = 1.5"),
    ("scenario.tracking_weight", -1, "scenario: tracking_weight = -1"),
    ("scenario.push_min", 2.0, "scenario: push_min = 2 N s exceeds push_max = 1.5"),
    ("scenario.push_max", float("nan"), "scenario: push_max = nan"),
    ("scenario.duration", 1e9, "scenario: duration = 1000000000.0"),
    ("scenario.forward", -0.3, "scenario: forward = -0.3"), ("scenario.turn", "fast", "scenario: turn = 'fast'"),
    ("scenario.segment_min", 4.0, "scenario: segment_min = 4 s exceeds segment_max = 3 s"),
    ("scenario.bogus", 1, "unknown key 'bogus'"), ("scenario", [1], "scenario must be a mapping"),
    ("scenario.randomisation", {"mass_scale": -1}, "scenario.randomisation"),
    ("scenario.servo_share", 0.0, "scenario: servo_share = 0.0: expected a share of the servos' speed"),
    ("scenario.top_hold", -1, "scenario: top_hold = -1"),
]


def _ids(rows):
    return [f"{path}={value!r}"[:60] for path, value, _ in rows]


@pytest.fixture
def workdir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MPLBACKEND", "Agg")
    return tmp_path


def run_bad(capsys, argv: list[str], words: str) -> None:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip()
    lines = err.splitlines()
    assert code == 2, (code, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("gait-tuner: error:"), err
    assert "Traceback" not in err
    assert words.lower() in lines[0].lower(), (words, err)


def dump(path: Path, doc) -> Path:
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.mark.parametrize("field, value, words", STUDY_FIELDS, ids=_ids(STUDY_FIELDS))
def test_study_fields(capsys, workdir, field, value, words):
    study = dump(workdir / "study.yaml", _set(STUDY, field, value))
    run_bad(capsys, ["tune", study, "--workers", "1"], words)


@pytest.mark.parametrize("field, value, words", SCENARIO_FIELDS, ids=_ids(SCENARIO_FIELDS))
def test_scenario_fields(capsys, workdir, field, value, words):
    study = dump(workdir / "study.yaml", _set(ENGINE_STUDY, field, value))
    run_bad(capsys, ["tune", study, "--workers", "1"], words)


def test_a_scenario_message_names_its_section_once(capsys, workdir):
    study = dump(workdir / "study.yaml", _set(ENGINE_STUDY, "scenario.push_max", -1))
    assert main(["tune", str(study), "--workers", "1"]) == 2
    err = capsys.readouterr().err
    assert "study.yaml: scenario: push_max = -1: expected a number in [0, 50] N s" in err, err


@pytest.mark.parametrize("field, value, words", MAP_FIELDS, ids=_ids(MAP_FIELDS))
def test_robot_map_fields(capsys, workdir, field, value, words):
    (workdir / "kid3kg.xml").write_text((MAP.parent / "kid3kg.xml").read_text())
    robot = dump(workdir / "robot.yaml", _set(MAP_DOC, field, value))
    run_bad(capsys, ["robot", "check", robot], words)


@pytest.mark.parametrize("field, value, words", PARAMS_FIELDS, ids=_ids(PARAMS_FIELDS))
def test_params_fields(capsys, workdir, field, value, words):
    params = dump(workdir / "params.yaml", _set(PARAMS, field, value))
    run_bad(capsys, ["simulate", "--params", params, "--surface", "rigid", "--duration", "0.5"], words)


@pytest.mark.parametrize("field, value, words", SURFACE_FIELDS, ids=_ids(SURFACE_FIELDS))
def test_surface_fields(capsys, workdir, field, value, words):
    surface = dump(workdir / "turf.yaml", _set(SURFACE, field, value))
    run_bad(capsys, ["simulate", "--params", "tkux-table2", "--surface", surface, "--duration", "0.5"], words)


@pytest.mark.parametrize("field, value, words", RANDOM_FIELDS, ids=_ids(RANDOM_FIELDS))
def test_randomisation_fields(capsys, workdir, field, value, words):
    rnd = dump(workdir / "random.yaml", _set(RANDOM, field, value))
    run_bad(capsys, ["robustness", "--params", "tkux-table2", "--surface", "rigid", "--rollouts", "1",
                     "--randomisation", rnd], words)


@pytest.mark.parametrize("rng, words", [({"low": 2.2, "high": 2.8}, "holds no integer"),
                                         ({"low": 7.01, "high": 7.99, "log": True}, "holds no integer")])
def test_an_integer_range_must_hold_an_integer(capsys, workdir, rng, words):
    doc = {**STUDY, "fixed": {}, "space": {"n_steps": rng}}
    run_bad(capsys, ["tune", dump(workdir / "s.yaml", doc), "--workers", "1"], words)


@pytest.mark.parametrize("argv", [["compare", "tkux-table2", "--out", ""], ["export", "quickstart", "--out", ""],
                                  ["trajectory", "--gait", "tlipfm", "--out", " "],
                                  ["render", "--params", "tkux-table2", "--out", ""],
                                  ["simulate", "--params", "tkux-table2", "--plot", ""]])
def test_an_empty_output_path_is_refused_before_any_work(capsys, workdir, argv):
    run_bad(capsys, argv, "an empty path")
    assert list(workdir.iterdir()) == []


# -- file kinds, for every option that reads a file ---------------------------------------------

KINDS = {
    "binary": (b"\x00\x01\x02binary\xff", "binary"),
    "latin1": ("name: caf\xe9\n".encode("latin-1"), "not UTF-8"),
    "nested": (b"a: " + b"[" * 5000 + b"]" * 5000 + b"\n", "nested too deeply"),
    "empty": (b"", ""),
    "list": (b"- 1\n- 2\n", ""),
    "scalar": (b"42\n", ""),
    "badyaml": (b"a: [1, 2\nb: }\n", ""),
    "directory": (None, "directory"),
    "missing": (False, ""),
    # never opened for reading, so nothing waits for a writer or reads forever
    "fifo": ("fifo", "FIFO"),
    "device": ("/dev/zero", "device"),
    "symlink-loop": ("loop", "loop of symbolic links"),
    "dangling-link": ("dangling", "link to a missing file"),
    "too-large": (b"# " + b"x" * 1_100_000 + b"\n", "limit of 1,000,000 bytes"),
}
FILE_OPTIONS = {
    "study": lambda f: ["tune", f, "--workers", "1"],
    "robot": lambda f: ["robot", "check", f],
    "robot-simulate": lambda f: ["simulate", "--params", "tkux-table2", "--robot", f, "--duration", "0.5"],
    "params": lambda f: ["simulate", "--params", f, "--duration", "0.5"],
    "surface": lambda f: ["simulate", "--params", "tkux-table2", "--surface", f, "--duration", "0.5"],
    "randomisation": lambda f: ["robustness", "--params", "tkux-table2", "--rollouts", "1", "--randomisation", f],
    "compare": lambda f: ["compare", f, "--out", "cmp"],
    "export-study": lambda f: ["export", f, "--out", "x.yaml"],
    "trials-study": lambda f: ["trials", f],
}


@pytest.mark.parametrize("kind", list(KINDS))
@pytest.mark.parametrize("option", list(FILE_OPTIONS))
def test_file_kinds(capsys, workdir, option, kind):
    content, words = KINDS[kind]
    path = workdir / f"input-{option}.yaml"
    make_kind(path, content)
    run_bad(capsys, FILE_OPTIONS[option](path), words)


def make_kind(path: Path, content) -> None:
    if content is None:
        path.mkdir()
    elif content == "fifo":
        os.mkfifo(path)
    elif content == "loop":
        path.symlink_to(path.with_name(path.name + ".other"))
        path.with_name(path.name + ".other").symlink_to(path)
    elif content == "dangling":
        path.symlink_to(path.with_name("nowhere.yaml"))
    elif isinstance(content, str):
        path.symlink_to(content)
    elif content is not False:
        path.write_bytes(content)


@pytest.mark.parametrize("kind", ["fifo", "device", "symlink-loop", "directory", "too-large"])
@pytest.mark.parametrize("what", ["mjcf", "commands"])
def test_file_kinds_of_a_robot_mjcf_and_a_command_stream(capsys, workdir, what, kind):
    content, words = KINDS[kind]
    if what == "mjcf":
        if kind == "too-large":
            with (workdir / "robot.xml").open("wb") as fh:
                fh.truncate(50_000_001)   # sparse: no 50 MB written
        else:
            make_kind(workdir / "robot.xml", content)
        robot = dump(workdir / "map.yaml", {**MAP_DOC, "mjcf": "robot.xml"})
        run_bad(capsys, ["robot", "check", robot], words.replace("1,000,000", "50,000,000"))
    else:
        make_kind(workdir / "s.csv", content if kind != "too-large" else b"#" * 10_000_001)
        run_bad(capsys, ["simulate", "--params", "tkux-table2", "--commands", workdir / "s.csv"],
                words.replace("1,000,000", "10,000,000"))


# -- option values -------------------------------------------------------------------------------

OPTIONS = [
    (["simulate", "--params", "tkux-table2", "--duration", "-1"], "duration"),
    (["simulate", "--params", "tkux-table2", "--duration", "nan"], "duration"),
    (["simulate", "--params", "tkux-table2", "--duration", "abc"], "duration"),
    (["simulate", "--params", "tkux-table2", "--duration", "1e9"], "duration"),
    (["simulate", "--params", "tkux-table2", "--surface", "nope"], "nope"),
    (["simulate", "--params", "no-such-set"], "no-such-set"),
    (["simulate", "--params", "tkux-table2", "--command", "a,b,c"], "command"),
    (["simulate", "--params", "tkux-table2", "--command", "0.1,0"], "command"),
    (["simulate", "--params", "tkux-table2", "--command", "9,0,0"], "command"),
    (["simulate", "--params", "tkux-table2", "--command", "nan,0,0"], "command"),
    (["simulate", "--params", "cosine-setiono", "--command", "0,0,0.1"], "command"),
    (["simulate", "--params", "tkux-table2", "--robot", "nope-robot"], "nope-robot"),
    (["simulate", "--gait", "nope"], "nope"),
    (["simulate", "--nope"], "nope"),
    (["trajectory", "--gait", "tlipfm", "--out", ""], "out"),
    (["trajectory", "--params", "tkux-table2", "--command", "1,2", "--out", "o"], "command"),
    (["tune", "quickstart", "--trials", "0"], "trials"),
    (["tune", "quickstart", "--trials", "ten"], "trials"),
    (["tune", "quickstart", "--workers", "0"], "workers"),
    (["tune", "quickstart", "--workers", "1000"], "workers"),
    (["tune", "quickstart", "--seed", "abc"], "seed"),
    (["tune", "quickstart", "--storage", "nonsense"], "storage"),
    (["tune", "quickstart", "--storage", ""], "storage"),
    (["tune", "quickstart", "--storage", "sqlite://"], "storage"),
    (["tune", "quickstart", "--storage", "sqlite:////no/such/dir/x.db"], "does not exist"),
    (["tune", "quickstart", "--storage", "oracle://u@h/db"], "oracle"),
    (["tune", "quickstart", "--storage", "postgresql://u@127.0.0.1:1/db"], "cannot"),
    (["tune", "quickstart", "--storage", "mysql+nope://u@h/db"], "storage"),
    (["tune", "no-such-study"], "no-such-study"),
    (["worker", "quickstart", "--storage", "nonsense"], "storage"),
    (["worker", "quickstart", "--workers", "0"], "workers"),
    (["worker"], "STUDY"),
    (["export", "quickstart", "--out", "x.yaml", "--runs", "never-tuned"], "no runs"),
    (["trials", "quickstart", "--runs", "never-tuned"], "no runs"),
    (["compare", "tkux-table2", "--study", "quickstart", "--runs", "never-tuned", "--out", "c"], "quickstart"),
    (["compare", "tkux-table2", "--random-rollouts", "-1", "--out", "c"], "random-rollouts"),
    (["compare", "no-such-set", "--out", "c"], "no-such-set"),
    (["compare", "tkux-table2", "--surfaces", "", "--out", "c"], "surfaces"),
    (["compare", "tkux-table2", "--surfaces", "nope", "--out", "c"], "nope"),
    (["export", "quickstart", "--trial", "-1", "--runs", "never-tuned"], "no runs"),
    (["robustness", "--params", "tkux-table2", "--rollouts", "0"], "rollouts"),
    (["robustness", "--params", "tkux-table2", "--pushes", "a"], "pushes"),
    (["robustness", "--params", "tkux-table2", "--pushes", "-1"], "pushes"),
    (["robustness", "--params", "tkux-table2", "--pushes", "999"], "pushes"),
    (["robustness", "--params", "tkux-table2", "--seed", "x"], "seed"),
    (["robustness", "--params", "tkux-table2", "--surface", "nope"], "nope"),
    (["robustness", "--params", "tkux-table2", "--stabiliser"], "stabiliser"),
    (["experiment", "nope"], "nope"),
    (["experiment", "tlipfm", "--surface", "nope"], "nope"),
    (["params", "nope"], "nope"),
    (["robot", "check", "no-such-map.yaml"], "no-such-map"),
    (["robot", "nope"], "nope"),
    (["nope-verb"], "nope-verb"),
    # NaN passes click's FloatRange (every comparison with it is false): refused by name
    (["challenge", "push", "--params", "kidsize-engine-carpet4", "--step", "nan"], "--step"),
    (["challenge", "push", "--params", "kidsize-engine-carpet4", "--rope", "nan"], "--rope"),
    (["challenge", "push", "--params", "kidsize-engine-carpet4", "--rope", "inf"], "--rope"),
    (["robot", "check", "kidsize", "--duration", "nan"], "--duration"),
    (["experiment", "eros", "--lift-scale", "nan"], "--lift-scale"),
    (["experiment", "eros", "--double-support", "nan"], "--double-support"),
    (["calibrate", "--lift-scale", "nan"], "--lift-scale"),
    (["calibrate", "--layer", "turf"], "--layer"),
    (["calibrate", "--out", ""], "--out"),
]


@pytest.mark.parametrize("argv, words", OPTIONS, ids=[" ".join(a)[:60] for a, _ in OPTIONS])
def test_option_values(capsys, workdir, argv, words):
    run_bad(capsys, argv, words)


def test_runs_folder_that_is_a_file(capsys, workdir):
    (workdir / "runs").write_text("not a folder")
    run_bad(capsys, ["tune", "quickstart", "--runs", "runs"], "--runs")


def test_runs_folder_read_only(capsys, workdir):
    import os
    if os.geteuid() == 0:
        pytest.skip("root writes anywhere")
    ro = workdir / "ro"
    ro.mkdir(mode=0o500)
    run_bad(capsys, ["tune", "quickstart", "--runs", ro], "not writable")


@pytest.mark.parametrize("kind", ["fifo", "device", "symlink-loop", "directory"])
def test_journal_of_the_wrong_kind(capsys, workdir, kind):
    content, words = KINDS[kind]
    (workdir / "runs").mkdir()
    make_kind(workdir / "runs" / "quickstart.journal", content)
    run_bad(capsys, ["trials", "quickstart"], words)


def test_journal_that_is_not_a_journal(capsys, workdir):
    runs = workdir / "runs"
    runs.mkdir()
    (runs / "quickstart.journal").write_bytes(b"\x00\x01 not json\n")
    run_bad(capsys, ["trials", "quickstart"], "journal")


def test_the_suite_is_as_large_as_promised():
    n = (len(STUDY_FIELDS) + len(SCENARIO_FIELDS) + len(MAP_FIELDS) + len(PARAMS_FIELDS) + len(SURFACE_FIELDS) + len(RANDOM_FIELDS)
         + len(KINDS) * len(FILE_OPTIONS) + len(OPTIONS) + 3)
    assert n >= 200, n


@pytest.mark.parametrize("args, content, key", [
    (["simulate", "--params"], "gait: tlipfm\nparams:\n  t1: 0.1\n  t1: 0.2\n", "t1"),
    (["tune"], "gait: tlipfm\ngait: eros\nspace: {t1: {low: 0.1, high: 0.2}}\n", "gait"),
    (["robustness", "--params", "tkux-table2", "--rollouts", "1", "--randomisation"], "push: 1\npush: 2\n", "push"),
])
def test_duplicate_yaml_keys_are_refused_naming_the_key(gait_tuner_cmd, run_env, tmp_path, args, content, key):
    f = tmp_path / "dup.yaml"
    f.write_text(content)
    r = run_cli(gait_tuner_cmd, args + [str(f)] + (['--runs', str(tmp_path / 'runs')] if args == ['tune'] else []),
                run_env, timeout=120)
    assert r.returncode == 2 and f"key {key!r} appears twice" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_a_study_names_its_surfaces_and_overlapping_soles_are_refused(gait_tuner_cmd, run_env, tmp_path):
    study = tmp_path / "s.yaml"
    study.write_text("gait: tlipfm\nspace: {t1: {low: 0.1, high: 0.2}}\n")
    r = run_cli(gait_tuner_cmd, ['tune', str(study), '--runs', str(tmp_path / 'runs')], run_env, timeout=120)
    assert r.returncode == 2 and "missing 'surfaces'" in r.stderr and len(r.stderr.strip().splitlines()) == 1
    params = tmp_path / "p.yaml"
    params.write_text("gait: tlipfm\nparams:\n  half_width: 0.02\n")
    for verb in (["simulate", "--surface", "rigid"], ["trajectory", "--out", str(tmp_path / "t")]):
        r = run_cli(gait_tuner_cmd, verb + ['--params', str(params)], run_env, timeout=120)
        assert r.returncode == 2 and "the soles overlap by 20.0 mm" in r.stderr, r.stderr


def test_an_output_path_inside_a_file_or_too_long_is_one_line(capsys, workdir):
    (workdir / "afile").write_text("x")
    run_bad(capsys, ["trajectory", "--gait", "tlipfm", "--out", "afile/sub", "--no-plot"],
            "a part of the path is a file, not a folder")
    run_bad(capsys, ["trajectory", "--gait", "tlipfm", "--out", "a" * 300, "--no-plot"],
            "longer than the file system allows")


REFUSING = "/proc/gait-tuner-none"           # a file system that takes no new folder (Linux)


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
@pytest.mark.parametrize("argv", [
    ["trajectory", "--gait", "tlipfm", "--out", f"{REFUSING}/t", "--no-plot"],
    ["init", "--robot", "kidsize", "--surface", "rigid", "--out", f"{REFUSING}/start"],
    ["train", "kidsize-engine-push", "--robot", "kidsize", "--surface", "carpet4", "--iterations", "1",
     "--out", f"{REFUSING}/r.yaml"],
    ["simulate", "--params", "kidsize-engine-carpet4", "--surface", "rigid", "--duration", "0.1", "--command", "0.1,0,0",
     "--record", f"{REFUSING}/r.json"],
], ids=["trajectory", "init", "train", "simulate"])
def test_an_output_folder_the_file_system_refuses_is_one_line(capsys, workdir, argv):
    """It was an internal error in every verb (mkdir's ENOENT under /proc): the path, in words."""
    run_bad(capsys, argv, f"{REFUSING}: no folder can be made there")


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
@pytest.mark.parametrize("argv", [
    ["compare", "kidsize-engine-carpet4", "--surfaces", "rigid", "--no-baselines", "--workers", "1",
     "--random-rollouts", "0"],
    ["experiment", "tlipfm"],
    ["calibrate", "--workers", "1"],
    ["identify", "servos", "--robot", "kidsize", "--recording", "sweep.csv"],
    ["identify", "ground", "--robot", "kidsize", "--surface", "grass30", "--recording", "walk.csv"],
], ids=["compare", "experiment", "calibrate", "identify-servos", "identify-ground"])
def test_long_work_says_a_folder_it_cannot_write_before_it_starts(capsys, workdir, monkeypatch, argv):
    """compare, the papers' experiments, calibrate (tens of minutes) and the fits wrote their folder
    after the work: a bad --out lost it. Each says so first (any walk here would fail the test)."""
    import tuner.sim.rollout as rollout

    def no_walk(*a, **kw):
        raise AssertionError("walked before the --out folder was checked")
    monkeypatch.setattr(rollout.Simulator, "run", no_walk)
    if argv[0] == "identify":
        from tuner.identify import field_recordings
        monkeypatch.setattr(field_recordings, "read_field_recording", no_walk)
        import tuner.identify.ground as ground
        monkeypatch.setattr(ground, "read_walk_logs", no_walk)
    run_bad(capsys, argv + ["--out", f"{REFUSING}/out"], f"{REFUSING}: no folder can be made there")


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_a_runs_folder_the_file_system_refuses_is_one_line(capsys, workdir):
    run_bad(capsys, ["tune", "quickstart", "--trials", "1", "--runs", REFUSING],
            f"--runs {REFUSING}: cannot create it: no folder can be made there")


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux's /proc")
def test_robot_loop_recording_where_no_folder_can_be_made_is_one_line():
    r = subprocess.run([os.sys.executable, str(ROOT / "examples" / "robot_loop.py"),
                        str(ROOT / "studies" / "results" / "kidsize-engine-carpet4.yaml"), "--dry-run",
                        "--seconds", "0.05", "--record", f"{REFUSING}/run.mcap"], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert f"{REFUSING}: no folder can be made there" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("argv, words", [
    (["versus", "kidsize-engine-carpet4", "nope", "--walks", "1"], "walk 'nope': no such file, and not a shipped set"),
    (["train", "nope", "--out", "r.yaml"], "set 'nope': no such file"),
    (["compare", "nope", "--surfaces", "rigid"], "set 'nope': no such file"),
    (["transfer", "nope", "--robot", "kidsize", "--surface", "grass30"], "set 'nope': no such file"),
    (["experiment", "eros", "--tuned", "nope"], "--tuned 'nope': no such file"),
    (["simulate", "--params", "nope"], "--params 'nope': no such file"),
], ids=["versus", "train", "compare", "transfer", "experiment", "simulate"])
def test_an_unknown_set_is_named_as_the_verb_takes_it(capsys, workdir, argv, words):
    """Every verb said "--params 'nope'", the verbs that take the set as an argument too."""
    run_bad(capsys, argv, words)


def test_a_study_s_unknown_base_is_named_as_its_field(capsys, workdir):
    (workdir / "st.yaml").write_text("gait: tlipfm\nbase: nope\nsurfaces: [rigid]\nspace: {t1: {low: 0.1, high: 0.2}}\n")
    run_bad(capsys, ["tune", "st.yaml"], "st.yaml: base: 'nope': no such file, and not a shipped set")


def test_a_stream_cell_past_the_csv_limit_is_one_line(capsys, workdir):
    (workdir / "big.csv").write_text("t,vx,vy,wz\n0," + "1" * 200_000 + ",0,0\n")
    run_bad(capsys, ["simulate", "--params", "kidsize-engine-carpet4", "--commands", "big.csv"],
            "big.csv: line 2: not CSV a stream can hold")


def test_robot_loop_given_a_shipped_set_name_is_one_line():
    r = subprocess.run([os.sys.executable, str(ROOT / "examples" / "robot_loop.py"), "kidsize-engine-carpet4",
                        "--dry-run"], capture_output=True, text=True)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and "Traceback" not in r.stderr
    assert "studies/results/kidsize-engine-carpet4.yaml" in r.stderr


def test_an_engine_set_with_no_command_says_it_stood(capsys, workdir):
    """It walked nowhere: simulate says so (a note, and its drive line), not a perfect walk only."""
    assert main(["simulate", "--params", "kidsize-engine-carpet4", "--surface", "rigid", "--duration", "2"]) == 0
    out = capsys.readouterr()
    assert "was given no --command or --commands: it stands where it started" in out.err
    assert "no command: it stands where it started" in out.out


def test_compare_of_an_engine_set_compares_its_table(capsys, workdir):
    """It was an internal error ("give a duration"): an online set is compared as its gait's table."""
    code = main(["compare", "kidsize-engine-carpet4", "--surfaces", "rigid", "--no-baselines", "--workers", "1",
                 "--random-rollouts", "0", "--out", "cmp"])
    out = capsys.readouterr()
    assert code == 0, out.err
    assert "kidsize-engine-carpet4 (its table)" in (workdir / "cmp" / "compare.md").read_text()


def test_an_out_path_inside_a_file_is_one_line(tmp_path, capsys):
    """`--out a_file/x.yaml` where a_file is a file: one line naming it (export said 'internal error:
    FileExistsError' when it made the folder)."""
    (tmp_path / "a_file").write_text("mine")
    assert main(["robot", "export", "kidsize", "--out", str(tmp_path / "a_file" / "robot.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "a file stands where a folder is needed" in err and "internal" not in err
    assert (tmp_path / "a_file").read_text() == "mine"


def test_versus_with_nothing_to_measure_is_one_line(tmp_path, capsys):
    assert main(["versus", "kidsize-engine-carpet4", "--speeds", "0,0,0,0", "--walks", "0", "--no-challenge",
                 "--out", str(tmp_path / "vs")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "nothing to measure" in err and not (tmp_path / "vs").exists()


@pytest.mark.parametrize("verb", [["robustness", "--params", "kidsize-engine-carpet4"],
                                  ["transfer", "kidsize-engine-carpet4"], ["versus", "kidsize-engine-carpet4"]])
def test_walks_and_rollouts_are_one_option_in_every_verb(verb):
    """robustness said --rollouts where transfer and versus say --walks for the same thing: each takes
    both names."""
    from conftest import run_in_process
    for name in ("--walks", "--rollouts"):
        r = run_in_process(verb + [name, "-1"])
        assert r.returncode == 2 and "-1 is not in the range" in r.stderr and "--walks" in r.stderr \
            and "--rollouts" in r.stderr, r.stderr
