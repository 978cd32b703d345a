"""The ground's room (tuner/sim/ground/): a kind of ground is one class, chosen by a surface's
``kind:`` or by its fields, and a new kind is one class plus one registration."""

from __future__ import annotations

import mujoco
import numpy as np
import pytest

import gaits
from tuner.errors import UserError
from tuner.robots import load_robot
from tuner.sim.ground import KINDS, PREFIX, GroundKind, kind_of, register_kind
from tuner.sim.randomisation import Randomisation, draw
from tuner.sim.rollout import Simulator
from tuner.sim.surfaces import SURFACES, Surface, load_surface

ROBOT = load_robot("kidsize")


def table(sim: Simulator) -> gaits.GaitTrajectory:
    return gaits.generate(gaits.load_baseline("tkux-table2").params, sim.robot.leg, sim.control_period)


def test_each_built_in_surface_is_the_kind_its_fields_make_it():
    kinds = {name: kind_of(s).name for name, s in SURFACES.items()}
    assert kinds == {"rigid": "rigid", "carpet4": "layer", "grass10": "layer", "grass30": "layer", "grass50": "layer"}
    from conftest import ROOT
    assert kind_of(load_surface(str(ROOT / "examples/surfaces/grass50-blades.yaml"))).name == "blades"
    # the fields identify ground fits are the kind's
    assert kind_of(SURFACES["carpet4"]).fit_fields() == ("layer_timeconst", "layer_dampratio", "friction")
    assert kind_of(SURFACES["grass30"]).fit_fields()[:2] == ("layer_timeconst", "drag")


def test_a_surface_that_names_its_kind_reads_as_before_when_it_names_none():
    """``kind`` shows in a surface's repr (a study's scoring parts digest it) only when named."""
    s = SURFACES["grass30"]
    assert "kind=" not in repr(s)
    named = s.replace(kind="layer")
    assert repr(named) == repr(s)[:-1] + ", kind='layer')"
    assert kind_of(named).name == "layer"


def test_a_named_kind_the_fields_contradict_or_an_unknown_one_is_refused_in_one_line(tmp_path):
    with pytest.raises(UserError, match=r"kind = 'rigid', but its fields make it 'layer'"):
        kind_of(SURFACES["grass30"].replace(kind="rigid"))
    path = tmp_path / "mud.yaml"
    path.write_text("layer_height: 0.02\nkind: mud\n")
    surface = load_surface(str(path))
    with pytest.raises(UserError, match=r"kind = 'mud' is not a ground kind \(known: rigid, layer, blades"):
        Simulator(ROBOT, surface)


def test_a_walk_on_a_named_kind_is_the_walk_on_the_kind_its_fields_make_it():
    """Naming the kind its fields give changes nothing: the same walk to the bit."""
    sim = Simulator(ROBOT, SURFACES["grass50"])
    a = sim.rollout(table(sim), duration=1.5)
    b = Simulator(ROBOT, SURFACES["grass50"].replace(kind="layer")).rollout(table(sim), duration=1.5)
    assert np.array_equal(a.q, b.q) and np.array_equal(a.pitch, b.pitch) and np.array_equal(a.force, b.force)


