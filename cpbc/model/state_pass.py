"""The per-step state's one producer: one Pinocchio pass, then one kernel that finishes it.

Every :class:`~cpbc.model.arm_state.ArmState` comes from a :class:`StatePass`
(``RobotModel.state``, a law's ``state``): the pass in joint coordinates — CRBA, the
nonlinear effects and gravity, or, when the state holds the joint kinematics or a frame,
CRBA in world axes (which leaves the joint Jacobians), RNEA and the static regressor (the
joint placements); with ``coriolis`` the matrix C first — and its finishing
(cpbc.kernels.state_terms.finish_into: the controller coordinates, the friction, g from the
joint kinematics when the pass holds them, and every frame from the joint kinematics, so
that a frame has one source whoever reads it). The state is finished when it is first read, by
``finish_state``, or by the law's kernel it is handed to.

The pass's arrays are views of the model's Pinocchio data, which its next pass overwrites: a
state finished after another pass ran (``RobotModel.holds``) makes its own pass again.
"""

from __future__ import annotations

from collections.abc import Mapping
from types import MappingProxyType
from typing import TYPE_CHECKING

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import CpbcError
from cpbc.kernels.coordinate_maps import to_joint
from cpbc.kernels.state_terms import finish_state, layout, pack_state
from cpbc.model.arm_state import LATER, NO_FRAMES, ArmState
from cpbc.model.frames import FrameKinematics

if TYPE_CHECKING:
    from cpbc.model.robot_model import RobotModel

# a finished state's pass: its arrays all empty (cpbc.kernels.laws.finished); no terms
NO_TERMS = np.zeros(0)
FINISHED = (np.zeros((0, 0)), NO_TERMS, NO_TERMS, np.zeros((0, 0)), np.zeros((3, 0)),
            np.zeros((6, 0)))


