"""RobotModel against MuJoCo (the plant), against the thesis's closed form (eq. 6.69) and
against the structural identities every Euler–Lagrange model satisfies."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cpbc.errors import ModelError
from cpbc.model import LinearCoordinates, RobotModel

N_STATES = 20
T = np.array([[1.0, 0.0], [1.0, 1.0]])  # θ = T q


def random_states(rng: np.random.Generator, n: int = N_STATES):
    """(x, ẋ) pairs: angles anywhere on the circle and beyond, rates of order 1."""
    for _ in range(n):
        yield rng.uniform(-4.0, 4.0, 2), rng.normal(scale=1.5, size=2)


def mujoco_terms(path: Path, q: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's mass matrix and bias force C q̇ + g at (q, q̇)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    d.qpos[:] = q
    d.qvel[:] = dq
    mujoco.mj_forward(m, d)
    mass = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, mass)
    return mass, d.qfrc_bias.copy()


def thesis_d_c(th: np.ndarray, dth: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """D and C of eq. 6.69 in absolute angles θ (m = 1, l = 1, l_c = 0.5, I = 1)."""
    m1 = m2 = 1.0
    l1 = 1.0
    lc1 = lc2 = 0.5
    i1 = i2 = 1.0
    d11 = m1 * lc1**2 + m2 * l1**2 + i1
    d12 = m2 * l1 * lc2 * math.cos(th[1] - th[0])
    d22 = m2 * lc2**2 + i2
    h = m2 * l1 * lc2 * math.sin(th[1] - th[0])
    return (
        np.array([[d11, d12], [d12, d22]]),
        np.array([[0.0, -h * dth[1]], [h * dth[0], 0.0]]),
    )


# -- MuJoCo (plant) and Pinocchio (controller's model) agree ---------------------------------
def test_inertia_equals_mujoco_full_mass_matrix(joint_model, planar_path, rng):
    for q, dq in random_states(rng):
        mass, _ = mujoco_terms(planar_path, q, dq)
        np.testing.assert_allclose(joint_model.inertia(q), mass, rtol=0, atol=1e-10)
        np.testing.assert_allclose(joint_model.dynamics(q, dq).inertia, mass, rtol=0, atol=1e-10)


def test_bias_force_equals_mujoco_qfrc_bias(joint_model, planar_path, rng):
    for q, dq in random_states(rng):
        _, bias = mujoco_terms(planar_path, q, dq)
        dyn = joint_model.dynamics(q, dq)
        np.testing.assert_allclose(dyn.coriolis_force + dyn.gravity, bias, rtol=0, atol=1e-10)
        rnea = pin.rnea(joint_model.model, joint_model.data, q, dq, np.zeros(2))
        np.testing.assert_allclose(rnea, bias, rtol=0, atol=1e-10)
        # the Christoffel matrix gives the same force as RNEA
        np.testing.assert_allclose(
            joint_model.coriolis(q, dq) @ dq, dyn.coriolis_force, rtol=0, atol=1e-10
        )


def test_bias_is_not_trivially_zero(joint_model):
    """Guard for the test above: the arm has real Coriolis forces to compare."""
    dyn = joint_model.dynamics(np.array([0.3, 1.1]), np.array([1.0, -0.5]))
    assert np.linalg.norm(dyn.coriolis_force) > 0.1


# -- the thesis's closed form (6.69) in absolute angles --------------------------------------
def test_absolute_coordinates_equal_thesis_closed_form(absolute_model, rng):
    for th, dth in random_states(rng):
        d_ref, c_ref = thesis_d_c(th, dth)
        np.testing.assert_allclose(absolute_model.inertia(th), d_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(absolute_model.coriolis(th, dth), c_ref, rtol=0, atol=1e-12)
        dyn = absolute_model.dynamics(th, dth)
        np.testing.assert_allclose(dyn.inertia, d_ref, rtol=0, atol=1e-12)
        np.testing.assert_allclose(dyn.coriolis_force, c_ref @ dth, rtol=0, atol=1e-12)
        np.testing.assert_allclose(dyn.gravity, 0.0, rtol=0, atol=1e-12)


def test_absolute_coordinates_are_the_congruence_of_joint_ones(joint_model, absolute_model, rng):
    t_inv = np.linalg.inv(T)
    for q, dq in random_states(rng, 5):
        th, dth = T @ q, T @ dq
        np.testing.assert_allclose(
            absolute_model.inertia(th), t_inv.T @ joint_model.inertia(q) @ t_inv, atol=1e-12
        )
        np.testing.assert_allclose(
            absolute_model.coriolis(th, dth),
            t_inv.T @ joint_model.coriolis(q, dq) @ t_inv,
            atol=1e-12,
        )
        # kinetic energy is a property of the motion, not of the coordinates
        assert absolute_model.kinetic_energy(th, dth) == pytest.approx(
            joint_model.kinetic_energy(q, dq), rel=1e-12
        )


@pytest.mark.parametrize("which", ["joint_model", "absolute_model"])
def test_dynamics_bundle_equals_individual_terms(which, request, rng):
    model: RobotModel = request.getfixturevalue(which)
    for x, dx in random_states(rng, 5):
        dyn = model.dynamics(x, dx)
        np.testing.assert_allclose(dyn.inertia, model.inertia(x), atol=1e-12)
        np.testing.assert_allclose(dyn.coriolis_force, model.coriolis(x, dx) @ dx, atol=1e-12)
        np.testing.assert_allclose(dyn.gravity, model.gravity(x), atol=1e-12)
        np.testing.assert_array_equal(dyn.dissipation, np.zeros(2))
        assert model.kinetic_energy(x, dx) == pytest.approx(0.5 * dx @ model.inertia(x) @ dx)


# -- structure: skew symmetry and the Christoffel identity -----------------------------------
@pytest.mark.parametrize("which", ["joint_model", "absolute_model"])
def test_d_dot_minus_two_c_is_skew_symmetric(which, request, rng):
    model: RobotModel = request.getfixturevalue(which)
    h = 1e-5
    for x, dx in random_states(rng):
        d_dot = (model.inertia(x + h * dx) - model.inertia(x - h * dx)) / (2 * h)
        c = model.coriolis(x, dx)
        n = d_dot - 2 * c
        np.testing.assert_allclose(n + n.T, 0.0, rtol=0, atol=1e-8)
        # equivalently Ḋ = C + Cᵀ for the Christoffel form
        np.testing.assert_allclose(d_dot, c + c.T, rtol=0, atol=1e-8)


@pytest.mark.parametrize("which", ["joint_model", "absolute_model"])
def test_gradient_of_kinetic_energy_is_c_transpose_xdot(which, request, rng, central_difference):
    model: RobotModel = request.getfixturevalue(which)
    for x, dx in random_states(rng):
        fd = central_difference(lambda y, dx=dx: model.kinetic_energy(y, dx), x)
        np.testing.assert_allclose(fd, model.coriolis(x, dx).T @ dx, rtol=0, atol=1e-8)


# -- forward dynamics --------------------------------------------------------------------------
@pytest.mark.parametrize("coords", ["joint", "absolute"])
@pytest.mark.parametrize("friction", [None, [0.4, 1.3]])
def test_forward_dynamics_inverts_the_dynamics(planar_path, coords, friction, rng):
    c = LinearCoordinates.identity(2) if coords == "joint" else (
        LinearCoordinates.absolute_link_angles(2)
    )
    model = RobotModel.from_mjcf(planar_path, coordinates=c, viscous_friction=friction)
    for x, dx in random_states(rng, 10):
        tau = rng.normal(scale=3.0, size=2)
        ddx = model.forward_dynamics(x, dx, tau)
        dyn = model.dynamics(x, dx)
        lhs = dyn.inertia @ ddx + dyn.coriolis_force + dyn.gravity + dyn.dissipation
        np.testing.assert_allclose(lhs, tau, rtol=0, atol=1e-10)


def test_forward_dynamics_with_friction_matches_mujoco_damping(planar_path, rng):
    """Joint viscous friction F_d is MuJoCo's dof_damping: same accelerations."""
    fd = np.array([0.4, 1.3])
    model = RobotModel.from_mjcf(planar_path, viscous_friction=fd)
    m = mujoco.MjModel.from_xml_path(str(planar_path))
    m.dof_damping[:] = fd
    d = mujoco.MjData(m)
    for q, dq in random_states(rng, 5):
        tau = rng.normal(size=2)
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, dq, tau
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(model.forward_dynamics(q, dq, tau), d.qacc, atol=1e-9)


