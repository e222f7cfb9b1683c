"""The compiled kernels: nopython only, equal to the numpy formulas they replace, and equal
to themselves run as plain Python (NUMBA_DISABLE_JIT=1, in a subprocess)."""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from cpbc.bench import planar_2link
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.controllers import CPBC, CPBCKineticEnergy
from cpbc.errors import ConstraintViolation
from cpbc.kernels.laws import cpbc_ke_torque, cpbc_torque

ROOT = Path(__file__).resolve().parents[1]
JIT_OFF = os.environ.get("NUMBA_DISABLE_JIT", "0") not in ("", "0")


@pytest.mark.skipif(JIT_OFF, reason="the kernels run as Python here")
def test_every_kernel_is_compiled_in_nopython_mode() -> None:
    from cpbc.kernels.__main__ import kernels, problems

    assert len(list(kernels())) >= 7
    assert problems() == []


def _reference_cpbc(inertia, gravity, bias, force, gradient, weight, rho):
    """The numpy code the kernel replaced: a = force + ρ b, τ = g + c + D (D + ρΠ)⁻¹ (a − c)."""
    a = force + rho * gradient
    if weight is None:
        return gravity + a
    return gravity + bias + inertia @ np.linalg.solve(inertia + rho * weight, a - bias)


@pytest.mark.parametrize("n", [1, 2, 6, 7])
def test_law_kernels_equal_the_numpy_formulas(n: int) -> None:
    rng = np.random.default_rng(n)
    for _ in range(50):
        m = rng.normal(size=(n, n))
        inertia = m @ m.T + 0.1 * np.eye(n)
        w = rng.normal(size=(n, n))
        weight = w @ w.T
        g, c, f, b = (rng.normal(size=n) for _ in range(4))
        rho = float(rng.uniform(0.0, 5.0))
        for wt in (weight, None):
            tau = np.empty(n)
            cpbc_torque(inertia, g, c, -f, np.zeros(n), b,
                        np.zeros((n, n)) if wt is None else wt,
                        wt is not None, rho, tau)
            np.testing.assert_allclose(tau, _reference_cpbc(inertia, g, c, f, b, wt, rho),
                                       rtol=1e-12, atol=1e-12)
        psi = float(rng.uniform(0.01, 3.0))
        tau = np.empty(n)
        cpbc_ke_torque(g, -f, np.zeros(n), b, rho, psi, tau)
        np.testing.assert_allclose(tau, g + (f + rho * b) / (1.0 + rho / psi), rtol=1e-12,
                                   atol=1e-12)


def test_an_indefinite_matrix_is_solved_by_elimination() -> None:
    """D + ρΠ is positive definite in theory; when rounding makes it not, the kernel solves
    by Gaussian elimination as numpy.linalg.solve would."""
    inertia = np.array([[1.0, 2.0], [2.0, 1.0]])  # indefinite
    g, c, f = np.array([0.5, -0.2]), np.array([0.1, 0.3]), np.array([1.0, 2.0])
    tau = np.empty(2)
    cpbc_torque(inertia, g, c, -f, np.zeros(2), np.zeros(2), np.zeros((2, 2)), True, 0.0, tau)
    np.testing.assert_allclose(tau, _reference_cpbc(inertia, g, c, f, np.zeros(2),
                                                    np.zeros((2, 2)), 0.0), rtol=1e-12)


def _law_reference(law, state) -> np.ndarray:
    """τ of CPBC / CPBC-KE from the generic (numpy) barrier formulas of the base classes."""
    config = [c for c in law.constraints.configuration]
    phis, b = [], np.zeros(law.model.n)
    for c in config:
        phi, grad, _ = ConfigurationConstraint.barrier_terms(c, state)
        phis.append(phi)
        b = b + grad
    _, du = law.potential.evaluate(state)
    dx = state.dx
    kinetic = 0.5 * float(dx @ state.inertia @ dx)
    lag = kinetic + law.potential.evaluate(state)[0]
    force = -du - law.damping.force(dx) - law.task_damping_force(state)
    log_phi = sum(math.fsum(np.log(p)) for p in phis)
    if isinstance(law, CPBCKineticEnergy):
        psi = law.energy.limit - kinetic
        rho = law.shaping.ratio(log_phi + math.log(psi)) * lag
        return state.gravity + (force + rho * b) / (1.0 + rho / psi)
    weight, log_psi = None, 0.0
    for v in law.constraints.velocity:
        psi, pi, bv = VelocityConstraint.barrier_terms(v, state)
        log_psi += math.fsum(np.log(psi))
        weight = pi if weight is None else weight + pi
        b = b + bv
    rho = law.shaping.ratio(log_phi + log_psi) * lag
    bias = state.coriolis_force + state.dissipation
    return _reference_cpbc(state.inertia, state.gravity, bias, force, b, weight, rho)


