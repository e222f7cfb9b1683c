"""A law's packed step (one kernel call, cpbc.controllers.packed_law) against its general
path (method by method), and every override that must make a law leave the packed step."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from bounded_goal import bounded_goal_laws

from cpbc.bench import planar_2link, taskspace_pair
from cpbc.bench_arms import panda
from cpbc.constraints import ConstraintSet
from cpbc.controllers import CPBC, Power
from cpbc.controllers.packed_law import PythonPathWarning
from cpbc.controllers.potentials import FramePositionLogCosh, JointSpring, PotentialSum
from cpbc.controllers.potentials.potential import OfTheJoints
from cpbc.controllers.task_damping import TaskDamping, TaskTanhDamping
from cpbc.controllers.terms import LinearDamping
from cpbc.errors import ConstraintViolation


def _general(law):  # type: ignore[no-untyped-def]
    """The same law as an instance of a subclass whose ``_law`` only calls the base class's:
    the same formula, taken method by method."""

    class General(type(law)):  # type: ignore[misc]
        def _law(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            return super()._law(*args, **kwargs)

    copy = type(law).__new__(type(law))
    copy.__dict__.update(law.__dict__)
    copy.__class__ = General
    return copy


def _laws():  # type: ignore[no-untyped-def]
    planar, arm = planar_2link(), panda(states=12)
    for setup in (planar, arm):
        for name in ("cpbc", "cpbc_ke", "bpbc", "bpbc_ke"):
            if name in setup.controllers:
                yield f"{setup.robot}/{name}", setup.controllers[name], setup.states
    laws, states = taskspace_pair(states=12)
    for name, law in laws.items():
        yield f"panda_goal_pose/{name}", law, states
    bounded, states = bounded_goal_laws(states=12)
    for name, law in bounded.items():
        yield f"panda_goal_bpbc/{name}", law, states
    law = bounded_goal_laws(states=0)[0]["bpbc"]  # a feed-forward ṗ_ff ≠ 0 in the tanh
    law.task_damping = dataclasses.replace(law.task_damping, feedforward=[0.05, -0.1, 0.02])
    yield "panda_goal_bpbc/bpbc_feedforward", law, states


@pytest.mark.parametrize("entry", list(_laws()), ids=lambda e: e[0])
def test_the_packed_step_equals_the_general_path(entry) -> None:  # type: ignore[no-untyped-def]
    """τ, V and every margin of the packed step equal the general path's to 1e-12 (τ and V
    the same without the margins), and a state outside S raises the same violation."""
    name, law, states = entry
    general = _general(law)
    assert law.packed_law().terms is not None, name
    assert general.packed_law().terms is None, name
    checked = 0
    for x, dx in states:
        fast, slow = law.evaluate_state(law.state(x, dx), margins=True), (
            general.evaluate_state(general.state(x, dx), margins=True))
        np.testing.assert_allclose(fast.torque, slow.torque, rtol=1e-12, atol=1e-12)
        assert fast.lyapunov == pytest.approx(slow.lyapunov, rel=1e-12, abs=1e-14)
        np.testing.assert_allclose(fast.margins, slow.margins, rtol=1e-12, atol=1e-14)
        bare = law.evaluate_state(law.state(x, dx))  # τ and V alike without the margins
        assert bare.margins is None
        np.testing.assert_array_equal(bare.torque, fast.torque)
        assert bare.lyapunov == fast.lyapunov
        checked += 1
    assert checked >= 10
    x, dx = states[0]
    far = (x, 1e3 * np.ones_like(dx)) if law.constraints.velocity else (x + 50.0, dx)
    with pytest.raises(ConstraintViolation) as a:
        law.torque(*far)
    with pytest.raises(ConstraintViolation) as b:
        general.torque(*far)
    assert str(a.value) == str(b.value)


class _Stiffer(JointSpring):
    def evaluate(self, at):  # type: ignore[no-untyped-def]
        value, grad = super().evaluate(at)
        return value, grad + 1.0


class _Harder(LinearDamping):
    def force(self, dx):  # type: ignore[no-untyped-def]
        return super().force(dx) + 1.0


class _Steeper(Power):
    def ratio(self, log_x: float) -> float:
        return 2.0 * super().ratio(log_x)


class _Pushing(TaskDamping):
    def force(self, at, dx):  # type: ignore[no-untyped-def]
        return super().force(at, dx) + 1.0


class _Pulled(FramePositionLogCosh):
    def evaluate_toward(self, at, goal):  # type: ignore[no-untyped-def]
        value, grad = super().evaluate_toward(at, goal)
        return value, grad + 1.0


class _Braking(TaskTanhDamping):
    def force_with(self, at, dx, feedforward):  # type: ignore[no-untyped-def]
        return super().force_with(at, dx, feedforward) + 1.0


def _as(cls: type, term: object) -> object:
    """``term``'s fields in an instance of ``cls`` (a subclass of its class)."""
    return cls(**{f.name: getattr(term, f.name) for f in dataclasses.fields(term) if f.init})


