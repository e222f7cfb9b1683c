"""cpbc.gym: a scenario's constrained law as a Gymnasium environment, on the Panda beside a
ball and above a table (panda_goal_pose) in real MuJoCo. The full 10⁴-step random policy is
scripts/gym_random_policy.py (its numbers in its docstring); here a shorter one, drawn
toward the ball, checks the same from MuJoCo's own state."""

from __future__ import annotations

import subprocess
import sys
import warnings

import mujoco
import numpy as np
import pytest
from gymnasium.spaces import Box
from gymnasium.utils.env_checker import check_env

from cpbc.gym import ScenarioEnv, make_env
from cpbc.scenario import ScenarioSetup, build, load_scenario

STEPS = 1500  # env steps of the random policy here (20 Hz: 75 s of the arm's time)


@pytest.fixture(scope="module")
def setup() -> ScenarioSetup:
    return build(*load_scenario("panda_goal_pose"))


def test_gymnasiums_env_checker_passes(setup: ScenarioSetup) -> None:
    env = make_env(setup, "pose_delta", max_episode_steps=20)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, skip_render_check=True)
    # the velocity and the point are unbounded (as MuJoCo's own envs'): nothing else
    assert all("infinity" in str(w.message) for w in caught), [str(w.message) for w in caught]


def _obstacle_contacts(env: ScenarioEnv) -> int:
    model, data = env.plant.model, env.plant.data
    ids = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, ob.name)
           for ob in env.setup.obstacles}
    return sum(1 for c in data.contact[:data.ncon] if (c.geom1 in ids) != (c.geom2 in ids))


def test_a_random_policy_crosses_nothing(setup: ScenarioSetup) -> None:
    """Uniform random pose deltas with a pull toward the ball: at every env step MuJoCo's
    state is inside every constraint and no arm geom touches an obstacle; ``info`` (every
    control period) agrees, and the arm did come near the ball."""
    env = make_env(setup, "pose_delta", max_episode_steps=STEPS)
    obs, _ = env.reset(seed=0)
    ball = next(ob.centre for ob in setup.obstacles if ob.name == "ball")
    rng = np.random.default_rng(0)
    smallest = np.inf
    nearest_ball = np.inf
    ball_rows = [i for i, name in enumerate(env.constraint_names) if name.endswith("|ball]")]
    for k in range(STEPS):
        pull = np.clip((ball - obs["frame_position"]) / 0.02, -1.0, 1.0)
        action = 0.6 * rng.uniform(-1, 1, size=6) + 0.4 * np.concatenate([pull, np.zeros(3)])
        obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
        data = env.plant.data
        margins = setup.monitor.margins(data.qpos, data.qvel)
        assert np.all(margins > 0), (k, setup.monitor.names[int(np.argmin(margins))])
        assert _obstacle_contacts(env) == 0 and info["obstacle_contacts"] == 0, k
        assert info["margin"] > 0 and info["outcome"] is None and not terminated, k
        assert truncated == (k == STEPS - 1)
        smallest = min(smallest, info["margin"])
        nearest_ball = min(nearest_ball, float(np.min(info["margins"][ball_rows])))
    assert nearest_ball < 0.05  # within half the clearance's influence: the barrier worked


def test_a_seeded_reset_is_reproducible(setup: ScenarioSetup) -> None:
    env = make_env(setup, "pose_delta")
    actions = np.random.default_rng(5).uniform(-1, 1, size=(10, 6)).astype(np.float32)

    def episode(seed: int) -> list[np.ndarray]:
        obs, _ = env.reset(seed=seed)
        seen = [obs["joint_position"]]
        for a in actions:
            seen.append(env.step(a)[0]["joint_position"])
        return seen

    first, again, other = episode(3), episode(3), episode(4)
    assert all(np.array_equal(a, b) for a, b in zip(first, again, strict=True))
    assert not np.array_equal(first[0], other[0])


def _run(env: ScenarioEnv, action: np.ndarray, steps: int) -> dict[str, np.ndarray]:
    env.reset(seed=1)
    for _ in range(steps):
        obs = env.step(action.astype(np.float32))[0]
    return obs


