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

   or, for periods longer than ``max_step`` (1 ms), in ⌈h/max_step⌉ semi-implicit Euler
   steps of the model's forward dynamics;
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

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array
from cpbc.constraints.base import ConfigurationConstraint
from cpbc.constraints.brakes import TorqueBox
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.stopping import Braking
from cpbc.controllers.base import Controller, Evaluation, SafetyFilter
from cpbc.controllers.hold import hold_corrected, hold_share
from cpbc.controllers.linalg import solve_spd
from cpbc.controllers.rescue import Rescue
from cpbc.errors import CpbcError
from cpbc.model.robot_model import ArmState, RobotModel

# (mid-period positions, end positions, end rates, then positions and rates inside the
# period), one row per prediction (per prediction and sub-step for the inner ones)
Predictor = Callable[[Array], "tuple[Array, Array, Array, Array, Array]"]


@dataclass(frozen=True)
class SafeguardSettings:
    """Parameters of the sampled-data safeguard.

    Attributes:
        decay_rate: κ [1/s] of (S1): over one period h a tightened margin keeps at least
            e^{−κh} of its value. Larger is more permissive.
        cushion: η, the cushion as a fraction of each margin's value at the target at rest,
            for a 10 ms period (it scales linearly with the period).
        braking: λ > 0 of the braking torque (λ = 1 stops the model's motion in one period).
        substeps: 1 for the closed-form prediction with the dynamics frozen at the sample;
            k > 1 for k semi-implicit Euler steps of the model's forward dynamics.
        max_step: the longest prediction step [s]: a period longer than this is predicted
            in ⌈h / max_step⌉ sub-steps whatever ``substeps`` says (over 10 ms a 7-joint
            arm's acceleration changes too much for the frozen prediction).
        backoffs: Illinois steps on β when the law's torque fails (S1) (≥ 1).
        brake_search: predictions spent searching the braking factor λ between stopping
            and reversing when neither satisfies (S1) (0: none).
        velocity_cushion: η for the velocity margins (rates, kinetic energy), None: the same
            as ``cushion``. A thicker one keeps a law riding a velocity bound further from
            it, where its inertia shaping D + ρΠ leaves it more authority; the hold correction
            is what keeps such a law's margin from being worn down (README, "A law that rides
            a rate bound").
        hold_correction: test and hold τ − ½ D Δa instead of the law's τ
            (:func:`cpbc.controllers.hold.hold_corrected`):
            the law's acceleration of the sample kept on average over the period, to first
            order, as the continuous-time law asks. Without it a law that rides a rate bound
            loses its margin to the hold error (README, "A law that rides a rate bound").
        plant_step: the step [s] of a plant integrated by a one-stage (semi-implicit Euler)
            integrator (MuJoCo's Euler, implicit, implicitfast), None for an arm in
            continuous time or an RK4 plant. It sets s of the hold correction τ − s D Δa,
            the share of the period's drift Δa the plant's acceleration has on average
            (:func:`cpbc.controllers.hold.hold_share`): ½ in continuous time, 0 for a plant
            stepped once per period, which holds the sample's acceleration exactly.
        corrector: with the closed-form prediction, also predict to second order (the
            model's acceleration evaluated once more at the predicted end, taken as linear
            over the period, Heun's) and hold every margin under both predictions. The
            frozen one is what a semi-implicit Euler step of the plant does; the corrected
            one is nearer continuous time (a real arm, RK4): on a 7-joint arm near its rate
            bounds the acceleration changes enough within 1 ms (Coriolis terms of fast
            joints) that the frozen one alone misses a rate margin by more than its cushion.
    """

    decay_rate: float = 50.0
    cushion: float = 1e-3
    braking: float = 1.0
    substeps: int = 1
    max_step: float = 0.001
    backoffs: int = 6
    brake_search: int = 5
    corrector: bool = True
    velocity_cushion: float | None = None
    hold_correction: bool = True
    plant_step: float | None = None

    def __post_init__(self) -> None:
        for name in ("decay_rate", "braking"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise CpbcError(f"safeguard {name} must be > 0, got {v}")
        for name in ("cushion", "velocity_cushion"):
            v = getattr(self, name)
            if v is not None and not (math.isfinite(v) and 0 <= v < 1):
                raise CpbcError(f"safeguard {name} must be in [0, 1), got {v}")
        if self.plant_step is not None and not (math.isfinite(self.plant_step)
                                                and self.plant_step > 0):
            raise CpbcError(f"safeguard plant_step must be > 0, got {self.plant_step}")
        if self.substeps < 1 or self.backoffs < 1:
            raise CpbcError("safeguard substeps and backoffs must be ≥ 1")
        if self.brake_search < 0:
            raise CpbcError(f"safeguard brake_search must be ≥ 0, got {self.brake_search}")
        if not (math.isfinite(self.max_step) and self.max_step > 0):
            raise CpbcError(f"safeguard max_step must be > 0, got {self.max_step}")

    def steps_for(self, period: float) -> int:
        """Prediction sub-steps for a control period."""
        return max(self.substeps, math.ceil(period / self.max_step - 1e-9))

    def keep_fraction(self, period: float) -> float:
        """e^{−κh}: the share of each tightened margin (S1) requires after one period."""
        return math.exp(-self.decay_rate * period)


def viable(constraints: ConstraintSet, x: Array, dx: Array, period: float) -> bool:
    """Whether some held torque that keeps every speed can keep (x, ẋ) inside S over one
    period, to first order: the configuration margins at x + ¼hẋ — the least excursion
    towards ∂S of a constant deceleration that ends at speed |ẋ| (reversal, λ = 2) — are > 0.

    A state that fails this is in S but cannot be kept in S by sampled-data control at
    period h; the reliability campaigns count such states apart.
    """
    if not constraints.configuration:
        return True
    probe = x + 0.25 * period * dx
    return bool(np.all(constraints.configuration_margins(probe) > 0))


def guarded(
    law: Controller,
    period: float,
    settings: SafeguardSettings | None,
    torque_limit: Array | float | None = None,
    also_keep: Sequence[ConfigurationConstraint] = (),
) -> Controller:
    """The law as a sampled-data loop at period h should run it: wrapped in a Safeguard with
    ``settings`` when it enforces constraints, else the law itself (also with no settings).

    ``torque_limit`` is the plant's joint torque saturation (a number or one per joint)."""
    if isinstance(law, SafetyFilter):  # a filter already (a peer): fresh counts, no wrap
        return law.restarted()
    if settings is None or law.constraints.empty:
        return law
    limit = None if torque_limit is None else np.broadcast_to(
        np.asarray(torque_limit, dtype=float), (law.model.n,))
    return Safeguard(law, period, settings, limit, also_keep)


class Safeguard(SafetyFilter):
    """Wraps a constrained law so that (S1) holds under zero-order hold at period h.

    Args:
        law: the constrained law (its ``constraints`` and ``model`` are used).
        period: control period h [s].
        settings: κ, λ, prediction sub-steps, back-off steps.
        torque_limit: joint torque limits |τ_q| ≤ limit (the actuators'), shape (n,). Every
            torque the safeguard returns or predicts with lies in this box: the law's torque,
            the brakes and the escape are scaled toward C ẋ + g + f until they fit
            (:meth:`_box`), which keeps the direction of the acceleration they ask for.
        also_keep: configuration constraints the law does not enforce (obstacles it does
            not know of, the plant's joint ranges) that the safeguard keeps as well: (S1)
            on them makes it brake before the arm reaches them. Those the law enforces
            already are skipped.

    Attributes:
        calls: control instants seen.
        acted: instants at which the law's torque was replaced (β > 0).
        infeasible: instants at which even the braking torque failed (S1).
        scaled: instants at which the law's torque was outside the torque box and was scaled
            into it (it is then tested as scaled).
        uncorrected: instants at which the hold-corrected torque failed (S1) and the law's
            own torque kept it: the guard held a blend of the two, with as much of the
            correction as (S1) allows (not counted as acting: the torque is the law's).
    """

    type_name = "safeguard"

    def __init__(
        self,
        law: Controller,
        period: float,
        settings: SafeguardSettings | None = None,
        torque_limit: Array | None = None,
        also_keep: Sequence[ConfigurationConstraint] = (),
    ) -> None:
        if not (math.isfinite(period) and period > 0):
            raise CpbcError(f"safeguard period must be > 0, got {period}")
        super().__init__(law.model, law.target, law.constraints)
        self.law = law
        self.period = float(period)
        self.settings = settings or SafeguardSettings()
        self.keep = self.settings.keep_fraction(self.period)
        self.keep_half = math.sqrt(self.keep)
        self.substeps = self.settings.steps_for(self.period)
        # s of the hold correction τ − s D Δa: the drift the plant's hold has (hold.py)
        self.hold_share = hold_share(self.period, self.settings.plant_step) \
            if self.settings.hold_correction else 0.0
        own = law.constraints
        seen = set(own.names)  # a constraint the law enforces already, or a repeat, is skipped
        extra = []
        for c in also_keep:
            if seen.isdisjoint(c.names):
                extra.append(c)
                seen.update(c.names)
        # the constraints the guard keeps: the law's own, and the extra configuration ones
        self.guarded = own if not extra or own.empty else ConstraintSet(
            own.n, (*own.configuration, *extra), own.velocity)
        self._extra = ConstraintSet(own.n, extra) if extra and not own.empty else None
        at_target = self.guarded.margins(law.target, np.zeros(law.model.n))
        scale = self.settings.cushion * self.period / 0.01
        # δ_i; a constraint only the guard keeps may have the target beyond it (a joint limit
        # the law does not know of between it and its target): the size of its margin there
        self.cushion = scale * np.abs(at_target)
        nc = self.guarded.n_configuration
        if self.settings.velocity_cushion is not None:
            self.cushion[nc:] = (self.settings.velocity_cushion * self.period / 0.01
                                 * np.abs(at_target[nc:]))
        self._n_config = nc
        self._n_own_config = own.n_configuration
        self.torque_limit = None if torque_limit is None else np.asarray(torque_limit, float)
        self._torque_box = None if torque_limit is None else TorqueBox.of(law.model,
                                                                          torque_limit)
        # under bounded torque the guard also keeps the braking margins σ (stopping.Braking)
        self.braking = None if torque_limit is None or not self._n_config else Braking.of(
            law.model, torque_limit)
        self._sigma_floor = np.maximum(self.cushion[: self._n_config], 1e-300)
        # where no torque of its own will do: brakes better than the uniform one (rescue.py)
        self.rescue = None if self.braking is None or self._torque_box is None else Rescue(
            law.model, self.guarded, self._torque_box, self.cushion,
            self.period, self.substeps)
        self.calls = 0
        self.acted = 0
        self.infeasible = 0
        self.scaled = 0
        self.uncorrected = 0
        self.rescues = 0

    def reset_counts(self) -> None:
        self.calls = self.acted = self.infeasible = self.scaled = self.uncorrected = 0
        self.rescues = 0
        if self.rescue is not None:
            self.rescue.forget()

    # -- the Controller interface ------------------------------------------------------------
    def state(self, x: Array, dx: Array) -> ArmState:
        return self.law.state(x, dx)

    def evaluate_state(self, state: ArmState, margins: bool = False) -> Evaluation:
        """The guarded torque and the law's V at the per-step state; ConstraintViolation
        outside S."""
        out = self.law.evaluate_state(state, margins=True)  # raises outside S
        self.calls += 1
        if self.constraints.empty:
            return out
        assert out.margins is not None  # asked for
        tau = self._guard(state, out.torque, out.margins)
        return Evaluation(tau, out.lyapunov, out.margins if margins else None)

    def lyapunov(self, x: Array, dx: Array) -> float:
        """The law's V, which the guard leaves as it is: the law alone is asked, no guard runs
        and no count moves (the loop asks for the true state's V beside every guarded call
        when the measurement is noisy)."""
        return self.law.lyapunov(x, dx)

    # -- the guard ---------------------------------------------------------------------------
    def _search_braking(
        self, bias: Array, stop: Array, slack: Callable[[Array], float], f_stop: float,
        f_reverse: float,
    ) -> tuple[float, float]:
        """Golden-section search of λ ∈ (λ₀, 2) for the braking torque bias − λ D ẋ / h with
        the largest F, stopping at the first λ with F ≥ 0. Between stopping (excursion ½hẋ)
        and reversing (excursion ¼hẋ, speed kept) lies a λ whose excursion h ẋ / (2λ) fits
        the configuration margin while the end speed |1 − λ|·|ẋ| keeps the velocity ones."""
        a, b = self.settings.braking, 2.0
        best = max((f_stop, a), (f_reverse, b))
        budget = self.settings.brake_search if a < b else 0
        ratio = 0.5 * (math.sqrt(5.0) - 1.0)
        c, d = b - ratio * (b - a), a + ratio * (b - a)
        fc = fd = -math.inf
        for i in range(budget):
            at_c = i == 0 or (i > 1 and fc > fd)
            if at_c:  # a new point c: the larger F lies in [a, d]
                if i > 1:
                    b, d, fd = d, c, fc
                    c = b - ratio * (b - a)
                lam = c
            else:  # a new point d: the larger F lies in [c, b]
                if i > 1:
                    a, c, fc = c, d, fd
                    d = a + ratio * (b - a)
                lam = d
            f = slack(self._brake(bias, stop, lam))
            if at_c:
                fc = f
            else:
                fd = f
            best = max(best, (f, lam))
            if f >= 0.0:
                break
        return best[1], best[0]

    def _fallback(
        self, bias: Array, stop: Array, positivity: Callable[[Array], float],
        escape: Array | None = None,
        holding: Callable[[Array], float] | None = None,
    ) -> Array:
        """When no torque satisfies (S1): the calmest braking torque that keeps every margin
        above its cushion (S0) — the smallest λ ≥ λ₀, so that the arm is not bounced off
        the boundary period after period; else the first escape torque
        C ẋ + g + f − D ẋ/h + s·D v/h, s = 1, 1.5, 2, that holds (S−) (the larger s for
        the curvature of φ that the first-order escape misses); else the λ that comes
        closest to (S0)."""
        lam0 = self.settings.braking
        calmest = self._brake(bias, stop, lam0)
        f_stop = positivity(calmest)
        if f_stop >= 0.0:
            return calmest
        lam, f_lam = self._search_braking(bias, stop, positivity, f_stop,
                                          positivity(self._brake(bias, stop, 2.0)))
        if f_lam >= 0.0:  # bisect down towards the smallest λ that keeps (S0)
            lo = lam0
            for _ in range(self.settings.brake_search):
                mid = 0.5 * (lo + lam)
                if positivity(self._brake(bias, stop, mid)) >= 0.0:
                    lam = mid
                else:
                    lo = mid
        elif escape is not None and holding is not None:
            start = bias - stop  # ends the period at rest ...
            for s in (1.0, 1.5, 2.0):  # ... plus the push to the end velocity s·v
                push = self._box(bias, start + s * escape)
                if holding(push) >= 0.0:
                    return push
        return self._brake(bias, stop, lam)

    def _escape(
        self, x: Array, dx: Array, inertia: Array, now: Array, end_floor: Array,
        mid_floor: Array,
    ) -> Array:
        """The push D v/h of a braking torque that ends the period at a velocity v pushing
        off the nearby configuration boundaries — for when one factor λ for every joint
        cannot both keep one joint off its limit and let another move away from its own.

        Under τ = C ẋ + g + f + D (v − ẋ)/h the frozen prediction ends at x + ½h(ẋ + v) and
        passes x + ⅛h(3ẋ + v) at mid-period, so to first order a floor φ̲ at the end and
        φ̲ᵐ at mid-period ask of each configuration margin φ_i

            ∇φ_i · v ≥ r_i = max(2(φ̲_i − φ_i)/h − ∇φ_i·ẋ,  8(φ̲ᵐ_i − φ_i)/h − 3∇φ_i·ẋ).

        v starts at rest and is projected onto the most violated of these half-spaces, at
        most twice per constraint (joint limits are orthogonal to each other, so one
        projection meets each): a closed-form construction, not an optimisation. A joint
        heading away from its limit just stops. The caller adds the push to the stopping
        torque C ẋ + g + f − D ẋ/h and checks the sum with the full prediction.
        """
        h = self.period
        nc = self._n_config
        grads = self._gradients(x)
        rate = grads @ dx
        need = np.maximum(2.0 * (end_floor[:nc] - now[:nc]) / h - rate,
                          8.0 * (mid_floor - now[:nc]) / h - 3.0 * rate)
        return inertia @ _project(grads, need, np.zeros_like(dx)) / h

    def _gradients(self, x: Array) -> Array:
        """∇φ_i of every guarded configuration constraint, shape (number of φ_i, n)."""
        return np.concatenate([c.gradient(x) for c in self.guarded.configuration])

    def _slide(self, state: ArmState, bias: Array, tau: Array, now: Array, end_floor: Array,
               mid_floor: Array, stop: tuple[float, Array] | None) -> Array:
        """The law's torque less what drives the arm into the configuration boundaries:
        its acceleration a = D⁻¹(τ − b) projected onto the half-spaces that (S1) asks of
        each configuration margin to first order,

            ∇φ_i · a ≥ r_i = max(2(φ̲_i − φ_i − h∇φ_i·ẋ)/h²,  8(φ̲ᵐ_i − φ_i − ½h∇φ_i·ẋ)/h²),

        (φ(h) ≈ φ + h∇φ·ẋ + ½h²∇φ·a, and at mid-period with h/2), as :func:`_project`
        builds it, then b + D a scaled into the torque box. Blending toward it, not toward a
        brake, lets the law go on along a boundary it presses against: a law that does not
        know of a joint limit and whose acceleration, through D, pushes that joint into it
        would otherwise be braked to rest there for good. Where the result would leave a
        braking margin σ_i below its floor (``stop``), the arm must also stop approaching
        that boundary by the end of the period, ∇φ_i · (ẋ + h a) ≥ 0, and a is projected
        again with that half-space added."""
        h = self.period
        nc = self._n_config
        grads = self._gradients(state.x)
        rate = grads @ state.dx
        phi = now[:nc]
        # aimed a little past each floor (a twentieth of the step, and 10⁻⁴ of the floor for
        # a margin resting on it): the projection lands on the first-order boundary, which
        # the curvature of φ may put a hair short of the floor
        end = end_floor[:nc] + 0.05 * np.abs(end_floor[:nc] - phi) + 1e-4 * np.abs(end_floor[:nc])
        mid = mid_floor + 0.05 * np.abs(mid_floor - phi) + 1e-4 * np.abs(mid_floor)
        need = np.maximum(2.0 * (end - phi - h * rate) / (h * h),
                          8.0 * (mid - phi - 0.5 * h * rate) / (h * h))
        law = solve_spd(state.inertia, tau - bias)
        acc = _project(grads, need, law)
        if stop is not None:
            v1 = state.dx + h * acc
            x_stop = state.x + h * state.dx + (0.5 * h * h) * acc + (
                stop[0] * math.sqrt(float(v1.dot(v1)))) * v1
            short = self.guarded.configuration_margins(x_stop) < stop[1]
            if short.any():
                need = np.where(short, np.maximum(need, -rate / h), need)
                acc = _project(grads, need, law)
        return self._box(bias, bias + state.inertia.dot(acc))

    def _box(self, bias: Array, tau: Array) -> Array:
        """τ scaled toward the bias b = C ẋ + g + f until it fits the torque box
        (:meth:`TorqueBox.toward`): the acceleration D⁻¹(τ − b) keeps its direction and only
        shrinks, so no joint is spun up by the coupling through D, as clipping each joint
        would (τ itself when it fits, or when there is no limit)."""
        return tau if self._torque_box is None else self._torque_box.toward(bias, tau)

    def _brake(self, bias: Array, stop: Array, lam: float) -> Array:
        """The braking torque b − λ D ẋ/h, scaled into the torque box (:meth:`_box`)."""
        return self._box(bias, bias - lam * stop)

    def _saturate(self, tau: Array) -> Array:
        return tau if self._torque_box is None else self._torque_box.clip(tau)

    @staticmethod
    def _no_nan(m: Array) -> Array:
        """NaN margins (a prediction gone wild) count as −∞; one sum tells if there are any."""
        total = m.sum()
        return np.where(np.isnan(m), -np.inf, m) if total != total else m

    def _now(self, x: Array, law_margins: Array) -> Array:
        """Every guarded margin at the sample: the law's, with the extra configuration
        constraints' after its own configuration margins."""
        if self._extra is None:
            return self._no_nan(law_margins)
        k = self._n_own_config
        return self._no_nan(np.concatenate(
            (law_margins[:k], self._extra.configuration_margins(x), law_margins[k:])))

    def _predictor(self, state: ArmState, bias: Array) -> Predictor:
        """(mid-period x, end x, end ẋ, then x and ẋ inside the period) under a held τ, one
        row per prediction (per prediction and inner instant for the last two; the Predictor
        alias): the frozen closed form with the dynamics of the sample (and, with
        ``corrector``, the second-order one beside it), or ``substeps`` semi-implicit Euler
        steps of the model."""
        x, dx, h = state.x, state.dx, self.period
        if self.substeps == 1:
            coast_mid, coast = x + (0.5 * h) * dx, x + h * dx  # the motion without torque
            inertia = state.inertia
            corrector = self.settings.corrector

            def frozen(t: Array) -> tuple[Array, Array, Array, Array, Array]:
                t = self._saturate(t)
                acc = solve_spd(inertia, t - bias)
                mid = coast_mid + (0.125 * h * h) * acc
                end, speed = coast + (0.5 * h * h) * acc, dx + h * acc
                mid_speed = dx + (0.5 * h) * acc
                if not corrector:
                    return mid[None], end[None], speed[None], mid[None], mid_speed[None]
                # the acceleration at the predicted end, taken as linear in between
                late = self.model.forward_dynamics(end, speed, t) - acc
                mids = np.array((mid, mid + (h * h / 48.0) * late))
                return (mids, np.array((end, end + (h * h / 6.0) * late)),
                        np.array((speed, speed + (0.5 * h) * late)), mids,
                        np.array((mid_speed, mid_speed + (0.125 * h) * late)))

            return frozen
        return _substepped(self.model, x, dx, h, self.substeps, self._saturate,
                           self.settings.corrector)

    def _check(self, predict: Predictor, end_floor: Array, mid_floor: Array | None,
               stop: tuple[float, Array] | None = None,
               past: np.ndarray | None = None) -> Callable[[Array], float]:
        """F(τ) = min_i m_i/floor_i − 1 over the predicted end (and mid-period
        configuration) margins of every prediction, and with ``stop`` = (1/(2θA), floors)
        the braking margins σ_i at the predicted ends: ≥ 0 when τ keeps every margin above
        its floor. ``past`` marks the margins already ≤ 0 (only the extra constraints can
        be): their floor is their present value, compared by difference, and their braking
        margin is not held (:meth:`_guard`)."""
        guarded, no_nan, nc = self.guarded, self._no_nan, self._n_config
        past_mid = None if past is None else past[:nc]
        past_v = None if past is None else past[nc:]
        has_velocity = bool(guarded.velocity)

        def f(t: Array) -> float:
            mids, ends, speeds, inner_x, inner_v = predict(t)
            velocity = no_nan(guarded.velocity_margins_along(ends, speeds))
            # the velocity margins inside the period too, held to their end floor: under a
            # held torque whose acceleration turns within the period a rate can cross its
            # bound and be back by the end (seen at 100 Hz once the torque was corrected
            # for the hold)
            inner = float(_shares(no_nan(guarded.velocity_margins_along(inner_x, inner_v)),
                                  end_floor[nc:], past_v).min()) if has_velocity else math.inf
            if mid_floor is None:
                return min(inner, float(_shares(velocity, end_floor, past).min())) - 1.0
            rows = [mids, ends]
            if stop is not None:  # x_s = x₁ + (|ẋ₁|/(2θA)) ẋ₁, A frozen at the sample
                speed = np.sqrt(np.einsum("ij,ij->i", speeds, speeds))
                rows.append(ends + (stop[0] * speed)[:, None] * speeds)
            config = no_nan(guarded.configuration_margins_along(np.concatenate(rows)))
            r = len(ends)
            end = np.concatenate((config[r:2 * r], velocity), axis=1)
            low = min(inner, float(_shares(end, end_floor, past).min()),
                      float(_shares(config[:r], mid_floor, past_mid).min()))
            if stop is not None:
                braking = config[2 * r:] / stop[1]
                if past_mid is not None:
                    braking = np.where(past_mid, np.inf, braking)
                low = min(low, float(braking.min()))
            return low - 1.0

        return f

    def _braking_floor(self, state: ArmState, bias: Array) -> tuple[float, Array] | None:
        """(1/(2θA), the floors of the braking margins σ_i: their cushions δ_i), or None
        without a torque box, at rest, or where the box leaves no deceleration (then no
        torque can help and σ is not held). σ is held above its cushion, not by the decay
        rule (S1): that would cost a second evaluation of every constraint per step, at the
        stopping point of the sample, and φ itself is held by (S1) already."""
        if self.braking is None:
            return None
        per_speed = self.braking.per_speed(state.inertia, bias, state.dx)
        if per_speed == 0.0 or per_speed == math.inf:
            return None
        return per_speed, self._sigma_floor

    def _guard(self, state: ArmState, tau: Array, law_margins: Array) -> Array:
        """τ if it satisfies (S1), else the smallest blend toward braking that does."""
        bias = state.coriolis_force + state.gravity
        if self.model.has_friction:
            bias = bias + state.dissipation
        predict = self._predictor(state, bias)
        now = self._now(state.x, law_margins)
        delta, nc = self.cushion, self._n_config
        floor = delta + self.keep * (now - delta)
        floor_mid = None
        past = None
        if nc:
            floor_mid = delta[:nc] + self.keep_half * (now[:nc] - delta[:nc])
            if self._extra is not None and not now[now.argmin()] > 0.0:
                # An extra constraint (one only the guard keeps) is broken already: the arm
                # went past a limit the law does not know of, from a state nothing could stop
                # it from. No torque brings its margin back within one period, so it must
                # merely not shrink: a law that leads back is let through, and the guard
                # never holds the arm at rest beyond the limit (it did, for good, once
                # asking for a positive margin at the period's end made every step fail).
                past = now <= 0.0
                floor = np.where(past, now, floor)
                floor_mid = np.where(past[:nc], now[:nc], floor_mid)
        stop = self._braking_floor(state, bias)
        slack = self._check(predict, floor, floor_mid, stop, past)  # (S1)
        tau, f0 = self._held(state, bias, tau, slack)
        if f0 >= 0.0:
            return tau
        self.acted += 1
        if floor_mid is not None:  # first the law less its push into the boundaries
            slid = self._slide(state, bias, tau, now, floor, floor_mid, stop)
            f_slid = slack(slid)
            if f_slid >= 0.0:
                return self._blend(tau, slid, f0, f_slid, slack)
        stop = state.inertia.dot(state.dx) / self.period
        brake = self._brake(bias, stop, self.settings.braking)
        f1 = slack(brake)
        if f1 < 0.0:
            # Reverse instead of stop: x⁺ = x, ẋ⁺ = −ẋ, the least excursion at this speed.
            reverse = self._brake(bias, stop, 2.0)
            f_rev = slack(reverse)
            if f_rev < 0.0:
                # Stopping goes too far and reversing at full speed breaks a velocity
                # margin: search the deceleration λ in between.
                lam, f_lam = self._search_braking(bias, stop, slack, f1, f_rev)
                if f_lam < 0.0:
                    self.infeasible += 1
                    rescued = self._rescued(state, bias, predict, now)
                    if rescued is not None:
                        return rescued
                    return self._infeasible(state, bias, stop, predict, now, floor, floor_mid)
                reverse, f_rev = self._brake(bias, stop, lam), f_lam
            brake, f1 = reverse, f_rev
        return self._blend(tau, brake, f0, f1, slack)

    def _rescued(self, state: ArmState, bias: Array, predict: Predictor,
                 now: Array) -> Array | None:
        """The rescue's brake (rescue.py) when it finds one that stops the arm inside S in
        the model; a committed one is held again while its one-period prediction keeps every
        margin above the floor it was found with."""
        if self.rescue is None:
            return None
        nc = self._n_config

        def holds(t: Array, floor: Array) -> bool:
            return self._check(predict, np.maximum(floor, 1e-300),
                               np.maximum(floor[:nc], 1e-300) if nc else None)(t) >= 0.0

        tau = self.rescue.torque(state, bias, now, holds)
        if tau is not None:
            self.rescues += 1
        return tau

    def _held(self, state: ArmState, bias: Array, law: Array,
              slack: Callable[[Array], float]) -> tuple[Array, float]:
        """The law's torque as the guard would hold it, and F of (S1) there: corrected for
        the hold (:func:`hold_corrected`, by the plant's share ``hold_share``) and scaled
        into the torque box. If that fails (S1) while the law's own torque keeps it, the
        blend of the two with as much of the correction as (S1) lets through (F ≥ 0): the
        correction, not the law, is what fails then. It is right for a plant whose
        acceleration drifts within the period (the corrected prediction), while the frozen
        prediction sees the correction and none of the drift, and finds the margin moved
        by s h Δa against the law's own torque; near a velocity bound that is more than
        (S1) allows, and braking there fought the law on every other step."""
        share = self.hold_share
        tau = hold_corrected(self.model, state, bias, law, self.period, share) if share else law
        boxed = self._box(bias, tau)
        if boxed is not tau:
            self.scaled += 1
            tau = boxed
        f0 = slack(tau)
        if f0 >= 0.0 or not share:
            return tau, f0
        plain = self._box(bias, law)
        f_plain = slack(plain)
        if f_plain < 0.0:
            return tau, f0
        self.uncorrected += 1
        return self._blend(tau, plain, f0, f_plain, slack), 0.0

    def _infeasible(self, state: ArmState, bias: Array, stop: Array, predict: Predictor,
                    now: Array, floor: Array, floor_mid: Array | None) -> Array:
        """When no brake satisfies (S1): the fallback, with the escape where there are
        configuration constraints, judged on the first (frozen) prediction alone: asking
        the fallback to satisfy both predictions left it choosing among torques that all
        fail, and worse ones (a Panda joint limit broken at 100 Hz)."""
        delta, nc = self.cushion, self._n_config

        def frozen(t: Array) -> tuple[Array, Array, Array, Array, Array]:
            mids, ends, speeds, inner_x, inner_v = predict(t)
            inner = len(inner_x) // len(ends)  # rows per prediction
            return mids[:1], ends[:1], speeds[:1], inner_x[:inner], inner_v[:inner]

        positivity = self._check(frozen, delta, delta[:nc] if nc else None)  # (S0) m ≥ δ
        if floor_mid is None:
            return self._fallback(bias, stop, positivity)
        # (S−), for the escape: configuration margins recover as (S1) asks at the end but,
        # below their cushion, may shrink at mid-period by the decay share; velocity
        # margins may be spent down to their cushion.
        hold_end = np.minimum(delta, self.keep * now)
        hold_end[:nc] = floor[:nc]
        hold_mid = np.minimum(floor_mid, self.keep_half * now[:nc])
        escape = self._escape(state.x, state.dx, state.inertia, now, hold_end, hold_mid)
        return self._fallback(bias, stop, positivity, escape,
                              self._check(frozen, hold_end, hold_mid))

    def _blend(self, tau: Array, brake: Array, f0: float, f1: float,
               slack: Callable[[Array], float]) -> Array:
        """Illinois steps for the smallest β with F(β) ≥ 0, bracketed by F(0) < 0 ≤ F(1)."""
        lo, f_lo, hi, f_hi = 0.0, f0, 1.0, f1
        side = 0
        for _ in range(self.settings.backoffs):
            beta = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
            if not lo < beta < hi:
                beta = 0.5 * (lo + hi)
            f = slack((1.0 - beta) * tau + beta * brake)
            if f >= 0.0:
                hi, f_hi = beta, f
                if side == 1:
                    f_lo *= 0.5
                side = 1
            else:
                lo, f_lo = beta, f
                if side == -1:
                    f_hi *= 0.5
                side = -1
        return (1.0 - hi) * tau + hi * brake


def _shares(m: Array, floor: Array, past: np.ndarray | None) -> Array:
    """m / floor per margin (≥ 1: the margin keeps its floor); where ``past`` (floor ≤ 0, the
    margin broken already) 1 + (m − floor)/|floor| instead, which is ≥ 1 when m ≥ floor."""
    if past is None:
        return m / floor
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(past, 1.0 + (m - floor) / np.maximum(np.abs(floor), 1e-12), m / floor)


def _project(grads: Array, need: Array, start: Array) -> Array:
    """``start`` moved onto the half-spaces {v : ∇φ_i · v ≥ r_i}: one orthogonal projection
    at a time onto the most violated, at most twice per constraint (joint limits are
    orthogonal to each other, so one projection meets each): a closed-form construction,
    not an optimisation."""
    norms = np.einsum("ij,ij->i", grads, grads)
    movable = norms > 1e-300
    scale = np.sqrt(np.where(movable, norms, 1.0))
    v = start
    for _ in range(2 * len(need)):
        short = np.where(movable, need - grads @ v, -np.inf)
        i = int(np.argmax(short / scale))
        if not short[i] > 0.0:
            break
        v = v + (short[i] / norms[i]) * grads[i]
    return v


def _substepped(model: RobotModel, x: Array, dx: Array, h: float, k: int,
                saturate: Callable[[Array], Array], corrector: bool) -> Predictor:
    """The prediction in k semi-implicit Euler steps of the model's forward dynamics, and
    with ``corrector`` beside it in k second-order (Heun) steps."""
    dt = h / k
    mid_step = k // 2 if k % 2 == 0 else (k + 1) // 2  # the step that ends nearest h/2

    def predict(t: Array) -> tuple[Array, Array, Array, Array, Array]:
        t = saturate(t)
        xs, vs = x.copy(), dx.copy()
        inner_x, inner_v = [], []  # the states after every sub-step but the last
        for _ in range(k):
            vs = vs + dt * model.forward_dynamics(xs, vs, t)
            xs = xs + dt * vs
            inner_x.append(xs)
            inner_v.append(vs)
        mid = inner_x[mid_step - 1]
        if not corrector:
            return (mid[None], xs[None], vs[None], np.array(inner_x[:-1]).reshape(-1, len(x)),
                    np.array(inner_v[:-1]).reshape(-1, len(x)))
        xh, vh = x.copy(), dx.copy()
        heun_x, heun_v = [], []
        for _ in range(k):
            a0 = model.forward_dynamics(xh, vh, t)
            a1 = model.forward_dynamics(xh + dt * vh + (0.5 * dt * dt) * a0, vh + dt * a0, t)
            xh = xh + dt * vh + (dt * dt) * (a0 / 3.0 + a1 / 6.0)
            vh = vh + (0.5 * dt) * (a0 + a1)
            heun_x.append(xh)
            heun_v.append(vh)
        rows_x = np.array(inner_x[:-1] + heun_x[:-1]).reshape(-1, len(x))
        rows_v = np.array(inner_v[:-1] + heun_v[:-1]).reshape(-1, len(x))
        return (np.array((mid, heun_x[mid_step - 1])), np.array((xs, xh)), np.array((vs, vh)),
                rows_x, rows_v)

    return predict
