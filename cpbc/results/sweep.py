"""The arm's poses along a logged trajectory, from the MuJoCo model it was simulated with.

Shared by the figures (end-point path in the plane) and the 3-D viewer (body poses, traces,
clearance colours). Only MuJoCo kinematics is used: positions in the controller's
coordinates are mapped to joint positions ``q = T⁻¹ x`` and the model is posed with
``mj_kinematics``; clearances come from ``mj_geomDistance`` (any pair of geom types).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import mujoco
import numpy as np

from cpbc.constraints.constraint_types import Array
from cpbc.errors import ModelError

#: MuJoCo's default visible geom groups; higher groups usually hold collision-only copies.
DRAWN_GROUPS = (0, 1, 2)
_NOT_OBSTACLES = (int(mujoco.mjtGeom.mjGEOM_PLANE), int(mujoco.mjtGeom.mjGEOM_HFIELD))
DEFAULT_TRACE_SITE = "end_point"


@dataclass(frozen=True)
class Sweep:
    """Poses sampled along one trajectory.

    Attributes:
        time: sample times (F,) [s].
        body_position: world position of every body, (F, nbody, 3) [m].
        body_quaternion: world orientation (w, x, y, z) of every body, (F, nbody, 4).
        trace: world position of the traced frame, (F, 3) [m].
        body_clearance: smallest distance from any drawn geom of each body to any obstacle,
            (F, nbody) [m], capped at the ``distmax`` of the sweep (∞ without obstacles);
            negative in penetration.
        obstacle_clearance: smallest distance from each obstacle to the arm, (F, nobstacle).
    """

    time: Array
    body_position: Array
    body_quaternion: Array
    trace: Array
    body_clearance: Array
    obstacle_clearance: Array


def _name(model: mujoco.MjModel, kind: mujoco.mjtObj, i: int, fallback: str) -> str:
    return mujoco.mj_id2name(model, kind, i) or f"{fallback}{i}"


def default_trace_frame(model: mujoco.MjModel) -> str:
    """The site ``end_point`` when the model has one, else the last site, else the last body."""
    if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, DEFAULT_TRACE_SITE) >= 0:
        return DEFAULT_TRACE_SITE
    if model.nsite:
        return _name(model, mujoco.mjtObj.mjOBJ_SITE, model.nsite - 1, "site")
    return _name(model, mujoco.mjtObj.mjOBJ_BODY, model.nbody - 1, "body")


class SceneKinematics:
    """Poses, traced point and clearances of a MuJoCo arm at positions in controller coordinates.

    Robot geoms are the drawn geoms (groups 0–2) of every body but the world. Obstacles are
    the world body's geoms named in ``obstacles``; when it is None, every drawn world geom
    but planes and height fields. The other drawn world geoms are scenery (``static_geoms``):
    drawn, never measured — e.g. an arm's base link, which MuJoCo fuses into the world.

    Args:
        model: the compiled scene (arm and obstacles).
        coordinates: T of x = T q, shape (nq, nq).
        trace_frame: a site or body name; see :func:`default_trace_frame` when omitted.
        obstacles: names of the obstacle geoms, or None.
    """

    def __init__(
        self,
        model: mujoco.MjModel,
        coordinates: Array,
        trace_frame: str | None = None,
        obstacles: Sequence[str] | None = None,
    ) -> None:
        t = np.asarray(coordinates, dtype=float)
        if t.shape != (model.nq, model.nq):
            raise ModelError(f"coordinates must be ({model.nq}, {model.nq}), got {t.shape}")
        self.model = model
        self.data = mujoco.MjData(model)
        self.coordinates = t
        self._t_inv = np.linalg.inv(t)
        self.trace_frame = trace_frame or default_trace_frame(model)
        site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, self.trace_frame)
        body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.trace_frame)
        if site < 0 and body < 0:
            sites = [_name(model, mujoco.mjtObj.mjOBJ_SITE, i, "site") for i in range(model.nsite)]
            bodies = [_name(model, mujoco.mjtObj.mjOBJ_BODY, i, "body") for i in range(model.nbody)]
            raise ModelError(
                f"no site or body '{self.trace_frame}' to trace; sites: {sites}, bodies: {bodies}"
            )
        self._site, self._body = site, body
        drawn = [
            g
            for g in range(model.ngeom)
            if model.geom_group[g] in DRAWN_GROUPS and model.geom_rgba[g, 3] > 0
        ]
        self.body_names = tuple(
            _name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body") for b in range(model.nbody)
        )
        self.geom_names = tuple(
            _name(model, mujoco.mjtObj.mjOBJ_GEOM, g, "geom") for g in range(model.ngeom)
        )
        self.robot_geoms = tuple(g for g in drawn if model.geom_bodyid[g] != 0)
        world = [
            g
            for g in drawn
            if model.geom_bodyid[g] == 0 and int(model.geom_type[g]) not in _NOT_OBSTACLES
        ]
        if obstacles is None:
            self.obstacle_geoms = tuple(world)
        else:
            named = {self.geom_names[g]: g for g in range(model.ngeom) if model.geom_bodyid[g] == 0}
            unknown = [o for o in obstacles if o not in named]
            if unknown:
                raise ModelError(
                    f"no world geoms {unknown} to take for obstacles; world geoms: {list(named)}"
                )
            self.obstacle_geoms = tuple(named[o] for o in obstacles)
        self.static_geoms = tuple(g for g in world if g not in self.obstacle_geoms)

    def pose(self, x: Array) -> mujoco.MjData:
        """Pose the model at x (controller coordinates); returns the posed MjData."""
        self.data.qpos[:] = self._t_inv @ x
        mujoco.mj_kinematics(self.model, self.data)
        return self.data

    def traced_point(self) -> Array:
        """The traced frame's world position at the current pose, shape (3,)."""
        if self._site >= 0:
            return self.data.site_xpos[self._site].copy()
        return self.data.xpos[self._body].copy()

    def clearances(self, distmax: float) -> tuple[Array, Array]:
        """Per-body and per-obstacle clearance at the current pose, capped at ``distmax``."""
        m, d = self.model, self.data
        body = np.full(m.nbody, np.inf)
        obstacle = np.full(len(self.obstacle_geoms), np.inf)
        for j, og in enumerate(self.obstacle_geoms):
            for rg in self.robot_geoms:
                dist = mujoco.mj_geomDistance(m, d, rg, og, distmax, None)
                b = m.geom_bodyid[rg]
                body[b] = min(body[b], dist)
                obstacle[j] = min(obstacle[j], dist)
        return body, obstacle

    def sweep(self, time: Array, position: Array, times: Array, distmax: float = 1.0) -> Sweep:
        """Sample poses at ``times`` by linear interpolation of a trajectory.

        Args:
            time: logged sample times (N,) [s].
            position: logged positions in controller coordinates (N, n).
            times: where to sample (F,) [s]; clipped to the logged span.
            distmax: clearances larger than this are reported as ``distmax`` [m].
        """
        times = np.clip(np.asarray(times, dtype=float), time[0], time[-1])
        xs = np.column_stack(
            [np.interp(times, time, position[:, k]) for k in range(position.shape[1])]
        )
        f, nb = len(times), self.model.nbody
        pos, quat = np.empty((f, nb, 3)), np.empty((f, nb, 4))
        trace = np.empty((f, 3))
        body_c = np.empty((f, nb))
        obst_c = np.empty((f, len(self.obstacle_geoms)))
        for k, x in enumerate(xs):
            d = self.pose(x)
            pos[k], quat[k] = d.xpos, d.xquat
            trace[k] = self.traced_point()
            body_c[k], obst_c[k] = self.clearances(distmax)
        return Sweep(times, pos, quat, trace, body_c, obst_c)
