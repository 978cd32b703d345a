"""Ground identification (tuner/identify/ground.py, `gait-tuner identify ground`): walks the
tests record on a hidden surface of their own (grass30 with its layer 30 % slower and 25 % less
drag) with the randomisation's sensor noise; the fit recovers the layer's time constant and drag
within 15 % and its residuals come down to the noise; friction is read only from a walk that slips."""

from __future__ import annotations

import dataclasses
import json

import pytest

from gaits import parse_command
from gaits.robot.recorder import Recorder, RecordingController, RecordingMeta
from tuner.params_io import resolve_drive
from tuner.robots import load_robot
from tuner.sim.randomisation import SENSORS_ONLY as NOISE, draw
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES, load_surface
from conftest import run_cli

BASE = SURFACES["grass30"]
HIDDEN = dataclasses.replace(BASE, name="hidden", layer_timeconst=BASE.layer_timeconst * 1.3, drag=BASE.drag * 0.75)


def record_walk(path, command: str, seconds: float, surface=HIDDEN, seed: int = 7):
    robot = load_robot("kidsize")
    drive = resolve_drive("kidsize-engine-carpet4", None, command=parse_command(command))
    sim = Simulator(robot, surface)
    options = drive.run_options()
    options["duration"] = seconds
    rec = Recorder(path, RecordingMeta(robot=robot.name, task="walk", simulated=True, surface=surface.name), start_ns=0)
    try:
        trace = sim.run(RecordingController(drive.controller(robot, sim.control_period), rec),
                        perturb=draw(NOISE, seed, *sim.n_random()), **options)
    finally:
        rec.close()
    assert trace.completed
    return path


def _identify(gait_tuner_cmd, run_env, tmp_path, recording, out):
    r = run_cli(gait_tuner_cmd, ["identify", "ground", "--robot", "kidsize", "--surface", "grass30",
                                         "--recording", str(recording), "--out", str(tmp_path / out), "--json"], run_env)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


@pytest.mark.slow   # ~25 s: a whole ground fit
def test_a_hidden_layer_is_recovered_from_a_walk(tmp_path, gait_tuner_cmd, run_env):
    walk = record_walk(tmp_path / "walk.mcap", "0.15,0,0", 3.0)
    out = _identify(gait_tuner_cmd, run_env, tmp_path, walk, "ground")
    v = out["values"]
    assert abs(v["layer_timeconst"] / 1.3 - 1) <= 0.15 and abs(v["drag"] / 0.75 - 1) <= 0.15, v
    assert out["identifiable"]["layer_timeconst"] and out["identifiable"]["drag"]
    assert all(x <= 1.2 for x in out["rms_after"].values()), out["rms_after"]
    assert all(out["rms_before"][k] > out["rms_after"][k] for k in ("gyro", "encoders"))
    fitted = load_surface(str(tmp_path / "ground" / "surface.yaml"))
    assert fitted.layer_timeconst == pytest.approx(BASE.layer_timeconst * v["layer_timeconst"], rel=1e-6)
    assert fitted.name == "grass30-identified" and fitted.layer_height == BASE.layer_height
    report = (tmp_path / "ground" / "report.txt").read_text()
    assert "layer_timeconst" in report and "accel_peak_mps2" in report and "step_period_s" in report
    assert "layer_timeconst" in (tmp_path / "ground" / "report.html").read_text()


@pytest.mark.slow
def test_friction_is_not_read_from_a_robot_that_does_not_slip(tmp_path, gait_tuner_cmd, run_env):
    stand = record_walk(tmp_path / "stand.mcap", "0,0,0", 2.0)
    out = _identify(gait_tuner_cmd, run_env, tmp_path, stand, "ground")
    assert not out["identifiable"]["friction"]
    doc = json.loads((tmp_path / "ground" / "fit.json").read_text())
    assert doc["slip_ticks"] < 3 and doc["parameters"]["friction"]["fitted"] == BASE.friction
    assert "cannot tell it" in (tmp_path / "ground" / "report.txt").read_text()


def test_a_walk_without_an_imu_is_one_line(tmp_path, gait_tuner_cmd, run_env):
    from gaits.control import Measurement
    with Recorder(tmp_path / "r.mcap", RecordingMeta(robot="kidsize")) as rec:
        for k in range(100):
            rec.record(Measurement(k * 0.01, q=[0.0] * 20), None, [0.0] * 20)
    r = run_cli(gait_tuner_cmd, ["identify", "ground", "--robot", "kidsize", "--recording",
                                         str(tmp_path / "r.mcap"), "--out", str(tmp_path / "g")], run_env)
    assert r.returncode == 2 and len(r.stderr.strip().splitlines()) == 1, r.stderr
    assert "no IMU orientation channel" in r.stderr and not (tmp_path / "g").exists()


def test_transfer_walks_a_set_in_both_worlds(tmp_path, gait_tuner_cmd, run_env):
    """`transfer` on an identified surface file: both worlds walked, the default one named from the
    identified file's start; a file whose name does not say it is one line asking for it."""
    from tuner.report.calibration import surface_yaml
    (tmp_path / "s.yaml").write_text(surface_yaml(dataclasses.replace(HIDDEN, name="grass30-identified"), "test"))
    r = run_cli(gait_tuner_cmd, ["transfer", "kidsize-engine-carpet4", "--robot", "kidsize", "--surface",
                                         str(tmp_path / "s.yaml"), "--walks", "2", "--json"], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["default"]["world"] == "kidsize on grass30" and out["identified"]["world"] == "kidsize on grass30-identified"
    assert all(out[k]["walks"] == 2 and 0.0 <= out[k]["survival"] <= 1.0 for k in out)
    (tmp_path / "t.yaml").write_text(surface_yaml(dataclasses.replace(HIDDEN, name="field-a"), "test"))
    r = run_cli(gait_tuner_cmd, ["transfer", "kidsize-engine-carpet4", "--robot", "kidsize", "--surface",
                                         str(tmp_path / "t.yaml"), "--walks", "2"], run_env)
    assert r.returncode == 2 and "give --default-surface" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_transfer_lines_give_units_in_a_header_not_a_letter_after_a_number():
    """The pitch column read '9.66d'; units now sit under the header, a missing figure is '-' in
    its column."""
    from tuner.report.transfer import transfer_lines
    s = {"walks": 2, "survival": 0.5, "falls": 1, "pitch_rms_deg": 9.664, "vx_rmse_mps": 0.05, "vy_rmse_mps": None,
         "wz_rmse_radps": 0.1}
    lines = transfer_lines("set", {"default": ("kid on grass30", s)})
    assert "[deg]" in lines[2] and "[m/s]" in lines[2] and "9.66d" not in lines[3]
    row = lines[3].split()
    assert row[3:7] == ["9.66", "0.050", "-", "0.100"]
    assert len(lines[3].split("kid on")[0]) == len(lines[1].split("what")[0])      # the columns line up


def test_the_fits_sensor_noises_are_the_randomisations_and_the_clis_default_is_the_encoders():
    """A walk's fit reads each channel in the sensor noise the randomisation draws (ground.NOISE is
    derived from its defaults), and `identify servos --noise` defaults to the encoders' (written in the
    CLI so its start imports no simulator): one number, tied here."""
    import math

    from tuner.cli.identify import ENCODER_NOISE
    from tuner.identify.ground import NOISE as FIT_NOISE
    assert FIT_NOISE == {"rpy": math.radians(NOISE.imu_noise_deg), "gyro": NOISE.gyro_noise, "q": NOISE.encoder_noise}
    assert ENCODER_NOISE == FIT_NOISE["q"] > 0