def test_law_torques_equal_the_numpy_formulas_at_random_states() -> None:
    """The planar bench's laws (thesis constraints, KE limits, shaping) at its states and at
    random ones: the compiled torque equals the numpy formulas to 1e-12."""
    setup = planar_2link()
    rng = np.random.default_rng(7)
    states = list(setup.states) + [(rng.uniform(-1, 1, 2), rng.uniform(-0.5, 0.5, 2))
                                   for _ in range(40)]
    checked = 0
    for name, law in setup.controllers.items():
        if not isinstance(law, CPBC | CPBCKineticEnergy):
            continue
        for x, dx in states:
            state = law.state(x, dx)
            try:
                tau = law.evaluate_state(state).torque
            except ConstraintViolation:
                continue
            np.testing.assert_allclose(tau, _law_reference(law, state), rtol=1e-12,
                                       atol=1e-12, err_msg=name)
            checked += 1
    assert checked >= 100


SCRIPT = """
import json, sys
import numpy as np
sys.path.insert(0, "tests")
from bounded_goal import bounded_goal_laws
from cpbc.bench import planar_2link, taskspace_pair
from cpbc.bench_arms import panda
from cpbc.errors import ConstraintViolation
out = {}
laws, states = taskspace_pair(states=8)
bounded, bounded_states = bounded_goal_laws(states=8)
sets = [(s.robot, s.controllers, s.states) for s in (planar_2link(), panda(states=8))]
for robot, controllers, picked in sets + [("panda_goal_pose", laws, states),
                                          ("panda_goal_bpbc", bounded, bounded_states)]:
    for name, law in controllers.items():
        for i, (x, dx) in enumerate(picked[:8]):
            try:
                out[f"{robot}/{name}/{i}"] = law.torque(x, dx).tolist()
            except ConstraintViolation:
                pass
# the bounded task terms' own methods (their kernels, outside the law's step)
law = bounded["bpbc"]
for i, (x, dx) in enumerate(bounded_states):
    state = law.state(x, dx)
    for k, part in enumerate(law.potential.parts):
        value, grad = part.evaluate(state)
        out[f"panda_goal_bpbc/potential/{k}/{i}"] = [value, *grad.tolist()]
    out[f"panda_goal_bpbc/task_damping/{i}"] = law.task_damping.force(state, dx).tolist()
# the guard's kernels (cpbc.kernels.sampled_guard): its accept path, and blends, brakes and box
# scalings from the law's torque pushed off by a fixed noise (the guard's own entry point)
from cpbc.controllers.safeguard import SafeguardSettings, guarded
from cpbc.model.input_bounds import InputBounds
setup = panda(states=8)
rng = np.random.default_rng(5)
for period in (0.001, 0.01):
    guard = guarded(setup.controllers["cpbc"], InputBounds(period, setup.torque_limit),
                    SafeguardSettings())
    for i, (x, dx) in enumerate(setup.states[:8]):
        state = guard.state(x, dx)
        law = guard.law.evaluate_state(state, margins=True)
        for push in (0.0, 3.0, 30.0):
            tau = law.torque + push * rng.standard_normal(len(x))
            out[f"guard/{period}/{i}/{push}"] = guard.filter(state, tau, law.margins).tolist()
    out[f"guard/{period}/counts"] = [guard.acted, guard.scaled]
# the CBF-QP peer's per-pair rows (cpbc.kernels.clearance_motion.sphere_pair_rows), from the state
from cpbc.constraints.clearance import Clearance
law = setup.controllers["cpbc"]
clearance = next(c for c in law.constraints.configuration if isinstance(c, Clearance))
for i, (x, dx) in enumerate(setup.states[:8]):
    phi, grad, curv, _ = clearance.sphere_pairs_at(law.state(x, dx))
    out[f"sphere_pairs/{i}"] = np.concatenate([phi, grad.ravel(), curv]).tolist()
json.dump(out, sys.stdout)
"""