# -- kinematics --------------------------------------------------------------------------------
def end_point_thesis(th: np.ndarray, offset: np.ndarray | None = None) -> np.ndarray:
    """End point of Figure 6.1 in absolute angles, plus an offset fixed in link 2's frame."""
    p = np.array([math.cos(th[0]) + math.cos(th[1]), math.sin(th[0]) + math.sin(th[1]), 0.0])
    if offset is not None:
        c, s = math.cos(th[1]), math.sin(th[1])
        p += np.array([c * offset[0] - s * offset[1], s * offset[0] + c * offset[1], offset[2]])
    return p


@pytest.mark.parametrize("offset", [None, np.array([0.3, -0.2, 0.1])])
def test_end_point_position_in_absolute_angles(absolute_model, rng, offset):
    fid = absolute_model.frame_id("end_point")
    for th, _ in random_states(rng):
        np.testing.assert_allclose(
            absolute_model.point_position(fid, th, offset), end_point_thesis(th, offset),
            rtol=0, atol=1e-12,
        )


@pytest.mark.parametrize("which", ["joint_model", "absolute_model"])
@pytest.mark.parametrize("offset", [None, np.array([0.3, -0.2, 0.1])])
def test_point_jacobian_matches_finite_differences(which, offset, request, rng, central_difference):
    model: RobotModel = request.getfixturevalue(which)
    fid = model.frame_id("end_point")
    for x, _ in random_states(rng):
        fd = central_difference(lambda y: model.point_position(fid, y, offset), x)
        model.point_position(fid, x, offset)
        jac = model.point_jacobian(fid, x, offset)
        assert jac.shape == (3, 2)
        np.testing.assert_allclose(jac, fd, rtol=0, atol=1e-8)
        p, jac_one_pass = model.point_kinematics(fid, x, offset)
        np.testing.assert_allclose(p, model.point_position(fid, x, offset), atol=1e-14)
        np.testing.assert_allclose(jac_one_pass, fd, rtol=0, atol=1e-8)


