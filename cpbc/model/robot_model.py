"""The controller's model of the arm: Pinocchio dynamics and kinematics in its coordinates."""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array
from cpbc.errors import ModelError
from cpbc.kernels.coordinate_maps import joint_friction, to_joint
from cpbc.kernels.state_terms import WORLD
from cpbc.model.arm_state import ArmState
from cpbc.model.coordinates import LinearCoordinates
from cpbc.model.coulomb import FRICTION_SMOOTHING, coulomb_levels
from cpbc.model.frames import offset_jacobian
from cpbc.model.measured_state import measured
from cpbc.model.state_pass import StatePass

# the arrays of one pass (RobotModel.pinocchio_pass): D_q, nle, g_q, C_q, the joint placements
# and Jacobians; and its empty ones: no Coriolis matrix, no joint kinematics
PassArrays = tuple[Array, Array, Array, Array, Array, Array]
_NO_MATRIX = np.zeros((0, 0))
_NO_JOINTS = (np.zeros((3, 0)), np.zeros((6, 0)))
_NO_G = np.zeros(0)  # g left to the finishing (cpbc.kernels.state_terms.joint_gravity)



def _returns_own_arrays(model: pin.Model, data: pin.Data) -> bool:
    """Whether Pinocchio's CRBA, gravity, static regressor and Coriolis matrix return arrays
    of their own (eigenpy copies a function's result), not views of ``data`` that the next
    pass overwrites: then ``RobotModel.state`` need not copy them again. Asked once,
    of the installed Pinocchio."""
    q = pin.neutral(model)
    found = (pin.crba(model, data, q), pin.computeGeneralizedGravity(model, data, q),
             pin.computeStaticRegressor(model, data, q),
             pin.computeCoriolisMatrix(model, data, q, np.ones(model.nv)))
    views = (data.M, data.g, data.staticRegressor, data.C)
    return all(a.flags.owndata and not np.shares_memory(a, v)
               for a, v in zip(found, views, strict=True))