def test_each_action_kind_moves_toward_its_target(setup: ScenarioSetup) -> None:
    # +z, 20 mm above the measured hand at each step (20 Hz) for 1 s: the hand rises (9.8 cm)
    # and the point alone likewise
    for kind, size in (("pose_delta", 6), ("position_delta", 3)):
        env = make_env(setup, kind)
        start = env.reset(seed=1)[0]["frame_position"]
        up = np.zeros(size)
        up[2] = 1.0
        end = _run(env, up, 20)["frame_position"]
        assert end[2] - start[2] > 0.05 and np.linalg.norm(end[:2] - start[:2]) < 0.03, kind
    # a turn about the world x axis, 0.1 rad past the measured pose at each step, tips the
    # gripper's axis (down) toward +y: by 16° in 0.5 s
    env = make_env(setup, "pose_delta")
    down = _rotation(env.reset(seed=1)[0]["frame_orientation"])[:, 2]
    turn = np.array([0.0, 0.0, 0.0, 1.0, 0.0, 0.0])
    axis = _rotation(_run(env, turn, 10)["frame_orientation"])[:, 2]
    assert axis[1] - down[1] > np.sin(np.radians(10)) and abs(axis[0] - down[0]) < 0.05, axis
    # a joint target within the ranges (that keeps the gripper down: the law's axis spring
    # holds it so) is reached in 4 s; a joint delta moves the joint it names
    env = make_env(setup, "joint_target")
    assert env.action_space == Box(-1.0, 1.0, (7,), np.float32)
    assert setup.goal is not None
    goal = setup.goal.posture + np.array([0.2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3])
    action = 2.0 * (goal - env.joint_lower) / (env.joint_upper - env.joint_lower) - 1.0
    reached = _run(env, action, 80)["joint_position"]
    assert np.max(np.abs(reached - goal)) < 0.01, reached - goal
    env = make_env(setup, "joint_delta")
    start = env.reset(seed=1)[0]["joint_position"]
    step = np.zeros(7)
    step[0] = 1.0
    # (joint 3 follows joint 1 part of the way: their axes are nearly aligned at x_n, and
    # the hand's point at the target's kinematics holds the law's stiffer spring)
    moved = _run(env, step, 20)["joint_position"] - start
    assert moved[0] > 0.1 and np.argmax(np.abs(moved)) == 0, moved


def _rotation(quat: np.ndarray) -> np.ndarray:
    from cpbc.constraints.geometry import quat_to_matrix

    return quat_to_matrix(quat)


@pytest.mark.parametrize("action", [[np.nan, 0, 0, 0, 0, 0], [0.1] * 5, "up",
                                    [0, 0, np.inf, 0, 0, 0]])
def test_a_bad_action_raises_and_changes_nothing(setup: ScenarioSetup, action: object
                                                 ) -> None:
    env = make_env(setup, "pose_delta")
    env.reset(seed=2)
    env.step(np.full(6, 0.5, dtype=np.float32))
    assert env.tracker is not None
    before = (env.plant.data.time, env.plant.data.qpos.copy(), env.tracker.requested.copy())
    with pytest.raises(ValueError, match="action"):
        env.step(action)  # type: ignore[arg-type]
    assert env.plant.data.time == before[0] and np.array_equal(env.plant.data.qpos, before[1])
    assert np.array_equal(env.tracker.requested, before[2])
    obs, _, terminated, _, info = env.step(np.zeros(6, dtype=np.float32))
    assert not terminated and np.all(np.isfinite(obs["joint_position"])) and info["margin"] > 0


def test_bad_options_name_themselves(setup: ScenarioSetup) -> None:
    for options, name in (({"policy_rate": 0.0}, "policy_rate"),
                          ({"policy_rate": 300.0}, "policy_rate"),
                          ({"max_step": float("nan")}, "max_step"),
                          ({"max_episode_steps": 0}, "max_episode_steps"),
                          ({"speed": 1.0}, "speed"), ({"controller": "OSC"}, "controller")):
        with pytest.raises(ValueError, match=name):
            make_env(setup, "pose_delta", **options)
    with pytest.raises(ValueError, match="action"):
        make_env(setup, "torque")
    with pytest.raises(ValueError, match="goal scenario"):
        make_env("panda_cpbc_sphere")


def test_cpbc_imports_without_gymnasium_and_cpbc_gym_says_what_to_install() -> None:
    blocked = "import sys; sys.modules['gymnasium'] = None\n"
    library = subprocess.run([sys.executable, "-c", blocked + "import cpbc.scenario, "
                              "cpbc.reference, cpbc.simulation"], capture_output=True, text=True)
    assert library.returncode == 0, library.stderr
    env = subprocess.run([sys.executable, "-c", blocked + "import cpbc.gym"],
                         capture_output=True, text=True)
    assert env.returncode == 1
    assert "ImportError: cpbc.gym needs gymnasium" in env.stderr
    assert "pip install 'cpbc[gym]'" in env.stderr