@pytest.mark.parametrize("term", ["position_log_cosh", "task_tanh_damping"])
@pytest.mark.parametrize("name", ["bpbc", "bpbc_ke"])
def test_an_overridden_bounded_task_term_runs_in_python(name: str, term: str) -> None:
    """A ln cosh position spring or a tanh task damping whose class overrides its formula
    (``evaluate_toward``, ``force_with``: the methods ``evaluate`` and ``force`` call) does
    not pack: the bounded law asks it in Python, as a row of its kernel call, and the
    override reaches the torque."""
    (base, _), (changed, states) = bounded_goal_laws(states=0), bounded_goal_laws(states=6)
    if term == "position_log_cosh":
        position, *rest = changed[name].potential.parts  # type: ignore[attr-defined]
        assert type(position) is FramePositionLogCosh
        changed[name].potential = PotentialSum((_as(_Pulled, position), *rest))  # type: ignore[arg-type]
    else:
        assert type(changed[name].task_damping) is TaskTanhDamping  # type: ignore[attr-defined]
        changed[name].task_damping = _as(_Braking, changed[name].task_damping)  # type: ignore[attr-defined]
    assert base[name].packed_law().terms is not None  # type: ignore[attr-defined]
    with pytest.warns(PythonPathWarning):  # its own row, asked in Python
        packed = changed[name].packed_law()  # type: ignore[attr-defined]
    assert packed.terms is not None
    assert [type(t.term) for t in packed.python] == [
        _Pulled if term == "position_log_cosh" else _Braking]
    for x, dx in states:
        assert not np.allclose(changed[name].torque(x, dx), base[name].torque(x, dx),
                               rtol=1e-9)


@pytest.mark.parametrize("term", ["potential", "damping", "shaping", "task_damping"])
def test_an_overridden_term_runs_in_python(term: str) -> None:
    """A potential, damping, shaping or task damping whose class overrides its formula does
    not pack: the law asks it in Python, as a row of its kernel call (a shaping: the law
    takes its general path), and the override reaches the torque."""
    laws, states = taskspace_pair(states=6)
    law = laws["taskspace_cpbc"]
    base = CPBC(law.model, law.target, law.constraints, law.kp, law.kd, law.shaping,
                law.potential, law.task_damping)
    changed = CPBC(law.model, law.target, law.constraints, law.kp, law.kd, law.shaping,
                   law.potential, law.task_damping)
    if term == "potential":
        changed.potential = _Stiffer(law.target, law.kp)
        base.potential = JointSpring(law.target, law.kp)
    elif term == "damping":
        changed.damping = _Harder(law.kd)
    elif term == "shaping":
        changed.shaping = _Steeper(law.shaping.alpha)  # type: ignore[attr-defined]
    else:
        damping = law.task_damping
        assert isinstance(damping, TaskDamping)
        changed.task_damping = _Pushing(**{f.name: getattr(damping, f.name)
                                           for f in dataclasses.fields(damping) if f.init})
    assert base.packed_law().terms is not None
    with pytest.warns(PythonPathWarning):
        packed = changed.packed_law()
    if term == "shaping":  # r(ΦΨ) needs the kernel's log Φ: the general path
        assert packed.terms is None
    else:  # its own row, asked in Python before each call
        assert packed.terms is not None and len(packed.python) == 1
    for x, dx in states:
        assert not np.allclose(changed.torque(x, dx), base.torque(x, dx), rtol=1e-9)


def test_setting_a_term_packs_the_law_again() -> None:
    """A law packs again when one of its terms is set after construction (as
    cpbc.reference.target steers a law), so the kernel never reads stale constants."""
    laws, states = taskspace_pair(states=4)
    law = laws["joint_cpbc"]
    x, dx = states[0]
    before = law.torque(x, dx)
    law.potential = JointSpring(law.target + 0.1, law.kp)
    moved = _general(law).torque(x, dx)
    np.testing.assert_allclose(law.torque(x, dx), moved, rtol=1e-12, atol=1e-12)
    assert not np.allclose(law.torque(x, dx), before)


