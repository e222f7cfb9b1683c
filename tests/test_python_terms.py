"""A constraint without a kernel (a user's kind) in a law that has one: only its own terms run
in Python (cpbc.constraints.python_terms), copied into the law's one kernel call; the torque
is the general path's to rounding, and the law says so once, when it packs, with the cost."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from cpbc.arrays import Array
from cpbc.bench import planar_2link
from cpbc.constraints import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.margins import CLEARANCE, RATE
from cpbc.controllers import CPBC, CPBCKineticEnergy
from cpbc.controllers.packed_law import PythonPathWarning
from cpbc.errors import ConstraintViolation
from cpbc.kernels.barrier_set import LINEAR, POINT
from cpbc.kernels.barriers import ENERGY
from cpbc.kernels.barriers import RATE as RATE_KIND
from cpbc.kernels.python_rows import PYTHON_CONFIGURATION, PYTHON_VELOCITY
from cpbc.model.robot_model import ArmState, RobotModel


class PointBelow(ConfigurationConstraint):
    """φ = h − p_y(x): a frame's origin below the height h [m] — a user's kind, no kernel.
    ``asked`` counts its evaluations."""

    margin_type = CLEARANCE

    def __init__(self, model: RobotModel, frame: str, height: float) -> None:
        self.model, self.frame_id, self.height = model, model.frame_id(frame), height
        self.names = ("below",)
        self.asked = 0

    def value(self, x: Array) -> Array:
        return np.array([self.height - self.model.point_position(self.frame_id, x)[1]])

    def gradient(self, x: Array) -> Array:
        return -self.model.point_jacobian(self.frame_id, x)[1:2]

    def evaluate(self, x: Array) -> tuple[Array, Array]:
        self.asked += 1
        return self.value(x), self.gradient(x)


class SpeedEllipse(VelocityConstraint):
    """ψ = Ω − ½ẋᵀWẋ with a constant W ≻ 0 — a user's velocity kind, no kernel."""

    margin_type = RATE

    def __init__(self, weight: Array, limit: float) -> None:
        self.weight, self.limit, self.names = weight, limit, ("speed",)

    def value(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        return np.array([self.limit - 0.5 * dx @ self.weight @ dx])

    def weights(self, x: Array, state: ArmState | None = None) -> Array:
        return self.weight[None, :, :]

    def gradient(self, x: Array, dx: Array, state: ArmState | None = None) -> Array:
        return np.zeros((1, x.shape[0]))


def _general(law):  # type: ignore[no-untyped-def]
    """The same law taking its general path, method by method (a subclass whose ``_law``
    only calls the base class's packs nothing)."""

    class General(type(law)):  # type: ignore[misc]
        def _law(self, *args, **kwargs):  # type: ignore[no-untyped-def]
            return super()._law(*args, **kwargs)

    copy = type(law).__new__(type(law))
    copy.__dict__.update(law.__dict__)
    copy.__class__ = General
    return copy


def _laws(height: float = 1.9) -> dict[str, CPBC | CPBCKineticEnergy]:
    """The planar bench's CPBC and CPBC-KE with a point below ``height`` among the thesis's
    constraints (and CPBC with a speed ellipse besides its rate limits)."""
    setup = planar_2link()
    cpbc, ke = setup.controllers["cpbc"], setup.controllers["cpbc_ke"]
    assert isinstance(cpbc, CPBC) and isinstance(ke, CPBCKineticEnergy)
    model = cpbc.model
    below = PointBelow(model, "end_point", height)
    cs = cpbc.constraints
    speed = SpeedEllipse(np.array([[2.0, 0.3], [0.3, 1.0]]), 0.05)
    return {
        "cpbc": CPBC(model, cpbc.target, ConstraintSet(2, [*cs.configuration, below],
                                                       [*cs.velocity, speed]),
                     cpbc.kp, cpbc.kd, cpbc.shaping),
        "cpbc_ke": CPBCKineticEnergy(model, ke.target, ConstraintSet(
            2, [*ke.constraints.configuration, below], ke.constraints.velocity), ke.kp, ke.kd,
            ke.shaping),
    }


@pytest.mark.parametrize("name", ["cpbc", "cpbc_ke"])
def test_only_the_constraint_without_a_kernel_leaves_the_compiled_path(name: str) -> None:
    law = _laws()[name]
    with pytest.warns(PythonPathWarning) as said:
        packed = law.packed_law()
    expected = ["below"] if name == "cpbc_ke" else ["below", "speed"]
    assert [str(w.message).split("'")[1] for w in said] == expected
    assert all("µs a step (measured at build)" in str(w.message) for w in said)
    # the law keeps its one kernel call; the set's plan holds the others' kinds
    assert packed.terms is not None
    tables = law.constraints.packed_tables if name == "cpbc" else law._config.packed_tables  # type: ignore[union-attr]
    assert tables is not None
    kinds = tables.plan[:, 0].tolist()
    assert kinds == ([POINT, LINEAR, PYTHON_CONFIGURATION, RATE_KIND, PYTHON_VELOCITY]
                     if name == "cpbc" else [POINT, LINEAR, PYTHON_CONFIGURATION])
    assert ENERGY not in kinds  # CPBC-KE's own bound is its kernel's ψ
    general = _general(law)
    assert general.packed_law().terms is None
    below = next(c for c in law.constraints.configuration if isinstance(c, PointBelow))
    checked = 0
    for x, dx in planar_2link().states[:24]:
        state = law.state(x, dx)
        asked = below.asked
        fast = law.evaluate_state(state, margins=True)
        assert below.asked == asked + 1  # asked once a step, in Python
        slow = general.evaluate_state(general.state(x, dx), margins=True)
        np.testing.assert_allclose(fast.torque, slow.torque, rtol=1e-12, atol=1e-12)
        assert fast.lyapunov == pytest.approx(slow.lyapunov, rel=1e-12, abs=1e-14)
        np.testing.assert_allclose(fast.margins, slow.margins, rtol=1e-12, atol=1e-14)
        np.testing.assert_allclose(law.torque(x, dx), slow.torque, rtol=1e-12, atol=1e-12)
        checked += 1
    assert checked == 24


def test_the_law_says_it_once() -> None:
    """Packing again (a term set anew) says nothing new: the same constraint, the same note."""
    law = _laws()["cpbc"]
    with pytest.warns(PythonPathWarning):
        law.packed_law()
    with warnings.catch_warnings():
        warnings.simplefilter("error", PythonPathWarning)
        law.constraints = law.constraints  # packs again at the next step
        law.torque(*planar_2link().states[0])


def test_outside_s_the_python_constraint_is_named_as_on_the_general_path() -> None:
    with pytest.warns(PythonPathWarning):
        law = _laws(height=0.2)["cpbc"]
        law.packed_law()
    x = np.array([0.3, 0.4])  # the end point at 0.69 m, above 0.2 m
    with pytest.raises(ConstraintViolation, match="below") as fast:
        law.torque(x, np.zeros(2))
    with pytest.raises(ConstraintViolation) as slow:
        _general(law).torque(x, np.zeros(2))
    assert str(fast.value) == str(slow.value)


CAPSULES = {
    "name": "capsules",
    "robot": {"model": "planar_2link"},
    "simulation": {"duration": 0.01},
    "target": [0.5, 0.5],
    "cases": [{"name": "rest", "position": [0.2, 0.3]}],
    "obstacles": [{"type": "sphere", "name": "ball", "centre": [0.0, 2.0, 0.0],
                   "radius": 0.3}],
    "constraints": [{"type": "clearance", "name": "clear", "links": [], "primitives": [
        {"link": "link2", "start": [0, 0, 0], "end": [1, 0, 0], "radius": 0.05}]}],
    "controllers": [{"type": "cpbc", "name": "law", "kp": 4, "kd": 2}],
}


def test_the_command_line_says_it_once_after_the_build(tmp_path, capsys) -> None:  # type: ignore[no-untyped-def]
    """A shipped kind the set's kernel cannot take (a clearance's capsules): cpbc.run names
    it in one note, and runs."""
    import yaml

    from cpbc.run import main

    path = tmp_path / "capsules.yaml"
    path.write_text(yaml.safe_dump(CAPSULES, sort_keys=False), encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("error", PythonPathWarning)  # said as a note, not a warning
        assert main([str(path), "--out", str(tmp_path / "out"), "--quiet", "--no-plots",
                     "--workers", "1"]) == 0
    err = capsys.readouterr().err
    assert err.count("has no kernel") == 1
    assert "note: cpbc: constraint 'clear' (Clearance) has no kernel" in " ".join(err.split())


def test_a_law_with_a_python_constraint_pickles_and_says_nothing_again() -> None:
    """Sent to a worker process whole, the law packs again there, steps alike, and does not
    repeat its note."""
    import pickle

    law = _laws()["cpbc"]
    x, dx = planar_2link().states[1]
    with pytest.warns(PythonPathWarning):
        tau = law.torque(x, dx)
    copy = pickle.loads(pickle.dumps(law))
    with warnings.catch_warnings():
        warnings.simplefilter("error", PythonPathWarning)
        np.testing.assert_array_equal(copy.torque(x, dx), tau)
    assert copy.packed_law().python and copy.packed_law().terms is not None
