"""Shared fixtures: the thesis's 2-link arm (eq. 6.69) in joint and absolute coordinates,
the same kind of arm tilted into gravity with friction, a seeded random generator and a
central finite-difference helper."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
import yaml

from cpbc.constraints import ConstraintSet, joint_position_limit, joint_rate_limit
from cpbc.controllers import RecentredBarrier
from cpbc.model import ArmState, LinearCoordinates, RobotModel
from cpbc.resources import models_dir
from cpbc.scenario import ScenarioSetup, build, load_scenario

FiniteDifference = Callable[..., np.ndarray]


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_auto_num_workers(config: pytest.Config) -> int | None:
    """One process when the command names tests of one file only (``pytest tests/test_x.py``,
    ``…::test_y``): starting the workers (each imports Pinocchio, MuJoCo and the kernels)
    would take longer than the file. Else None: pytest-xdist's count of the cores
    (pyproject's addopts, ``-n auto``)."""
    files = {arg.split("::")[0] for arg in config.args}
    if len(files) == 1 and Path(next(iter(files))).is_file():
        return 0
    return None


@pytest.fixture
def load_dict(tmp_path: Path) -> Callable[[dict], ScenarioSetup]:
    """Write a scenario dict to YAML in tmp_path, load and build it."""
    counter = iter(range(1000))

    def _load(data: dict) -> ScenarioSetup:
        path = tmp_path / f"scenario_{next(counter)}.yaml"
        path.write_text(yaml.safe_dump(data, sort_keys=False))
        scenario, file = load_scenario(path)
        return build(scenario, file)

    return _load

TS_CPBC = {"type": "cpbc", "name": "TS-CPBC",
           "task": {"omega_n": 12, "zeta": 1, "rotation_omega_n": 24},
           "posture": {"omega_n": 2, "zeta": 1}}


@pytest.fixture
def ur10_under_ball() -> Callable[..., dict]:
    """The UR10 tool just under a ball (no seed reaches the goal): a scenario dict for
    ``duration`` seconds with one controller, TS-CPBC updated by ``law``."""

    def _scenario(duration: float, **law: object) -> dict:
        return {
            "name": "ur10_under_ball", "robot": {"model": "ur10"},
            "simulation": {"duration": duration, "timestep": 0.001},
            "goal": {"frame": "tool0", "position": [0.6, 0.2, 0.36],
                     "orientation": {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}}},
            "cases": [{"name": "start", "position": [0.0, -1.57, 1.57, -1.57, -1.57, 0.0]}],
            "obstacles": [{"type": "plane", "name": "table", "point": [0, 0, -0.08]},
                          {"type": "sphere", "name": "ball", "centre": [0.6, 0.2, 0.5],
                           "radius": 0.1}],
            "constraints": [
                {"type": "joint_position_limit", "name": "ranges", "lower": "from_model",
                 "upper": "from_model"},
                {"type": "clearance", "name": "clearance", "margin": 0.01, "influence": 0.1}],
            "controllers": [{**TS_CPBC, **law}],
        }

    return _scenario


@pytest.fixture
def kinova_behind_base() -> Callable[..., dict]:
    """The Kinova Jaco2 from its upright start (the wrist all but singular) to a goal behind
    the base, joints 2, 3 and 5 kept in range: a scenario dict for ``duration`` seconds with
    one controller, TS-CPBC updated by ``law``."""

    def _scenario(duration: float, **law: object) -> dict:
        return {
            "name": "kinova_behind", "robot": {"model": "kinova"},
            "simulation": {"duration": duration, "timestep": 0.001},
            "goal": {"frame": "j2s6s200_end_effector", "position": [-0.30, 0.10, 0.45],
                     "orientation": {"axis": {"tool": [0, 0, 1], "world": [0, 0, -1]}}},
            "cases": [{"name": "upright",
                       "position": [-0.1, 3.0416, 3.0416, -0.1, 3.0416, -0.1]}],
            "constraints": [{"type": "joint_position_limit", "name": "ranges",
                             "lower": "from_model", "upper": "from_model",
                             "joints": ["j2s6s200_joint_2", "j2s6s200_joint_3",
                                        "j2s6s200_joint_5"]}],
            "controllers": [{**TS_CPBC, **law}],
        }

    return _scenario


@pytest.fixture(scope="session")
def planar_path() -> Path:
    """The MJCF of the thesis's horizontal 2-link arm, loaded by MuJoCo and Pinocchio."""
    path = models_dir() / "planar_2link.xml"
    assert path.is_file()
    return path


@pytest.fixture
def joint_model(planar_path: Path) -> RobotModel:
    """The arm in its own (relative) joint coordinates q."""
    return RobotModel.from_mjcf(planar_path)


