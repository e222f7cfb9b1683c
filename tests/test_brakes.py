"""Brakes within the torque box, the stricter classification, and the safeguard's rescue."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from cpbc.constraints.brakes import FRICTION_LEFT, TorqueBox, brakes, least_squares_brake
from cpbc.reliability.campaign import RecordingPlant, checked_run, kept_constraints
from cpbc.reliability.verification import draw_state, in_braking_set, stopping_brake
from cpbc.scenario import build, load_scenario


@pytest.fixture(scope="module")
def panda():
    setup = build(*load_scenario("panda_cpbc_sphere"))
    entry = next(e for e in setup.controllers if e.controller.type_name != "cbf_qp"
                 and not e.controller.constraints.empty)
    return setup, entry


def test_least_squares_brake_stays_in_the_box_and_stops_faster_than_it_can(panda):
    setup, _ = panda
    s = draw_state(setup, 5)
    state = setup.model.state(s.position, s.velocity)
    bias = state.coriolis_force + state.gravity + state.dissipation
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
    tau = least_squares_brake(box)(state, bias, 0.001)
    assert np.all(np.abs(box.joint(tau)) <= box.limit * (1 + 1e-9))
    acc = np.linalg.solve(state.inertia, tau - bias)
    assert acc.dot(s.velocity) < 0  # it decelerates


def test_the_nearest_reachable_torque_costs_the_acceleration_least(panda):
    """Under a rate limit a torque far outside the step box is reached with the least
    acceleration error any torque in the box has: less than scaling the whole step into the
    box (which starved the FR3's light last joint) and than clipping joint by joint."""
    setup, _ = panda
    rng = np.random.default_rng(3)
    box = TorqueBox.of(setup.model, setup.loop_settings.bounds.torque)
    for seed in range(20):
        s = draw_state(setup, seed)
        inertia = setup.model.inertia(s.position)
        held = rng.uniform(-0.5, 0.5, 7) * box.limit
        step = box.around(held, np.full(7, 1.0))  # 1 N·m a period
        wanted = rng.uniform(-1, 1, 7) * box.limit
        near = step.nearest(inertia, wanted)
        lower, upper = step.bounds
        assert np.all(near >= lower - 1e-9) and np.all(near <= upper + 1e-9)
        errors = [np.linalg.norm(np.linalg.solve(inertia, tau - wanted))
                  for tau in (near, step.toward(held, wanted), step.clip(wanted))]
        assert errors[0] <= min(errors[1:]) + 1e-9
    inside = (lower + upper) / 2
    assert step.nearest(inertia, inside) is inside  # a torque that fits is returned as it is


def test_the_nearest_reachable_torque_in_mapped_coordinates(panda):
    """The same reach in controller coordinates that are not the joints' (τ = T⁻ᵀ τ_q, a
    box on Tᵀ τ): its joint torques lie in the step box, its acceleration error is no
    larger than clipping's or scaling's, and it is the least-squares optimum over the box
    as scipy's bounded least squares finds it (to 1e-9 of the error), and a torque that fits
    is returned as it is."""
    from scipy.optimize import lsq_linear

    setup, _ = panda
    rng = np.random.default_rng(5)
    n = 7
    t = np.eye(n) + np.tril(rng.uniform(-0.3, 0.3, (n, n)), -1)  # q = T x, unit diagonal
    box = TorqueBox(np.asarray(setup.loop_settings.bounds.torque, dtype=float), t.T.copy(),
                    np.linalg.inv(t.T))
    for seed in range(10):
        s = draw_state(setup, seed)
        inertia_q = setup.model.inertia(s.position)
        inertia = t.T @ inertia_q @ t  # D in the coordinates x
        held = box.from_joint @ (rng.uniform(-0.5, 0.5, n) * box.limit)
        step = box.around(box.joint(held), np.full(n, 1.0))
        wanted = box.from_joint @ (rng.uniform(-1, 1, n) * box.limit)
        near = step.nearest(inertia, wanted)
        lower, upper = step.bounds
        q = box.joint(near)
        assert np.all(q >= lower - 1e-9) and np.all(q <= upper + 1e-9)
        accel = np.linalg.solve(inertia, box.from_joint)  # acceleration per joint torque
        best = lsq_linear(accel, accel @ box.joint(wanted), bounds=(lower, upper),
                          method="bvls", tol=1e-14)
        error = np.linalg.norm(accel @ (q - box.joint(wanted)))
        assert error <= np.linalg.norm(accel @ (best.x - box.joint(wanted))) + 1e-9
        for other in (step.toward(held, wanted), step.clip(wanted)):
            assert error <= np.linalg.norm(accel @ (box.joint(other) - box.joint(wanted))) + 1e-9
    inside = box.from_joint @ ((lower + upper) / 2)
    assert step.nearest(inertia, inside) is inside


# States outside the guard's braking set V (its uniform brake cannot stop them) that another
# brake within the torque box stops in the true plant; the guard without its rescue broke each
# of them (by 0.7 to 3 mrad, most within the first period). Found by python -m cpbc.verify.
CASES = [("panda_cpbc_sphere", 1000.0, seed) for seed in (1, 5, 22, 51, 61)] + [
    ("panda_cpbc_ke_box", 1000.0, 106), ("panda_cpbc_ke_box", 1000.0, 140),
    ("panda_cpbc_ke_box", 100.0, 127)]


@pytest.mark.parametrize(("scenario", "rate", "seed"), CASES)
def test_the_guard_keeps_states_only_a_better_brake_can_stop(scenario, rate, seed):
    setup = build(*load_scenario(scenario))
    entry = next(e for e in setup.controllers if e.controller.type_name != "cbf_qp"
                 and not e.controller.constraints.empty)
    h = 1.0 / rate
    kept = kept_constraints(setup, entry, h, setup.safeguard)
    plant = RecordingPlant(setup.make_plant().model, setup.plant_settings)
    s = draw_state(setup, seed)
    assert not in_braking_set(setup, kept, s.position, s.velocity, h)
    assert stopping_brake(setup, kept, s.position, s.velocity, h, plant) is not None
    settings = replace(setup.loop_settings, duration=0.3,
        bounds=replace(setup.loop_settings.bounds, period=h), log_every=1,
                       noise=None)
    check = checked_run(plant, setup, entry, s.position, s.velocity, settings, kept,
                        safeguard=setup.safeguard)
    assert not check.violated, (check.constraint, check.min_margin)
    assert check.trajectory.rescues > 0  # the rescue held a brake, and the run counts it


def test_a_step_reaches_the_interval_of_its_rate_within_the_box(rng) -> None:
    """TorqueBox.around: |τ_q − τ_held| ≤ ρh inside the box, min(max(lower, τ_h − ρh), upper)
    and max(min(upper, τ_h + ρh), lower) — the interval nearest to the box where the held
    torque lies outside it (a limit lowered under it); the maps shared with the box."""
    box = TorqueBox(np.array([87.0, 87.0, 12.0]))
    step = np.full(3, 1.0)
    for held in (np.zeros(3), np.array([86.5, -87.0, 11.2]), np.array([90.0, -95.0, 0.0]),
                 rng.normal(scale=50.0, size=3)):
        low, high = box.around(held, step).bounds
        np.testing.assert_array_equal(low, np.minimum(np.maximum(-box.limit, held - step),
                                                      box.limit))
        np.testing.assert_array_equal(high, np.maximum(np.minimum(box.limit, held + step),
                                                       -box.limit))
        assert np.all(low <= high)
    narrowed = box.around(np.array([90.0, 0.0, 0.0]), step)
    assert narrowed.bounds[0][0] == narrowed.bounds[1][0] == 87.0  # the nearest: the limit
    np.testing.assert_array_equal(narrowed.clip(np.array([0.0, 5.0, -5.0])), [87.0, 1.0, -1.0])


def test_a_heavy_wrist_is_stopped_only_by_a_brake_that_leaves_its_friction() -> None:
    """The xArm7 with 2 N·m of dry friction on a 0.01 kg·m² wrist rotor, seed 0 at 1 kHz: the
    three brakes that cancel the model's friction keep joint 7 creeping (the plant's soft
    friction answers their push along the motion), and the same uniform brake held against
    b without the dry friction (brakes.holding_bias) brings the arm to rest in the plant."""
    path = Path(__file__).resolve().parents[1] / "tools" / "campaigns" / "xarm7_wrist_friction.yaml"
    setup = build(*load_scenario(str(path)))
    entry = next(e for e in setup.controllers if not e.controller.constraints.empty)
    kept = kept_constraints(setup, entry, 0.001, setup.safeguard)
    names = tuple(brakes(TorqueBox.of(setup.model, 20.0), kept, setup.model))
    assert names[3:] == tuple(name + FRICTION_LEFT for name in names[:3])
    s = draw_state(setup, 0)
    assert stopping_brake(setup, kept, s.position, s.velocity, 0.001) == "uniform" + FRICTION_LEFT


def _in_order(a: np.ndarray, b: np.ndarray) -> float:
    """Σ a_j b_j summed in the order of j: what a kernel's loop makes. numpy's ``a.dot(b)``
    is BLAS's ddot, whose order is its CPU kernel's: on an AVX-512 host it differed from
    the loop's in the last bit where an AVX2 one had not."""
    total = 0.0
    for x, y in zip(a.tolist(), b.tolist(), strict=True):
        total += x * y
    return total


@pytest.mark.parametrize("seed", range(3))
def test_the_aimed_row_is_numpy_s_argmin_and_a_sum_in_order_to_the_bit(seed: int) -> None:
    """``aim_row`` (the aimed brake's row, compiled) against the numpy it replaced: the
    approached margin of least stopping margin — ties to the first, a NaN before any number
    —, its gradient scaled to length 30 and the rate asked, equal to the bit (its products
    summed in order, :func:`_in_order`); none approached or a zero gradient: no row,
    nothing written."""
    from cpbc.kernels.stopping_test import aim_row
    rng = np.random.default_rng(seed)
    n, h, weight = 7, 1e-3, 30.0
    aimed_rows = 0
    for _ in range(300):
        k = int(rng.integers(1, 25))
        s, speed = rng.normal(size=k), rng.normal(size=k)
        s[rng.random(k) < 0.3] = s[0]  # ties
        for special in (np.nan, -np.inf):
            if rng.random() < 0.2:
                s[rng.integers(k)] = special
        grads = rng.normal(size=(k, n)) * 10.0 ** rng.uniform(-3, 3, (k, 1))
        if rng.random() < 0.1:
            grads[:] = 0.0
        dx = rng.normal(size=n)
        row, wanted = np.full(n, 7.0), np.full(1, 7.0)
        aimed = aim_row(s, speed, grads, dx, h, weight, row, wanted)
        approaching = np.flatnonzero(speed > 0)
        g = grads[approaching[np.argmin(s[approaching])]] if approaching.size else None
        norm = 0.0 if g is None else math.sqrt(_in_order(g, g))
        if norm == 0.0:
            assert not aimed and np.all(row == 7.0) and wanted[0] == 7.0
            continue
        expected = (weight / norm) * g
        assert aimed and np.array_equal(row, expected)
        assert wanted[0] == _in_order(expected, -dx) / h
        aimed_rows += 1
    assert aimed_rows > 200


def _nearest_stop_in_numpy(box: TorqueBox, state, bias: np.ndarray, h: float,
                           rows: np.ndarray | None, wanted: np.ndarray | None) -> np.ndarray:
    """The least-squares stop in the box as it was made from Python before its kernel
    (cpbc.kernels.stopping_test.nearest_stop): A = D⁻¹T⁻ᵀ and the targets with numpy's
    products, ``rows`` · ẍ = ``wanted`` on top, the compiled bounded least squares."""
    from cpbc.kernels.bounded_lsq import bounded_least_squares
    from cpbc.kernels.small_solves import inverse_inertia
    inv_d = inverse_inertia(state.inertia)
    a = np.ascontiguousarray(inv_d if box.from_joint is None else inv_d @ box.from_joint)
    free = a.dot(box.joint(bias))
    target = free - state.dx / h
    if rows is not None and wanted is not None:
        a = np.vstack((a, rows @ a))
        target = np.concatenate((target, wanted + rows @ free))
    tau_q = np.empty(a.shape[1])
    lower, upper = box.bounds
    bounded_least_squares(a, target, lower, upper, tau_q)
    return tau_q if box.from_joint is None else box.from_joint.dot(tau_q)


def _aimed_in_steps(box: TorqueBox, kept, model, state, bias: np.ndarray,
                    h: float) -> tuple[np.ndarray, bool]:
    """The aimed brake as the steps it was made of from Python gave it: the stopping terms,
    the aimed row (compiled), the least-squares stop in the box with numpy's products."""
    from cpbc.constraints.stopping import stopping_terms
    from cpbc.kernels.stopping_test import aim_row
    s, speed, _, grads = stopping_terms(kept, model, state, bias, box.limit)
    row, wanted = np.empty((1, len(state.dx))), np.empty(1)
    if not aim_row(s, speed, grads, state.dx, h, 30.0, row[0], wanted):
        return _nearest_stop_in_numpy(box, state, bias, h, None, None), False
    return _nearest_stop_in_numpy(box, state, bias, h, row, wanted), True


def test_the_aimed_brake_in_one_call_is_its_steps_to_the_bit(panda):
    """The aimed brake's one compiled call (cpbc.kernels.stopping_test.aimed_stop), and the
    least-squares brake's (nearest_stop), give the torques their steps gave from Python, to
    the bit: on the Panda among its spheres and joint
    limits, from drawn states at their rates and three times them, in the whole box and in
    a step's box under a rate limit; and on the thesis's arm in absolute link angles (a map
    to the joints, its products through T⁻ᵀ), where the aim is asked and where it is not."""
    from cpbc.bench import planar_2link
    from cpbc.constraints.brakes import aimed_brake
    from cpbc.constraints.constraint_set import ConstraintSet
    from cpbc.constraints.linear_limit import LinearLimit, joint_position_limit

    setup, entry = panda
    kept = kept_constraints(setup, entry, 0.001, setup.safeguard)
    model, rng, aimed = setup.model, np.random.default_rng(5), 0
    whole = TorqueBox.of(model, setup.loop_settings.bounds.torque)
    for seed in range(12):
        s = draw_state(setup, seed)
        for speed in (1.0, 3.0):
            state = kept.state(model, s.position, speed * s.velocity, motion=True)
            bias = state.coriolis_force + state.gravity + state.dissipation
            held = rng.uniform(-0.3, 0.3, 7) * whole.limit
            for box in (whole, whole.around(held, np.full(7, 1.0))):
                expected, with_row = _aimed_in_steps(box, kept, model, state, bias, 0.001)
                np.testing.assert_array_equal(aimed_brake(box, kept, model)(state, bias, 0.001),
                                              expected)
                np.testing.assert_array_equal(  # the least-squares brake: no row
                    least_squares_brake(box)(state, bias, 0.001),
                    _nearest_stop_in_numpy(box, state, bias, 0.001, None, None))
                aimed += with_row
    assert aimed >= 20

    arm = planar_2link()
    model = arm.controllers["cpbc"].model
    assert not model.coordinates.is_identity
    names = ["theta1", "theta2"]
    limits = ConstraintSet(2, [joint_position_limit([-0.5, -0.5], [3.5, 3.5], names),
                               LinearLimit([[-1, 1]], [-3.0], [3.0], ["relative"])], [])
    box, rows = TorqueBox.of(model, np.array([30.0, 20.0])), set()
    for x, dx in arm.states[:24]:
        state = limits.state(model, x, 4.0 * dx, motion=True)
        bias = state.coriolis_force + state.gravity
        expected, with_row = _aimed_in_steps(box, limits, model, state, bias, 0.001)
        np.testing.assert_array_equal(aimed_brake(box, limits, model)(state, bias, 0.001),
                                      expected)
        np.testing.assert_array_equal(least_squares_brake(box)(state, bias, 0.001),
                                      _nearest_stop_in_numpy(box, state, bias, 0.001, None,
                                                             None))
        rows.add(with_row)
    assert rows == {True, False}