class StatePass:
    """The producer of the per-step states that hold the joint kinematics (``kinematics``),
    ``frames`` (frame ids) and the matrix C (``coriolis``) of ``model``, its choices made
    once (``RobotModel.state_pass``).

    Attributes:
        model: the robot model whose pass it makes.
        kinematics, frames, coriolis: what its states hold.
        run: its Pinocchio pass, a function of (x, ẋ) (``RobotModel.pinocchio_pass``).
        tables: the finishing's constant tables (cpbc.kernels.state_terms.pack_state).
        size: the length of a state's terms.
    """

    def __init__(self, model: RobotModel, kinematics: bool, frames: tuple[int, ...],
                 coriolis: bool) -> None:
        self.model = model
        self.kinematics, self.frames, self.coriolis = kinematics, frames, coriolis
        joint_pass = bool(kinematics or frames)
        columns = model.regressor_columns if joint_pass else 0
        self.tables = pack_state(model.n, coriolis, kinematics, columns,
                                 model.coordinates.inverse, model.viscous_friction,
                                 model.coulomb_friction, model.friction_smoothing,
                                 tuple(model.frame_place(f) for f in frames),
                                 model.gravity_on_joints() if joint_pass else NO_TERMS)
        at = self._at = layout(model.n, coriolis, kinematics, columns, len(frames))
        self._columns = columns
        self.size = at["size"]
        # each field's place in the terms, made once (``_fill``)
        n = model.n
        self._square = (n, n)
        self._views = (slice(0, n * n), *(slice(at[k], at[k] + n) for k in
                                          ("coriolis_force", "gravity", "dissipation")))
        self._coriolis = slice(at["coriolis_matrix"], at["coriolis_matrix"] + n * n)
        self._joints = ((slice(at["joint_jacobians"], at["joint_jacobians"] + 6 * n), (6, n)),
                        (slice(at["regressor"], at["regressor"] + 3 * columns), (3, columns)))
        starts = [at["frames"] + f * (16 + 6 * n) for f in range(len(frames))]
        self._frames = tuple((slice(s, s + 16), slice(s + 16, s + 16 + 6 * n), (6, n))
                             for s in starts)
        self._identity, self._t_inv = model.coordinates.is_identity, model.coordinates.inverse
        self.run = model.pinocchio_pass(joint_pass, coriolis)

    def __call__(self, x: Array, dx: Array) -> ArmState:
        """The state at (x, ẋ), from one pass; finished when first read. x and ẋ are kept
        as given, or as float copies when the pass refuses them (integers; read-only arrays
        in other coordinates than the joints')."""
        try:
            raw = self.run(x, dx)
        except TypeError:
            x, dx = np.array(x, dtype=float), np.array(dx, dtype=float)
            raw = self.run(x, dx)
        state = object.__new__(ArmState)
        state.x, state.dx, state.source, state.raw, state.terms = x, dx, self, raw, None
        self.model.holder = state
        return state

    def finish(self, state: ArmState) -> None:
        """The state's dynamics fields from its terms, made first when it has none
        (cpbc.kernels.state_terms.finish_state): from its own pass again when the model's
        data no longer holds it. The kinematics, C and the frames are taken from the terms
        when each is first read (:meth:`fill`)."""
        if state.terms is None:
            raw = state.raw if self.model.holder is state else None
            if raw is None:
                raw = self.run(state.x, state.dx)
            terms = np.empty(self.size)
            ints, floats = self.tables
            mass, bias, weight, c_matrix, y, jac = raw
            finish_state(ints, floats, state.dx, mass, bias, weight, c_matrix, y, jac, terms)
            state.terms = terms
        state.raw = None
        self._fill(state, state.terms)

    def fill(self, state: ArmState, name: str) -> None:
        """The field ``name`` of a state from this pass, read for the first time: with the
        dynamics (:meth:`finish`), or alone where it is the matrix C, the joint kinematics or
        the frames, which a guard's calm step does not read (each a view or two of the
        terms, made when it is asked for)."""
        if name not in LATER:
            self.finish(state)
            return
        if state.terms is None:
            self.finish(state)
        terms = state.terms
        assert terms is not None  # finished
        if name == "coriolis_matrix":
            state.coriolis_matrix = (terms[self._coriolis].reshape(self._square)
                                     if self.coriolis else None)
        elif name == "frames":
            state.frames = self._frames_of(terms)
        elif self.kinematics:
            (jacobians, rows), (placements, columns) = self._joints
            state.joint_jacobians = terms[jacobians].reshape(rows)
            state.regressor = terms[placements].reshape(columns)
        else:
            state.joint_jacobians = state.regressor = None

    def _fill(self, state: ArmState, terms: Array) -> None:
        """The dynamics fields as views of the terms (the layout of
        cpbc.kernels.state_terms)."""
        if self._identity:
            state.q, state.dq = state.x, state.dx
        else:
            joint = np.empty((2, self.model.n))
            to_joint(self._t_inv, state.x, state.dx, joint)
            state.q, state.dq = joint[0], joint[1]
        inertia, bias, gravity, dissipation = self._views
        state.inertia = terms[inertia].reshape(self._square)
        state.coriolis_force, state.gravity = terms[bias], terms[gravity]
        state.dissipation = terms[dissipation]

    def _frames_of(self, terms: Array) -> Mapping[int, FrameKinematics]:
        """Every frame's placement and Jacobian, views of the terms."""
        if not self.frames:
            return NO_FRAMES
        found = {}
        for frame, (placement, jacobian, shape) in zip(self.frames, self._frames,
                                                       strict=True):
            found[frame] = FrameKinematics(terms[placement].reshape(4, 4),
                                           terms[jacobian].reshape(shape))
        return MappingProxyType(found)

    def terms_of(self, state: ArmState) -> Array:
        """A state's terms in this pass's layout: its own when it comes from this pass
        (finished first), else its fields packed (a state made elsewhere)."""
        if state.source is self:
            if state.terms is None:
                self.finish(state)
            assert state.terms is not None
            return state.terms
        n, at = self.model.n, self._at
        terms = np.zeros(self.size)
        for name in ("coriolis_force", "gravity", "dissipation"):
            terms[at[name]:at[name] + n] = getattr(state, name)
        terms[:n * n] = np.ravel(state.inertia)
        if self.coriolis:
            c = at["coriolis_matrix"]
            terms[c:c + n * n] = np.ravel(_given(state.coriolis_matrix, "coriolis=True"))
        if self.kinematics:
            j, y = at["joint_jacobians"], at["regressor"]
            terms[j:j + 6 * n] = np.ravel(_given(state.joint_jacobians, "kinematics=True"))
            terms[y:y + 3 * self._columns] = np.ravel(_given(state.regressor,
                                                             "kinematics=True"))
        start = at["frames"]
        for frame in self.frames:
            kin = state.frames.get(frame)
            if kin is None:
                raise CpbcError(f"the law reads frame {frame} from the state: build it with "
                                "the law's state(x, dx)")
            terms[start:start + 16] = np.ravel(kin.placement)
            terms[start + 16:start + 16 + 6 * n] = np.ravel(kin.jacobian)
            start += 16 + 6 * n
        return terms


def _given(found: Array | None, asked: str) -> Array:
    """A field the law reads, or a clear error naming how to build the state with it."""
    if found is None:
        raise CpbcError(f"the law reads a term the state does not hold: build it with {asked} "
                        "(a law's state(x, dx) does)")
    return found

