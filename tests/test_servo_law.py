"""The servo laws (``tuner/servos/``) against Rhoban's BAM, whose published identifications the
presets carry: the torque-speed lines, and trajectories on BAM's pendulum bench that BAM's own code
produced (``tests/data/bam/reference.npz``; ``tests/data/bam/make_reference.py`` says the command).

What is compared, and why at a 0.2 ms step: BAM's MuJoCo simulator computes the motor's torque
explicitly before each step, ours gives MuJoCo the back-EMF as a damping it integrates implicitly.
Both are the same law; at the simulator's 2 ms step each carries its own step-size error where the
servo saturates hardest (a 3 Hz sine on the light arm, 2 Hz on the heavy one: 10-12 mrad RMS from
the converged trajectory for either), so the laws are compared where both have converged, on BAM's
bench as BAM runs it (one noslip iteration). docs/servos.md has the 2 ms figures.
"""

from __future__ import annotations

import json
import math
from typing import ClassVar       # at module level: dataclasses read a string annotation's ClassVar here

import numpy as np
import pytest

from conftest import ROOT
from tuner.errors import UserError
from tuner.servos import MotorServo, PDServo, friction_budget, preset, preset_names, preset_source, servo_from_mapping
from tuner.servos.motor import FRICTION_MODELS
from tuner.sim.servo_bench import Bench, track

REF = np.load(ROOT / "tests" / "data" / "bam" / "reference.npz")
META = json.loads(str(REF["meta"]))
OURS = {"mx64": "MX-64", "mx106": "MX-106", "xl320": "XL-320", "xl330": "XL-330", "feetech_sts3215_7_4V": "STS3215"}
FINE = 0.0002


def _goal(target: str, t: np.ndarray) -> np.ndarray:
    if target.startswith("step"):
        return np.full_like(t, float(target[4:]))
    return 0.5 * np.sin(2 * math.pi * float(target[3:]) * t)


@pytest.mark.parametrize("key", list(META["models"]))
def test_each_presets_torque_speed_line_is_bams_within_one_percent(key):
    motor, form = key.split("/")
    ours = preset(OURS[motor], form)
    bam = META["models"][key]["torque_speed"]
    assert (ours.voltage, ours.max_duty, ours.error_gain) == pytest.approx((bam["vin"], bam["max_pwm"], bam["error_gain"]),
                                                                           rel=1e-5)
    got = ours.torque_at(np.array(bam["speed"]))
    stall = bam["torque"][0]
    assert np.all(np.abs(got - np.array(bam["torque"])) <= 0.01 * np.maximum(np.abs(bam["torque"]), 0.05 * stall))


@pytest.mark.parametrize("key", list(META["models"]))
def test_our_law_tracks_bams_pendulum_trajectories_within_5_mrad(key):
    """Steps of 0.1 and 1 rad and 0.5 rad sines of 1-3 Hz, on 0.567 kg at 0.105 m and 1.5 kg at
    0.2 m: M1 (Coulomb-viscous, MuJoCo's own pieces) and M6 (our per-step friction term) within
    5 mrad RMS of BAM's MuJoCo simulator, each run. The Feetech's firmware caps the goal's speed;
    BAM's simulator advances that cap twice a step (its rollout logs a control by calling the same
    stateful law before the step does), so the bench runs it at twice the preset's speed here."""
    motor, form = key.split("/")
    servo = preset(OURS[motor], form)
    if servo.profile_speed:
        servo = servo.replace(profile_speed=2 * servo.profile_speed)
    t = np.arange(int(round(META["duration"] / FINE))) * FINE
    every = int(round(META["dt"] / FINE))
    worst = 0.0
    for bench, g in META["benches"].items():
        for target in META["targets"]:
            q = track(servo, Bench(g["mass"], g["length"], g["arm_mass"]), _goal(target, t), FINE, noslip=1)[::every]
            rms = float(np.sqrt(np.mean((q - REF[f"{key}/{bench}/{target}/fine"]) ** 2)))
            worst = max(worst, rms)
    assert worst < 0.005, f"{key}: worst RMS {1000 * worst:.1f} mrad"


def test_the_old_law_is_far_from_bams_on_the_same_bench():
    """The test can fail: round one's MX-64 (a PD clamped at the stall torque at any speed) misses
    BAM's MX-64 by far more than 5 mrad on a fast sine and a large step."""
    t = np.arange(int(round(META["duration"] / FINE))) * FINE
    for target in ("step1", "sin3"):
        q = track(preset("MX-64-pd"), Bench(1.5, 0.2), _goal(target, t), FINE, noslip=1)[::10]
        assert np.sqrt(np.mean((q - REF[f"mx64/m1/heavy/{target}/fine"]) ** 2)) > 0.02


