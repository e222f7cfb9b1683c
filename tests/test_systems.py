"""The Part-I plants: MJCF against the ODE under the same open-loop input, state maps, checks
of the model files, and the road profile of §3.3.3."""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest

from cpbc.errors import CpbcError, ModelError
from cpbc.simulation import run_system_mujoco, run_system_reference
from cpbc.systems import ConstrainedQuantity, HaversineBump, QuarterCar, ReactionWheelPendulum


def test_bump_is_the_thesis_profile() -> None:
    """d = 12.5πA sin(25πt) on (0, 0.08] for l = 2 m, v = 25 m/s, and d = ṙ."""
    bump = HaversineBump(0.11)
    assert bump.duration == pytest.approx(0.08)
    for t in np.linspace(0.001, 0.079, 17):
        thesis = 12.5 * math.pi * 0.11 * math.sin(25 * math.pi * t)
        assert bump.velocity_at(t) == pytest.approx(thesis)
        h = 1e-7
        fd = (bump.height_at(t + h) - bump.height_at(t - h)) / (2 * h)
        assert bump.velocity_at(t) == pytest.approx(fd, rel=1e-6, abs=1e-9)
    assert bump.height_at(0.04) == pytest.approx(0.11)
    assert bump.height_at(0.0) == bump.height_at(0.0801) == bump.velocity_at(0.09) == 0.0
    with pytest.raises(CpbcError):
        HaversineBump(-0.1)


def _held(fun, dt: float):
    """An open-loop input that the fixed-step driver holds over [t, t + dt): sampled at the
    midpoint there, so the held value matches the continuous input to O(dt²) (the ODE gets
    the continuous input)."""

    def sim(x: tuple[float, ...], t: float) -> float:
        return fun(t + 0.5 * dt)

    def ode(x: tuple[float, ...], t: float) -> float:
        return fun(t)

    return sim, ode


def _wiggle(t: float) -> float:
    return 5.0 * math.sin(2 * math.pi * 3.0 * t) + 2.0 * math.cos(2 * math.pi * 11.0 * t)


def test_quarter_car_mujoco_matches_its_ode() -> None:
    """Open-loop u(t) over a 0.05 m bump, 1 s at the MJCF's 1e-4 s RK4 step: deflections within
    1e-6 m, velocities within 5e-5 m/s of the continuous-time solution (measured: 2e-7, 1.1e-5;
    peak travel here 0.24 m, wheel speed 6.7 m/s)."""
    plant = QuarterCar(HaversineBump(0.05))
    x0 = (0.001, -0.2, 0.01, 0.1)
    held, cont = _held(_wiggle, 1e-4)
    sim = run_system_mujoco(plant, held, x0, 1.0)
    ref = run_system_reference(plant, cont, x0, 1.0, 1e-4)
    assert np.abs(ref.state[:, 2]).max() > 0.01
    err = np.abs(sim.state - ref.state).max(axis=0)
    assert err[[0, 2]].max() < 1e-6  # deflections [m]
    assert err[[1, 3]].max() < 5e-5  # velocities [m/s]


def _torque(t: float) -> float:
    return 0.02 * math.sin(3.0 * t) - 0.01


def test_wheel_pendulum_mujoco_matches_its_ode() -> None:
    """Open-loop τ(t) from q1 = 0.2 rad, 1.5 s at the MJCF's 1e-3 s RK4 step (the pendulum falls
    through 5.8 rad; measured errors 1.6e-6 rad, 8.7e-6 rad/s, 1.6e-4 rad/s on a 225 rad/s
    wheel)."""
    plant = ReactionWheelPendulum()
    x0 = (0.2, -0.1, 5.0)
    held, cont = _held(_torque, 1e-3)
    sim = run_system_mujoco(plant, held, x0, 1.5)
    ref = run_system_reference(plant, cont, x0, 1.5, 1e-3)
    assert abs(ref.state[-1, 0] - x0[0]) > 0.5  # it falls: the comparison is not trivial
    err = np.abs(sim.state - ref.state).max(axis=0)
    assert err[0] < 1e-5 and err[1] < 5e-5 and err[2] < 1e-3  # q1 [rad], q̇1, q̇2 [rad/s]


@pytest.mark.parametrize("plant", [QuarterCar(HaversineBump(0.02)), ReactionWheelPendulum()],
                         ids=["quarter_car", "rwp"])
def test_state_round_trip(plant) -> None:
    model = plant.load()
    data = mujoco.MjData(model)
    data.time = 0.03
    x = tuple(0.01 * (i + 1) for i in range(len(plant.state_names)))
    plant.write_state(model, data, x)
    assert plant.read_state(model, data) == pytest.approx(x)


def test_quarter_car_mass_scale_and_input_map() -> None:
    """Body acceleration is −u and wheel acceleration is −ω²x1 + ρu (3.62) in MuJoCo."""
    plant = QuarterCar()
    model = plant.load()
    data = mujoco.MjData(model)
    plant.write_state(model, data, (0.002, 0.0, 0.0, 0.0))
    plant.write_input(model, data, 7.0)
    plant.before_step(model, data)
    mujoco.mj_forward(model, data)
    assert data.qacc[1] == pytest.approx(-7.0)
    assert data.qacc[0] == pytest.approx(-((20 * math.pi) ** 2) * 0.002 + 10 * 7.0)


def test_constrained_quantities() -> None:
    rwp = ReactionWheelPendulum()
    rate, tau = rwp.constrained
    assert (rate.name, rate.upper, tau.name, tau.upper) == ("dq1", 1.0, "tau", 0.4)
    assert tau.value((0.0, 0.5, 0.0), 0.3) == 0.3 and rate.value((0.0, 0.5, 0.0), 0.3) == 0.5
    assert rate.margin((0.0, 0.9, 0.0), 0.0) == pytest.approx(0.1)
    assert QuarterCar().constrained[0].upper == 0.1
    with pytest.raises(CpbcError):
        ConstrainedQuantity("bad", 1.0, -1.0)


def test_model_mismatch_is_reported(tmp_path: Path) -> None:
    """An MJCF whose tire stiffness does not give ω = 20π rad/s is refused by name."""
    src = QuarterCar().mjcf.read_text()
    bad = tmp_path / "qc.xml"
    bad.write_text(src.replace('stiffness="118435.2528"', 'stiffness="100000"'))
    with pytest.raises(ModelError, match="k_t/m_us"):
        QuarterCar(path=bad).load()
    with pytest.raises(ModelError, match="missing"):
        ReactionWheelPendulum(path=tmp_path / "none.xml").load()


def test_part_one_models_are_not_offered_as_arms() -> None:
    """The quarter car and the pendulum live in models/systems/, apart from the arms that
    a scenario's ``robot.model`` may name."""
    from cpbc.resources import builtin_models

    assert not {"quarter_car", "reaction_wheel_pendulum"} & set(builtin_models())