@pytest.mark.parametrize("entry", list(_laws()), ids=lambda e: e[0])
def test_every_step_is_evaluate_state_on_the_one_state(entry) -> None:  # type: ignore[no-untyped-def]
    """torque, evaluate and lyapunov at (x, ẋ) are evaluate_state on the law's state: the
    same numbers, bit for bit, whether the law's kernel finishes the state's pass itself
    (nothing read it before), the state was read first (finished by its own kernel), or it
    was made by the model's state with the law's frames (packed into the law's layout)."""
    name, law, states = entry
    packed = law.packed_law()
    assert packed.produce is not None, name
    for x, dx in states:
        tau, value = law.evaluate(x, dx)
        np.testing.assert_array_equal(law.torque(x, dx), tau, err_msg=name)
        assert law.lyapunov(x, dx) == value
        read = law.state(x, dx)
        assert read.inertia.shape == (x.shape[0], x.shape[0])  # finished here
        first = law.evaluate_state(read)
        np.testing.assert_array_equal(first.torque, tau, err_msg=name)
        assert first.lyapunov == value
        produce = packed.produce
        made = law.model.state(x, dx, produce.kinematics, produce.frames, produce.coriolis)
        np.testing.assert_array_equal(law.evaluate_state(made).torque, tau, err_msg=name)
        guarded = law.state(x, dx)  # as a guard asks: the margins, then it reads the state
        with_margins = law.evaluate_state(guarded, margins=True)
        np.testing.assert_array_equal(with_margins.torque, tau, err_msg=name)
        np.testing.assert_array_equal(guarded.inertia, read.inertia)
        np.testing.assert_array_equal(guarded.gravity, read.gravity)
        for frame, kin in read.frames.items():
            np.testing.assert_array_equal(guarded.frames[frame].jacobian, kin.jacobian)


def test_a_state_read_after_another_pass_makes_its_pass_again() -> None:
    """A state holds its pass unfinished until it is read; when the model made another pass
    in between (the data no longer holds its pass), it makes its own again: its terms are
    those of its own (x, ẋ), not of the later pass."""
    setup = panda(states=2)
    law = setup.controllers["cpbc"]
    (x, dx), (y, dy) = setup.states
    early = law.state(x, dx)
    law.model.state(y, dy)  # another pass over the same data
    expected = law.model.state(x, dx, kinematics=True)  # the law's pass (computeAllTerms)
    np.testing.assert_array_equal(early.inertia, expected.inertia)
    np.testing.assert_array_equal(early.coriolis_force, expected.coriolis_force)
    later = law.state(x, dx)
    law.model.gravity(y)
    np.testing.assert_array_equal(law.evaluate_state(later).torque, law.torque(x, dx))


def test_the_bare_step_reads_friction() -> None:
    """With viscous friction the kernel reads c = C ẋ + f, f = F_d ẋ, finished in the law's
    kernel as in the state's own (the planar arm: F_d in its absolute link angles)."""
    law = planar_2link().controllers["cpbc"]
    from cpbc.model import RobotModel

    model = law.model
    law.model = RobotModel(model.model, model.coordinates, np.array([0.4, 0.7]),
                           name=model.name)
    law.constraints = law.constraints  # pack again for the new model
    checked = 0
    for x, dx in planar_2link().states[:12]:
        slow = law.evaluate_state(law.model.state(x, dx, frames=law.packed_law().produce.frames,
                                                  kinematics=True))
        np.testing.assert_allclose(law.torque(x, dx), slow.torque, rtol=1e-13, atol=1e-13)
        assert not np.allclose(slow.torque, planar_2link().controllers["cpbc"].torque(x, dx),
                               rtol=1e-6, atol=1e-9)  # the friction reaches the torque
        checked += 1
    assert checked == 12