def test_a_new_ground_kind_is_one_class_and_one_registration(tmp_path):
    """What docs/architecture.md promises: a kind of one's own (here sticky soil: a vertical damper
    under each sole corner while it is within 5 mm of the soil; not physics, a test) is a class
    that adds its parts to the scene and runs its term each control tick, registered once; a
    surface file names it by ``kind:`` and the simulator walks it, randomised too."""

    @register_kind
    class Sticky(GroundKind):
        name = "test-sticky"
        fields = ("friction", "drag")
        ticks = 0

        @property
        def on_points(self) -> bool:
            return True

        def add_point(self, spec, gt, site, label) -> int:
            act = spec.add_actuator(default=gt, name=f"{PREFIX}sticky/{label}", target=site,
                                    refsite=self.ref_site(spec, gt), trntype=mujoco.mjtTrn.mjTRN_SITE)
            act.set_to_damper(kv=self.surface.drag)
            act.gear = [0, 0, 1, 0, 0, 0]
            act.ctrllimited = mujoco.mjtLimited.mjLIMITED_TRUE
            act.ctrlrange = [0.0, 1.0]
            return 1

        @property
        def python_tick(self) -> bool:
            return True

        def tick(self, model, data) -> None:
            type(self).ticks += 1
            near = self._points(data)[:, 2] < 0.005
            data.ctrl[self.first:self.first + self.n_actuators] = near

    try:
        path = tmp_path / "sticky.yaml"
        path.write_text("kind: test-sticky\ndrag: 50\nlayer_height: 0.001\nsoil_friction: 0.9\n")
        surface = load_surface(str(path))
        assert surface == Surface(name="sticky", kind="test-sticky", drag=50.0, layer_height=0.001)
        sim = Simulator(ROBOT, surface)
        assert isinstance(sim.ground, Sticky) and sim.ground.n_actuators == 8 and sim.layout.n_drag == 8
        names = [sim.model.actuator(k).name for k in range(sim.ground.first, sim.model.nu)]
        assert names == [f"{PREFIX}sticky/{side}{k}" for side in "lr" for k in range(4)]
        trace = sim.rollout(table(sim), duration=1.0)
        assert Sticky.ticks == len(trace.t) - 1                 # once a control tick, in Python
        # a randomised walk scales the kind's dampers, and puts them back after
        p = draw(Randomisation(), 3, *sim.n_random())
        nominal = sim.model.actuator_gainprm[sim.ground.first:, 2].copy()
        seen = []
        sim.run(gaits.control.TablePlayer(table(sim)), duration=0.2, perturb=p,
                on_tick=lambda k, d: seen.append(sim.model.actuator_gainprm[sim.ground.first, 2]))
        assert seen[0] == pytest.approx(nominal[0] * p.drag) and p.drag != 1.0
        assert np.array_equal(sim.model.actuator_gainprm[sim.ground.first:, 2], nominal)
    finally:
        del KINDS["test-sticky"]


def test_a_kind_needs_a_name_and_one_class_a_name():
    with pytest.raises(ValueError, match="needs a name"):
        register_kind(type("Nameless", (GroundKind,), {}))
    with pytest.raises(ValueError, match="registered twice"):
        register_kind(type("Another", (GroundKind,), {"name": "rigid"}))


def test_the_surfaces_verb_names_each_kind_and_refuses_an_unknown_one(tmp_path):
    from conftest import ROOT, run_in_process
    r = run_in_process(["surfaces", "--surface", "rigid", "--surface", str(ROOT / "examples/surfaces/grass50-blades.yaml")])
    assert r.returncode == 0, r.stderr
    assert [line.split()[:2] for line in r.stdout.splitlines()[:2]] == [["rigid", "rigid"], ["grass50-blades", "blades"]]
    (tmp_path / "mud.yaml").write_text("kind: mud\nlayer_height: 0.01\n")
    r = run_in_process(["surfaces", "--surface", str(tmp_path / "mud.yaml")])
    assert r.returncode == 2 and r.stderr.strip().splitlines() == [
        "gait-tuner: error: surface 'mud': kind = 'mud' is not a ground kind (known: rigid, layer, blades)"]


def test_a_rigid_floors_friction_is_its_friction_field(tmp_path):
    """The field that says "sliding friction of the layer (or the rigid floor)" is the floor's: it was
    the soil's soil_friction, so identify ground's friction fit on a rigid floor changed nothing it
    replayed, and a rigid surface file's friction was silently not walked."""
    from tuner.sim.ground import PREFIX as P
    sim = Simulator(ROBOT, SURFACES["rigid"].replace(friction=0.35))
    assert sim.model.geom_friction[sim.model.geom(P + "soil").id, 0] == 0.35
    grass = Simulator(ROBOT, SURFACES["grass30"].replace(soil_friction=0.6))     # under a layer: the soil's
    assert grass.model.geom_friction[grass.model.geom(P + "soil").id, 0] == 0.6
    path = tmp_path / "floor.yaml"
    path.write_text("soil_friction: 0.5\n")
    with pytest.raises(UserError, match=r"soil_friction = 0.5 on a rigid floor: the floor's friction is friction = 0.9"):
        load_surface(str(path))
