"""`gait-tuner versus`: walks of every kind side by side (a set, a policy file), one table, strict
JSON, a plot; bad input one line."""

from __future__ import annotations

import json

import pytest
import yaml

from conftest import run_cli


def run(cmd, args, env, timeout=900):
    return run_cli(cmd, [str(a) for a in args], env, timeout=timeout)


def test_a_set_and_a_policy_side_by_side(tmp_path, gait_tuner_cmd, run_env):
    pytest.importorskip("onnx", reason="onnx (the dev extra) builds the test's policy")
    pytest.importorskip("onnxruntime", reason="onnxruntime (the onnx extra) runs policies")
    import test_policy as P
    P.write_onnx(tmp_path / "walk.onnx", P.N_OBS, 12, gain=0.01)
    (tmp_path / "still.yaml").write_text(yaml.safe_dump({"policy": P.spec_doc()}))
    out = tmp_path / "vs"
    r = run(gait_tuner_cmd, ["versus", "kidsize-engine-carpet4", tmp_path / "still.yaml", "--surfaces", "rigid",
                             "--speeds", "0.2,0,0,0.5", "--walks", "1", "--no-challenge", "--out", out, "--json"], run_env)
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    cells = {c["walk"]: c for c in doc["cells"]}
    assert set(cells) == {"kidsize-engine-carpet4", "still"} and doc["speeds"] == {"forward": 0.2, "turning": 0.5}
    engine, still = cells["kidsize-engine-carpet4"]["speeds"], cells["still"]["speeds"]
    assert 0.15 < engine["forward"]["reached"] < 0.3 and abs(still["forward"]["reached"]) < 0.02
    assert engine["turning"]["reached"] > 0.3
    assert {r["outcome"] for r in (*engine.values(), *still.values())} == {"completed"}   # the table says how one did not
    assert cells["still"]["match"]["walks"] == 1 and cells["still"]["tick_ms"]["median"] > 0
    assert "challenge" not in cells["still"]
    text = (out / "versus.md").read_text()
    assert "| still | rigid |" in text and "| kidsize-engine-carpet4 | rigid |" in text
    assert (out / "versus.png").stat().st_size > 1000
    assert json.loads((out / "versus.json").read_text())["cells"][0]["walk"] == "kidsize-engine-carpet4"


@pytest.mark.parametrize("args, needle", [
    (["kidsize-engine-carpet4", "--speeds", "0.2,0.1"], "--speeds '0.2,0.1': expected four numbers in [0, 2]"),
    (["kidsize-engine-carpet4", "--speeds", "a,b,c,d"], "expected four numbers FWD,BACK,SIDE,TURN"),
    (["kidsize-engine-carpet4", "kidsize-engine-carpet4"], "two walks share the name 'kidsize-engine-carpet4'"),
    (["kidsize-engine-carpet4", "--surfaces", "moon"], "moon"),
    (["no-such-set"], "no-such-set"),
])
def test_bad_input_is_one_line(tmp_path, gait_tuner_cmd, run_env, args, needle):
    r = run(gait_tuner_cmd, ["versus", *args, "--out", tmp_path / "vs"], run_env, timeout=300)
    assert r.returncode == 2, (r.stdout, r.stderr)
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    assert needle in lines[0], lines[0]


def test_the_table_says_what_its_columns_are_and_a_walk_with_no_d_shows_none():
    """A walk that fell at the challenge's first D has no D, momentum or M (it read 0.00 / 0.00 /
    0.000, as if measured); the columns are defined under the table."""
    from tuner.report.versus import VERSUS_COLUMNS, versus_markdown
    cell = {"speeds": {"forward": {"reached": 0.2, "fell": False, "outcome": "completed"}},
            "match": {"survival": 0.0, "walks": 5, "vx_rmse_mps": None}, "pitch_rms_deg": 1.5,
            "challenge": {"full_m": 0.0, "momentum_Ns": 0.0, "M": 0.0}, "tick_ms": None}
    text = versus_markdown("kidsize", [("engine", "rigid", cell)], {"forward": 0.2})
    row = [line for line in text.splitlines() if line.startswith("| engine")][0]
    assert row.endswith("| none | - | - | - |") and "0.00" not in row.split("| 1.50 |")[1], row
    assert VERSUS_COLUMNS in text and "challenge D" in VERSUS_COLUMNS


def test_a_walk_that_drifts_or_goes_the_other_way_says_so():
    """A walk asked sideways at 0.1 that drifts 0.154 m/s forward read 'sideways 0.048' alone; one
    asked backward that walks forward read '-0.103' alone."""
    from tuner.report.versus import versus_markdown
    cell = {"speeds": {"sideways": {"reached": 0.048, "fell": False, "outcome": "completed",
                                    "drift": {"axis": "vx", "value": 0.154}},
                       "backward": {"reached": -0.103, "fell": False, "outcome": "completed", "drift": None}},
            "tick_ms": None}
    text = versus_markdown("kidsize", [("w", "rigid", cell)], {"sideways": 0.1, "backward": 0.1})
    row = [line for line in text.splitlines() if line.startswith("| w ")][0]
    assert "| 0.048, drifts vx +0.154 | -0.103 (the other way) |" in row, row


def test_the_tick_time_of_a_slower_policy_counts_the_ticks_it_computes_in(monkeypatch):
    """A 50 Hz policy in the 100 Hz loop computes every second tick and holds between: its median was
    of both kinds (0.5 and 0.05 ms); now of the computing ticks. A clock of the test's own: no
    timing."""
    import numpy as np
    import tuner.report.versus as versus
    clock = [0.0]
    monkeypatch.setattr(versus.time, "perf_counter", lambda: clock[0])

    class Slow:
        every = 2

        def __init__(self):
            self.k = 0

        def step(self, m, command=None):
            clock[0] += 0.5e-3 if self.k % self.every == 0 else 0.05e-3
            self.k += 1
            return np.zeros(3)

    timed = versus._Timed(Slow())
    for _ in range(40):
        timed.step(None)
    assert np.allclose(timed.computing(), 0.5e-3) and len(timed.computing()) == 20
    assert np.median(timed.times) < 0.3e-3           # what the table showed before
