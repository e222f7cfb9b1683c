"""Live view: the simulation streamed to a loopback meshcat server while it runs.

``python -m cpbc.run SCENARIO --view`` starts a :class:`LiveView`, prints its URL and runs
the scenario through :meth:`LiveView.run`, which gives the runner a plant that reports every
control step. The view paces the simulation to ``speed`` × real time (0: as fast as it
runs), poses the arm of the controller being simulated at up to ``rate`` frames per second
of wall time, grows its end-point trace, and reddens links as they near an obstacle. When
the runs are done, :meth:`LiveView.show_results` loads the replay animation of every case.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np
from meshcat.animation import Animation

from cpbc.constraints.constraint_types import Array
from cpbc.results.saved_run import SavedRun, load_run
from cpbc.results.sweep import SceneKinematics
from cpbc.scenario.build import ScenarioSetup
from cpbc.scenario.runner import RunProgress, RunResult, run_one
from cpbc.simulation.plant import MujocoPlant, PlantSettings
from cpbc.viewer.outputs import scene_kinematics
from cpbc.viewer.scene import ROOT, CaseScene, ViewSettings, set_animation
from cpbc.viewer.server import MeshcatServer

_COLOUR_LEVELS = 8  # clearance colours are redrawn only when they change this coarsely
_TRACE_PERIOD = 0.25  # [s] of wall time between redraws of a growing trace


class StreamingPlant(MujocoPlant):
    """A MuJoCo plant that reports each reset and each control step to a live view."""

    def __init__(self, model: mujoco.MjModel, settings: PlantSettings, view: LiveView) -> None:
        super().__init__(model, settings)
        self._view = view

    def reset(self, q: Array, dq: Array) -> None:
        super().reset(q, dq)
        self._view.on_reset(self.data)

    def step(self, substeps: int) -> None:
        super().step(substeps)
        self._view.on_step(self.data)


@dataclass
class _Current:
    case: str
    controller: str
    wall_start: float = 0.0
    last_frame: float = -np.inf
    last_trace: float = -np.inf
    levels: Array | None = None
    trace: list[Array] | None = None


class LiveView:
    """Streams a scenario's runs to a meshcat server as they are simulated.

    Args:
        server: a started loopback server.
        kinematics: the scene (model with obstacles, coordinates, traced frame).
        cases: (name, initial x) of each case, in order.
        controllers: controller names, in order.
        target: x_d, shape (n,).
        settings: colours and warning distance.
        speed: simulated seconds per wall-clock second; 0 runs unpaced.
        rate: most frames per wall-clock second sent to the viewer.
    """

    def __init__(
        self,
        server: MeshcatServer,
        kinematics: SceneKinematics,
        cases: Sequence[tuple[str, Array]],
        controllers: Sequence[str],
        target: Array,
        settings: ViewSettings | None = None,
        speed: float = 1.0,
        rate: float = 30.0,
    ) -> None:
        if speed < 0:
            raise ValueError(f"speed must be >= 0, got {speed}")
        if not rate > 0:
            raise ValueError(f"rate must be > 0, got {rate}")
        self.server = server
        self.vis = server.visualizer()
        self.speed, self.rate = speed, rate
        self._t = kinematics.coordinates
        self.scenes = {
            name: CaseScene(kinematics, controllers, target, x0, settings, root=f"{ROOT}/{name}")
            for name, x0 in cases
        }
        self._drawn: set[str] = set()
        self._shown: str | None = None
        self._current: _Current | None = None

    @property
    def url(self) -> str:
        return self.server.web_url

    def run(
        self, setup: ScenarioSetup, backend: str | None = None, progress: RunProgress | None = None
    ) -> list[RunResult]:
        """Every (case, controller) pair in case-major order, as ``run_all`` with one worker,
        streamed to the viewer (the reference backend has no plant to stream: its runs appear
        when they are done)."""
        backend = backend or setup.scenario.simulation.backend
        plant = None
        if backend == "mujoco":
            plant = StreamingPlant(setup.make_plant().model, setup.plant_settings, self)
        results = []
        for case in setup.cases:
            for entry in setup.controllers:
                self.begin(case.name, entry.name)
                results.append(run_one(setup, case, entry, backend, plant, progress))
        self._finish_trace()
        self._current = None
        return results

    # -- called by the plant -------------------------------------------------------------------
    def _show_case(self, case: str) -> None:
        scene = self.scenes[case]
        if case not in self._drawn:
            scene.draw_environment(self.vis)
            for controller in scene.controllers:
                scene.draw_arm(self.vis, controller)
            self._drawn.add(case)
        if self._shown != case:
            for name in self.scenes:
                self.vis[f"{ROOT}/{name}"].set_property("visible", name == case)
            self._shown = case

    def begin(self, case: str, controller: str) -> None:
        """The next run to stream."""
        self._finish_trace()
        if case not in self.scenes:
            raise ValueError(f"unknown case '{case}'; cases: {list(self.scenes)}")
        self._show_case(case)
        self._current = _Current(case, controller)

    def on_reset(self, data: mujoco.MjData) -> None:
        """The plant was reset to the run's initial state: start its clock and trace."""
        cur = self._current
        if cur is None:
            return
        now = time.perf_counter()
        cur.wall_start, cur.last_trace = now, now
        cur.levels = np.zeros(0)
        cur.trace = []
        self._frame(data, force=True)

    def on_step(self, data: mujoco.MjData) -> None:
        """After each control step: pace, and draw when a frame is due."""
        cur = self._current
        if cur is None or cur.trace is None:
            return
        now = time.perf_counter()
        if self.speed > 0:
            ahead = cur.wall_start + data.time / self.speed - now
            if ahead > 0:
                time.sleep(ahead)
                now += ahead
        if now - cur.last_frame >= 1.0 / self.rate:
            self._frame(data)

    def _frame(self, data: mujoco.MjData, force: bool = False) -> None:
        cur = self._current
        assert cur is not None and cur.trace is not None
        scene = self.scenes[cur.case]
        x = self._t @ data.qpos
        bodies, obstacles = scene.pose_arm(self.vis, cur.controller, x)
        cur.trace.append(scene.kin.traced_point())
        warn = scene.settings.warn_distance
        levels = np.round(_COLOUR_LEVELS * np.clip(1 - np.r_[bodies, obstacles] / warn, 0, 1))
        if scene.kin.obstacle_geoms and (cur.levels is None
                                          or not np.array_equal(levels, cur.levels)):
            scene.recolour_arm(self.vis, cur.controller, bodies)
            scene.recolour_obstacles(self.vis, obstacles)
            cur.levels = levels
        now = time.perf_counter()
        cur.last_frame = now
        if force or now - cur.last_trace >= _TRACE_PERIOD:
            scene.draw_trace(self.vis, cur.controller, np.array(cur.trace))
            cur.last_trace = now

    def _finish_trace(self) -> None:
        cur = self._current
        if cur is not None and cur.trace is not None and len(cur.trace) > 1:
            self.scenes[cur.case].draw_trace(self.vis, cur.controller, np.array(cur.trace))

    # -- after the runs ------------------------------------------------------------------------
    def show_results(self, run: SavedRun) -> None:
        """Full traces, final poses and the replay animation (paused) of every case."""
        self._finish_trace()
        self._current = None
        anim = Animation()
        last = None
        for case in run.cases:
            scene = self.scenes.get(case.name)
            if scene is None:
                continue
            if case.name not in self._drawn:
                self._show_case(case.name)
            sweeps = scene.sweeps(case.runs)
            nearest = np.full(len(scene.kin.obstacle_geoms), np.inf)
            for r in case.runs:
                s = sweeps[r.controller]
                scene.draw_trace(self.vis, r.controller, s.trace)
                final = r.position[np.all(np.isfinite(r.position), axis=1)][-1]
                bodies, obstacles = scene.pose_arm(self.vis, r.controller, final)
                nearest = np.minimum(nearest, obstacles)
                if scene.kin.obstacle_geoms:
                    scene.recolour_arm(self.vis, r.controller, bodies)
            if scene.kin.obstacle_geoms:
                scene.recolour_obstacles(self.vis, nearest)
            anim.clips.update(scene.animation(self.vis, sweeps).clips)
            last = case.name
        if last is not None:
            self._show_case(last)
        set_animation(self.vis, anim, play=False)

    # -- lifetime ------------------------------------------------------------------------------
    def hold(self, run_folder: Path) -> None:
        """Load the finished run's replay, then keep serving until Ctrl-C."""
        self.show_results(load_run(run_folder))
        print(f"meshcat viewer still serving at {self.url} (replay with the Animations "
              "controls); Ctrl-C to stop", flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass
        finally:
            self.close()

    def close(self) -> None:
        """Stop the meshcat server."""
        self.server.close()


def start_live_view(
    setup: ScenarioSetup, speed: float = 1.0, settings: ViewSettings | None = None
) -> LiveView:
    """Start a loopback meshcat server and a live view of the scenario's runs on it.

    The server stops with :meth:`LiveView.close` (and, in any case, when this process ends).
    """
    kin = scene_kinematics(setup)
    server = MeshcatServer().__enter__()
    try:
        return LiveView(
            server, kin, [(c.name, c.position) for c in setup.cases],
            [e.name for e in setup.controllers], setup.target, settings, speed,
        )
    except BaseException:
        server.close()
        raise
