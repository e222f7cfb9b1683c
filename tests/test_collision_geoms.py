"""An MJCF arm's collision geoms (cpbc.model.collision_geoms), its automatic cover, and every
kind of cover measured against the geometry MuJoCo collides with: on seeded configurations
a ball is put near each link and MuJoCo's ``mj_geomDistance`` to the link's geoms compared
with the cover's distance; a cover must never read more clearance than the geoms have."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cache
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cpbc.constraints.clearance import Clearance
from cpbc.constraints.cover_cache import cached_cover, cached_point_cover
from cpbc.constraints.covering import LinkPrimitive, geoms_points, moving_frames
from cpbc.errors import ScenarioError
from cpbc.model.collision_geoms import covered_bodies, mjcf_collision_geoms
from cpbc.model.loading import load_arm
from cpbc.resources import models_dir
from cpbc.run import uncovered_links
from cpbc.scenario import ScenarioSetup

SHAPES = Path(__file__).parent / "models" / "shapes_arm.xml"
BALL = 0.03  # the probe ball's radius [m]


def _with_probe(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """The arm with a mocap ball (colliding with nothing: only measured), its distances by
    MuJoCo's native convex collision (dm-control's Jaco turns it off, and the older one
    reads a ball 6 cm off a mesh as touching it)."""
    spec.option.disableflags &= ~int(mujoco.mjtDisableBit.mjDSBL_NATIVECCD)
    probe = spec.worldbody.add_body(name="probe", mocap=True)
    probe.add_geom(name="probe", type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[BALL, 0, 0],
                   contype=0, conaffinity=0)
    return spec.compile()


@cache
def _shapes() -> tuple[mujoco.MjModel, pin.Model]:
    return (_with_probe(mujoco.MjSpec.from_file(str(SHAPES))),
            pin.buildModelFromMJCF(str(SHAPES)))


def _worst_overread(mj: mujoco.MjModel, model: pin.Model, cover: Sequence[LinkPrimitive],
                    configurations: int, seed: int) -> float:
    """The most clearance the cover reads beyond the geoms' over seeded configurations and
    probe balls near each covered link [m] (≤ 0: never more, and contact whenever the geoms
    touch the ball)."""
    rng = np.random.default_rng(seed)
    data, pdata = mujoco.MjData(mj), model.createData()
    probe = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_GEOM, "probe")
    geoms: dict[str, list[int]] = {}
    for g in range(mj.ngeom):
        body = mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_BODY, int(mj.geom_bodyid[g]))
        if (mj.geom_contype[g] or mj.geom_conaffinity[g]) and mj.body_weldid[
                mj.geom_bodyid[g]] != 0:
            geoms.setdefault(str(body), []).append(g)
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -np.pi)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, np.pi)
    worst = -np.inf
    for _ in range(configurations):
        q = rng.uniform(lo, hi)
        data.qpos[:] = q
        mujoco.mj_kinematics(mj, data)
        pin.framesForwardKinematics(model, pdata, q)
        for link in {p.frame for p in cover}:
            frame = pdata.oMf[model.getFrameId(link, pin.FrameType.BODY)]
            for _ in range(4):  # a ball a few cm from one of the link's geoms
                near = data.geom_xpos[rng.choice(geoms[link])]
                centre = near + rng.normal(size=3) * 0.08
                data.mocap_pos[0] = centre
                mujoco.mj_kinematics(mj, data)
                truth = min(mujoco.mj_geomDistance(mj, data, g, probe, 1.0, None)
                            for g in geoms[link])
                local = frame.actInv(centre)
                read = min(float(p.distance_to_points(local[None])[0]) - p.radius - BALL
                           for p in cover if p.frame == link)
                # in contact, a union of spheres reads the depth of its deepest sphere,
                # not the union's: there it need only read contact
                worst = max(worst, read - truth if truth >= 0 else read)
    return worst


def test_every_colliding_geom_of_a_moving_body_is_read_in_its_link_frame() -> None:
    mj = mujoco.MjModel.from_xml_path(str(SHAPES))
    model = pin.buildModelFromMJCF(str(SHAPES))
    geoms = mjcf_collision_geoms(mj, model)
    assert [(g.name, g.frame, g.kind) for g in geoms] == [
        ("upper_capsule", "upper", "capsule"), ("upper_box", "upper", "box"),
        ("fore_cylinder", "fore", "cylinder"), ("fore_ellipsoid", "fore", "ellipsoid"),
        ("hand_mesh", "hand", "mesh"), ("hand_sphere", "hand", "sphere")]
    assert covered_bodies(mj) == ("upper", "fore", "hand")  # not the base, not the visual
    data, pdata = mujoco.MjData(mj), model.createData()
    for q in np.random.default_rng(3).uniform(-1, 1, (5, 3)) * [2, 2, 0.05]:
        data.qpos[:] = q
        mujoco.mj_kinematics(mj, data)
        pin.framesForwardKinematics(model, pdata, q)
        for g in geoms:  # the placement holds at every configuration
            link = pdata.oMf[model.getFrameId(g.frame, pin.FrameType.BODY)]
            np.testing.assert_allclose(link.rotation @ g.translation + link.translation,
                                       data.geom_xpos[g.geom_id], atol=1e-12)
            np.testing.assert_allclose(link.rotation @ g.rotation,
                                       data.geom_xmat[g.geom_id].reshape(3, 3), atol=1e-12)


@pytest.mark.parametrize("kind", ["spheres", "capsules"])
def test_the_automatic_cover_of_an_mjcf_arm_never_reads_more_than_its_geoms(
        kind: str) -> None:
    mj, model = _shapes()
    cover = cached_point_cover(geoms_points(mjcf_collision_geoms(mj, model)),
                               moving_frames(model), kind=kind)
    assert {p.frame for p in cover} == {"upper", "fore", "hand"}
    worst = _worst_overread(mj, model, cover, configurations=12, seed=1)
    assert worst <= 1e-6
    assert worst > -0.05  # and it is measured close: within a few cm of the geoms


def test_the_automatic_cover_of_a_urdf_arm_never_reads_more_than_its_meshes() -> None:
    arm = load_arm("ur5")
    cover = cached_cover(arm.model, arm.collision_model)
    mj = _with_probe(arm.mujoco_spec())
    assert _worst_overread(mj, arm.model, cover, configurations=6, seed=2) <= 1e-6


def test_a_hand_written_cover_that_leaves_a_geom_out_is_caught() -> None:
    """The issue's case: spheres along a link that miss part of it read clearance the link
    does not have; the same check passes a sphere that holds the whole link."""
    mj, model = _shapes()
    short = [LinkPrimitive("fore", "fore", np.array([0.1, 0, 0]), np.array([0.1, 0, 0]), 0.11)]
    assert _worst_overread(mj, model, short, configurations=6, seed=4) > 0.01
    whole = [LinkPrimitive("fore", "fore", np.array([0.14, 0, 0]), np.array([0.14, 0, 0]),
                           0.15)]
    assert _worst_overread(mj, model, whole, configurations=6, seed=4) <= 1e-6


def _scenario(model: str, clearance: dict) -> dict:
    return {"name": "s", "robot": {"model": model}, "simulation": {"duration": 0.1},
            "target": [0.3, 0.2, 0.0], "cases": [{"name": "a", "position": [0.0, 0.0, 0.0]}],
            "obstacles": [{"type": "sphere", "name": "ball", "centre": [0.6, 0.4, 0.3],
                           "radius": 0.05}],
            "constraints": [{"type": "clearance", **clearance}],
            "controllers": [{"type": "cpbc", "name": "CPBC", "omega_n": 4, "zeta": 1}]}


def test_a_scenario_clearance_covers_an_mjcf_arm_from_its_geoms(
        load_dict: Callable[[dict], ScenarioSetup]) -> None:
    setup = load_dict(_scenario(str(SHAPES), {}))
    names = setup.monitor.configuration[0].names
    assert {n.split("|")[0].split("#")[0].removeprefix("clearance[") for n in names} == {
        "upper", "fore", "hand"}, names


def test_an_mjcf_without_colliding_geoms_is_told_to_declare_primitives(
        load_dict: Callable[[dict], ScenarioSetup]) -> None:
    with pytest.raises(ScenarioError, match="no moving body of the model has a colliding geom"):
        load_dict(_scenario(str(models_dir() / "planar_2link.xml"), {}))


@pytest.mark.parametrize(("centre", "radius", "outside"), [
    (0.1, 0.11, True),     # the hand-written sphere that reads 1-4 cm too much above
    (0.14, 0.15, False)])  # the one that holds the link
def test_a_declared_cover_is_checked_against_the_links_geoms(
        load_dict: Callable[[dict], ScenarioSetup], centre: float, radius: float,
        outside: bool) -> None:
    setup = load_dict(_scenario(str(SHAPES), {"links": [], "primitives": [
        {"link": "fore", "centre": [centre, 0, 0], "radius": radius}]}))
    clearance = setup.monitor.configuration[0]
    assert isinstance(clearance, Clearance)
    if outside:
        (link, gap), = clearance.uncovered
        assert link == "fore" and 0.01 < gap < 0.1
        (line,) = uncovered_links(setup)  # what cpbc.run warns
        assert f"declared on 'fore' leave its collision geometry up to {gap * 1000:.3g} mm" in line
    else:
        assert clearance.uncovered == () and uncovered_links(setup) == []
