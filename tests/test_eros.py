"""EROS quarter-circle trajectory, T_mn stepping, heel strike and landing deceleration."""

import math

import numpy as np
import pytest

from gaits import ErosParams, ParamError, load_baseline
from gaits import eros

# the paper's literal cycle (no double-support phase) at 2.5 deg per tick, for exact tick counts
WITHOUT = load_baseline("eros-x16-without").params.replace(double_support=0.0, t_mn=math.radians(2.5))
WITH = load_baseline("eros-x16-with").params.replace(double_support=0.0, t_mn=math.radians(2.5),
                                                     heel_gain=2.0, c_dc=1.0)
# the project's gait: a double-support phase of 40% of each step (ours)
DSP = load_baseline("eros-x16-without").params


def test_quarter_circle_profiles_hand_checked():
    th = np.radians([0.0, 30.0, 60.0, 90.0])
    x, up = eros.quarter_circle(th, "lift")
    assert np.allclose(x, [0.0, 1 - math.sqrt(3) / 2, 0.5, 1.0], atol=1e-15)      # eq 37
    assert np.allclose(up, [0.0, 0.5, math.sqrt(3) / 2, 1.0], atol=1e-15)          # eq 38
    _, down = eros.quarter_circle(th, "land")
    assert np.allclose(down, [0.0, 1 - math.sqrt(3) / 2, 0.5, 1.0], atol=1e-15)    # eq 39 read as 1 - cos
    assert x[-1] == 1.0 and up[-1] == 1.0 and down[-1] == 1.0                     # exactly at 90 deg


@pytest.mark.parametrize("deg,ticks", [(3.0, 30), (7.0, 13), (45.0, 2), (0.5, 180)])
def test_t_mn_stepping(deg, ticks):
    th = eros.angle_steps(math.radians(deg))
    assert len(th) == ticks
    assert th[-1] == math.pi / 2
    assert np.allclose(np.diff(np.r_[0.0, th])[:-1], math.radians(deg))   # T_T(i) = T_T(i-1) + T_mn
    assert np.all(np.diff(th) > 0)


@pytest.mark.parametrize("params", [WITHOUT, WITH, WITH.replace(step_x=-0.016)])
def test_via_points_are_reached_exactly(params):
    ref = eros.eros_references(params)
    assert np.array_equal(ref.state[ref.via_ticks], ref.via_states)
    # four transitions per cycle: lift / land alternate, legs alternate per step
    chain = eros.via_points(params)
    kinds = [tr.kind for tr in chain]
    assert kinds[:2] == ["shift", "pre"] and kinds[-3:] == ["post", "return", "settle"]
    assert kinds[2:6] == ["lift", "land", "lift", "land"]
    assert [tr.swing for tr in chain[2:6]] == [1, 1, -1, -1]


def test_walk_distance_and_direction():
    fwd = eros.eros_references(WITHOUT)
    # n steps: the first is X, the middle ones 2X per foot, the last lands beside: feet end at (n-1) X
    assert fwd.state[-1, eros.XL] == pytest.approx(7 * 0.016)
    assert fwd.state[-1, eros.XR] == pytest.approx(7 * 0.016)
    back = eros.eros_references(WITHOUT.replace(step_x=-0.016))
    assert back.state[-1, eros.XL] == pytest.approx(-7 * 0.016)


def test_swing_foot_lifts_to_z_and_hip_sways_to_y():
    ref = eros.eros_references(WITHOUT)
    assert np.max(ref.state[:, eros.ZL]) == pytest.approx(0.095)
    assert np.max(ref.state[:, eros.BY]) == pytest.approx(0.035)
    assert np.min(ref.state[:, eros.BY]) == pytest.approx(-0.035)
    # the landing meets the ground at full speed without deceleration (eq 39)
    land = [i for i, tr in enumerate(eros.via_points(WITHOUT)) if tr.kind == "land"][0]
    end = ref.via_ticks[land + 1]
    z = ref.state[:, eros.ZL]
    last_drop = z[end - 1] - z[end]
    first_drop = z[ref.via_ticks[land]] - z[ref.via_ticks[land] + 1]
    assert last_drop > 10 * first_drop


