"""Parameter files: round trips of every baseline, and one clear message per kind of mistake."""

import dataclasses

import pytest

from gaits import (ErosParams, ParamError, TlipfmParams, families, family_class, list_baselines,
                   load_baseline, load_gait_file, save_gait_file)


@pytest.mark.parametrize("name", list_baselines())
def test_baseline_round_trip(name, tmp_path):
    gf = load_baseline(name)
    out = save_gait_file(tmp_path / "p.yaml", gf.params, gf.description)
    again = load_gait_file(out)
    assert again.params == gf.params
    assert again.description == gf.description


def test_expected_baselines_are_shipped():
    names = set(list_baselines())
    for x in (8, 16, 24):
        assert {f"eros-x{x}-without", f"eros-x{x}-with"} <= names
    assert {"tkux-table2", "tkux-table2-lipm", "tkux-table2-dlipm", "cosine-setiono"} <= names


def test_paper_values_in_baselines():
    tk = load_baseline("tkux-table2").params
    assert (tk.step_length, tk.half_width, tk.d1, tk.a, tk.z_c, tk.h_z) == (0.02, 0.045, 0.01, 0.004, 0.217, 0.03)
    assert (tk.t1, tk.t2, tk.period, tk.n_steps) == (0.15, 0.49, 0.64, 14)
    assert (tk.mass_upper, tk.mass_thigh, tk.mass_calf, tk.l_u) == (3.05, 0.2, 0.75, 0.09)
    e = load_baseline("eros-x24-with").params
    assert (e.step_x, e.sway_y, e.foot_lift) == (0.024, 0.025, 0.09)
    assert e.heel_strike and e.landing_deceleration
    assert not load_baseline("eros-x24-without").params.heel_strike


def test_every_field_documents_unit_and_range():
    for fam in families():
        for row in family_class(fam).field_table():
            assert row["doc"], (fam, row["name"])
            assert row["unit"], (fam, row["name"])
            assert row["range"], (fam, row["name"])


def write(tmp_path, text):
    path = tmp_path / "g.yaml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("text,match", [
    ("gait: tlipfm\nparams:\n  step_lenght: 0.02\n", r"unknown parameter 'step_lenght' for gait 'tlipfm'"),
    ("gait: tlipfm\nparams:\n  z_c: tall\n", r"tlipfm.z_c must be a number in \[0.08, 0.5\] m, got str 'tall'"),
    ("gait: tlipfm\nparams:\n  z_c: 0.9\n", r"tlipfm.z_c = 0.9 m is out of range \[0.08, 0.5\] m"),
    ("gait: tlipfm\nparams:\n  t1: 0.5\n", r"need 0 < t1 < t2 < period, got t1 = 0.5 s, t2 = 0.49 s"),
    ("gait: tlipfm\nparams:\n  t2: 0.7\n", r"t2 = 0.7 s, period = 0.64 s"),
    ("gait: eros\nparams:\n  n_steps: 4.0\n", r"eros.n_steps must be an integer in \[2, 500\] -, got float 4.0"),
    ("gait: eros\nparams:\n  heel_strike: 1\n", r"eros.heel_strike must be true or false, got int 1"),
    ("gait: eros\nparams:\n  first_swing: both\n", r"eros.first_swing = 'both' is not allowed"),
    ("gait: walker\nparams: {}\n", r"unknown gait family 'walker': expected one of cosine, eros, tlipfm"),
    ("params: {}\n", r"missing 'gait'"),
    ("gait: eros\nparams: [1, 2]\n", r"'params' must be a mapping"),
    ("gait: eros\nextra: 1\n", r"unknown top-level key 'extra'"),
    ("gait: eros\nparams:\n  step_x: [0.01\n", r"not valid YAML at line 4, column 1"),
    ("- just a list\n", r"expected a mapping"),
    ("gait: eros\nparams:\n  step_x: .nan\n", r"eros.step_x must be finite"),
])
def test_malformed_files_name_the_problem(tmp_path, text, match):
    path = write(tmp_path, text)
    with pytest.raises(ParamError, match=match) as err:
        load_gait_file(path)
    assert str(path) in str(err.value)
    assert "\n" not in str(err.value)


def test_missing_file(tmp_path):
    with pytest.raises(ParamError, match="no such parameter file"):
        load_gait_file(tmp_path / "nope.yaml")


def test_unknown_baseline():
    with pytest.raises(ParamError, match="unknown baseline 'tkux'"):
        load_baseline("tkux")


def test_params_are_frozen_and_revalidated_on_replace():
    p = TlipfmParams()
    with pytest.raises(dataclasses.FrozenInstanceError):
        p.t1 = 0.2
    with pytest.raises(ParamError):
        p.replace(t1=0.6)
    assert ErosParams().replace(step_x=-0.01).step_x == -0.01


def test_ints_are_accepted_for_floats(tmp_path):
    gf = load_gait_file(write(tmp_path, "gait: cosine\nparams:\n  motion_time: 3\n"))
    assert gf.params.motion_time == 3.0 and isinstance(gf.params.motion_time, float)
