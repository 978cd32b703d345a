"""Metric definitions pinned on synthetic traces."""

import math

import numpy as np
import pytest

from tuner.sim.metrics import centre_of_pressure, pitch_pm, pitch_rms, zmp_error


def test_sine_pitch_gives_known_rms_and_amplitude():
    t = np.arange(0, 6.0 + 1e-9, 0.001)
    A, P = math.radians(7.0), 0.5
    pitch = 0.1 + A * np.sin(2 * np.pi * t / P)
    assert pitch_rms(pitch) == pytest.approx(A / math.sqrt(2), rel=1e-3)
    assert pitch_pm(t, pitch, cycle=1.0) == pytest.approx(A, rel=1e-6)


def test_pm_uses_complete_cycles_only():
    t = np.arange(0, 2.5, 0.01)
    pitch = np.where(t < 1.0, 1.0, 0.0) * np.sin(2 * np.pi * t) + np.where(t >= 2.0, 10.0, 0.0)
    # cycles [0, 1] and [1, 2]: amplitudes 1 and ~0 (the step at t = 2 lies outside)
    assert pitch_pm(t, pitch, 1.0) == pytest.approx(0.5, abs=1e-3)
    with pytest.raises(ValueError, match="cycle must be positive"):
        pitch_pm(t, pitch, 0.0)


def test_centre_of_pressure_of_known_forces():
    pos = np.array([[[0.05, 0.03, 0.0], [0.05, -0.03, 0.0], [-0.05, 0.03, 0.0], [-0.05, -0.03, 0.0]]])
    force = np.array([[30.0, 10.0, 0.0, 0.0]])            # all on the toe, mostly left
    cop = centre_of_pressure(force, pos)
    assert cop[0] == pytest.approx([0.05, (0.03 * 30 - 0.03 * 10) / 40])
    force = np.array([[5.0, 5.0, 5.0, 5.0]])
    assert centre_of_pressure(force, pos)[0] == pytest.approx([0.0, 0.0])
    assert np.all(np.isnan(centre_of_pressure(np.zeros((1, 4)), pos)))
    assert np.all(np.isnan(centre_of_pressure(force, pos, min_total=25.0)))
    with pytest.raises(ValueError, match=r"\(1, 4\) and \(1, 3, 3\)"):
        centre_of_pressure(force, pos[:, :3])


def test_zmp_error_ignores_unloaded_samples():
    zmp = np.array([[0.01, 0.0], [np.nan, np.nan], [0.0, -0.02]])
    ref = np.zeros((3, 2))
    assert zmp_error(zmp, ref) == pytest.approx((0.005, 0.01))


def test_steady_tracking_counts_the_steps_after_the_engines_ramp_and_a_tables_from_the_second():
    """Forward 0.2 m/s from 0 s and a 1 rad/s turn from 2 s; the engine's first step at 1 s, its
    ramps 0.5 m/s^2 and 2 rad/s^2: the forward command settles at 1.4 s, the turn at 2.5 s (0.2 m/s
    down at 0.5 and 1 rad/s up at 2 take 0.4 and 0.5 s). Steps that start before are left out; a
    walk that fell is left out; without an engine every listed step counts."""
    from gaits import CommandStream
    from tuner.sim.metrics import settled_after, steady_tracking

    class Engine:
        accel_vx, accel_vy, accel_wz, t_stand = 0.5, 0.4, 2.0, 1.0
    stream = CommandStream([0.0, 2.0], [[0.2, 0.0, 0.0], [0.0, 0.0, 1.0]], tail=2.0)
    assert settled_after(stream, np.array([0.5, 0.4, 2.0]), 1.0) == pytest.approx([1.4, 2.5], abs=1e-12)
    walked = {"survived": True, "segments": [
        {"command": [0.2, 0.0, 0.0], "measured": None,
         "step_velocities": [[1.2, 0.1, 0, 0], [1.5, 0.2, 0, 0], [1.7, 0.18, 0, 0]]},
        {"command": [0.0, 0.0, 1.0], "measured": None,
         "step_velocities": [[2.3, 0, 0, 0.5], [2.6, 0, 0, 0.9], [2.8, 0, 0, 1.1]]}]}
    fell = {"survived": False, "segments": [dict(s, step_velocities=[[1.9, 5.0, 0, 0], [2.9, 0, 0, 5.0]])
                                            for s in walked["segments"]]}
    tk = steady_tracking([walked, fell], stream, Engine())
    assert tk["forward"] == pytest.approx(0.95) and tk["turning"] == pytest.approx(1.0)
    assert tk["backward"] is None and tk["sideways"] is None
    assert tk["median"] == pytest.approx(0.975) and tk["iqr"] == pytest.approx(0.025)
    table = steady_tracking([walked], stream)
    assert table["forward"] == pytest.approx(0.8) and table["turning"] == pytest.approx(2.5 / 3)
    assert steady_tracking([fell], stream, Engine()) is None


