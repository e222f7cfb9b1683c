"""A sampled-data safeguard for the constrained laws: keep S invariant under zero-order hold.

The theorems of Chapters 6–7 hold in continuous time. A real controller holds its torque
for a control period h; near a barrier the shaped law is stiff, and one held torque can carry
the state across ∂S, where every log and division of the law is undefined. The safeguard
wraps a constrained law and, at every control instant,

1. asks the law for τ₀ = k(x, ẋ) and corrects it for the hold, τ₀ − s D Δa
   (:mod:`cpbc.controllers.hold`: the law's acceleration of the sample kept on average over
   the period, not its torque; ``hold_correction``), by the share s of the drift Δa the
   plant has (½ in continuous time, 0 for a plant that steps once per period by
   semi-implicit Euler; ``plant_step``). Should the corrected torque fail the test below
   while τ₀ passes it, the correction is what fails, not the law: the guard keeps as much
   of it as the test allows and does not act;
2. predicts the state half a period and one period ahead under the held τ with the
   controller's own model, in closed form with the dynamics frozen at the sample,

       a = D⁻¹(τ − C ẋ − g − f),   x(t) = x + t ẋ + ½t² a,   ẋ(t) = ẋ + t a

   except that the period's end is x + hẋ + ½(1 + 1/k)h² a for a plant that takes k
   one-stage (semi-implicit Euler) steps a period (``plant_step``; x + hẋ + h² a at one
   step: where that plant lands, which ½h² a misses by ½h² a on every margin); or, for
   periods longer than ``max_step`` (1 ms), in ⌈h/max_step⌉ semi-implicit Euler steps of
   the model's forward dynamics;
3. accepts τ₀ when every predicted margin keeps its share of the present one — a discrete-time
   barrier condition on margins tightened by a cushion δ_i,

       m_i(h) − δ_i ≥ e^{−κh} (m_i − δ_i)       for every φ_i and ψ_j              (S1)
       φ_i(h/2) − δ_i ≥ e^{−κh/2} (φ_i − δ_i)   for every φ_i (between the samples)
       ψ_j(t) − δ_j ≥ e^{−κh} (ψ_j − δ_j)       at every predicted instant t inside the
                                                period (h/2, or every sub-step)

   so no margin may shrink faster than at the rate κ [1/s], and below the cushion a margin
   must grow. The cushion δ_i = η (h / 10 ms) |m_i(x_d, 0)| is a fraction of the margin at
   the target at rest (its size, for a constraint only the guard keeps that has the target
   beyond it): a tightening scaled to the period that absorbs what the frozen prediction
   gets wrong (it is what keeps a margin from being driven to zero where a prediction error
   of 10⁻⁸ would cross it);
4. otherwise, first, blends toward the law's torque less its push into the configuration
   boundaries (:meth:`Safeguard._slide`: its acceleration projected onto the half-spaces
   (S1) asks of each margin), so that a law pressing against a boundary goes on along it
   instead of being braked to rest there; if that fails (S1) too, it
   blends toward a braking torque that stops the model's motion in one period,

       τ_b = C ẋ + g + f − λ D ẋ / h,     τ(β) = (1 − β) τ₀ + β τ_b,   β ∈ [0, 1]

   and takes the smallest β that satisfies (S1), found by a fixed number of Illinois
   (regula falsi) steps on F(β) = min_i [m_i(β)/floor_i] − 1 between β = 0 (the law) and
   β = 1 (the brake): no QP, no optimiser, a bounded number of closed-form predictions.

With λ = 1 the braking prediction has ẋ⁺ = 0 and x⁺ = x + ½hẋ: every rate and kinetic-energy
margin grows, and configuration margins change by at most half the coasting motion. When
that is not enough, the brake becomes λ = 2, which predicts x⁺ = x and ẋ⁺ = −ẋ with the
smallest excursion towards ∂S that keeps the speed (¼hẋ, at mid-period). Stopping can go
too far while reversing at full speed breaks a velocity margin (a model error of a few
percent in the energy is enough); then a golden-section search of λ ∈ (1, 2) (excursion
hẋ/(2λ), end speed |1 − λ|·|ẋ|) looks for a brake in between. If no brake satisfies (S1)
the step is counted as *infeasible*, and the safeguard takes the smallest λ that keeps
every margin above its cushion (S0: m_i ≥ δ_i at mid-period and at the end) — the calmest
brake, so that the arm is not bounced off the boundary period after period. One λ for
every joint fails where a joint is closer to its limit than its cushion and heading in
while another leaves its own: reversal sends the second back at its limit. Then an
*escape* brake, which ends the period at a velocity that pushes off the nearby configuration
boundaries and merely stops the rest (:meth:`Safeguard._escape`), is taken if it keeps
(S−): configuration margins recover as (S1) asks at the end of the period, and shrink
at mid-period by no more than the decay share. Otherwise the λ that comes closest to (S0).
A state whose distance to a configuration boundary is less than ¼h of its approach speed
cannot be kept inside by any held torque that respects the rate bounds (:func:`viable`);
such states are outside what sampled-data control can promise.

Under bounded torque (``torque_limit``) a margin can be lost long before one period shows
it: the arm may be too fast to stop before the boundary. The guard then also holds the
*braking margins* σ_i = φ_i(x_s) of :class:`cpbc.constraints.stopping.Braking` — the
configuration margins where the uniform brake, the one the guard blends toward, would stop
the arm — above their cushions at the predicted end of the period:

    σ_i(h) ≥ δ_i                                                                      (S2)

so the state stays in the braking set V = {σ > 0}, from which the brake within the box can
stop the arm before every configuration boundary. The uniform brake lets the joint with the
least torque to spare set every joint's deceleration; where it fails (a state outside V, or
one no torque of the guard's own keeps in it) the *rescue* (:mod:`cpbc.controllers.rescue`)
holds the first of the least-squares, aimed and uniform brakes of
:mod:`cpbc.constraints.brakes` that, held in the model at the control rate until the arm
rests, keeps every guarded margin above its cushion throughout; only where none does is the
step answered by the fallback below. Initial states outside V are refused by the scenario
builder; campaigns (which start anywhere) class states by whether some brake stops them in the
true plant.

The wrapper returns the (hold-corrected) law's torque whenever the prediction satisfies (S1). It
is pure (no simulator) like the laws it wraps, so the same object could drive a real arm
at its control rate. The law's torque bound (Theorem 7.7, Corollary 7.8) does not cover
τ_b; the wrapper's ``torque_bound`` is None.
"""

from cpbc.controllers.safeguard.guard import Safeguard, guarded
from cpbc.controllers.safeguard.prediction import Predictor
from cpbc.controllers.safeguard.settings import SafeguardSettings, viable

__all__ = ["Predictor", "Safeguard", "SafeguardSettings", "guarded", "viable"]