def _torques(jit_off: bool) -> dict[str, list[float]]:
    env = dict(os.environ, NUMBA_DISABLE_JIT="1" if jit_off else "0")
    done = subprocess.run([sys.executable, "-c", SCRIPT], cwd=ROOT, env=env, check=True,
                          capture_output=True, text=True, timeout=600)
    return json.loads(done.stdout)


def test_the_kernels_run_uncompiled_give_the_same_torques() -> None:
    """Every bench law (planar and Panda, panda_goal_pose's task-space and joint CPBC, and
    its goal in task-space BPBC and BPBC-KE, tests/scenarios/panda_goal_bpbc.yaml), the
    Panda's guard accepting, blending and scaling into the torque box, and the CBF-QP
    peer's per-pair sphere rows (φ, ∇φ, κ), with the kernels compiled and run as plain
    Python (NUMBA_DISABLE_JIT=1): the same torques (guard decisions, rows) to 1e-12."""
    compiled, plain = _torques(False), _torques(True)
    assert compiled.keys() == plain.keys() and len(compiled) >= 40
    assert sum(k.startswith("panda_goal_bpbc/") for k in compiled) == 16 + 4 * 8
    for period in ("0.001", "0.01"):
        acted, scaled = compiled[f"guard/{period}/counts"]
        assert acted >= 4 and scaled >= 2, (period, acted, scaled)
    for key, tau in compiled.items():
        np.testing.assert_allclose(tau, plain[key], rtol=1e-12, atol=1e-12, err_msg=key)


def test_a_changed_kernel_source_drops_the_cached_kernels(tmp_path: Path) -> None:
    """numba keys a cached kernel on its own file: after any kernel source changes, the
    package's cached kernels are dropped (a caller compiled against the old callee would
    compute with its old formula), and kept while nothing changes."""
    from cpbc.kernels import STAMP, drop_stale_cache

    (tmp_path / "a.py").write_text("x = 1\n")
    (tmp_path / "b.py").write_text("y = 2\n")
    cache = tmp_path / "__pycache__"
    cache.mkdir()

    def cached() -> None:
        for name in ("a.f-1.py311.nbi", "a.f-1.py311.1.nbc"):
            (cache / name).write_bytes(b"compiled")

    cached()
    assert drop_stale_cache(tmp_path)  # no stamp yet: nothing known about them
    assert not list(cache.glob("*.nb?")) and (cache / STAMP).exists()
    cached()
    assert not drop_stale_cache(tmp_path)
    assert len(list(cache.glob("*.nb?"))) == 2
    (tmp_path / "b.py").write_text("y = 3\n")  # the callee's module changed
    assert drop_stale_cache(tmp_path)
    assert not list(cache.glob("*.nb?"))


def test_warm_says_each_module_as_it_is_compiled() -> None:
    from cpbc.kernels.__main__ import MODULES, kernels, warm

    lines: list[str] = []
    every = warm(lines.append)
    assert len(lines) == len(MODULES)
    counts = []
    for i, (line, name) in enumerate(zip(lines, MODULES, strict=True), 1):
        head, _, rest = line.partition(": ")
        assert head == f"[{i}/{len(MODULES)}] {name}", line
        counts.append(int(rest.split(" kernels, ")[0]))
    assert sum(counts) == len(every) == len(list(kernels()))
    assert all(counts)  # every module holds kernels of its own