class RobotModel:
    """Rigid-body dynamics of a serial arm from Pinocchio, in controller coordinates x = T q.

    All methods take and return controller coordinates. With the identity map they are the
    model's own joint coordinates.

    The joints' rotor inertia (armature) is the Pinocchio model's ``armature``: its CRBA, RNEA
    and ABA add it to D's diagonal (the motor's inertia reflected through the gear), as
    MuJoCo's ``dof_armature`` does; set it on the model before building this.

    Args:
        model: a Pinocchio model whose configuration and velocity spaces coincide (nq == nv).
        coordinates: the linear map x = T q; identity when omitted.
        viscous_friction: joint viscous friction F_d in the *joint* coordinates, shape (n,)
            (diagonal) or (n, n); zero when omitted.
        name: a label for summaries.
        torque_rate_limits: the joint torque-rate limits the robot declares, shape (n,)
            [N·m/s] (no robot file format has a tag for them: a built-in arm sets them), or
            None.
        coulomb_friction: each joint's Coulomb (dry) friction level F_c ≥ 0 [N·m or N],
            shape (n,); zero when omitted.
        friction_smoothing: ε > 0 of the smoothed sign tanh(q̇/ε) of the Coulomb friction
            [rad/s or m/s] (``FRICTION_SMOOTHING``).
    """

    def __init__(
        self,
        model: pin.Model,
        coordinates: LinearCoordinates | None = None,
        viscous_friction: Array | None = None,
        name: str = "robot",
        torque_rate_limits: Array | None = None,
        coulomb_friction: Array | None = None,
        friction_smoothing: float = FRICTION_SMOOTHING,
    ) -> None:
        if model.nq != model.nv:
            raise ModelError(
                f"model '{name}' has nq={model.nq} != nv={model.nv}; only arms with revolute "
                "or prismatic joints (no continuous/free joints) are supported"
            )
        if model.nv == 0:
            raise ModelError(f"model '{name}' has no joint to drive: an arm needs at least one "
                             "revolute or prismatic joint")
        self.name = name
        self.model = model
        self.data = model.createData()
        self.n = model.nv
        self.torque_rate_limits = None if torque_rate_limits is None else np.broadcast_to(
            np.asarray(torque_rate_limits, dtype=float), (self.n,)).copy()
        self.coordinates = coordinates or LinearCoordinates.identity(self.n)
        if self.coordinates.matrix.shape != (self.n, self.n):
            raise ModelError(
                f"coordinates matrix has shape {self.coordinates.matrix.shape}, "
                f"expected ({self.n}, {self.n}) for model '{name}'"
            )
        self._identity = self.coordinates.is_identity
        self._t_inv = self.coordinates.inverse
        self._t_inv_t = np.ascontiguousarray(self.coordinates.inverse.T)
        fd = np.zeros((self.n, self.n)) if viscous_friction is None else np.asarray(
            viscous_friction, dtype=float
        )
        if fd.shape == (self.n,):
            fd = np.diag(fd)
        if fd.shape != (self.n, self.n):
            raise ModelError(
                f"viscous_friction must have shape ({self.n},) or ({self.n}, {self.n})"
            )
        self.viscous_friction = self.coordinates.matrix_from_joint(fd)  # F_d in x-coordinates
        self.coulomb_friction = coulomb_levels(coulomb_friction, self.n)
        if not (np.isfinite(friction_smoothing) and friction_smoothing > 0):
            raise ModelError(f"friction_smoothing must be > 0, got {friction_smoothing}")
        self.friction_smoothing = float(friction_smoothing)
        self._has_friction = bool(np.any(fd) or np.any(self.coulomb_friction))
        self._no_dissipation = np.zeros(self.n)
        self._no_dissipation.setflags(write=False)
        self.joint_names: tuple[str, ...] = tuple(model.names[1:])
        # Older Pinocchio releases fill only the upper triangle of the CRBA result.
        probe = pin.crba(model, self.data, np.linspace(0.3, 1.1, self.n)) if self.n > 1 else None
        self._crba_upper_only = probe is not None and not np.allclose(probe, probe.T)
        self._lower = np.tril_indices(self.n, -1)
        # numpy views of the Pinocchio data's D, C q̇ + g, g, joint Jacobians and static
        # regressor, which each pass rewrites in place: ``state`` copies them out (a view
        # made once costs nothing per step; Pinocchio's accessors make a new one each call)
        self._own_results = _returns_own_arrays(model, self.data)
        self._views()

    def _views(self) -> None:
        """The numpy views of the data, and no pass made yet (``holder``, ``state_pass``)."""
        self._all_terms = (self.data.M, self.data.nle, self.data.g)
        self._joint_jacobians = self.data.J
        self._regressor = self.data.staticRegressor
        self._state_passes: dict[tuple[bool, tuple[int, ...], bool], StatePass] = {}
        # the state whose unfinished pass the data holds (cpbc.model.state_pass); every other
        # pass over the data sets it to None
        self.holder: ArmState | None = None

    def __getstate__(self) -> dict[str, Any]:
        """Pickled without the views of its Pinocchio data and the passes bound to them
        (a copy's views would be arrays of their own, not its data's): made again."""
        state = dict(self.__dict__)
        for name in ("_all_terms", "_joint_jacobians", "_regressor", "_state_passes",
                     "holder"):
            state.pop(name, None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._views()

    @property
    def length_joints(self) -> Array:
        """Which joints are prismatic (their coordinate a length [m], their torque a force
        [N]), in the order of ``joint_names``."""
        # Pinocchio's prismatic joints: JointModelPX/PY/PZ and JointModelPrismaticUnaligned
        return np.array([j.shortname() in ("JointModelPX", "JointModelPY", "JointModelPZ")
                         or "Prismatic" in j.shortname() for j in self.model.joints[1:]],
                        dtype=bool)

    @property
    def length_coordinates(self) -> Array:
        """Which controller coordinates are lengths [m], not angles [rad]: those whose row of
        T involves prismatic joints only."""
        prismatic = self.length_joints
        used = np.abs(self.coordinates.matrix) > 0
        return np.array([bool(np.any(u)) and bool(np.all(prismatic[u])) for u in used])

    @classmethod
    def from_mjcf(cls, path: str | Path, **kwargs: object) -> RobotModel:
        path = Path(path)
        if not path.is_file():
            raise ModelError(f"model file not found: {path}")
        try:
            parsed = pin.buildModelFromMJCF(str(path))
        except (RuntimeError, ValueError) as exc:  # Pinocchio's parser on a malformed file
            detail = str(exc).strip().splitlines()[-1] if str(exc).strip() else type(exc).__name__
            raise ModelError(f"{path} is not an MJCF model Pinocchio can read: {detail}") from None
        return cls(parsed, name=path.stem, **kwargs)  # type: ignore[arg-type]

    @property
    def has_friction(self) -> bool:
        """Whether the model has viscous or Coulomb friction (f ≠ 0)."""
        return self._has_friction

    @property
    def armature(self) -> Array:
        """Each joint's rotor inertia in D [kg·m² or kg], joint coordinates (a copy)."""
        return np.array(self.model.armature, dtype=float)

    # -- coordinates -------------------------------------------------------------------------
    def _q(self, x: Array) -> Array:
        return x if self._identity else self._t_inv.dot(x)

    def _back(self, m: Array) -> Array:
        """T⁻ᵀ M T⁻¹."""
        return m if self._identity else self.coordinates.matrix_from_joint(m)

    def _back_vec(self, v: Array) -> Array:
        """T⁻ᵀ v (a generalised force)."""
        return v if self._identity else self._t_inv_t.dot(v)

    # -- dynamics ----------------------------------------------------------------------------
    def inertia(self, x: Array) -> Array:
        """D(x), shape (n, n)."""
        self.holder = None
        m = pin.crba(self.model, self.data, self._q(x)).copy()
        if self._crba_upper_only:
            m[self._lower] = m.T[self._lower]
        return self._back(m)

    def coriolis(self, x: Array, dx: Array) -> Array:
        """C(x, ẋ) in Christoffel form, shape (n, n)."""
        self.holder = None
        c = pin.computeCoriolisMatrix(self.model, self.data, self._q(x), self._q(dx))
        return self._back(c.copy())

    def gravity(self, x: Array) -> Array:
        """g(x), shape (n,)."""
        self.holder = None
        g = pin.computeGeneralizedGravity(self.model, self.data, self._q(x))
        return self._back_vec(g.copy())

    def dissipation(self, dx: Array) -> Array:
        """f(ẋ) = F_d ẋ + T⁻ᵀ F_c tanh(T⁻¹ẋ/ε), shape (n,)
        (cpbc.kernels.coordinate_maps.joint_friction)."""
        if not self._has_friction:
            return self._no_dissipation
        f = np.empty(self.n)
        joint_friction(self._identity, self._t_inv, self.viscous_friction,
                       self.coulomb_friction, self.friction_smoothing,
                       np.asarray(dx, dtype=float), f)
        return f

    def state(self, x: Array, dx: Array, kinematics: bool = False,
              frames: Iterable[int] = (), coriolis: bool = False) -> ArmState:
        """The per-step state at (x, ẋ), finished (fresh arrays, nothing kept between
        calls), from the one producer (``state_pass``): one Pinocchio pass — CRBA, RNEA and
        gravity, or with ``kinematics`` or any ``frames`` CRBA in world axes (with the joint
        Jacobians), RNEA and the static regressor (the joint placements), g then computed
        from the joint kinematics by the finishing (it differs from Pinocchio's gravity pass
        in the last bits, 1e-14); with ``coriolis`` the matrix C (one more pass) — and one
        kernel that finishes it. Each frame of ``frames`` is read from the joint kinematics into
        ``ArmState.frames``, and — with ``kinematics`` — the joint Jacobians and placements
        are in the state. x and ẋ are copied when read-only or not float64 vectors (a list,
        a float32 log); a ParameterError (ValueError) names either if not n numbers."""
        producer = self.state_pass(bool(kinematics), tuple(frames), bool(coriolis))
        x, dx = measured(x, dx, self.n)
        if not (x.flags.writeable and dx.flags.writeable):
            # the compiled kernels take writable float arrays, and a law's own target may be
            # the state asked for
            x, dx = np.array(x, dtype=float), np.array(dx, dtype=float)
        found = producer(x, dx)
        producer.finish(found)
        return found

    def state_pass(self, kinematics: bool, frames: tuple[int, ...], coriolis: bool
                   ) -> StatePass:
        """The producer of the states that hold the joint kinematics, ``frames`` and C
        (cpbc.model.state_pass), made once for each choice (its tables packed then)."""
        key = (kinematics, tuple(dict.fromkeys(frames)), coriolis)
        found = self._state_passes.get(key)
        if found is None:
            found = self._state_passes[key] = StatePass(self, *key)
        return found

    @property
    def regressor_columns(self) -> int:
        """The columns of Pinocchio's static regressor (4 per joint)."""
        return 4 * (self.model.njoints - 1)

    def pinocchio_pass(self, all_terms: bool, coriolis: bool
                       ) -> Callable[[Array, Array], PassArrays]:
        """The per-step state's one Pinocchio pass (cpbc.model.state_pass), as a function of
        (x, ẋ) giving, in joint coordinates, D_q, nle = C q̇ + g_q, g_q, C_q (``coriolis``;
        else empty) and — with ``all_terms`` (CRBA in world axes, which also leaves the
        joint Jacobians in the data, RNEA and the static regressor, else CRBA, RNEA and
        gravity) — the joint placements (the static regressor) and Jacobians (else empty);
        with ``all_terms`` g_q is empty: the finishing computes it from the joint
        kinematics (cpbc.kernels.state_terms.joint_gravity, ``gravity_on_joints``), which
        on the Panda costs about 0.4 µs less than computeAllTerms (its centroidal terms,
        centre of mass and energies went unread). The joint Jacobians are a view of the
        model's data, which its next pass overwrites. The choices are made here, once, and
        the function reads only names bound here (a global or attribute lookup costs 20–40
        ns; a step would make a dozen); its q and q̇ (other coordinates than the joints')
        are the rows of one array of its own, overwritten by each call, as Pinocchio's data
        is."""
        model, data, t_inv = self.model, self.data, self._t_inv
        identity, mirror, lower = self._identity, self._crba_upper_only, self._lower
        joints_jac, own = self._joint_jacobians, self._own_results
        coriolis_pass, no_matrix, no_joints = self.coriolis_pass, _NO_MATRIX, _NO_JOINTS
        joint = np.empty((2, self.n))
        joint_q, joint_dq = joint[0], joint[1]
        crba, rnea, gravity = pin.crba, pin.nonLinearEffects, pin.computeGeneralizedGravity
        world, regressor, no_gravity = pin.Convention.WORLD, pin.computeStaticRegressor, _NO_G

        def run(x: Array, dx: Array) -> PassArrays:
            if identity:
                q, dq = x, dx
            else:
                q, dq = joint_q, joint_dq
                to_joint(t_inv, x, dx, joint)
            c_matrix = coriolis_pass(q, dq) if coriolis else no_matrix
            if all_terms:  # the joint Jacobians (WORLD) with D; g from them
                mass, bias, weight = crba(model, data, q, world), rnea(model, data, q, dq), (
                    no_gravity)
                y = regressor(model, data, q)
                placements, jac = (y if own else y.copy()), joints_jac
            else:
                mass, bias, weight = crba(model, data, q), rnea(model, data, q, dq), gravity(
                    model, data, q)
                placements, jac = no_joints
            if mirror:
                mass[lower] = mass.T[lower]
            return mass, bias, weight, c_matrix, placements, jac

        return run

    def gravity_on_joints(self) -> Array:
        """How the finishing kernel computes g(q) from a pass's joint kinematics
        (cpbc.kernels.state_terms.joint_gravity): [g₀ (3), s (``regressor_scale``), then per
        joint's link its mass m, its centre of mass c on the joint (3) and the coordinates
        that move it (n, ``joint_supports``)], read from the Pinocchio model now."""
        model, supports = self.model, self.joint_supports()
        rows: list[Array] = [np.asarray(model.gravity.linear, dtype=float),
                             np.array([self.regressor_scale()])]
        for j in range(1, model.njoints):
            inertia = model.inertias[j]
            rows += [np.array([inertia.mass]), np.asarray(inertia.lever, dtype=float),
                     supports[j]]
        return np.concatenate(rows).astype(float)

    def frame_place(self, frame_id: int) -> tuple[int, Array]:
        """How the finishing kernel reads a frame (cpbc.kernels.state_terms.pack_state): from
        the joint kinematics (``frame_on_joints``), or (``WORLD``, its constant placement)
        for a frame welded to the world."""
        on_joints = self.frame_on_joints(frame_id)
        if on_joints is not None:
            return on_joints
        return WORLD, np.asarray(self.model.frames[frame_id].placement.homogeneous, dtype=float)

    def frame_on_joints(self, frame_id: int) -> tuple[int, Array] | None:
        """How a compiled law reads a frame from a pass's joint kinematics
        (cpbc.kernels.task.frame_on_joints): the first column of its joint in the static
        regressor Y = [t_1 R_1 … t_m R_m]/s and [s, s p_l, R_l row-major, the support mask
        (n)], p_l and R_l its placement on the joint; None for a frame welded to the world."""
        frame = self.model.frames[frame_id]
        joint = frame.parentJoint
        if joint == 0:
            return None
        scale, local = self.regressor_scale(), frame.placement
        return 4 * (joint - 1), np.concatenate(
            [[scale], scale * local.translation, local.rotation.reshape(-1),
             self.joint_supports()[joint]])

    def regressor_scale(self) -> float:
        """s such that s·Y is every joint placement [t_1 R_1 … t_m R_m], Y Pinocchio's static
        regressor (s is the total mass: Y's R_1 block is R_1/s), checked against the joint
        placements of a pass of the model's own."""
        model, data = self.model, self.data
        q = pin.neutral(model) + 0.3
        self.holder = None
        y = pin.computeStaticRegressor(model, data, q)
        pin.forwardKinematics(model, data, q)
        scale = float(np.sqrt(3.0) / np.linalg.norm(y[:, 1:4]))
        rebuilt = np.hstack([np.column_stack([data.oMi[j].translation, data.oMi[j].rotation])
                             for j in range(1, model.njoints)])
        if not np.allclose(scale * y, rebuilt, atol=1e-9):  # pragma: no cover
            raise ModelError("unexpected layout of Pinocchio's static regressor")
        return scale

    def joint_supports(self) -> Array:
        """(joints + 1, n): row j is 1 on the coordinates of the joints that move joint j's
        link (row 0, the world, is zero)."""
        model = self.model
        supports = np.zeros((model.njoints, self.n))
        for j in range(1, model.njoints):
            for k in model.supports[j].tolist()[1:]:
                moved = model.joints[k]
                supports[j, moved.idx_v:moved.idx_v + moved.nv] = 1.0
        return supports

    def coordinate_supports(self) -> Array:
        """(n, n): row k is 1 on the coordinates of the joints that move coordinate k's link
        (``joint_supports`` by coordinate), what cpbc.kernels.clearance_motion.sphere_motion
        reads as ``joint_supports``."""
        model, supports = self.model, self.joint_supports()
        out = np.zeros((self.n, self.n))
        for j in range(1, model.njoints):
            moved = model.joints[j]
            out[moved.idx_v:moved.idx_v + moved.nv] = supports[j]
        return out

    def coriolis_pass(self, q: Array, dq: Array) -> Array:
        """C(q, q̇) in Christoffel form, joint coordinates, an array of its own."""
        self.holder = None
        c_matrix = pin.computeCoriolisMatrix(self.model, self.data, q, dq)
        return c_matrix if self._own_results else c_matrix.copy()

    def dynamics_pass(self, q: Array, dq: Array, all_terms: bool
                      ) -> tuple[Array, Array, Array, bool]:
        """D, nle = C q̇ + g and g in joint coordinates from one Pinocchio pass: with
        ``all_terms`` the one that also gives every joint placement and Jacobian
        (``computeAllTerms``), else CRBA, RNEA and gravity; and whether D and g are arrays
        of their own (else views of the data)."""
        model, data = self.model, self.data
        self.holder = None
        if all_terms:
            pin.computeAllTerms(model, data, q, dq)
            m, nle, g = self._all_terms
            owned = False
        else:
            m = pin.crba(model, data, q)
            nle = pin.nonLinearEffects(model, data, q, dq)
            g = pin.computeGeneralizedGravity(model, data, q)
            owned = self._own_results
        if self._crba_upper_only:
            m[self._lower] = m.T[self._lower]
        return m, nle, g, owned

    def dynamics(self, x: Array, dx: Array) -> ArmState:
        """The per-step state without kinematics (``state``)."""
        return self.state(x, dx)

    def kinetic_energy(self, x: Array, dx: Array) -> float:
        """½ ẋᵀ D(x) ẋ [J], computed in joint coordinates (the energy does not depend on
        them) by one Pinocchio pass, without forming D."""
        self.holder = None
        return float(pin.computeKineticEnergy(self.model, self.data, self._q(x), self._q(dx)))

    def forward_dynamics(self, x: Array, dx: Array, tau: Array) -> Array:
        """ẍ from D ẍ = τ − C ẋ − g − f (generalised forces τ in x-coordinates)."""
        q, dq = (x, dx) if self._identity else (self._q(x), self._q(dx))
        tau_q = tau if self._identity else self.coordinates.torque_to_joint(tau)
        if self._has_friction:
            f = self.dissipation(dx)
            tau_q = tau_q - (f if self._identity else self.coordinates.torque_to_joint(f))
        self.holder = None
        ddq = pin.aba(self.model, self.data, q, dq, tau_q)
        return ddq if self._identity else self.coordinates.from_joint(ddq)

    # -- kinematics --------------------------------------------------------------------------
    def joint_coordinates(self, x: Array) -> Array:
        """q = T⁻¹ x (x itself with the identity map)."""
        return self._q(x)

    def frame_id(self, frame: str) -> int:
        """The frame named ``frame``. Where several frames share the name (a URDF joint and
        the link it moves, as on the Unitree Z1), the link's body frame is the one meant."""
        ids = [i for i, f in enumerate(self.model.frames) if f.name == frame]
        if not ids:
            names = ", ".join(f.name for f in self.model.frames[1:])
            raise ModelError(f"model '{self.name}' has no frame '{frame}'; frames: {names}")
        bodies = [i for i in ids if self.model.frames[i].type == pin.FrameType.BODY]
        return (bodies or ids)[0]

    def point_kinematics(
        self, frame_id: int, x: Array, offset: Array | None = None
    ) -> tuple[Array, Array]:
        """Position (3,) and Jacobian ∂p/∂x (3, n) of a point fixed in a frame, in one pass."""
        self.holder = None
        j = pin.computeFrameJacobian(
            self.model, self.data, self._q(x), frame_id, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        )  # also updates the frame's placement
        return self._point(frame_id, j, offset)

    def _point(self, frame_id: int, j: Array, offset: Array | None) -> tuple[Array, Array]:
        """The point's position and Jacobian from its frame's placement and Jacobian j (6, n)."""
        placement = self.data.oMf[frame_id]
        if offset is None:
            p, jv = placement.translation.copy(), j[:3]
        else:
            r = placement.rotation @ offset
            p = placement.translation + r
            jv = offset_jacobian(j[:3], j[3:], r)
        return p, (jv if self._identity else jv.dot(self._t_inv))

    def point_position(self, frame_id: int, x: Array, offset: Array | None = None) -> Array:
        """World position of a point fixed in a frame, shape (3,) [m] (the joints' placements
        and that frame's only: the guard asks it at every predicted configuration)."""
        self.holder = None
        pin.forwardKinematics(self.model, self.data, self._q(x))
        placement = pin.updateFramePlacement(self.model, self.data, frame_id)
        if offset is None:
            return placement.translation.copy()
        return placement.act(np.asarray(offset, dtype=float))

    def frame_placement(self, frame_id: int, x: Array) -> tuple[Array, Array]:
        """A frame's origin (3,) [m] and axes R (3, 3) in the world, from one kinematics pass."""
        self.holder = None
        pin.framesForwardKinematics(self.model, self.data, self._q(x))
        placement = self.data.oMf[frame_id]
        return placement.translation.copy(), placement.rotation.copy()

    def point_jacobian(self, frame_id: int, x: Array, offset: Array | None = None) -> Array:
        """∂p/∂x of a point fixed in a frame, shape (3, n) (``point_kinematics``)."""
        return self.point_kinematics(frame_id, x, offset)[1]