@pytest.fixture
def recentred(joint_model: RobotModel) -> RecentredBarrier:
    """The re-centred barrier law on the planar arm (joint coordinates) toward (1.2, −1.0),
    inside joint limits [−1, 1.4] × [−1.3, 1] and rates ±0.6: the safeguard's test law."""
    names = ["q1", "q2"]
    cons = ConstraintSet(
        2,
        [joint_position_limit(np.array([-1.0, -1.3]), np.array([1.4, 1.0]), names)],
        [joint_rate_limit([0.6, 0.6], names)],
    )
    return RecentredBarrier(joint_model, np.array([1.2, -1.0]), cons, 20, 4)


@pytest.fixture
def absolute_model(planar_path: Path) -> RobotModel:
    """The arm in the thesis's absolute link angles θ = T q, T = [[1, 0], [1, 1]]."""
    return RobotModel.from_mjcf(
        planar_path, coordinates=LinearCoordinates.absolute_link_angles(2)
    )


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator: every run draws the same states."""
    return np.random.default_rng(20070601)


def _central_difference(
    f: Callable[[np.ndarray], np.ndarray | float], x: np.ndarray, h: float = 1e-6
) -> np.ndarray:
    """∂f/∂x by central differences, shape f(x).shape + (n,)."""
    x = np.asarray(x, dtype=float)
    cols = []
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h
        cols.append((np.asarray(f(x + e), dtype=float) - np.asarray(f(x - e), dtype=float))
                    / (2 * h))
    return np.stack(cols, axis=-1)


@pytest.fixture(scope="session")
def central_difference() -> FiniteDifference:
    """``central_difference(f, x, h=1e-6)``: ∂f/∂x, shape f(x).shape + (n,)."""
    return _central_difference


def state_at(x: np.ndarray, dx: np.ndarray | None = None, model: RobotModel | None = None,
             frames: tuple[int, ...] = ()) -> ArmState:
    """The per-step state a law hands its constraints: the model's, with kinematics, or —
    for constraints that read only x and ẋ — the state alone (no dynamics terms)."""
    x = np.asarray(x, dtype=float)
    dx = np.zeros_like(x) if dx is None else np.asarray(dx, dtype=float)
    if model is not None:
        return model.state(x, dx, kinematics=True, frames=frames, coriolis=True)
    nothing = np.full(0, np.nan)
    return ArmState(x, dx, x, dx, nothing, nothing, nothing, nothing)



class CampaignRun(NamedTuple):
    """One run of a campaign as cpbc.verify makes it (:func:`campaign_run`)."""

    check: object  # cpbc.reliability.campaign's checked run: violated, constraint, …
    position: np.ndarray  # the drawn start
    velocity: np.ndarray
    kept: object  # the constraints judged (kept_constraints)


def campaign_run(setup: ScenarioSetup, seed: int, seconds: float, controller: str | None = None,
                 on_path: bool = False) -> CampaignRun:
    """The run cpbc.verify makes of ``setup``'s law ``controller`` (its first constrained one
    where None) from the campaign's state ``seed`` for ``seconds`` at 1 kHz
    (cpbc.reliability.campaign.checked_run, every step logged): from the seed's own phase of
    the path where ``on_path`` (as cpbc.verify does), else from its beginning."""
    from dataclasses import replace

    from cpbc.reliability.campaign import RecordingPlant, checked_run, kept_constraints
    from cpbc.reliability.verification import draw_state

    entry = next(e for e in setup.controllers if (e.name == controller if controller
                                                  else not e.controller.constraints.empty))
    kept = kept_constraints(setup, entry, 0.001, setup.safeguard)
    s = draw_state(setup, seed)
    settings = replace(setup.loop_settings, duration=seconds, log_every=1)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    phase = 0.0
    if on_path:
        assert setup.reference is not None
        phase = setup.reference.phase(entry.name, seed)
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard, phase=phase)
    return CampaignRun(check, s.position, s.velocity, kept)

TILTED = """
<mujoco model="tilted_2link">
  <option gravity="0 0 -9.81"/>
  <default><joint type="hinge" axis="0 1 0"/></default>
  <worldbody>
    <body name="link1">
      <joint name="j1"/>
      <inertial pos="0.5 0 0" mass="1.3" diaginertia="0.2 0.9 0.8"/>
      <body name="link2" pos="1 0 0">
        <joint name="j2"/>
        <inertial pos="0.4 0 0" mass="0.8" diaginertia="0.1 0.5 0.5"/>
        <site name="tip" pos="0.9 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture(scope="module")
def tilted(tmp_path_factory: pytest.TempPathFactory) -> RobotModel:
    """A 2-link arm in a vertical plane with unequal links, gravity and viscous friction."""
    path = Path(tmp_path_factory.mktemp("tilted")) / "tilted.xml"
    path.write_text(TILTED)
    return RobotModel.from_mjcf(path, viscous_friction=np.array([0.3, 0.15]))
