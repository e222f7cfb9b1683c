"""A scenario's ``robot.armature`` and ``robot.friction``: one value in the controller's model
and the MuJoCo plant, none by default (the shipped results stay as they were), what the
model file declares with ``from_model``, and bad values refused by name."""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from cpbc.errors import ScenarioError
from cpbc.resources import models_dir

PLANAR: dict = {
    "name": "joints",
    "robot": {"model": "planar_2link"},
    "simulation": {"duration": 0.02, "timestep": 0.001},
    "target": [0.5, 0.5],
    "cases": [{"name": "rest", "position": [0.0, 0.0]}],
    "constraints": [{"type": "joint_rate_limit", "name": "rates", "bounds": [1.0, 1.0]}],
    "controllers": [{"type": "cpbc", "name": "CPBC", "kp": 4, "kd": 6}],
}


def _declaring(folder: Path) -> str:
    """The planar arm with armature, damping and frictionloss declared on its joints."""
    text = (models_dir() / "planar_2link.xml").read_text().replace(
        'damping="0" armature="0" frictionloss="0"',
        'damping="0.2" armature="0.1" frictionloss="0.3"')
    path = folder / "declaring.xml"
    path.write_text(text)
    return str(path)


def _scenario(**robot: object) -> dict:
    data = copy.deepcopy(PLANAR)
    data["robot"].update(robot)
    return data


def test_none_by_default_in_model_and_plant(load_dict, tmp_path: Path) -> None:
    """What a file declares is left out unless asked for: the MJCF's and the Panda URDF's
    (damping 0.003) alike, in both engines."""
    setup = load_dict(_scenario(model=_declaring(tmp_path)))
    plant = setup.make_plant().model
    for values in (setup.model.armature, setup.model.coulomb_friction,
                   plant.dof_armature, plant.dof_damping, plant.dof_frictionloss):
        np.testing.assert_array_equal(values, [0.0, 0.0])
    assert not setup.model.has_friction
    panda = copy.deepcopy(PLANAR)
    panda.update(robot={"model": "panda"}, target=[0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0],
                 cases=[{"name": "rest", "position": [0.1, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0]}],
                 constraints=[], controllers=[{"type": "pd_gravity", "kp": 20, "kd": 4}])
    arm = load_dict(panda)
    assert not np.any(arm.make_plant().model.dof_damping)
    assert not np.any(arm.model.viscous_friction)


def test_from_model_reads_the_mjcf(load_dict, tmp_path: Path) -> None:
    setup = load_dict(_scenario(model=_declaring(tmp_path), armature="from_model",
                                friction="from_model"))
    np.testing.assert_array_equal(setup.model.armature, [0.1, 0.1])
    np.testing.assert_array_equal(setup.model.coulomb_friction, [0.3, 0.3])
    np.testing.assert_array_equal(np.diag(setup.model.viscous_friction), [0.2, 0.2])
    plant = setup.make_plant().model
    np.testing.assert_array_equal(plant.dof_armature, [0.1, 0.1])
    np.testing.assert_array_equal(plant.dof_damping, [0.2, 0.2])
    np.testing.assert_array_equal(plant.dof_frictionloss, [0.3, 0.3])


def test_from_model_reads_the_urdf(load_dict) -> None:
    """The Panda URDF's <dynamics damping="0.003" friction="0.0"/>."""
    panda = copy.deepcopy(PLANAR)
    panda.update(robot={"model": "panda", "friction": "from_model", "armature": "from_model"},
                 target=[0.0, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0],
                 cases=[{"name": "rest", "position": [0.1, 0.0, 0.0, -1.5, 0.0, 1.5, 0.0]}],
                 constraints=[], controllers=[{"type": "pd_gravity", "kp": 20, "kd": 4}])
    setup = load_dict(panda)
    np.testing.assert_array_equal(np.diag(setup.model.viscous_friction), np.full(7, 0.003))
    np.testing.assert_array_equal(setup.make_plant().model.dof_damping, np.full(7, 0.003))
    np.testing.assert_array_equal(setup.model.coulomb_friction, np.zeros(7))


def test_given_values_reach_both_and_the_mismatch_adds_on_top(load_dict) -> None:
    setup = load_dict(_scenario(armature=[0.2, 0.05],
                                friction={"coulomb": [0.5, 0.25], "viscous": 0.1},
                                plant={"armature": 0.01, "frictionloss": 0.02}))
    np.testing.assert_array_equal(setup.model.armature, [0.2, 0.05])
    np.testing.assert_array_equal(setup.model.coulomb_friction, [0.5, 0.25])
    plant = setup.make_plant().model
    np.testing.assert_allclose(plant.dof_armature, [0.21, 0.06], rtol=1e-15)
    np.testing.assert_allclose(plant.dof_frictionloss, [0.52, 0.27], rtol=1e-15)
    np.testing.assert_array_equal(plant.dof_damping, [0.1, 0.1])
    summary = setup.joint_dynamics.summary()
    assert summary == {"armature": [0.2, 0.05], "coulomb": [0.5, 0.25], "viscous": [0.1, 0.1]}


def test_viscous_friction_keeps_its_old_name(load_dict) -> None:
    setup = load_dict(_scenario(viscous_friction=[0.4, 1.3]))
    np.testing.assert_array_equal(np.diag(setup.model.viscous_friction), [0.4, 1.3])
    np.testing.assert_array_equal(setup.make_plant().model.dof_damping, [0.4, 1.3])


@pytest.mark.parametrize(("robot", "field", "word"), [
    ({"viscous_friction": 0.2, "friction": {"viscous": 0.1}}, "robot.viscous_friction", "once"),
    ({"viscous_friction": 0.2, "friction": "from_model"}, "robot.viscous_friction", "once"),
    ({"friction": {"coulomb": [0.1, 0.2, 0.3]}}, "robot.friction.coulomb", "2 entries"),
    ({"friction": {"viscous": [0.1, 0.2, 0.3]}}, "robot.friction.viscous", "2 entries"),
    ({"armature": [0.1]}, "robot.armature", "2 entries"),
    ({"friction": {"coulomb": -1.0}}, "robot.friction.coulomb", "greater than or equal"),
    ({"friction": {"smoothing": 0.0}}, "robot.friction.smoothing", "greater than 0"),
    ({"armature": "declared"}, "robot.armature", "from_model"),
    ({"coordinates": "absolute", "friction": {"coulomb": 0.3}}, "robot.friction.compensate",
     "coordinates: joint"),
])
def test_bad_joint_dynamics_name_their_field(load_dict, robot: dict, field: str,
                                             word: str) -> None:
    with pytest.raises(ScenarioError) as info:
        load_dict(_scenario(**robot))
    assert info.value.field == field
    assert word in str(info.value)


def test_no_compensation_asked_in_link_angles_is_accepted(load_dict) -> None:
    setup = load_dict(_scenario(coordinates="absolute",
                                friction={"coulomb": 0.3, "compensate": False}))
    assert setup.controllers[0].friction_compensation is None
    assert setup.model.has_friction


def test_a_worker_rebuilds_the_same_joint_dynamics() -> None:
    """A worker process rebuilds the scenario from its JSON dump (cpbc.scenario.runner):
    the friction spec and from_model survive it."""
    from cpbc.scenario.runner import scenario_in_worker, worker_payload
    from cpbc.scenario.schema import Scenario

    for robot in ({"armature": [0.2, 0.1], "friction": {"coulomb": 0.4, "compensate": False}},
                  {"armature": "from_model", "friction": "from_model"}):
        scenario = Scenario.model_validate(_scenario(**robot))
        assert scenario_in_worker(worker_payload(scenario)) == scenario