def test_warm_compiles_each_module_after_the_kernel_modules_it_imports() -> None:
    """Importing a module compiles the kernel modules it imports first: in MODULES' order,
    each step of the progress compiles only its own kernels."""
    import ast

    from cpbc.kernels.__main__ import MODULES

    folder = Path(__file__).parents[1] / "cpbc" / "kernels"
    for i, name in enumerate(MODULES):
        tree = ast.parse((folder / f"{name.rsplit('.', 1)[1]}.py").read_text())
        imported = {node.module for node in ast.walk(tree)
                    if isinstance(node, ast.ImportFrom) and node.module in MODULES}
        assert imported <= set(MODULES[:i]), (name, imported - set(MODULES[:i]))


def test_the_brake_path_under_a_ramp_is_the_frozen_dynamics_path() -> None:
    """configuration_rows' stopping rows under a torque-rate limit: the ramp's points are
    where x'' = a_∥⁺ ê + a_⊥ (1 − t/T) takes the arm at even times (integrated here step by
    step, not by the kernel's closed form), the rest evenly along the brake from x(T) on
    ẋ(T), the stopping point the last; with no acceleration across the motion that point is
    the straight path's |ẋ₁|T + ½a⁺T² + (|ẋ₁| + ½a⁺T)²/(2θA) along ê; without a ramp the
    points divide x₁ → x₁ + (|ẋ₁|/(2θA)) ẋ₁ evenly."""
    from cpbc.kernels.braking_path import configuration_rows

    rng = np.random.default_rng(7)
    n, h, per_speed, ramp, points = 7, 0.001, 0.004, 0.09, 4
    for across_too in (True, False):
        ends, mids = rng.normal(size=(2, n)), rng.normal(size=(2, n))
        speeds = rng.normal(size=(2, n))
        push = 0.2 * rng.normal(size=n)
        if not across_too:  # the period's acceleration along the first row's motion only
            push = 0.3 * speeds[0]
        start = speeds[0] - push
        rows = np.empty(((2 + points) * 2, n))
        configuration_rows(mids, ends, speeds, start, h, per_speed, ramp, rows)
        np.testing.assert_array_equal(rows[:2], mids)
        np.testing.assert_array_equal(rows[2:4], ends)
        for j in range(2):
            speed = np.linalg.norm(speeds[j])
            e = speeds[j] / speed
            a = (speeds[j] - start) / h
            along = e @ a
            across = a - along * e
            x, v, dt, t = ends[j].copy(), speeds[j].copy(), ramp / 20000, 0.0
            path = []
            for k in range(1, points // 2 + 1):
                while t < k * ramp / (points // 2) - 1e-12:  # midpoint steps of x'' (t)
                    acc = max(along, 0.0) * e + across * (1.0 - (t + 0.5 * dt) / ramp)
                    x, v, t = x + dt * v + 0.5 * dt * dt * acc, v + dt * acc, t + dt
                path.append(x.copy())
            # the ramp's speed along ê credits no deceleration and keeps only half of a⁺T
            v = (speed + 0.5 * max(along, 0.0) * ramp) * e + 0.5 * ramp * across
            stop = per_speed * np.linalg.norm(v) * v
            path += [x + (k + 1) / (points - points // 2) * stop
                     for k in range(points - points // 2)]
            got = rows[[(2 + k) * 2 + j for k in range(points)]]
            np.testing.assert_allclose(got[: points // 2], np.array(path[: points // 2]),
                                       atol=1e-7)
            np.testing.assert_allclose(got[points // 2:], np.array(path[points // 2:]),
                                       atol=1e-6)
            if not across_too and j == 0:
                lead = max(along, 0.0)
                travel = (speed * ramp + 0.5 * lead * ramp ** 2
                          + (speed + 0.5 * lead * ramp) ** 2 * per_speed)
                np.testing.assert_allclose(got[-1], ends[0] + travel * e, atol=1e-9)
        straight = np.empty(((2 + points) * 2, n))
        configuration_rows(mids, ends, speeds, start, h, per_speed, 0.0, straight)
        for j in range(2):
            stop = per_speed * np.linalg.norm(speeds[j]) * speeds[j]
            for k in range(points):
                np.testing.assert_allclose(straight[(2 + k) * 2 + j],
                                           ends[j] + (k + 1) / points * stop, atol=1e-12)
