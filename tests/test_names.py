"""A mistyped name gets the close one suggested; family facts come from the one family registry."""

import dataclasses

import pytest

import gaits
from gaits import did_you_mean
from gaits.families import register

from conftest import run_cli


def test_did_you_mean_picks_the_closest_or_nothing():
    assert did_you_mean("grass5", ["rigid", "grass50", "grass30"]) == " (did you mean 'grass50'?)"
    assert did_you_mean("KIDSIZE-omni-carpet4", ["kidsize-omni-carpet4"]) == " (did you mean 'kidsize-omni-carpet4'?)"
    assert did_you_mean("zzz", ["rigid", "grass50"]) == ""
    assert did_you_mean("rigid", ["rigid"]) == ""          # not a typo
    assert did_you_mean(None, ["rigid"]) == "" and did_you_mean("x", []) == ""


@pytest.mark.parametrize("args, words", [
    (["simulate", "--params", "kidsize-omni-carpt4"], "did you mean 'kidsize-omni-carpet4'?"),
    (["simulate", "--params", "tkux-table2", "--surface", "grass5"], "did you mean 'grass50'?"),
    (["simulate", "--params", "tkux-table2", "--robot", "kidsise"], "did you mean 'kidsize'?"),
    (["tune", "quickstrat"], "did you mean 'quickstart'?"),
])
def test_a_mistyped_name_is_one_line_with_the_close_one(gait_tuner_cmd, run_env, tmp_path, args, words):
    r = run_cli(gait_tuner_cmd, args, run_env, cwd=tmp_path)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1 and words in r.stderr, r.stderr


def test_a_mistyped_study_key_and_robot_joint(tmp_path):
    from tuner.errors import UserError
    from tuner.search.study import load_study
    p = tmp_path / "s.yaml"
    p.write_text("gait: tlipfm\nsurfaces: [rigid]\nspace: {z_c: {low: 0.2, high: 0.22}}\nrobsut: {rollouts: 2}\n")
    with pytest.raises(UserError, match="unknown key 'robsut' \\(did you mean 'robust'\\?\\)"):
        load_study(str(p))
    from conftest import ROOT
    from tuner.robots import load_robot
    src = (ROOT / "examples/robots/kid3kg/kid3kg.yaml").read_text()
    m = tmp_path / "kid3kg.yaml"
    src = src.replace("mjcf: kid3kg.xml", f"mjcf: {ROOT / 'examples/robots/kid3kg/kid3kg.xml'}")
    m.write_text(src.replace("r_knee: Knee_R", "r_kne: Knee_R"))
    with pytest.raises(UserError, match="unknown joint 'r_kne' \\(did you mean 'r_knee'\\?\\)"):
        load_robot(str(m))
    m.write_text(src.replace("l_knee: Knee_L", "l_knee: Kne_L"))
    with pytest.raises(UserError, match="'Kne_L' is not a joint of .*did you mean 'Knee_L'"):
        load_robot(str(m))


def test_one_family_registry_and_its_facts():
    assert gaits.families() == tuple(sorted(f.name for f in gaits.all_families()))
    for fam in gaits.all_families():
        assert gaits.family_class(fam.name) is fam.params_class
        params = fam.params_class()
        assert isinstance(getattr(params, fam.lift_field), float), fam.name
    with pytest.raises(gaits.ParamError, match="unknown gait family 'walk'"):
        gaits.family_class("walk")
    tl = gaits.family("tlipfm")
    with pytest.raises(ValueError, match="lift_field 'lift'"):
        register(dataclasses.replace(tl, lift_field="lift"))
    assert gaits.family("tlipfm") is tl          # the refused one was not registered
