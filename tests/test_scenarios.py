"""The scenario wing (``tuner/scenarios``): one file per scenario, one registry.

Three kinds of test: the shipped studies' trial scores replay equal to those the code before the
wing computed (``tests/data/scenario_replay.json``: written by the evaluator of commit fa892a3,
before the scenarios moved out of ``search/``, for the base set and the midpoint of each study's
space, on the reduced budgets below, on the built-in robot with round one's servos, ``kidsize-pd``;
one number changed since, by design: ``kidsize-engine-match:mid``'s fall constraint, 0.401 then,
0.401 + the share of its walks not stood (0.692) / 3 since an infeasible trial's constraint says
how long it stood, :func:`tuner.scenarios.base.survival_constraint`); every shipped study chooses the scenario its section names;
and a sixth scenario, added in one file (here, this test module) and one registration, is read from
a study file, walked and stored by a real study.
"""

import dataclasses
import json
import math
from dataclasses import dataclass

import numpy as np
import pytest

from conftest import ROOT
from tuner.errors import UserError
from tuner.scenarios import BUILT_IN, SCENARIOS, register
from tuner.scenarios.base import Scenario, TrialResult, check_section, fail, survival_constraint
from tuner.search.objective import Evaluator
from tuner.search.study import list_studies, load_study

REPLAY = json.loads((ROOT / "tests" / "data" / "scenario_replay.json").read_text())

#: the budgets the reference was computed on (the shipped studies' own, made smaller)
REDUCE = {
    "quickstart": lambda s: s,
    "tlipfm-robust": lambda s: dataclasses.replace(s, surfaces=s.surfaces[:2]),
    "kidsize-robust-grass50": lambda s: dataclasses.replace(
        s, settings=dataclasses.replace(s.settings, rollouts=3, min_survival=0.0)),
    "kidsize-robust-fb-grass50": lambda s: dataclasses.replace(
        s, surfaces=s.surfaces[:1], settings=dataclasses.replace(s.settings, rollouts=2, min_survival=0.0)),
    "kidsize-engine-carpet4": lambda s: dataclasses.replace(
        s, settings=dataclasses.replace(s.settings, walks=2, min_survival=0.0)),
    "kidsize-engine-push": lambda s: dataclasses.replace(
        s, surfaces=s.surfaces[:1], settings=dataclasses.replace(s.settings, seeds=(0,), start=0.5, step=0.1)),
    "kidsize-omni-carpet4": lambda s: s,
    "eros-robust": lambda s: s,
    "kidsize-engine-match": lambda s: dataclasses.replace(
        s, surfaces=s.surfaces[:1], settings=dataclasses.replace(s.settings, walks=2, min_survival=0.9)),
}


def _mid(spec):
    return {p.name: (int(round((p.low + p.high) / 2)) if p.integer else (p.low + p.high) / 2) for p in spec.space}


@pytest.mark.parametrize("study", list(REDUCE))
def test_shipped_studies_trial_scores_replay_equal(study):
    # the reference was walked on round one's servos: the built-in robot with them (the pd law)
    spec = dataclasses.replace(REDUCE[study](load_study(study)), robot="kidsize-pd")
    ev = Evaluator(spec)
    for tag, sampled in (("base", {}), ("mid", _mid(spec))):
        r = ev.evaluate(spec.drive_for(sampled))
        want = REPLAY[f"{study}:{tag}"]
        got = {"score": r.score, "speed": r.speed, "fall_constraint": r.fall_constraint, "fell": r.fell,
               "survival": r.survival, "values": list(r.values) if r.values else None, "hopeless": r.hopeless,
               "per_surface": r.per_surface}
        # equal to the last bits: numpy's releases move a sum's rounding (2.4 did), so floats to 1e-9
        assert _close(json.loads(json.dumps(got, default=str)), want), (study, tag, got, want)


