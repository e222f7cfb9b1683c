"""A random policy for 10⁴ env steps of cpbc.gym on the Panda beside a ball and above a table
(panda_goal_pose, pose_delta actions at 20 Hz: 500 000 control periods, 500 s of the arm's
time, in 20 seeded episodes of 500 steps), twice: uniform actions, and uniform actions
pulled toward the ball. After every env step MuJoCo's own state is checked against every
constraint of the scenario and for contacts between the arm and an obstacle; ``info``
carries the same at every control period. Prints, per policy: the smallest margin (and of
which constraint), the nearest the arm came to the ball (its clearance margin), the steps
the safeguard acted at, the contacts, and the wall time.

    python scripts/gym_random_policy.py [STEPS]

2026-11-28, a 2-core machine at load 3-5 (other sessions), STEPS = 10⁴ (the same figures
before and after the pose stream's compiled step, which equals the general path to 1e-12):

    uniform: 10⁴ env steps in 99-127 s; smallest margin 0.09187 (clearance[panda_hand|ball]);
        0 steps outside a constraint, 0 contacts, 0 terminated; the safeguard never acted
    pulled toward the ball: 10⁴ env steps in 104-170 s; smallest margin 0.02035
        (clearance[panda_hand|ball]: the hand 30 mm from the ball, the barrier's 10 mm
        margin plus 20 mm); 0 outside, 0 contacts, 0 terminated; the safeguard never acted

(the uniform walk, deltas from the measured pose, stays more than 10 cm from the ball: it is
the pulled one that presses the clearance's barrier.)
"""

from __future__ import annotations

import sys
import time

import mujoco
import numpy as np

from cpbc.gym import ScenarioEnv, make_env

EPISODE = 500


def _contacts(env: ScenarioEnv) -> int:
    model, data = env.plant.model, env.plant.data
    ids = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, ob.name)
           for ob in env.setup.obstacles}
    return sum(1 for c in data.contact[:data.ncon] if (c.geom1 in ids) != (c.geom2 in ids))


def run(pull: float, steps: int) -> None:
    env = make_env("panda_goal_pose", "pose_delta", max_episode_steps=EPISODE)
    monitor = env.setup.monitor
    ball = next(ob.centre for ob in env.setup.obstacles if ob.name == "ball")
    rows = [i for i, name in enumerate(env.constraint_names) if name.endswith("|ball]")]
    rng = np.random.default_rng(11)
    smallest, closest, near_ball = np.inf, "", np.inf
    outside, contacts, guarded, saturated, done = 0, 0, 0, 0, 0
    start = time.perf_counter()
    obs, _ = env.reset(seed=0)
    for k in range(steps):
        toward = np.clip((ball - obs["frame_position"]) / 0.02, -1.0, 1.0)
        action = (1 - pull) * rng.uniform(-1, 1, size=6) + pull * np.r_[toward, 0, 0, 0]
        obs, _, terminated, truncated, info = env.step(action.astype(np.float32))
        data = env.plant.data
        outside += int(not np.all(monitor.margins(data.qpos, data.qvel) > 0))
        contacts += max(_contacts(env), info["obstacle_contacts"])
        guarded += info["safeguard_steps"]
        saturated += info["saturated_steps"]
        if info["margin"] < smallest:
            smallest, closest = info["margin"], info["closest"]
        near_ball = min(near_ball, float(np.min(info["margins"][rows])))
        done += int(terminated)
        if terminated or truncated:
            obs, _ = env.reset(seed=k // EPISODE + 1)
    wall = time.perf_counter() - start
    print(f"pull {pull}: {steps} env steps ({steps * env.steps_per_action} control periods) "
          f"in {wall:.0f} s ({1e3 * wall / steps:.1f} ms a step); smallest margin "
          f"{smallest:.4g} ({closest}); nearest the ball: margin {near_ball:.4g} m; steps "
          f"outside a constraint (MuJoCo's state) {outside}; arm-obstacle contacts "
          f"{contacts}; terminated {done}; safeguard acted at {guarded} control periods, "
          f"torque clipped at {saturated}")


if __name__ == "__main__":
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 10_000
    for share in (0.0, 0.4):
        run(share, n)
