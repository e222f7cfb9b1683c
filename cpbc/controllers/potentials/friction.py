"""The potential that beats the joints' Coulomb friction near the set point.

A joint-space law's spring pulls K_P x̃ at an error x̃; where that is less than the joint's
dry friction F_c the arm sticks, |x̃| ≤ F_c/K_P short of the target (0.13–0.26 rad on an FR3
with the thesis's gains). The term added here is a second potential toward the same set
point, the ln cosh spring of eq. 7.18 with stiffness F̂_c and ξ = 1/ε_c:

    U_f(x̃) = Σ F̂_c,i ε_c ln cosh(x̃_i/ε_c),   ∂U_f/∂x = F̂_c tanh(x̃/ε_c)

Its force rises to the model's Coulomb level F̂_c within a few ε_c of the target, so the
total pull K_P x̃ + F̂_c tanh(x̃/ε_c) exceeds F_c ≤ F̂_c everywhere outside a band of a few
ε_c: the stall band shrinks from F_c/K_P to about ε_c ln(2F_c/(K_P ε_c))/2 (1.5 mrad on
the FR3's base joints with ε_c = 1 mrad).

Why the constraint guarantee still holds: U + U_f is a potential of the kind Theorems 6.9
and 7.7 (and Corollaries 6.11, 7.8) take — non-negative, zero only at x_d, inside S — and
their proofs use U only through U ≥ 0 and ∂U/∂x. So V = (½ẋᵀDẋ + U + U_f)/s stays a
Lyapunov function, V̇ = −ẋᵀ(K_D ẋ + f)/s ≤ 0 for any dissipative friction f (ẋᵀf ≥ 0,
whatever its level), V stays bounded along the loop and the barriers keep the state in S.
No torque is fed forward: nothing pushes the arm along its rate, so there is no energy
injection for the barriers to fight and no sign to guess at q̇ = 0. For the bounded laws
(Theorem 7.7) ∂U_f/∂x is bounded by F̂_c, so their torque bound grows by F̂_c (the sum's
``gradient_bound``). It is a joint-space term: a goal law's task springs do not settle at
its posture x_n, so a term toward x_n would bias the pose instead of beating the friction.
"""

from __future__ import annotations

import numpy as np

from cpbc.arrays import Array
from cpbc.controllers.potentials.joint import JointLogCoshSpring

#: ε_c [rad]: the stall band is a few ε_c wide, and the term's stiffness at the target is
#: F̂_c/ε_c (1137 N·m/rad for 1.137 N·m): with an FR3's wrist (D_ii ≈ 0.08 kg·m² with its
#: rotor) ω h = √(2000/0.08)·0.001 ≈ 0.16 at 1 kHz for 2 N·m, well inside the held loop's
#: stable range (cpbc.scenario.gain_check), and the band (≈ 2 mrad) inside the 5 mrad a
#: reach is judged by.
FRICTION_COMPENSATION_WIDTH = 0.001


def friction_compensation(target: Array, coulomb: Array,
                          width: float = FRICTION_COMPENSATION_WIDTH) -> JointLogCoshSpring | None:
    """U_f toward ``target`` for the joints' Coulomb levels ``coulomb`` F̂_c (controller
    coordinates = the joints'), ε_c = ``width``; None when no joint has friction. A joint
    without friction gets a vanishing stiffness (the spring's K must be > 0), which adds
    nothing measurable."""
    levels = np.asarray(coulomb, dtype=float)
    if not np.any(levels > 0):
        return None
    # a joint without friction: K = 1e-12 of the largest level, nothing a torque would show
    stiffness = np.maximum(levels, 1e-12 * float(levels.max()))
    return JointLogCoshSpring(target, stiffness, np.full(levels.shape, 1.0 / width))