def test_an_infeasible_trial_is_nearer_the_longer_it_stood():
    """Trials with as many falls rank by how much of the study's walking they stood (TPE ranks the
    infeasible by it: a study whose every trial falls was blind); a fall more is always further;
    survival that holds is no constraint at all."""
    # six walks, survival 0.5 allowed: the fourth fall stops the trial
    first = survival_constraint(0.5, 4, 6, 4, True, stood=3.1)       # fell in the walks 1-4
    later = survival_constraint(0.5, 4, 6, 6, True, stood=4.9)       # stood longer, ran them all
    assert first == pytest.approx(0.5 - (1 - 4 / 6) + 1e-3 + (1 - 3.1 / 6) / 7, abs=1e-15)
    assert later == pytest.approx(0.5 - (1 - 4 / 6) + 1e-3 + (1 - 4.9 / 6) / 7, abs=1e-15)
    assert 0 < later < first
    assert survival_constraint(0.5, 4, 6, 4, True) == pytest.approx(0.5 - (1 - 4 / 6) + 1e-3, abs=1e-15)
    worst_of_fewer = survival_constraint(0.5, 4, 6, 6, False, stood=0.0)
    best_of_more = survival_constraint(0.5, 5, 6, 6, False, stood=6.0)
    assert worst_of_fewer < best_of_more
    for total in (2, 6, 1000, 6000):       # at any size: a fall more outweighs every share not stood
        assert (survival_constraint(1.0, 2, total, total, False, stood=0.0)
                < survival_constraint(1.0, 3, total, total, False, stood=float(total)))
    assert survival_constraint(0.5, 3, 6, 6, False, stood=3.0) is None
    # out-of-range shares are held to [0, 1] of the walking
    assert survival_constraint(0.9, 1, 2, 1, True, stood=9.0) == pytest.approx(0.9 - 0.5 + 1e-3, abs=1e-15)
    assert survival_constraint(0.9, 1, 2, 1, True, stood=-1.0) == pytest.approx(0.9 - 0.5 + 1e-3 + 1 / 3, abs=1e-15)


