"""The joints' Coulomb friction: the levels F_c of the controller's model, checked once, and
how a plant's dry friction takes its sign (:class:`DryFriction`; the derivation is
cpbc.controllers.safeguard.model_error's docstring)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.errors import ModelError
from cpbc.kernels.friction_error import dry_force_error

# ε of the model's Coulomb friction F_c tanh(q̇/ε) [rad/s or m/s]: the rate below which the
# model's friction fades. A joint's smoothed friction is stiff in q̇ (slope F_c/ε), and the law
# feeds part of it forward once per control period (τ's c = C ẋ + f): at 0.05 rad/s the
# FR3's largest level (1.137 N·m) has slope 23 N·m·s/rad, h·F_c/(ε D_ii) ≈ 0.1 at 1 kHz for
# its lightest wrist (D_ii ≈ 0.2 kg·m² with armature) — no chatter of the feed-forward around
# q̇ = 0 — while at the joints' working rates (≥ 0.2 rad/s) tanh is within 2 % of the sign.
FRICTION_SMOOTHING = 0.05


def coulomb_levels(levels: Array | None, n: int) -> Array:
    """Each joint's Coulomb friction level, shape (n,), finite and ≥ 0 (read-only)."""
    fc = np.zeros(n) if levels is None else np.array(levels, dtype=float)
    if fc.shape == ():
        fc = np.full(n, float(fc))
    if fc.shape != (n,) or not np.all(np.isfinite(fc)) or np.any(fc < 0):
        raise ModelError(f"coulomb_friction must be {n} finite levels ≥ 0 (or one), "
                         f"got {levels}", "coulomb_friction")
    fc.setflags(write=False)
    return fc


# MuJoCo's default for a joint's frictionloss (solref 0.02, 1; solimp 0.9, 0.95): 1/b of
# cpbc.controllers.safeguard.model_error's docstring [s]
MUJOCO_BUILD_UP = 0.95 * 0.02 / 2.0
# d₀ of that default solimp: a frictionloss row's regulariser is R_j = (1 − d₀)/d₀ A_j
MUJOCO_IMPEDANCE = 0.9
# v_c = R_j F_j / b (R_j = (1 − d₀)/d₀ dof_invweight0): at most 0.033 rad/s on the UR5,
# 0.060 on the Panda, 0.145 on the FR3's last joint while the campaign plants' MuJoCo constants
# left out the rotor inertia; ≤ 0.008 on all three since (cpbc.model.joint_dynamics.on_mujoco).
# Kept as the least creep the guard assumes (model_error.mujoco_friction) [rad/s]
MUJOCO_CREEP = 0.15


@dataclass(frozen=True)
class DryFriction:
    """How the plant's dry friction takes its sign (cpbc.controllers.safeguard.model_error's
    docstring): exactly F_j sign(q̇_j) while |q̇_j| ≥ T_f α_j + v_c, anywhere in [−F_j, F_j]
    otherwise.

    Attributes:
        build_up: T_f [s] (MuJoCo: 1/b; an ideal Coulomb friction: 0).
        creep: v_c [rad/s], the largest speed at which the friction may not have built up
            to F_j at rest-free acceleration (MuJoCo: R_j F_j/b, from its constant diagonal
            estimate dof_invweight0; cpbc.controllers.safeguard.model_error.mujoco_friction
            takes it from the controller's model).
    """

    build_up: float = MUJOCO_BUILD_UP
    creep: float = MUJOCO_CREEP

    def force_error(self, levels: Array, smoothing: float, low: Array, high: Array,
                    deceleration: Array) -> Array:
        """e_j of model_error's docstring per joint: ``low``, ``high`` the least and largest
        |q̇_j| over the interval (s_j, S_j), ``deceleration`` α_j ≥ 0
        (cpbc.kernels.friction_error.slide_error)."""
        levels = np.asarray(levels, dtype=float)
        low, high, deceleration = (np.broadcast_to(np.asarray(v, dtype=float), levels.shape)
                                   for v in (low, high, deceleration))
        out = np.empty(levels.shape)
        dry_force_error(levels, smoothing, self.build_up, self.creep, low, high, deceleration,
                        out)
        return out


# MuJoCo's frictionloss with its default solref and solimp (the plant of cpbc and franky-sim)
MUJOCO_FRICTION = DryFriction()
