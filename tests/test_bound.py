"""The push-recovery challenge's physical bound (tuner/challenge/bound.py, `challenge bound`): the
trajectory optimisation against the closed-form one-step capture region, and what it reports."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from tuner.robots import load_robot
from tuner.challenge.bound import (LegLimits, bottle_figures, leg_limits, lipm_phase_function,
                                push_bound, speed_bound, swing_time)

from conftest import run_cli

LIM = LegLimits(mass=5.0, z_c=0.25, sole_front=0.06, sole_back=0.04, reach=0.16, leg=0.19, thigh=0.11, shank=0.11,
                crouch_height=0.19, hip_speed=6.0, knee_speed=6.0, ankle_torque=10.0, knee_torque=6.0, lift=0.02)


def test_the_lipm_block_is_the_pendulums_closed_form():
    f = lipm_phase_function()
    w = math.sqrt(9.81 / 0.25)
    x1, v1 = (float(v) for v in f(0.01, 0.3, 0.05, 0.2, w))
    c, s = math.cosh(w * 0.2), math.sinh(w * 0.2)
    assert x1 == pytest.approx(0.05 + (0.01 - 0.05) * c + 0.3 / w * s, abs=1e-12)
    assert v1 == pytest.approx((0.01 - 0.05) * w * s + 0.3 * c, abs=1e-12)


@pytest.mark.parametrize("lim", [LIM, dataclasses.replace(LIM, hip_speed=2.0, reach=0.2),
                                 dataclasses.replace(LIM, knee_speed=20.0, lift=0.01, leg_inertia=0.03,
                                                     hip_torque=4.0)])
def test_one_step_is_the_closed_form_capture_region(lim):
    """One step: the optimisation's largest Delta v is omega (b + l e^{-omega T_s(l)}) maximised
    over the step length l, computed by hand on a grid (1e-4 m/s: the grid's spacing)."""
    w = math.sqrt(9.81 / lim.z_c)
    by_hand = max(w * (min(lim.sole_front, lim.ankle_torque / (lim.mass * 9.81)) + l * math.exp(-w * swing_time(lim, l)))
                  for l in np.linspace(0, lim.reach, 4001))
    got = push_bound(lim, 1)
    assert got["delta_v_mps"] == pytest.approx(by_hand, abs=1e-4)
    assert got["one_step_closed_form_mps"] == pytest.approx(by_hand, abs=1e-4)
    (phase,) = got["plan"]
    assert phase["zmp_m"] == pytest.approx(lim.zmp_front(), abs=1e-6)         # the ZMP on the sole's edge


def test_more_steps_absorb_more_and_the_ankle_torque_can_bind():
    one, two, three = (push_bound(LIM, n)["delta_v_mps"] for n in (1, 2, 3))
    assert one < two < three < one * 2
    weak = dataclasses.replace(LIM, ankle_torque=1.0)                          # 1 / (5 g) = 20 mm < the sole's 60
    assert weak.zmp_front() == pytest.approx(1.0 / (5.0 * 9.81))
    assert push_bound(weak, 1)["delta_v_mps"] < one


def test_the_swing_time_is_the_servos_and_the_speed_bound_its_step_over_it():
    # no inertia given: each joint at its servo's speed from the start; by hand, the law of cosines
    def knee(h):
        return math.pi - math.acos((0.11 ** 2 * 2 - h * h) / (2 * 0.11 * 0.11))
    hip = 2 * math.asin(0.16 / (2 * 0.19)) / 6.0
    lift = 2 * (knee(0.19 - 0.02) - knee(0.19)) / 6.0
    assert swing_time(LIM, 0.16) == pytest.approx(max(hip, lift))
    assert swing_time(LIM, 0.0) == pytest.approx(lift)
    sp = speed_bound(LIM)
    assert sp["speed_mps"] == pytest.approx(sp["step_m"] / sp["period_s"])
    assert sp["froude"] == pytest.approx(sp["speed_mps"] ** 2 / (9.81 * 0.25))
    assert speed_bound(dataclasses.replace(LIM, hip_speed=3.0))["speed_mps"] < sp["speed_mps"]


def test_bottle_figures_invert_the_drop():
    f = bottle_figures(0.5, 3.0, 5.0, 1.5)
    assert f["momentum_Ns"] == pytest.approx(4.0)
    assert f["drop_m"] == pytest.approx((4.0 / 3.0) ** 2 / (2 * 9.81))
    assert f["distance_m"] == pytest.approx(math.sqrt(1.5 ** 2 - (1.5 - f["drop_m"]) ** 2))
    assert bottle_figures(20.0, 3.0, 5.0, 1.5)["distance_m"] is None


def test_a_robots_limits_come_from_its_model():
    lim = leg_limits(load_robot("kidsize"), 0.02)
    mx64 = load_robot("kidsize").servo_of("l_knee")
    assert lim.mass == pytest.approx(4.95) and lim.hip_speed == mx64.speed and lim.ankle_torque == mx64.torque
    assert lim.sole_front + lim.sole_back == pytest.approx(0.10) and lim.reach == pytest.approx(0.8 * 0.22)
    assert lim.leg_inertia > lim.shank_inertia > 0


def test_challenge_bound_through_the_cli(gait_tuner_cmd, run_env):
    r = run_cli(gait_tuner_cmd, ['challenge', 'bound', '--surface', 'grass30', '--steps', '2', '--json'], run_env)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)
    assert out["model"]["lift_m"] == pytest.approx(0.04) and out["bottle_kg"] == 3.0
    for side in ("from_behind", "from_the_front"):
        b = out[side]
        assert len(b["plan"]) == 2 and b["delta_v_mps"] >= b["one_step_closed_form_mps"] - 1e-6
        assert b["momentum_Ns"] == pytest.approx((3.0 + out["model"]["mass_kg"]) * b["delta_v_mps"])
    assert out["speed"]["froude"] > 0 and out["leaves_out"]