def _close(a, b) -> bool:
    """Equal structures, floats within 1e-9 relative (and 1e-12 absolute), everything else exactly."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and not isinstance(a, bool):
        return math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12) or (math.isnan(a) and math.isnan(b))
    return a == b and type(a) is type(b)


def test_every_shipped_study_walks_the_scenario_its_section_names():
    sections = {sc.section: sc.name for sc in SCENARIOS.values()}
    import yaml
    for path in list_studies():
        doc = yaml.safe_load(path.read_text())
        named = [k for k in doc if k in sections and doc[k] is not None]
        assert load_study(str(path)).kind == (sections[named[0]] if named else "walk"), path.name


def test_the_built_in_scenarios_are_registered_once_in_order():
    assert list(SCENARIOS)[:len(BUILT_IN)] == list(BUILT_IN)
    with pytest.raises(ValueError, match="taken"):
        register(SCENARIOS["robust"])


def test_two_scenario_sections_are_one_line_naming_both(tmp_path):
    p = tmp_path / "two.yaml"
    p.write_text("gait: tlipfm\nsurfaces: [rigid]\nspace: {z_c: {low: 0.2, high: 0.22}}\n"
                 "robust: {rollouts: 2}\nspeed: {directions: {forward: {top: 0.2}}}\n")
    with pytest.raises(UserError, match="speed does not go with robust"):
        load_study(str(p))


# -- a sixth scenario, in one file and one registration ------------------------------------------

@dataclass(frozen=True)
class StandSpec:
    seconds: float = 1.0


class Stand(Scenario):
    """Stand still for ``seconds`` on each surface; the score is the largest torso pitch RMS."""

    name = "stand-test"
    section = "stand_test"

    def parse(self, sec, doc, source):
        check_section(sec, "stand_test", ("seconds",), source)
        s = sec.get("seconds", 1.0)
        if not isinstance(s, (int, float)) or isinstance(s, bool) or not 0.1 <= s <= 10:
            fail(source, f"stand_test: seconds = {s!r}: expected a number in [0.1, 10] s")
        return StandSpec(float(s))

    def evaluate(self, settings, drive, world, report=None):
        from tuner.sim.metrics import summarize
        per, pitches = {}, []
        for name, m in world.in_order(1, lambda sim, i: summarize(sim.run(
                drive.controller(world.robot, sim.control_period), duration=settings.seconds, **drive.run_options()))):
            per[name] = {"survived": m.survived}
            pitches.append(m.pitch_rms_deg)
        return TrialResult(score=max(pitches), speed=0.0, fall_constraint=-1.0, fell=False, per_surface=per,
                           attrs={"stand_test": {"seconds": settings.seconds}})


@pytest.fixture
def stand_registered():
    register(Stand())
    yield
    del SCENARIOS["stand-test"]


STAND_STUDY = """\
gait: tlipfm
base: tkux-table2
surfaces: [rigid, carpet4]
space: {z_c: {low: 0.20, high: 0.22}}
trials: 2
enqueue: []
stand_test: {seconds: 0.5}
"""


def test_a_sixth_scenario_is_one_file_and_one_registration(stand_registered, tmp_path):
    import optuna

    from tuner.search.objective import objective_for
    p = tmp_path / "stand.yaml"
    p.write_text(STAND_STUDY)
    spec = load_study(str(p))
    assert spec.kind == "stand-test" and spec.settings == StandSpec(0.5) and spec.objectives == ("pitch_rms",)
    study = optuna.create_study(sampler=optuna.samplers.RandomSampler(seed=0))
    study.optimize(objective_for(spec, Evaluator(spec)), n_trials=2)
    t = study.trials[0]
    assert t.state == optuna.trial.TrialState.COMPLETE and math.isfinite(t.value)
    assert t.user_attrs["stand_test"] == {"seconds": 0.5}
    assert set(t.user_attrs["result"]["per_surface"]) == {"rigid", "carpet4"}
    p.write_text(STAND_STUDY.replace("{seconds: 0.5}", "{seconds: 50}"))
    with pytest.raises(UserError, match="stand_test: seconds = 50"):
        load_study(str(p))


def test_without_the_registration_its_section_is_an_unknown_key(tmp_path):
    p = tmp_path / "stand.yaml"
    p.write_text(STAND_STUDY)
    with pytest.raises(UserError, match="unknown key 'stand_test'"):
        load_study(str(p))


def test_a_randomised_studys_best_trial_is_told_by_its_survival():
    """The closing line of an engine (match) study said its 90 % survivor "fell" (one walk of ten
    did) and counted every trial as fallen; it says the survival and the trials below the minimum."""
    from types import SimpleNamespace
    from tuner.scenarios.match import ScenarioSpec
    from tuner.scenarios.robust import RobustSpec
    t = SimpleNamespace(number=7, values=[3.5], user_attrs={"result": {"fell": True, "survival": 0.9}})
    line = SCENARIOS["match"].describe_best(ScenarioSpec(walks=10, min_survival=0.8), t, fell=True, falls=12,
                                           infeasible=3)
    assert line == ("best trial 7: score 3.500; survival 90% of its match walks (10 a surface) (minimum 80%); "
                    "trials below the minimum or rejected in study: 3")
    assert "fell" not in SCENARIOS["robust"].describe_best(RobustSpec(), t, fell=True, falls=1, infeasible=0)


def test_servo_share_is_the_fastest_target_against_its_servo():
    from types import SimpleNamespace

    from tuner.sim.robustness import servo_share
    q_ref = np.zeros((4, 2))
    q_ref[2, 0] = 0.03                      # 3 rad/s at 10 ms ticks, servo 6 rad/s: half
    q_ref[3, 1] = -0.04                     # 4 rad/s, servo 5 rad/s: 0.8
    sim = SimpleNamespace(control_period=0.01, servo_speed=np.array([6.0, 5.0]))
    assert servo_share(SimpleNamespace(q_ref=q_ref), sim) == pytest.approx(0.8)
    assert servo_share(SimpleNamespace(q_ref=q_ref[:1]), sim) == 0.0


@pytest.mark.parametrize("share, asked, feasible", [(None, 2.0, True), (0.95, 0.9, True), (0.95, 1.2, False)])
def test_a_match_trial_that_asks_the_servos_too_much_is_infeasible(share, asked, feasible):
    """scenario.servo_share: every walk survived, but one asked a servo for `asked` of its speed."""
    from types import SimpleNamespace

    from tuner.scenarios.match import Match, ScenarioSpec
    rows = [{"survived": True, "pitch_rms_deg": 2.0, "tracking": None, "walked": 1.0, "servo_share": s}
            for s in (0.3, asked)]
    world = SimpleNamespace(sims={"rigid": None}, namespace=0,
                            in_order=lambda k, walk: (("rigid", r) for r in rows))
    res = Match().evaluate(ScenarioSpec(walks=2, min_survival=0.5, servo_share=share), None, world)
    assert (res.fall_constraint <= 0) == feasible and res.attrs["servo_share"] == asked
    if not feasible:
        assert res.fall_constraint == pytest.approx(asked - share)


def test_top_hold_ends_each_walk_at_the_top_speed_and_leaves_the_draws_as_they_were():
    """scenario.top_hold: the drawn segments are the same (no random draw added), then the top forward
    speed held top_hold seconds, then the stop; the pushes are the same."""
    from tuner.sim.match_walks import MatchDistribution, draw_scenario
    plain = MatchDistribution(forward=0.2, push_rate=0.5)
    held = MatchDistribution(forward=0.2, push_rate=0.5, top_hold=6.0)
    for seed in (0, 1, 7):
        (a, pa), (b, pb) = draw_scenario(plain, seed, 1), draw_scenario(held, seed, 1)
        n = len(a.t) - 1                                    # the drawn rows, before the final stop
        assert np.array_equal(a.t[:n], b.t[:n]) and np.array_equal(a.commands[:n], b.commands[:n])
        assert b.t[n] == plain.duration and np.array_equal(b.commands[n], [0.2, 0.0, 0.0])
        assert b.t[n + 1] == plain.duration + 6.0 and np.array_equal(b.commands[n + 1], np.zeros(3))
        assert len(pa) == len(pb) and all(x[0] == y[0] for x, y in zip(pa, pb))
    assert held.length == plain.length + 6.0