def test_without_noslip_the_extended_friction_creeps_a_little():
    """The simulator runs no noslip iteration (its surfaces were calibrated without): M6's static
    friction, a soft constraint there, lets the heavy arm held at 1 rad creep, within 7 mrad RMS of
    BAM's bench (docs/servos.md); M1 is unaffected (within 3 mrad)."""
    t = np.arange(int(round(META["duration"] / FINE))) * FINE
    for key, limit in (("mx64/m6", 0.007), ("mx64/m1", 0.003)):
        q = track(preset("MX-64", key[-2:]), Bench(1.5, 0.2), _goal("step1", t), FINE)[::10]
        assert np.sqrt(np.mean((q - REF[f"{key}/heavy/step1/fine"]) ** 2)) < limit


def test_the_native_friction_budget_is_the_numpy_reference():
    from tuner.sim.native_step import budget, install
    if not install():
        pytest.skip("no native step on this machine")
    rng = np.random.default_rng(3)
    for form in FRICTION_MODELS:
        for name in ("MX-64", "MX-106", "XL-330"):
            servo = preset(name, form)
            u = servo.friction_term()
            if u is None:
                assert form == "m1"
                continue
            for speed, motor, ext in rng.normal(0, 2, size=(200, 3)):
                assert budget(u, speed, motor, ext) == pytest.approx(float(friction_budget(u, speed, motor, ext)),
                                                                     rel=1e-12, abs=1e-15)
            # M6's quadratic terms: only when motor and external torque oppose
            if form == "m6":
                assert float(friction_budget(u, 0.0, 2.0, -1.0)) > float(friction_budget(u, 0.0, 2.0, 1.0)) - 1.0


def test_a_friction_term_gives_back_the_servo_it_came_from():
    """An identification writes a fitted term back as the servo's fields (``with_friction_term``):
    every BAM form of every preset comes back field for field; a term of no BAM form is refused."""
    for name in ("MX-64", "MX-106", "XL-330"):
        for form in FRICTION_MODELS:
            servo = preset(name, form)
            u = servo.friction_term()
            if u is None:
                continue
            back = preset(name, "m1").with_friction_term(u)
            assert back.friction_model == form
            for f in ("frictionloss", "stribeck", "stribeck_speed", "stribeck_alpha", "load", "load_stribeck",
                      "load_motor", "load_external", "load_motor_stribeck", "load_external_stribeck",
                      "load_motor_quad", "load_external_quad"):
                assert getattr(back, f) == getattr(servo, f), (name, form, f)
            assert list(back.friction_term()[:-1]) == list(u[:-1])     # all but the back-EMF (the motor's own)
    u = preset("MX-64", "m5").friction_term()
    u[1] = 4                                   # directional without the load term: no BAM form
    with pytest.raises(ValueError, match="BAM's forms"):
        preset("MX-64").with_friction_term(u)


def test_datasheet_presets_reproduce_their_datasheet_at_full_duty():
    sheet = {"MX-28": (12.0, 2.5, 55), "XM430-W350": (12.0, 4.1, 46), "XH540-W270": (12.0, 9.9, 39),
             "XM540-W270": (12.0, 10.6, 30)}
    for name, (volts, stall, rpm) in sheet.items():
        s = preset(name)
        assert s.voltage == volts and s.stall_torque == pytest.approx(stall, rel=1e-4)
        assert s.speed == pytest.approx(rpm * 2 * math.pi / 60, rel=1e-4)          # friction included
        assert "datasheet-derived" in preset_source(name)
    for name in preset_names():
        assert len(preset_source(name)) > 40


def test_the_motor_law_loses_torque_with_speed_and_voltage():
    """BAM's MX-64 (M1) at 15 V: 5.93 N m at rest, 2.60 at 5 rad/s before friction (5.84 and 2.45
    after it, the figures the servo issue quotes); at 12 V 1.41 at 5 rad/s. Round one's preset kept
    its 6 N m at any speed."""
    mx64 = preset("MX-64")
    assert float(mx64.torque_at(0.0)) == pytest.approx(5.931, abs=1e-3)
    assert float(mx64.torque_at(5.0)) - mx64.frictionloss - 5 * mx64.damping == pytest.approx(2.45, abs=0.01)
    assert float(mx64.replace(voltage=12.0).torque_at(5.0)) == pytest.approx(1.412, abs=1e-3)
    assert mx64.back_emf_damping == pytest.approx(0.6665, abs=1e-3)
    old = preset("MX-64-pd")
    assert isinstance(old, PDServo) and old.pieces().back_emf == 0.0 and old.torque == 6.0


def test_a_map_entry_names_preset_form_voltage_and_gains():
    base = preset("MX-64")
    s = servo_from_mapping({"preset": "MX-106", "friction_model": "m6", "voltage": 14.8, "p_gain": 40},
                           "servo.legs", base)
    assert isinstance(s, MotorServo) and (s.preset, s.friction_model, s.voltage, s.p_gain) == ("MX-106", "m6", 14.8, 40.0)
    assert s.kt == pytest.approx(2.20983) and s.friction_term() is not None
    # kp [N m/rad] on a motor is the P register that gives it at the servo's voltage
    k = servo_from_mapping({"kp": 40.0, "voltage": 12.0}, "servo.legs", base)
    assert k.kp == pytest.approx(40.0) and k.p_gain == pytest.approx(40.0 / (k.gain / k.p_gain))
    assert servo_from_mapping("MX-64-pd", "servo.legs", base) == preset("MX-64-pd")