@pytest.mark.parametrize("robot", ["planar", "panda"])
def test_the_bare_step_reads_coulomb_friction(robot: str) -> None:
    """With Coulomb friction the kernel's f = F_d ẋ + T⁻ᵀ F_c tanh(T⁻¹ẋ/ε) (the finishing's
    joint_friction) equals the model's (RobotModel.dissipation) to rounding: the planar arm
    in its absolute link angles, the Panda in its joints; and it reaches the torque."""
    from cpbc.model import RobotModel

    setup = planar_2link() if robot == "planar" else panda(states=12)
    law = setup.controllers["cpbc"]
    plain = setup.controllers["cpbc"]
    model = law.model
    n = model.n
    law = type(law).__new__(type(law))
    law.__dict__.update(plain.__dict__)
    law.model = RobotModel(model.model, model.coordinates, np.linspace(0.05, 0.2, n),
                           name=model.name, coulomb_friction=np.linspace(1.2, 0.3, n),
                           friction_smoothing=0.05)
    law.constraints = law.constraints  # pack again for the new model
    checked = 0
    for x, dx in setup.states[:12]:
        state = law.state(x, dx)
        np.testing.assert_allclose(state.dissipation, law.model.dissipation(dx), rtol=1e-14,
                                   atol=1e-14)
        slow = law.evaluate_state(state)
        np.testing.assert_allclose(law.torque(x, dx), slow.torque, rtol=1e-13, atol=1e-12)
        np.testing.assert_allclose(_general(law).torque(x, dx), slow.torque, rtol=1e-12,
                                   atol=1e-11)
        if np.any(dx):
            assert not np.allclose(slow.torque, plain.torque(x, dx), rtol=1e-6, atol=1e-9)
        checked += 1
    assert checked == 12


def test_an_overridden_evaluate_state_is_the_step() -> None:
    """A law whose class overrides evaluate_state (here: adding a torque) keeps its packed
    kernel under the override, and torque() honours it (every step is evaluate_state)."""
    law = planar_2link().controllers["cpbc"]

    class Nudged(CPBC):
        def evaluate_state(self, state, margins=False):  # type: ignore[no-untyped-def]
            out = super().evaluate_state(state, margins)
            return out._replace(torque=out.torque + 1.0)

    nudged = Nudged(law.model, law.target, law.constraints, law.kp, law.kd, law.shaping)
    assert nudged.packed_law().terms is not None
    x, dx = planar_2link().states[0]
    np.testing.assert_allclose(nudged.torque(x, dx), law.torque(x, dx) + 1.0, rtol=1e-12)


@pytest.mark.parametrize("robot", ["planar", "panda"])
def test_a_step_takes_read_only_and_integer_states(robot: str) -> None:
    """numba refuses read-only arrays; the law steps again from copies: a read-only state
    (the planar arm's absolute link angles go through to_joint first, the Panda's joint
    coordinates straight to Pinocchio), and a state given as integers, give the torque of
    writable floats, and the pass is not left half done (the next step is right too)."""
    setup = planar_2link() if robot == "planar" else panda(states=2)
    for name in ("cpbc", "cpbc_ke"):
        law = setup.controllers[name]
        x, dx = setup.states[1]
        expected, value = law.evaluate(x.copy(), dx.copy())
        frozen_x, frozen_dx = x.copy(), dx.copy()
        frozen_x.setflags(write=False)
        frozen_dx.setflags(write=False)
        np.testing.assert_array_equal(law.torque(frozen_x, frozen_dx), expected)
        tau, v = law.evaluate(frozen_x, dx.copy())
        np.testing.assert_array_equal(tau, expected)
        assert v == value
        np.testing.assert_array_equal(law.torque(x.copy(), dx.copy()), expected)
    if robot == "planar":  # the rest state [0, 0] is inside S (not so the Panda's)
        law = setup.controllers["cpbc"]
        whole = np.zeros(2, dtype=np.int64), np.zeros(2, dtype=np.int64)
        np.testing.assert_array_equal(law.torque(*whole), law.torque(np.zeros(2), np.zeros(2)))


@pytest.mark.parametrize("entry", list(_laws()), ids=lambda e: e[0])
def test_a_law_that_has_stepped_pickles(entry) -> None:  # type: ignore[no-untyped-def]
    """A law is sent to worker processes whole: after a step (its packed law made, its
    state's pass bound to the model's Pinocchio data) it pickles, and the copy steps alike —
    on another state too (its pass reads its own data, not arrays copied from the
    original's)."""
    import pickle

    name, law, states = entry
    x, dx = states[0]
    tau = law.torque(x, dx)
    copy = pickle.loads(pickle.dumps(law))
    np.testing.assert_array_equal(copy.torque(x, dx), tau, err_msg=name)
    y, dy = states[1]
    np.testing.assert_array_equal(copy.torque(y, dy), law.torque(y, dy), err_msg=name)


class _Tilted(ConstraintSet):
    """A user's constraint set with a formula of its own: every log-barrier gradient
    tilted (a formula the set's kernel cannot stand in for)."""

    def barrier(self, state, margins=False):  # type: ignore[no-untyped-def]
        found = super().barrier(state, margins)
        gradient = None if found.gradient is None else found.gradient + 0.5
        return found._replace(gradient=gradient)