def test_landing_deceleration_lengthens_landing_monotonically():
    lengths = []
    for c_dc in [0.0, 0.1, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0]:
        p = WITH.replace(c_dc=c_dc, heel_strike=False)
        ref = eros.eros_references(p)
        kinds = [tr.kind for tr in eros.via_points(p)]
        lengths.append(ref.transition_ticks[kinds.index("land")])
    assert lengths[0] == len(eros.angle_steps(WITH.t_mn)) == 36   # C_DC = 0: 90 / T_mn ticks (2.5 deg)
    assert all(b >= a for a, b in zip(lengths, lengths[1:]))
    assert lengths[-1] > 2 * lengths[0]
    # more areas: the later, slower increments reach further back
    ticks = [len(eros.decelerated_angle_steps(math.radians(3), 1.0, n)) for n in (1, 2, 4, 8, 16)]
    assert all(b >= a for a, b in zip(ticks, ticks[1:])) and ticks[-1] > ticks[0]
    # lift-offs keep their speed
    ref = eros.eros_references(WITH)
    kinds = [tr.kind for tr in eros.via_points(WITH)]
    assert ref.transition_ticks[kinds.index("lift")] == 36


def test_deceleration_slows_touchdown():
    def touchdown_speed(p):
        ref = eros.eros_references(p)
        kinds = [tr.kind for tr in eros.via_points(p)]
        end = ref.via_ticks[kinds.index("land") + 1]
        return (ref.state[end - 1, eros.ZL] - ref.state[end, eros.ZL]) / p.tick
    assert touchdown_speed(WITH.replace(heel_strike=False)) < 0.7 * touchdown_speed(WITHOUT)


def test_heel_strike_offsets_vanish_with_zero_gain():
    zero = WITH.replace(heel_gain=0.0)
    ref = eros.eros_references(zero)
    assert np.all(ref.ankle_offset == 0.0)
    off = eros.generate(WITH.replace(heel_strike=False))
    on_zero = eros.generate(zero)
    assert np.array_equal(off.q_ref, on_zero.q_ref)


def test_heel_strike_lands_heel_first_and_pushes_off():
    ref = eros.eros_references(WITH)
    chain = eros.via_points(WITH)
    lift = WITH.foot_lift
    gain = WITH.heel_gain
    # first landing (left leg): toe up by gain * dS'_z at touch-down (eqs 45, 47)
    land = [i for i, tr in enumerate(chain) if tr.kind == "land"][0]
    assert ref.ankle_offset[ref.via_ticks[land + 1], 0] == pytest.approx(-gain * lift)
    # during that landing the right (support) ankle ramps to +gain * dS_z for its push-off (eqs 44, 46)
    assert ref.ankle_offset[ref.via_ticks[land + 1], 1] == pytest.approx(gain * lift)
    # the ankles are flat again after the walk
    assert np.all(ref.ankle_offset[-1] == 0.0)
    # offsets are continuous: no jump larger than one tick's ramp
    assert np.max(np.abs(np.diff(ref.ankle_offset, axis=0))) < 2 * gain * lift * WITH.t_mn * 1.01


def test_joint_table_resampling_keeps_endpoints():
    a = eros.generate(WITHOUT)
    b = eros.generate(WITHOUT, dt=0.004)
    assert b.t[0] == 0.0 and b.t[-1] == pytest.approx(a.t[-1], abs=0.004)
    assert np.allclose(b.p_world_foot_l[-1], a.p_world_foot_l[-1])


def test_eros_parameter_errors():
    with pytest.raises(ParamError, match=r"eros.foot_lift = 0.2 m is out of range \[0, 0.11\] m"):
        ErosParams(foot_lift=0.2)
    with pytest.raises(ParamError, match="sway_y = 0.08 m carries the hip past the support foot"):
        ErosParams(sway_y=0.08, stance_width=0.06)
    with pytest.raises(ParamError, match="eros.heel_strike must be true or false"):
        ErosParams(heel_strike="yes")


def test_hip_sway_is_a_smooth_sinusoid():
    """Landing (1 - cos) then lift-off (sin) make y = Y cos(phase): no speed jump between them."""
    ref = eros.eros_references(WITHOUT)
    y = ref.state[:, eros.BY]
    v = np.diff(y) / WITHOUT.tick
    assert np.max(np.abs(np.diff(v))) < 2.5 * WITHOUT.sway_y * WITHOUT.t_mn ** 2 / WITHOUT.tick ** 2 * WITHOUT.tick
    assert y[0] == 0.0 and y[-1] == 0.0 and abs(v[0]) < 1e-3 and abs(v[-1]) < 1e-12


