"""MuJoCo rollouts: every family on every surface, the toe-sticking effect, failure modes."""

import math

import numpy as np
import pytest

import gaits
from tuner.sim.metrics import summarize
from tuner.robots import load_robot
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES, Surface

ROBOT = load_robot("kidsize")
SIMS = {}


def sim_for(name):
    if name not in SIMS:
        SIMS[name] = Simulator(ROBOT, SURFACES[name])
    return SIMS[name]


@pytest.mark.parametrize("surface", list(SURFACES))
@pytest.mark.parametrize("baseline", ["tkux-table2", "eros-x8-with", "cosine-setiono"])
def test_every_family_on_every_surface(surface, baseline):
    sim = sim_for(surface)
    traj = gaits.generate(gaits.load_baseline(baseline).params, ROBOT.leg, sim.control_period)
    trace = sim.rollout(traj, duration=3.0)
    for arr in (trace.pitch, trace.roll, trace.p_torso, trace.p_com, trace.force, trace.q, trace.tau):
        assert np.all(np.isfinite(arr))
    # a standing start: upright and loaded on both feet for the first 0.3 s
    first = trace.t <= 0.3
    assert np.max(np.abs(trace.pitch[first])) < math.radians(5)
    assert np.max(np.abs(trace.roll[first])) < math.radians(5)
    weight = 4.95 * 9.81
    assert np.all(trace.force[first][-5:].sum(axis=1) > 0.7 * weight)
    # servos respect their torque limits
    assert np.max(np.abs(trace.tau)) <= 6.0 + 1e-9
    m = summarize(trace)
    assert 0.0 <= m.pitch_rms_deg < 60 and 0.0 <= m.pitch_pm_deg < 90
    assert -0.2 < m.distance_m < 0.5
    assert trace.reason == "completed" or trace.reason.startswith("fell at t =")
    assert m.fell == trace.fell
    # the soles rest on the blade tips, never below the soil
    assert np.min(trace.p_sole_l[:, 2]) > -0.005


def test_tlipfm_walks_on_the_rigid_floor():
    sim = sim_for("rigid")
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, sim.control_period)
    m = summarize(sim.rollout(traj))
    assert not m.fell
    assert m.distance_m > 0.2            # 13 steps of 2 cm planned (0.26 m)


def test_toe_first_landing_sticks_on_tall_grass():
    """The same toe-first landing pitches the robot more on grass50 than on carpet4."""
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, ROBOT.leg).q_ref[0]
    out = {}
    for name in ("carpet4", "grass50"):
        tr = sim_for(name).landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
        out[name] = (np.degrees(tr.pitch.max()), np.degrees(tr.pitch[-1]))
    assert out["grass50"][0] > out["carpet4"][0] + 2.0       # measured 5.9 vs 3.3 deg
    assert out["grass50"][1] > out["carpet4"][1] + 4.0       # stays pitched: 5.1 vs -1.8 deg
    # landing deceleration's premise: the same landing at half the speed pitches less (4.2 deg)
    slow = sim_for("grass50").landing_test(q0, pitch=math.radians(3.0), forward_speed=0.05, sink_speed=0.15)
    assert np.degrees(slow.pitch.max()) < out["grass50"][0] - 1.0
    # the drag dampers are implicit: even at the bound the landing stays numerically calm
    strong = Simulator(ROBOT, SURFACES["grass50"].replace(drag=5000.0))
    tr = strong.landing_test(q0, pitch=math.radians(3.0), forward_speed=0.1)
    assert not tr.fell and np.max(np.abs(np.degrees(tr.pitch))) < 15
    assert np.all(np.isfinite(tr.pitch))


def test_fall_is_detected_with_time_and_place():
    sim = sim_for("rigid")
    q0 = gaits.generate(gaits.load_baseline("eros-x8-without").params, ROBOT.leg).q_ref[0]
    tr = sim.landing_test(q0, pitch=math.radians(12.0), forward_speed=0.4)
    assert tr.fell and tr.t_fall is not None and tr.t_fall < 1.0
    assert tr.reason.startswith(f"fell at t = {tr.t_fall:.2f} s")
    assert np.degrees(tr.pitch[-1]) >= 50.0 - 1e-6