def test_joint_and_absolute_models_place_the_end_point_alike(joint_model, absolute_model, rng):
    fj, fa = joint_model.frame_id("end_point"), absolute_model.frame_id("end_point")
    for q, _ in random_states(rng, 5):
        np.testing.assert_allclose(
            joint_model.point_position(fj, q), absolute_model.point_position(fa, T @ q),
            atol=1e-12,
        )


# -- gravity -----------------------------------------------------------------------------------
def test_gravity_is_zero_for_the_horizontal_arm(joint_model, absolute_model, rng):
    for x, _ in random_states(rng):
        np.testing.assert_array_equal(joint_model.gravity(x), np.zeros(2))
        np.testing.assert_allclose(absolute_model.gravity(x), 0.0, atol=1e-15)


TILTED = """
<mujoco model="tilted_2link">
  <compiler angle="radian"/>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="link1">
      <joint name="joint1" type="hinge" axis="0 1 0"/>
      <inertial pos="0.5 0 0" mass="1" diaginertia="1 1 1"/>
      <body name="link2" pos="1 0 0">
        <joint name="joint2" type="hinge" axis="0 1 0"/>
        <inertial pos="0.5 0 0" mass="1" diaginertia="1 1 1"/>
        <site name="end_point" pos="1 0 0"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.fixture
def tilted_path(tmp_path: Path) -> Path:
    """The same arm in a vertical plane (hinges along y): gravity does work."""
    path = tmp_path / "tilted_2link.xml"
    path.write_text(TILTED)
    return path


def test_gravity_of_a_vertical_arm_equals_mujoco_and_closed_form(tilted_path, rng):
    model = RobotModel.from_mjcf(tilted_path)
    absolute = RobotModel.from_mjcf(
        tilted_path, coordinates=LinearCoordinates.absolute_link_angles(2)
    )
    g0 = 9.81
    for q, _ in random_states(rng):
        _, bias = mujoco_terms(tilted_path, q, np.zeros(2))
        g = model.gravity(q)
        np.testing.assert_allclose(g, bias, rtol=0, atol=1e-10)
        # a rotation q about +y takes x to (cos q, 0, −sin q): U = −g0 (1.5 sin θ1 + 0.5 sin θ2)
        th = T @ q
        g_theta = -g0 * np.array([1.5 * math.cos(th[0]), 0.5 * math.cos(th[1])])
        np.testing.assert_allclose(absolute.gravity(th), g_theta, rtol=0, atol=1e-10)
        np.testing.assert_allclose(g, T.T @ g_theta, rtol=0, atol=1e-10)
    assert np.linalg.norm(model.gravity(np.zeros(2))) > 10.0


def test_gravity_of_a_vertical_arm_is_in_the_dynamics_bundle(tilted_path, rng):
    model = RobotModel.from_mjcf(tilted_path)
    for q, dq in random_states(rng, 5):
        _, bias = mujoco_terms(tilted_path, q, dq)
        dyn = model.dynamics(q, dq)
        np.testing.assert_allclose(dyn.gravity, model.gravity(q), atol=1e-12)
        np.testing.assert_allclose(dyn.coriolis_force + dyn.gravity, bias, atol=1e-10)


def test_a_state_with_the_joint_kinematics_has_the_gravity_of_the_closed_form(tilted_path, rng):
    """A pass that holds the joint kinematics leaves g to the finishing, which computes it
    from the joint placements and Jacobians (cpbc.kernels.state_terms.joint_gravity): in
    absolute link angles, g_θ = −g0 [1.5 cos θ1, 0.5 cos θ2], and C ẋ + g is MuJoCo's bias."""
    absolute = RobotModel.from_mjcf(
        tilted_path, coordinates=LinearCoordinates.absolute_link_angles(2))
    for q, dq in random_states(rng, 5):
        th, dth = T @ q, T @ dq
        state = absolute.state(th, dth, kinematics=True)
        g_theta = -9.81 * np.array([1.5 * math.cos(th[0]), 0.5 * math.cos(th[1])])
        np.testing.assert_allclose(state.gravity, g_theta, rtol=0, atol=1e-10)
        _, bias = mujoco_terms(tilted_path, q, dq)  # joint coordinates: τ_q = Tᵀ τ_θ
        np.testing.assert_allclose(T.T @ (state.coriolis_force + state.gravity), bias,
                                   rtol=0, atol=1e-10)