@pytest.mark.parametrize("entry, words", [
    ({"speed": 4.0}, "servo.legs.speed: not a field of the dc-motor law"),
    ({"voltage": -1}, "servo.legs.voltage = -1 V is out of range (0, 60] V"),
    ({"voltage": "high"}, "servo.legs.voltage = 'high': expected a number"),
    ({"preset": "MX-65"}, "servo.legs.preset = 'MX-65': unknown (did you mean 'MX-64'?)"),
    ({"preset": "STS3215", "friction_model": "m6"}, "servo.legs.friction_model = 'm6': preset 'STS3215' has only m1"),
    ({"friction_model": "m9", "preset": "MX-64"}, "friction_model = 'm9': preset 'MX-64' has only m1, m2"),
    ({"law": "hydraulic"}, "servo.legs.law = 'hydraulic': one of"),
    ({"kp": 0}, "servo.legs.kp = 0: expected a position gain > 0"),
    ({"bogus": 1}, "servo.legs: unknown field 'bogus' (allowed for the dc-motor law: preset, law, friction_model, kp,"),
])
def test_a_bad_map_entry_is_one_line_naming_the_field(entry, words):
    with pytest.raises(UserError) as err:
        servo_from_mapping(entry, "servo.legs", preset("MX-64"))
    assert words in str(err.value) and "\n" not in str(err.value)


def test_a_new_servo_law_is_one_class_and_one_registration(tmp_path):
    """What docs/architecture.md promises: a law of one's own (here a servo with a torque limit that
    halves beyond a speed: not physics, a test) is a dataclass giving MuJoCo its pieces, registered
    once; a map names it by ``law:`` and the simulator walks it."""
    from dataclasses import dataclass

    from tuner.servos import LAWS, ServoLaw, ServoPieces, register
    from tuner.sim.rollout import Simulator
    from tuner.sim.surfaces import SURFACES

    @register
    @dataclass(frozen=True)
    class TestStiff(ServoLaw):
        law: ClassVar[str] = "test-stiff"
        RANGES: ClassVar = {"gain": (0.0, 500.0, "N m/rad")}
        gain: float = 80.0
        backlash: float = 0.0
        latency: float = 0.0
        armature: float = 0.01
        damping: float = 1.0
        frictionloss: float = 0.05
        speed: float = 6.0

        def pieces(self) -> ServoPieces:
            return ServoPieces(kp=self.gain, kv=0.0, torque=8.0, back_emf=0.0, damping=self.damping,
                               frictionloss=self.frictionloss, armature=self.armature, target_speed=math.inf)
    try:
        import third_party_robot as T
        path = T.write(tmp_path, T.mjcf(), T.map_yaml(extra="servo: {legs: {law: test-stiff, gain: 90}}\n"))
        from tuner.robots import load_robot as load
        robot = load(str(path))
        assert robot.servo_of("l_knee") == TestStiff(gain=90.0)
        sim = Simulator(robot, SURFACES["rigid"])
        k = sim.joint_names.index("l_knee")
        assert sim.model.actuator_gainprm[k, 0] == 90.0 and sim.model.actuator_forcerange[k, 1] == 8.0
        import gaits
        trace = sim.rollout(gaits.generate(gaits.load_baseline("tkux-table2").params, robot.leg, sim.control_period),
                            duration=1.0)
        assert len(trace.t) > 50
    finally:
        del LAWS["test-stiff"]


@pytest.mark.parametrize("name", ["wolfgang/wolfgang.yaml", "berkeley-humanoid-lite/bhl-biped.yaml",
                                  "berkeley-humanoid-lite/bhl-biped-engine.yaml"])
def test_the_fetched_robots_example_maps_read_under_todays_servo_laws(name):
    """The example maps of robots that are fetched, not shipped (their files are not here, so no test
    loads them whole), state their servos as the pd law with the gains their learned walks ran: over
    the default a group gets when its file states none (the dc-motor law), each entry must read and
    keep its numbers. The Berkeley Humanoid Lite maps had no ``law: pd`` and were refused once the
    motor law became the default ("kv: not a field of the dc-motor law")."""
    import yaml
    from tuner.robots.robot_map import default_servo
    doc = yaml.safe_load((ROOT / "examples" / "robots" / name).read_text())
    assert set(doc["servo"]) == {"legs"}
    entry = doc["servo"]["legs"]
    servo = servo_from_mapping(entry, "servo.legs", default_servo("legs"))
    assert isinstance(servo, PDServo)
    assert (servo.kp, servo.kv, servo.torque) == (entry["kp"], entry["kv"], entry["torque"])