def test_a_motors_fastest_move_follows_its_torque_speed_line():
    """move_time: the bang-bang move of a motor whose torque falls with speed, checked against the ODE
    integrated finely (full duty forward, then back until rest); no shorter than the old bounds (at
    no-load speed throughout, at stall torque throughout); a swing on real MX-64s takes longer than
    the same swing with round one's servos, and the bound of kidsize is smaller than kidsize-pd's."""
    from tuner.challenge.bound import _move_bounds, move_time
    tau, droop, inertia = 5.84, 0.678, 0.03
    for angle in (0.1, 0.6, 1.2):
        t_exact = move_time(angle, tau, droop, inertia)
        # the ODE: switch when the braking from here (at full reverse duty) just reaches the angle
        dt, w, x, t = 1e-5, 0.0, 0.0, 0.0
        while True:
            # where braking from (x, w) ends: x + w/c - (a/c) ln(1 + w c / a) / c
            a, c = tau / inertia, droop / inertia
            if x + w / c - (a / c) * math.log1p(w * c / a) / c >= angle:
                break
            w += (tau - droop * w) / inertia * dt
            x += w * dt
            t += dt
        t += math.log1p(w * c / a) / c
        assert t_exact == pytest.approx(t, rel=2e-3)
        assert t_exact >= max(_move_bounds(angle, tau / droop, tau, inertia))
    real, old = leg_limits(load_robot("kidsize"), 0.02), leg_limits(load_robot("kidsize-pd"), 0.02)
    assert real.knee_droop > 0.6 and old.knee_droop == 0.0
    assert swing_time(real, 0.1) > swing_time(old, 0.1)
    assert speed_bound(real)["speed_mps"] < speed_bound(old)["speed_mps"]


def test_a_robot_whose_servos_cannot_swing_a_leg_is_one_line(tmp_path):
    """Servos at 1 V (their stall torque below their friction) move nothing: refused in one line, not
    an internal error of the solver."""
    import dataclasses

    from tuner.errors import UserError
    from tuner.challenge.bound import robot_bound
    from tuner.sim.surfaces import load_surface
    weak = load_robot("kidsize")
    weak = dataclasses.replace(weak, servos={k: s.replace(voltage=0.05) for k, s in weak.servos.items()})
    with pytest.raises(UserError, match="cannot swing a leg"):
        robot_bound(weak, load_surface("carpet4"), 3.0, 1.5, 2)
    out = robot_bound(load_robot("kidsize"), load_surface("grass30"), 3.0, 1.5, 1)
    assert "grass30's layer of 30 mm" in out["surface_terms"] and "rigid floor" in out["surface_terms"]