@pytest.mark.parametrize("arm", ["panda", "ur5", "kinova", "tiago_arm", "pr2_left"])
def test_a_state_with_the_joint_kinematics_has_pinocchios_gravity(arm, rng):
    """The gravity a pass with the joint kinematics leaves to the finishing is Pinocchio's
    gravity pass, and C ẋ its RNEA's, to 1e-10 on arms of 6 and 7 joints, with a frame."""
    from cpbc.model.loading import load_arm

    model = RobotModel(load_arm(arm).model, name=arm)
    frame = model.model.nframes - 1
    for _ in range(5):
        x, dx = rng.uniform(-1.5, 1.5, model.n), rng.normal(size=model.n)
        state = model.state(x, dx, kinematics=True, frames=(frame,))
        bundle = model.dynamics(x, dx)
        g = model.gravity(x)
        assert np.linalg.norm(g) > 1.0
        np.testing.assert_allclose(state.gravity, g, rtol=0, atol=1e-10)
        np.testing.assert_allclose(state.coriolis_force, bundle.coriolis_force, rtol=0,
                                   atol=1e-10)
        np.testing.assert_allclose(state.inertia, bundle.inertia, rtol=0, atol=1e-12)


# -- viscous friction --------------------------------------------------------------------------
def test_viscous_friction_transforms_to_absolute_coordinates(planar_path, rng):
    fd_q = np.array([0.4, 1.3])
    model = RobotModel.from_mjcf(
        planar_path,
        coordinates=LinearCoordinates.absolute_link_angles(2),
        viscous_friction=fd_q,
    )
    t_inv = np.linalg.inv(T)
    np.testing.assert_allclose(model.viscous_friction, t_inv.T @ np.diag(fd_q) @ t_inv)
    assert model.has_friction
    for _, dth in random_states(rng, 5):
        dq = t_inv @ dth
        f = model.dissipation(dth)
        # the joint friction torque F_d q̇, expressed as a generalised force in θ
        np.testing.assert_allclose(f, t_inv.T @ (fd_q * dq), atol=1e-12)
        # and it dissipates the same power
        assert dth @ f == pytest.approx(dq @ (fd_q * dq), rel=1e-12)
        np.testing.assert_allclose(model.dynamics(T @ dq, dth).dissipation, f, atol=1e-12)