class _Bowl(OfTheJoints):
    """A user's potential with no kernel: U = 1.5 ‖x − x_d‖² (no ``packed``)."""

    gradient_bound = None

    def __init__(self, goal):  # type: ignore[no-untyped-def]
        self.goal = np.asarray(goal, dtype=float)

    def evaluate(self, at):  # type: ignore[no-untyped-def]
        error = at.x - self.goal
        return 1.5 * float(error @ error), 3.0 * error


class _Viscous:
    """A user's joint damping with no kernel: F = 2 K ẋ (no ``packed``)."""

    def __init__(self, gain):  # type: ignore[no-untyped-def]
        self.gain = np.asarray(gain, dtype=float)

    def force(self, dx):  # type: ignore[no-untyped-def]
        return 2.0 * self.gain * dx


def test_a_constraint_set_with_its_own_barrier_says_the_law_leaves_its_kernel() -> None:
    """A user's ConstraintSet subclass overriding barrier sends the law down its general
    path: the law says so once, at build, naming the class and what a step costs, and the
    subclass's formula reaches the torque."""
    setup = planar_2link()
    base = setup.controllers["cpbc"]
    c = base.constraints
    law = CPBC(base.model, base.target, _Tilted(c.n, c.configuration, c.velocity), base.kp,
               base.kd, base.shaping)
    with pytest.warns(PythonPathWarning) as said:
        packed = law.packed_law()
    (note,) = [str(w.message) for w in said]
    assert "its constraint set's class _Tilted overrides barrier" in note, note
    assert "general path" in note and "µs a step (measured at build)" in note
    assert packed.terms is None
    with warnings.catch_warnings():
        warnings.simplefilter("error", PythonPathWarning)  # said once
        law.constraints = law.constraints  # packs again at the next step
        for x, dx in setup.states[:6]:
            tau = law.torque(x, dx)
            assert not np.allclose(tau, base.torque(x, dx), rtol=1e-9)
            state = law.state(x, dx)
            bar = law.constraints.barrier(state)
            value, grad = law.potential.evaluate(state)
            lag = 0.5 * float(dx @ state.inertia @ dx) + value
            np.testing.assert_allclose(tau, law._law(state, bar, grad, lag), rtol=1e-12,
                                       atol=1e-12)


@pytest.mark.parametrize("term", ["potential", "summed potential", "damping"])
def test_a_term_without_a_kernel_costs_only_its_own_row(term: str) -> None:
    """A user's potential or damping without a kernel (or one part of a sum) is asked in
    Python before each call and read by the law's kernel as a row of its own: the law keeps
    its one kernel call, says once which term runs in Python and what it costs, and its τ,
    V and margins equal the general path's."""
    setup = planar_2link()
    base = setup.controllers["cpbc"]
    law = CPBC(base.model, base.target, base.constraints, base.kp, base.kd, base.shaping)
    if term == "potential":
        law.potential = _Bowl(base.target)  # type: ignore[assignment]
    elif term == "summed potential":
        law.potential = PotentialSum((JointSpring(base.target, base.kp),
                                      _Bowl(base.target)))  # type: ignore[arg-type]
    else:
        law.damping = _Viscous(base.kd)  # type: ignore[assignment]
    with pytest.warns(PythonPathWarning) as said:
        packed = law.packed_law()
    (note,) = [str(w.message) for w in said]
    named = "its damping (_Viscous)" if term == "damping" else "its potential (_Bowl)"
    assert f"{named} has no kernel" in note and "one kernel call" in note, note
    assert packed.terms is not None and len(packed.python) == 1
    general = _general(law)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PythonPathWarning)
        assert general.packed_law().terms is None
    for x, dx in setup.states[:12]:
        fast = law.evaluate_state(law.state(x, dx), margins=True)
        slow = general.evaluate_state(general.state(x, dx), margins=True)
        np.testing.assert_allclose(fast.torque, slow.torque, rtol=1e-12, atol=1e-12)
        assert fast.lyapunov == pytest.approx(slow.lyapunov, rel=1e-12, abs=1e-14)
        np.testing.assert_allclose(fast.margins, slow.margins, rtol=1e-12, atol=1e-14)
        np.testing.assert_array_equal(law.torque(x, dx), fast.torque)
        assert not np.allclose(fast.torque, base.torque(x, dx), rtol=1e-9)