def test_rest_profile_starts_and_ends_at_rest():
    th = eros.angle_steps(math.radians(2.0))
    _, yz = eros.quarter_circle(np.r_[0.0, th], "rest")
    assert yz[0] == 0.0 and yz[-1] == 1.0
    assert abs(yz[1] - yz[0]) < 0.002 and abs(yz[-1] - yz[-2]) < 0.002


def _step_windows(p):
    """(lift start, landing end, next lift start or end of walk) ticks of every step."""
    ref = eros.eros_references(p)
    kinds = [tr.kind for tr in eros.via_points(p)]
    lifts = [i for i, k in enumerate(kinds) if k == "lift"]
    return ref, [(ref.via_ticks[i], ref.via_ticks[i + 2]) for i in lifts]


def test_literal_cycle_has_no_double_support():
    assert eros.dsp_ticks(WITHOUT) == 0
    kinds = [tr.kind for tr in eros.via_points(WITHOUT)]
    assert "dsp" not in kinds
    ref, steps = _step_windows(WITHOUT)
    # one step's landing is the next one's lift-off: no tick between them with both feet down
    assert all(b == a2 for (_, b), (a2, _) in zip(steps, steps[1:]))


@pytest.mark.parametrize("share", [0.2, 0.4, 0.5])
def test_double_support_takes_its_share_of_each_step(share):
    p = DSP.replace(double_support=share)
    ref, steps = _step_windows(p)
    z = ref.state[:, [eros.ZL, eros.ZR]]
    for (lift0, land1), (lift1, _) in zip(steps, steps[1:]):
        both_down = np.all(z[land1:lift1 + 1] == 0.0, axis=1)
        assert both_down.all()
        step = lift1 - lift0                           # lift-off to the next lift-off
        assert (lift1 - land1) / step == pytest.approx(share, abs=0.02)
        assert np.any(z[lift0 + 1:land1] > 0.0)        # the swing foot is up between them


def test_com_crosses_to_the_new_stance_foot_during_double_support():
    p = DSP
    ref, steps = _step_windows(p)
    y = ref.state[:, eros.BY]
    chain = eros.via_points(p)
    swings = [tr.swing for tr in chain if tr.kind == "lift"]
    for k, ((lift0, land1), (lift1, _)) in enumerate(zip(steps, steps[1:])):
        window = y[land1:lift1 + 1]
        # the sway crosses the midline inside the double support, halfway through it
        assert window[0] * window[-1] < 0.0
        cross = land1 + int(np.argmax(np.sign(window) != np.sign(window[0])))
        assert abs(cross - (land1 + lift1) / 2) <= 1
        # at the next lift-off the hip is already well over the new stance foot (sign -swing)
        assert -swings[k + 1] * y[lift1] > 0.5 * p.sway_y
    # the literal cycle lifts off with the hip still on the midline
    ref0, steps0 = _step_windows(WITHOUT)
    assert all(abs(ref0.state[a, eros.BY]) < 1e-12 for a, _ in steps0)


@pytest.mark.parametrize("params", [DSP, DSP.replace(landing_deceleration=True, c_dc=1.0, heel_strike=True)])
def test_double_support_sway_is_smooth(params):
    """The spread sway keeps the paper's shapes: no velocity jump anywhere (deceleration waits at the apex)."""
    ref = eros.eros_references(params)
    y = ref.state[:, eros.BY]
    v = np.diff(y) / params.tick
    assert np.max(np.abs(np.diff(v))) < 0.05          # [m/s per tick]: ~6x below a jump at full sway speed
    assert np.max(np.abs(y)) == pytest.approx(params.sway_y)
    assert y[-1] == 0.0
    # heel strike offsets stay continuous across the double support
    assert np.max(np.abs(np.diff(ref.ankle_offset, axis=0))) < 0.02


def test_double_support_parameter_bounds():
    with pytest.raises(ParamError, match=r"eros.double_support = 0.7 - is out of range \[0, 0.6\]"):
        ErosParams(double_support=0.7)