def test_viscous_friction_full_matrix_and_default(planar_path):
    full = np.array([[1.0, 0.2], [0.2, 0.5]])
    model = RobotModel.from_mjcf(planar_path, viscous_friction=full)
    np.testing.assert_allclose(model.viscous_friction, full)
    np.testing.assert_allclose(model.dissipation(np.array([1.0, -2.0])), full @ [1.0, -2.0])
    plain = RobotModel.from_mjcf(planar_path)
    assert not plain.has_friction
    np.testing.assert_array_equal(plain.dissipation(np.array([1.0, -2.0])), np.zeros(2))


def test_viscous_friction_of_wrong_shape_is_rejected(planar_path):
    with pytest.raises(ModelError, match="viscous_friction"):
        RobotModel.from_mjcf(planar_path, viscous_friction=[0.1, 0.2, 0.3])


# -- errors --------------------------------------------------------------------------------------
def test_missing_model_file_is_a_model_error(tmp_path):
    missing = tmp_path / "no_such_arm.xml"
    with pytest.raises(ModelError, match="not found") as info:
        RobotModel.from_mjcf(missing)
    assert "no_such_arm.xml" in str(info.value)


def test_unknown_frame_lists_the_frames(joint_model):
    with pytest.raises(ModelError) as info:
        joint_model.frame_id("gripper")
    msg = str(info.value)
    assert "gripper" in msg
    for frame in ("joint1", "link1", "joint2", "link2", "end_point"):
        assert frame in msg


def test_coordinates_of_the_wrong_size_are_rejected(planar_path):
    with pytest.raises(ModelError, match="shape"):
        RobotModel.from_mjcf(planar_path, coordinates=LinearCoordinates.absolute_link_angles(3))


def test_free_joint_model_is_rejected(tmp_path):
    path = tmp_path / "floating.xml"
    path.write_text(
        '<mujoco><worldbody><body name="b"><freejoint name="root"/>'
        '<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"/></body></worldbody></mujoco>'
    )
    with pytest.raises(ModelError, match="nq"):
        RobotModel.from_mjcf(path)


def test_state_is_computed_afresh_and_keeps_nothing(absolute_model, rng):
    """No state is kept between calls: the same state gives equal, separate arrays, and a
    caller that changes one state's arrays changes nothing another call returns."""
    x, dx = rng.uniform(-2, 2, 2), rng.normal(size=2)
    first = absolute_model.state(x, dx)
    again = absolute_model.state(x.copy(), dx.copy())
    for a, b in zip(first, again, strict=True):
        np.testing.assert_array_equal(a, b)
    assert first.inertia is not again.inertia
    first.inertia[:] = 0.0
    np.testing.assert_array_equal(absolute_model.state(x, dx).inertia, again.inertia)
    np.testing.assert_allclose(again.inertia, absolute_model.inertia(x), atol=1e-12)


@pytest.mark.parametrize("convert", [lambda a: a.astype(np.float32), list,
                                     lambda a: np.round(a).astype(int)],
                         ids=["float32", "list", "int"])