def test_servo_speed_limit_makes_fast_gaits_lag():
    """Round one's pd servos cap how fast their target moves; the motor's have no cap: their back-EMF
    holds the joint back instead (the same fast EROS table lags by more than 0.05 rad)."""
    old = load_robot("kidsize-pd")
    sim = Simulator(old, SURFACES["rigid"])
    p = gaits.load_baseline("eros-x24-without").params.replace(t_mn=math.radians(6.0))
    trace = sim.rollout(gaits.generate(p, old.leg, sim.control_period), duration=2.5)
    lag = np.abs(trace.q_cmd - trace.q_ref)
    assert lag.max() > 0.05                                   # the commanded targets could not keep up
    rate = np.abs(np.diff(trace.q_cmd, axis=0)) / sim.control_period
    assert rate.max() <= old.servo_of("l_knee").speed + 1e-9
    real = sim_for("rigid").rollout(gaits.generate(p, ROBOT.leg, sim.control_period), duration=2.5)
    assert np.allclose(real.q_cmd[1:], real.q_ref[1:], rtol=0, atol=1e-15)    # no cap on the command
    assert np.abs(real.q - real.q_cmd).max() > 0.05           # the joints lag it


def test_diverging_simulation_ends_with_a_reason():
    bad = Surface(name="bad", layer_height=0.05, layer_timeconst=0.002, layer_dampratio=0.1,
                  layer_dmin=0.9999, layer_dmax=0.9999, drag=5000.0)
    sim = Simulator(ROBOT, bad)
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, sim.control_period)
    trace = sim.rollout(traj, duration=2.0)
    assert trace.reason in ("completed",) or trace.reason.startswith(("fell", "diverged"))
    m = summarize(trace)
    assert np.isfinite(m.pitch_rms_deg) and np.isfinite(m.distance_m)


def test_control_period_mismatch_is_an_error():
    sim = sim_for("rigid")
    traj = gaits.generate(gaits.load_baseline("tkux-table2").params, ROBOT.leg, 0.005)
    with pytest.raises(ValueError, match=r"dt \(0.005 s\) must equal the control period \(0.01 s\)"):
        sim.rollout(traj)


def test_a_diverged_or_impossible_walk_never_survives():
    """Stiff servos without damping on a 5 ms physics step blow the simulation up (measured: 378 m/s
    at 0.08 s): the walk ends "impossible" (a state no kid-size robot reaches) or "diverged", is
    not a fall, and counts as a survival nowhere: the trace, the metrics, a robustness report."""
    import dataclasses

    from tuner.sim.metrics import summarize
    from tuner.servos import PDServo
    stiff = {k: PDServo(kp=1000.0, kv=0.0, damping=0.0, armature=0.0, frictionloss=0.0) for k in ROBOT.servos}
    bad = dataclasses.replace(ROBOT, servos=stiff)
    sim = Simulator(bad, SURFACES["rigid"], timestep=0.005)
    trace = sim.rollout(gaits.generate(gaits.load_baseline("tkux-table2").params, bad.leg, sim.control_period),
                        duration=2.0)
    assert trace.outcome in ("diverged", "impossible") and not trace.survived and not trace.fell
    assert trace.reason.startswith(trace.outcome)
    m = summarize(trace)
    d = m.to_dict()
    assert not m.survived and d["outcome"] == trace.outcome and d["survived"] is False
    from tuner.sim.robustness import RobustnessReport
    rep = RobustnessReport("r", "rigid", "p", False, [{"fell": False, "survived": False, "outcome": trace.outcome,
                                                         "t_fall_s": None, "pitch_rms_deg": 1.0, "speed_mps": 0.1}], {})
    assert rep.survival == 0.0 and rep.to_dict()["outcomes"][trace.outcome] == 1
