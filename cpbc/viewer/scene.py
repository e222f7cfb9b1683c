"""One case in meshcat: obstacles, the arm at its target, and one arm and trace per controller.

Scene tree under ``<root>`` (``cpbc`` by default)::

    obstacles/<geom>                 the obstacles; grey, reddening as an arm nears
    static/<geom>                    other world geoms (an arm's fused base link), as modelled
    target/<body>/<geom>, target/tip the arm posed at the target, translucent, and its end point
    <controller>/robot/<body>/<geom> the controller's arm in its colour; a body reddens as its
                                     clearance to the nearest obstacle falls to zero
    <controller>/trace, …/tip        the path of the traced frame (a thin tube) and a marker

Every MuJoCo geom type but planes and height fields is drawn (primitives, capsules,
cylinders, meshes), so URDF arms with meshes and any obstacle shape appear.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

import meshcat
import meshcat.geometry as mg
import mujoco
import numpy as np
from meshcat.animation import Animation, AnimationClip, AnimationTrack
from meshcat.commands import SetAnimation

from cpbc.constraints.constraint_types import Array
from cpbc.results.palette import (
    OBSTACLE_COLOUR,
    TARGET_COLOUR,
    clearance_colour,
    controller_colour,
)
from cpbc.results.sweep import SceneKinematics, Sweep
from cpbc.viewer.shapes import geom_geometry, tube

ROOT = "cpbc"
_GRID_STEPS = (0.01, 0.02, 0.05, 0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 5.0, 10.0)
#: Light background (top, bottom) instead of meshcat's blue sky, as in the thesis figures.
BACKGROUND = ([0.97, 0.97, 0.98], [0.80, 0.83, 0.87])


class RunPath(Protocol):
    """What the scene needs of a run (a SavedTrajectory has it); read-only, so frozen
    dataclasses match."""

    @property
    def controller(self) -> str: ...

    @property
    def time(self) -> Array: ...

    @property
    def position(self) -> Array: ...


@dataclass(frozen=True)
class ViewSettings:
    """How a case is shown.

    Attributes:
        fps: animation frames per simulated second; the replay runs in real time.
        warn_distance: clearance at which links and obstacles start to redden [m].
        opacity: of the controllers' arms (< 1 shows overlapping arms).
    """

    fps: float = 30.0
    warn_distance: float = 0.25
    opacity: float = 0.9

    def __post_init__(self) -> None:
        if not self.fps > 0:
            raise ValueError(f"fps must be > 0, got {self.fps}")
        if not self.warn_distance > 0:
            raise ValueError(f"warn_distance must be > 0, got {self.warn_distance}")


def _hex(rgb: Array) -> int:
    r, g, b = (round(255 * float(np.clip(c, 0.0, 1.0))) for c in rgb)
    return (r << 16) | (g << 8) | b


def _material(colour: int, opacity: float = 1.0) -> mg.MeshPhongMaterial:
    return mg.MeshPhongMaterial(color=colour, opacity=opacity, shininess=40)


def _matrix(pos: Array, quat: Array) -> Array:
    """4×4 pose from a position and a MuJoCo quaternion (w, x, y, z)."""
    m = np.eye(4)
    rot = np.empty(9)
    mujoco.mju_quat2Mat(rot, np.asarray(quat, dtype=float))
    m[:3, :3] = rot.reshape(3, 3)
    m[:3, 3] = pos
    return m


def segment(name: str) -> str:
    return name.replace("/", "_") or "_"


class CaseScene:
    """Draws and animates one case of a run in a meshcat Visualizer.

    Args:
        kinematics: the scene's MuJoCo model, coordinates and traced frame.
        controllers: controller names, in the scenario's order (this fixes their colours).
        target: x_d in controller coordinates, shape (n,).
        start: the initial x of the case, shape (n,).
        settings: frames per second, warning distance, opacity.
        root: scene-tree folder of this case.
    """

    def __init__(
        self,
        kinematics: SceneKinematics,
        controllers: Sequence[str],
        target: Array,
        start: Array,
        settings: ViewSettings | None = None,
        root: str = ROOT,
    ) -> None:
        self.kin = kinematics
        self.controllers = tuple(controllers)
        self.colours = {c: controller_colour(i) for i, c in enumerate(self.controllers)}
        self.target = np.asarray(target, dtype=float)
        self.start = np.asarray(start, dtype=float)
        self.settings = settings or ViewSettings()
        self.root = root.strip("/")
        m = kinematics.model
        self.bodies = tuple(
            b
            for b in range(1, m.nbody)
            if any(m.geom_bodyid[g] == b for g in kinematics.robot_geoms)
        )
        self._body_geoms = {
            b: tuple(g for g in kinematics.robot_geoms if m.geom_bodyid[g] == b)
            for b in self.bodies
        }
        self._shapes = {
            g: geom_geometry(m, g)
            for g in (*kinematics.robot_geoms, *kinematics.obstacle_geoms, *kinematics.static_geoms)
        }
        self.extent = self._extent()

    # -- paths ---------------------------------------------------------------------------------
    def _body_path(self, controller: str, b: int) -> str:
        return f"{self.root}/{segment(controller)}/robot/{segment(self.kin.body_names[b])}"

    def _geom_path(self, body_path: str, g: int) -> str:
        return f"{body_path}/{segment(self.kin.geom_names[g])}"

    def _obstacle_path(self, g: int) -> str:
        return f"{self.root}/obstacles/{segment(self.kin.geom_names[g])}"

    def controller_path(self, controller: str) -> str:
        return f"{self.root}/{segment(controller)}"

    # -- geometry ------------------------------------------------------------------------------
    def _extent(self) -> tuple[Array, float]:
        """Centre and radius of a sphere holding the arm (any pose) and the obstacles."""
        m = self.kin.model
        d = self.kin.pose(self.start)
        base = d.xpos[self.bodies[0]].copy() if self.bodies else np.zeros(3)
        reach = sum(float(np.linalg.norm(m.body_pos[b])) for b in self.bodies[1:])
        reach += float(np.linalg.norm(self.kin.traced_point() - d.xpos[m.nbody - 1]))
        radius = max(reach, 0.5)
        for g in self.kin.obstacle_geoms:
            radius = max(radius, float(np.linalg.norm(d.geom_xpos[g] - base) + m.geom_rbound[g]))
        return base, radius

    def _is_planar(self) -> bool:
        """All joints hinges about the world z-axis: look from above."""
        m, d = self.kin.model, self.kin.pose(self.start)
        hinge = mujoco.mjtJoint.mjJNT_HINGE
        return bool(m.njnt) and all(
            m.jnt_type[j] == hinge and abs(abs(d.xaxis[j][2]) - 1.0) < 1e-9 for j in range(m.njnt)
        )

    # -- drawing -------------------------------------------------------------------------------
    def draw_environment(self, vis: meshcat.Visualizer) -> None:
        """Background, camera, obstacles and the arm at its target."""
        vis["/Background"].set_property("top_color", BACKGROUND[0])
        vis["/Background"].set_property("bottom_color", BACKGROUND[1])
        centre, radius = self.extent
        # The camera hangs under a frame rotated to three.js's y-up: local (x, y, z) is world
        # (x, −z, y). It orbits the world origin.
        if self._is_planar():
            eye = centre + radius * np.array([0.0, -0.5, 1.35])
        else:
            eye = centre + radius * np.array([1.2, -1.2, 0.9])
        vis["/Cameras/default/rotated/<object>"].set_property(
            "position", [float(eye[0]), float(eye[2]), float(-eye[1])]
        )
        self._draw_floor(vis)
        m = self.kin.model
        d = self.kin.pose(self.start)
        for g in self.kin.obstacle_geoms:
            shape = self._shapes[g]
            if shape is None:
                continue
            node = vis[self._obstacle_path(g)]
            node.set_object(shape, _material(int(OBSTACLE_COLOUR[1:], 16), 0.55))
            node.set_transform(_matrix(d.geom_xpos[g], _quat_of(d.geom_xmat[g])))
        for g in self.kin.static_geoms:
            shape = self._shapes[g]
            if shape is None:
                continue
            mat = m.geom_matid[g]
            rgba = m.mat_rgba[mat] if mat >= 0 else m.geom_rgba[g]
            node = vis[f"{self.root}/static/{segment(self.kin.geom_names[g])}"]
            node.set_object(shape, _material(_hex(rgba[:3]), float(rgba[3])))
            node.set_transform(_matrix(d.geom_xpos[g], _quat_of(d.geom_xmat[g])))
        d = self.kin.pose(self.target)
        for b in self.bodies:
            path = f"{self.root}/target/{segment(self.kin.body_names[b])}"
            self._draw_body(vis, path, b, int(TARGET_COLOUR[1:], 16), 0.22)
            vis[path].set_transform(_matrix(d.xpos[b], d.xquat[b]))
        tip = vis[f"{self.root}/target/tip"]
        tip.set_object(mg.Sphere(self.marker_radius), _material(int(TARGET_COLOUR[1:], 16), 0.8))
        tip.set_transform(_translation(self.kin.traced_point()))

    def _draw_floor(self, vis: meshcat.Visualizer) -> None:
        """A grid sized to the scene under the arm's base, in place of meshcat's 20 m grid
        (whose lines reach behind the camera, which software renderers may drop)."""
        centre, radius = self.extent
        spacing = min((s for s in _GRID_STEPS if s >= radius / 6), default=_GRID_STEPS[-1])
        half = spacing * np.ceil(1.25 * radius / spacing)
        ticks = np.arange(-half, half + 0.5 * spacing, spacing)
        z = centre[2] - 0.002 * radius
        ends = []
        for t in ticks:
            ends += [[t, -half, z], [t, half, z], [-half, t, z], [half, t, z]]
        offset = np.array([centre[0], centre[1], 0.0])
        points = (np.array(ends) + offset).T.astype(np.float32)
        vis["/Grid"].set_property("visible", False)
        vis[f"{self.root}/floor"].set_object(
            mg.LineSegments(mg.PointsGeometry(points), mg.LineBasicMaterial(color=0xA9AFB8))
        )

    @property
    def trace_radius(self) -> float:
        return 0.004 * self.extent[1]

    @property
    def marker_radius(self) -> float:
        return 0.012 * self.extent[1]

    def _draw_body(
        self, vis: meshcat.Visualizer, path: str, b: int, colour: int, opacity: float
    ) -> None:
        m = self.kin.model
        for g in self._body_geoms[b]:
            shape = self._shapes[g]
            if shape is None:
                continue
            node = vis[self._geom_path(path, g)]
            node.set_object(shape, _material(colour, opacity))
            node.set_transform(_matrix(m.geom_pos[g], m.geom_quat[g]))

    def draw_template_body(self, vis: meshcat.Visualizer, path: str, b: int) -> None:
        """Body ``b``'s geoms under ``path``, in white, for a page to clone and colour."""
        self._draw_body(vis, path, b, 0xFFFFFF, self.settings.opacity)

    def geom_path(self, body_path: str, g: int) -> str:
        """Scene path of geom ``g`` under a body drawn at ``body_path``."""
        return self._geom_path(body_path, g)

    def body_geoms(self, b: int) -> tuple[int, ...]:
        """The drawn geoms of body ``b`` (those with a shape meshcat can show)."""
        return tuple(g for g in self._body_geoms[b] if self._shapes[g] is not None)

    def draw_arm(self, vis: meshcat.Visualizer, controller: str, x: Array | None = None) -> None:
        """The controller's arm (at the start unless x is given) and its end-point marker."""
        colour = int(self.colours[controller][1:], 16)
        for b in self.bodies:
            self._draw_body(vis, self._body_path(controller, b), b, colour, self.settings.opacity)
        tip = vis[f"{self.controller_path(controller)}/tip"]
        tip.set_object(mg.Sphere(self.marker_radius), _material(colour))
        self.pose_arm(vis, controller, self.start if x is None else x)

    def pose_arm(self, vis: meshcat.Visualizer, controller: str, x: Array) -> tuple[Array, Array]:
        """Move the controller's arm to x.

        Returns:
            Clearances [m] of every body (nbody,) and of every obstacle (nobstacle,).
        """
        d = self.kin.pose(x)
        for b in self.bodies:
            vis[self._body_path(controller, b)].set_transform(_matrix(d.xpos[b], d.xquat[b]))
        vis[f"{self.controller_path(controller)}/tip"].set_transform(
            _translation(self.kin.traced_point())
        )
        return self.kin.clearances(self.settings.warn_distance)

    def recolour_arm(self, vis: meshcat.Visualizer, controller: str, clearance: Array) -> None:
        """Redraw the controller's bodies in their clearance colours (used by the live view)."""
        base = self.colours[controller]
        for b in self.bodies:
            colour = _hex(clearance_colour(base, clearance[b], self.settings.warn_distance))
            self._draw_body(vis, self._body_path(controller, b), b, colour, self.settings.opacity)

    def recolour_obstacles(self, vis: meshcat.Visualizer, clearance: Array) -> None:
        """Redraw the obstacles in their clearance colours (used by the live view)."""
        for j, g in enumerate(self.kin.obstacle_geoms):
            shape = self._shapes[g]
            if shape is not None:
                rgb = clearance_colour(OBSTACLE_COLOUR, clearance[j], self.settings.warn_distance)
                vis[self._obstacle_path(g)].set_object(shape, _material(_hex(rgb), 0.55))

    def draw_trace(self, vis: meshcat.Visualizer, controller: str, points: Array) -> None:
        """The traced frame's path as a tube in the controller's colour."""
        shape = tube(points, self.trace_radius)
        if shape is not None:
            colour = int(self.colours[controller][1:], 16)
            vis[f"{self.controller_path(controller)}/trace"].set_object(shape, _material(colour))

    # -- animation -----------------------------------------------------------------------------
    def sweeps(self, runs: Sequence[RunPath]) -> dict[str, Sweep]:
        """Every run sampled at the animation's frame times."""
        out = {}
        for r in runs:
            ok = np.all(np.isfinite(r.position), axis=1)
            time, position = r.time[ok], r.position[ok]
            frames = np.arange(int(np.floor(time[-1] * self.settings.fps + 1e-9)) + 1)
            out[r.controller] = self.kin.sweep(
                time, position, frames / self.settings.fps, self.settings.warn_distance
            )
        return out

    def animation(self, vis: meshcat.Visualizer, sweeps: dict[str, Sweep]) -> Animation:
        """Body poses, end-point markers and clearance colours of every run, frame by frame.

        Frame k shows time k / fps; meshcat plays it in real time (its time-scale control
        speeds it up).
        """
        fps = self.settings.fps
        anim = Animation(default_framerate=fps)
        warn = self.settings.warn_distance

        def clip(path: str, tracks: list[AnimationTrack]) -> None:
            anim.clips[vis[path].path] = AnimationClip({t.name: t for t in tracks}, fps=fps)

        for controller, s in sweeps.items():
            frames = list(range(len(s.time)))
            for b in self.bodies:
                path = self._body_path(controller, b)
                clip(
                    path,
                    [
                        AnimationTrack(
                            "position", "vector3", frames, s.body_position[:, b].tolist()
                        ),
                        AnimationTrack(
                            "quaternion",
                            "quaternion",
                            frames,
                            s.body_quaternion[:, b][:, [1, 2, 3, 0]].tolist(),
                        ),
                    ],
                )
                if self.kin.obstacle_geoms:
                    colours = clearance_colour(
                        self.colours[controller], s.body_clearance[:, b], warn
                    )
                    for g in self._body_geoms[b]:
                        clip(
                            f"{self._geom_path(path, g)}/<object>",
                            [AnimationTrack("material.color", "color", frames, colours.tolist())],
                        )
            clip(
                f"{self.controller_path(controller)}/tip",
                [AnimationTrack("position", "vector3", frames, s.trace.tolist())],
            )
        if self.kin.obstacle_geoms and sweeps:
            length = max(len(s.time) for s in sweeps.values())
            frames = list(range(length))
            nearest = np.full((length, len(self.kin.obstacle_geoms)), np.inf)
            for s in sweeps.values():
                padded = np.vstack(
                    [
                        s.obstacle_clearance,
                        np.repeat(s.obstacle_clearance[-1:], length - len(s.time), 0),
                    ]
                )
                nearest = np.minimum(nearest, padded)
            for j, g in enumerate(self.kin.obstacle_geoms):
                if self._shapes[g] is None:
                    continue
                colours = clearance_colour(OBSTACLE_COLOUR, nearest[:, j], warn)
                clip(
                    f"{self._obstacle_path(g)}/<object>",
                    [AnimationTrack("material.color", "color", frames, colours.tolist())],
                )
        return anim

    def draw_runs(self, vis: meshcat.Visualizer, runs: Sequence[RunPath]) -> Animation:
        """Draw the environment and every run's arm and trace; returns their animation.

        The caller sets the animation (:func:`set_animation`), possibly merged with those of
        other cases: meshcat holds one animation per scene.
        """
        self.draw_environment(vis)
        sweeps = self.sweeps(runs)
        for r in runs:
            self.draw_arm(vis, r.controller)
            self.draw_trace(vis, r.controller, sweeps[r.controller].trace)
        return self.animation(vis, sweeps)


class _SetAnimationLast(SetAnimation):
    """meshcat's set_animation command, filed under its own top-level node of the server's
    scene tree. The server files animations at the root and replays its tree root first to a
    browser that connects later, so the animation would arrive before the objects it moves
    and colours; filed last, it arrives after them. (The page ignores the command's path.)"""

    __slots__ = ()

    def lower(self) -> dict[str, object]:
        data = super().lower()
        data["path"] = "/zz_cpbc_animation"
        return data


def set_animation(vis: meshcat.Visualizer, animation: Animation, play: bool = True) -> None:
    """Load ``animation`` in the viewer (played once when ``play``; it stops on its last frame)."""
    vis.window.send(_SetAnimationLast(animation, play=play, repetitions=1))


def _translation(p: Array) -> Array:
    m = np.eye(4)
    m[:3, 3] = p
    return m


def _quat_of(xmat: Array) -> Array:
    q = np.empty(4)
    mujoco.mju_mat2Quat(q, np.asarray(xmat, dtype=float).reshape(9))
    return q