def test_a_state_from_other_numbers_equals_the_float64_state(joint_model, absolute_model, rng,
                                                             convert):
    """A float32 log, a list or ints give the state of their float64 values (float32 once
    stopped the finishing kernel of a model with friction with numba's TypeError)."""
    rubbing = RobotModel(joint_model.model,
                         viscous_friction=np.array([0.1, 0.2]),
                         coulomb_friction=np.array([0.3, 0.4]))
    x, dx = rng.uniform(-2, 2, 2), rng.normal(size=2)
    same = np.asarray(convert(x), dtype=float), np.asarray(convert(dx), dtype=float)
    for model, kinematics in ((joint_model, False), (absolute_model, True),
                              (rubbing, False), (rubbing, True)):
        given = model.state(convert(x), convert(dx), kinematics=kinematics)
        for a, b in zip(given, model.state(*same, kinematics=kinematics), strict=True):
            if isinstance(a, np.ndarray):
                np.testing.assert_array_equal(a, b)


def test_a_state_of_the_wrong_length_names_the_argument(absolute_model):
    with pytest.raises(ValueError, match=r"^dx must be 2 finite numbers"):
        absolute_model.state(np.zeros(2), np.zeros(3))


@pytest.mark.parametrize("offset", [None, np.array([0.1, -0.2, 0.05])])
def test_state_kinematics_give_the_point_of_one_pass(absolute_model, rng, offset):
    """A point read from the state's kinematics is the one-pass point kinematics."""
    fid = absolute_model.frame_id(absolute_model.model.frames[-1].name)
    for _ in range(5):
        x, dx = rng.uniform(-3, 3, 2), rng.normal(size=2)
        state = absolute_model.state(x, dx, frames=[fid])
        p, jac = state.frames[fid].point(offset)
        p_ref, jac_ref = absolute_model.point_kinematics(fid, x, offset)
        np.testing.assert_allclose(p, p_ref, rtol=0, atol=1e-14)
        np.testing.assert_allclose(jac, jac_ref, rtol=0, atol=1e-14)


def test_a_name_shared_by_a_joint_and_a_link_means_the_link() -> None:
    """On the Unitree Z1, ``gripperStator`` names a joint's frame and a link's body frame:
    the name resolves to the link (it crashed with Pinocchio's 'Several frames match'), and a
    point-outside-sphere constraint on it builds and evaluates."""
    import pinocchio as pin

    from cpbc.constraints import PointOutsideSphere
    from cpbc.model.loading import load_arm

    arm = load_arm("z1")
    model = RobotModel(arm.model, name="z1")
    frames = [f for f in arm.model.frames if f.name == "gripperStator"]
    assert len(frames) >= 2
    fid = model.frame_id("gripperStator")
    assert arm.model.frames[fid].type == pin.FrameType.BODY
    c = PointOutsideSphere(model, "gripperStator", np.array([2.0, 0.0, 0.0]), 0.1)
    assert c.value(np.zeros(model.n))[0] > 0


@pytest.mark.parametrize(("kinematics", "coriolis"), [(False, False), (True, False),
                                                      (False, True)])
def test_a_state_keeps_its_arrays_after_the_next_pass(joint_model, rng, kinematics, coriolis):
    """The state owns what it holds (where Pinocchio's functions return arrays of their own
    the state keeps them uncopied): a second pass at another state changes none of the first
    state's arrays, and none shares memory with the model's Pinocchio data."""
    x, dx = rng.uniform(-2, 2, 2), rng.normal(size=2)
    first = joint_model.state(x, dx, kinematics=kinematics, coriolis=coriolis)
    fields = list(first)
    arrays = fields[:8] + fields[9:]  # all but the frames
    kept = [None if a is None else np.array(a) for a in arrays]
    joint_model.state(x + 0.7, -dx, kinematics=kinematics, coriolis=coriolis)
    data = joint_model.data
    for a, b in zip(arrays, kept, strict=True):
        if a is None:
            continue
        np.testing.assert_array_equal(a, b)
        for shared in (data.M, data.nle, data.g, data.J, data.staticRegressor, data.C):
            assert not np.shares_memory(a, shared)
    assert (first.regressor is not None) is kinematics
    assert (first.coriolis_matrix is not None) is coriolis