def test_distance_budget_splits_a_walk_into_slide_skid_air_and_sway():
    """A made-up walk of known parts: the left foot loaded throughout slides 10 mm; the right foot
    skids 4 mm unloaded on the ground, is carried 60 mm through the air and lands; the torso ends
    5 mm further ahead of the feet's midpoint than it began."""
    from types import SimpleNamespace

    from tuner.sim.metrics import distance_budget
    n = 100
    t = np.arange(n) * 0.01
    force = np.zeros((n, 8))
    force[:, :4] = 10.0                       # the left foot carries 40 N throughout
    force[:30, 4:] = 10.0                     # the right foot carries 40 N, then lifts
    force[80:, 4:] = 10.0                     # and lands
    left = np.zeros((n, 3))
    left[:, 0] = np.linspace(0.0, 0.010, n)  # loaded: a slide of 10 mm
    right = np.zeros((n, 3))
    right[30:40, 0] = np.linspace(0.0, 0.004, 10)             # unloaded, on the ground: 4 mm
    right[40:, 0] = 0.004
    right[40:70, 2] = 0.02                                    # lifted 20 mm
    right[41:70, 0] = np.linspace(0.004, 0.064, 29)           # carried 60 mm
    right[70:, 0] = 0.064
    torso = np.zeros((n, 3))
    torso[:, 0] = np.linspace(0.0, (0.010 + 0.064) / 2 + 0.005, n)
    trace = SimpleNamespace(t=t, force=force, p_sole_l=left, p_sole_r=right, p_torso=torso)
    b = distance_budget(trace)
    assert b["slide_m"] == pytest.approx(0.005)          # half of each foot's: the midpoint's share
    assert b["skid_m"] == pytest.approx(0.002)
    assert b["air_m"] == pytest.approx(0.030)
    assert b["feet_m"] == pytest.approx(0.037)
    assert b["sway_m"] == pytest.approx(0.005)
    assert b["torso_m"] == pytest.approx(b["feet_m"] + b["sway_m"])


def test_a_walk_whose_controller_reports_no_steps_is_tracked_in_one_second_windows():
    """A learned policy reports no steps: its walk is cut every TRACKING_WINDOW (1 s) instead,
    each segment's first window left out as its first step is. 0.2 m/s asked for 3 s, then 0;
    walked 0.2 m/s, then 0.1: windows 1-2 and 2-3 s match, 4-5 s is 0.1 m/s off."""
    from types import SimpleNamespace

    from gaits import CommandStream
    from tuner.sim.metrics import TRACKING_WINDOW, tracking
    assert TRACKING_WINDOW == 1.0
    stream = CommandStream(np.array([0.0, 3.0]), np.array([[0.2, 0.0, 0.0], [0.0, 0.0, 0.0]]), tail=2.0)
    t = np.arange(0.0, 5.0 + 1e-9, 0.01)
    x = np.where(t <= 3.0, 0.2 * t, 0.6 + 0.1 * (t - 3.0))
    trace = SimpleNamespace(t=t, p_torso=np.stack([x, 0 * t, 0 * t], axis=1), yaw=0 * t, fell=False, t_fall=None)
    tk = tracking(trace, stream, None)
    assert tk["steps"] == 3
    assert tk["vx_rmse_mps"] == pytest.approx(math.sqrt(0.1 ** 2 / 3), abs=1e-9)
    assert tk["vy_rmse_mps"] == pytest.approx(0.0, abs=1e-12)
    assert [s["steps"] for s in tk["segments"]] == [2, 1]
    # the controller's own steps, when it reports them, as before
    assert tracking(trace, stream, np.array([0.0, 0.5, 1.5, 2.5, 3.0, 4.0, 5.0]))["steps"] == 4


def test_a_walk_shorter_than_its_steady_window_says_so_not_nan(capsys):
    """`simulate --command 0.2,0,0 --duration 3` ends before the held command's steady window: the
    velocities are '-' and the line says why (it printed 'vx nan' and '0.2 -> nan (nan%)'); in
    JSON they are null with that reason (it said the robot fell)."""
    import json

    from tuner.cli import main
    args = ["simulate", "--params", "kidsize-engine-carpet4", "--command", "0.2,0,0", "--duration", "3"]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "nan" not in out and "not measured (the walk ended at 3.00 s, before its steady window" in out
    assert main(args + ["--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["metrics"]["vx_mps"] is None and "the walk ended at 3.00 s" in doc["metrics"]["undefined"]["vx_mps"]
