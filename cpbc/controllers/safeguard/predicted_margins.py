"""Every guarded margin along one prediction of the period, and F of (S1) and (S2) there
(step 3 of the package docstring): the guard's accept path in compiled kernels
(cpbc.kernels.sampled_guard), with the joint placements at the predicted configurations between
them (compiled, all in one call: cpbc.model.joint_chain; Pinocchio's, one a call, for an arm
with a joint of another kind).

The constraints whose kinds have kernels (linear and rate limits, Clearance's sphere pairs)
are packed once, at construction, in the tables of the constraint set's own barrier kernel
(cpbc.constraints.packing); the others (a point outside a sphere, which reads a frame's
kinematics; the kinetic-energy limit, which reads D at each predicted state; capsules; a
subclass with its own ``value``) are asked through ``values_along``, column by column.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple, TypeVar

import numpy as np
import pinocchio as pin

from cpbc.arrays import Array, unfinite_rows
from cpbc.constraints.constraint_set import ConstraintSet
from cpbc.constraints.constraint_types import ConfigurationConstraint, VelocityConstraint
from cpbc.constraints.packing import Packed, PackedSet
from cpbc.controllers.safeguard.prediction import Frozen
from cpbc.kernels.barrier_set import LINEAR, RATE, SPHERES
from cpbc.kernels.braking_path import configuration_rows
from cpbc.kernels.frozen_slack import (
    frozen_chain_test,
    frozen_finish,
    frozen_ramp,
    frozen_size,
    frozen_test,
)
from cpbc.kernels.sampled_guard import (
    bounded_slack,
    margins_along,
    predicted_slack,
    ramp_share,
    ramp_speeds,
)
from cpbc.kernels.slide import stopping_point, stopping_point_margins
from cpbc.model.joint_chain import JointChain
from cpbc.model.robot_model import RobotModel

C = TypeVar("C", ConfigurationConstraint, VelocityConstraint)
Rows = tuple[Array, Array, Array, Array, Array]  # as a Predictor returns them
_AT_REST = np.zeros(0)
# frozen_chain_test's ramp arguments where there is no ramp to test (unread)
_NO_RAMP = (np.zeros(0), 1.0, np.zeros((0, 0)), np.zeros((0, 0)), False, np.zeros(0), np.zeros(0))
# the share of the ramp time T over which the rates are taken to go on at the period's
# acceleration: ½ for a torque that ramps straight back to b with the dynamics frozen; 1
# for what coupling and the moving bias add (on the Panda at 1000 N·m/s the base joint's
# rate went on past ½ T a by 0.08 rad/s while the shoulder's and elbow's torques ramped)
RAMP_SHARE = 1.0
# the points of the uniform brake's path under a torque-rate limit at which (S2) holds the
# configuration margins (configuration_rows: half on the ramp, half on the brake, the stopping
# point the last): there the path is long (1.2–1.8 rad on the Panda at 1000 N·m/s) and turns,
# and a clearance can dip under its floor on the way to a stopping point above it. 4 let the
# figure eight's seed 19 (panda_figure8_ke_rate, inside V) through the table by 0.79 mm: the
# clearance dipped between them (tests/test_torque_rate.py); 8 cost +2–5 µs at the robot's
# acting median under 1000 N·m/s (docs/reliability.md)
SEGMENT_POINTS = 8


class BrakingTest(NamedTuple):
    """What (S2) asks at the predicted ends: the uniform brake's stopping points x_s
    (cpbc.kernels.braking_path.configuration_rows) and the floors of σ_i there.

    Attributes:
        per_speed: 1/(2θA) of the uniform brake (stopping.Braking.per_speed).
        floor: the floors of σ_i (their cushions δ_i).
        ramp: T, the time the brake takes to build under a torque-rate limit [s]; 0 without.
        start: ẋ at the sample (read when ``ramp`` > 0).
        period: h [s] (read when ``ramp`` > 0).
        points: K, the points along the path to the stopping point at which the margins
            are held, the stopping point the last (configuration_rows).
    """

    per_speed: float
    floor: Array
    ramp: float = 0.0
    start: Array = _AT_REST
    period: float = 1.0
    points: int = 1


class Sample(NamedTuple):
    """Where the step's predictions start: the sample x and every guarded margin there (NaN
    counted as −∞), which bound the sphere clearances at the predicted configurations
    (cpbc.kernels.clearance.travel) where they need not be computed.

    Attributes:
        x: the configuration at the sample.
        margins: every guarded margin there, the configuration ones first.
    """

    x: Array
    margins: Array


class RampTest(NamedTuple):
    """What the velocity margins ask under a torque-rate limit: the held torque cannot
    change at once, so a joint goes on accelerating after the period while the torque
    ramps. Taking back the period's acceleration a = (ẋ₁ − ẋ₀)/h (frozen dynamics, D a of
    torque) takes T = max_j |(Tᵀ D a)_j| / ρ_j, over which the rates move on by ½ T a with
    the dynamics frozen, and by more as the bias and the coupling move: every velocity
    margin at (x₁, ẋ₁ + s T a) must keep its cushion, s = RAMP_SHARE.

    Attributes:
        start: ẋ₀ at the sample.
        period: h [s].
        inertia: D at the sample.
        to_joint: Tᵀ, or None for joint coordinates.
        rate: ρ per joint [N·m/s].
        floor: the velocity margins' cushions δ_j (their floors here).
    """

    start: Array
    period: float
    inertia: Array
    to_joint: Array | None
    rate: Array
    floor: Array


def _own_values(c: ConfigurationConstraint | VelocityConstraint) -> bool:
    """Whether ``c`` reports the margins its packed kind computes: no subclass below the
    class that packs it overrides ``value`` or ``values_along``."""
    cls = type(c)
    owner = next(k for k in cls.__mro__ if "packed" in vars(k))
    return all(getattr(cls, name) is getattr(owner, name) for name in ("value", "values_along"))


def _split(constraints: Sequence[C], kinds: tuple[int, ...]
           ) -> tuple[list[tuple[int, int, Packed]], list[tuple[int, int, C]]]:
    """(first column, columns, packed) of the constraints a kernel evaluates along a
    prediction, and (first column, columns, constraint) of the others."""
    packed: list[tuple[int, int, Packed]] = []
    generic: list[tuple[int, int, C]] = []
    at = 0
    for c in constraints:
        k = len(c.names)
        p = c.packed()
        if p is not None and p.kind in kinds and _own_values(c):
            packed.append((at, k, p))
        else:
            generic.append((at, k, c))
        at += k
    return packed, generic


def _not_finite(out: Array, xs: Array, dxs: Array) -> None:
    """NaN into the rows of ``out`` where (x, ẋ) is not finite (a kernel's linear limit
    would read a finite joint's margin there), as ConstraintSet.margins_along has them."""
    bad = unfinite_rows(xs, dxs)
    if bad is not None:
        out[bad] = np.nan


class PredictedMargins:
    """The guarded margins along a prediction, and F = min_i m_i/floor_i − 1."""

    def __init__(self, constraints: ConstraintSet, model: RobotModel) -> None:
        config, self._generic_config = _split(constraints.configuration, (LINEAR, SPHERES))
        velocity, self._generic_velocity = _split(constraints.velocity, (RATE,))
        self._config = PackedSet.build(config)
        self._velocity = PackedSet.build(velocity)
        self.n = model.n
        self.nc = constraints.n_configuration
        self.nv = len(constraints.names) - self.nc
        self._spheres = any(p.kind == SPHERES for _, _, p in config)
        self._pin = model.model
        # the placements compiled where every joint is revolute or prismatic, else Pinocchio's
        # with data of its own (made only then)
        self._chain = JointChain.of(self._pin, model.regressor_scale()) if self._spheres else None
        self._data = (self._pin.createData() if self._spheres and self._chain is None
                      else None)
        self._no_placements = np.zeros((0, 1, 1))
        self._no_config = np.zeros((0, 0))
        self._no_floor = np.zeros(0)
        self._no_past = np.zeros(0, dtype=bool)
        self._everywhere = np.zeros(0, dtype=np.int64)  # the sphere pairs at every row
        # every constraint packs: a frozen prediction's test is two kernel calls (frozen_slack)
        self.fuses = not self._generic_config and not self._generic_velocity

    def _placements(self, rows: Array) -> Array:
        """The joint placements (the static regressor's layout) at every row, joint
        coordinates (the sphere pairs pack only then): compiled where the chain is
        (JointChain; 38 rows at the median of a step the guard acts in on the Panda under a
        rate limit, 14 µs against Pinocchio's 32), else Pinocchio's, a row a call."""
        if not self._spheres or not len(rows):
            return self._no_placements
        if self._chain is not None:  # compiled, all rows in one call (JointChain)
            return self._chain.placements(rows)
        data, model = self._data, self._pin
        assert data is not None  # made where there is no chain
        # one array of the list: a copy into a row of an empty array costs as much as the call
        return np.array([pin.computeStaticRegressor(model, data, x) for x in rows])

    def _generic_velocity_margins(self, xs: Array, dxs: Array,
                                  out: Array | None = None) -> Array:
        """The velocity margins along rows (into ``out`` where given), those of the
        constraints that do not pack filled in (the kernel fills the others)."""
        out = np.empty((len(xs), self.nv)) if out is None else out
        for at, k, v in self._generic_velocity:
            out[:, at:at + k] = v.values_along(xs, dxs)
        return out

    def margins_along(self, xs: Array, dxs: Array) -> Array:
        """Every guarded margin at the rows (x, ẋ), one row each, in the order of the set's
        names, NaN rows where the state is not finite (ConstraintSet.margins_along): the
        packed ones by their kernels, from the joint placements at each row (the
        rescue's rollout, a period at a time)."""
        nc = self.nc
        out = np.empty((len(xs), nc + self.nv))
        self._configuration_margins(xs, out[:, :nc])
        velocity = self._generic_velocity_margins(xs, dxs, out[:, nc:])
        vp = self._velocity
        margins_along(vp.plan, vp.ints, vp.floats, xs, dxs, self._no_placements,
                      self._everywhere, velocity)
        _not_finite(out, xs, dxs)
        return out

    def configuration_margins(self, rows: Array) -> Array:
        """Every configuration margin at the rows, one row each, NaN rows where they are not
        finite (ConstraintSet.configuration_margins row by row; the slide's stopping
        point)."""
        out = np.empty((len(rows), self.nc))
        self._configuration_margins(rows, out)
        _not_finite(out, rows, rows)
        return out

    def stopping_point_margins(self, x: Array, dx: Array, acc: Array, h: float,
                               travel: float, reach: float) -> Array:
        """Every configuration margin where the uniform brake stops the arm after a period
        at the acceleration ``acc`` (cpbc.kernels.slide.stopping_point; ``reach`` 1/(2θA)),
        NaN where that point is not finite: the slide's test of its braking margins
        (Brakes.slide). One compiled call where every configuration constraint packs and
        the chain is compiled (``stopping_point_margins``), the same numbers as the point
        and :meth:`configuration_margins` give apart."""
        chain = self._chain
        if chain is None or self._generic_config:
            point = np.empty(len(x))
            stopping_point(x, dx, acc, h, travel, reach, point)
            return self.configuration_margins(point[None])[0]
        out = np.empty((1, self.nc))
        cp = self._config
        stopping_point_margins(x, dx, acc, h, travel, reach, cp.plan, cp.ints, cp.floats,
                               self._everywhere, self._spheres, chain.parents, chain.kinds,
                               chain.axes, chain.rotations, chain.translations,
                               chain.coordinates, chain.scale, out)
        return out[0]

    def _configuration_margins(self, rows: Array, out: Array) -> None:
        """The configuration margins at the rows into ``out``: the others' values, then the
        packed kernels' with the joint placements at each row."""
        for at, k, c in self._generic_config:
            out[:, at:at + k] = c.values_along(rows)
        if self.nc:
            cp = self._config
            margins_along(cp.plan, cp.ints, cp.floats, rows, rows, self._placements(rows),
                          self._everywhere, out)

    def ramp_slack(self, predicted: Rows, ramp: RampTest) -> float:
        """min_j m_j/δ_j − 1 of the velocity margins where the rates peak while the torque
        ramps back from the period's acceleration (:class:`RampTest`)."""
        _, ends, speeds, _, _ = predicted
        peaks = np.empty_like(speeds)
        to_joint = ramp.to_joint
        ramp_speeds(speeds, ramp.start, ramp.period, ramp.inertia,
                    ramp.inertia if to_joint is None else to_joint, to_joint is not None,
                    ramp.rate, RAMP_SHARE, peaks)
        vp = self._velocity
        return ramp_share(vp.plan, vp.ints, vp.floats, ends, peaks, self._no_placements,
                          self._generic_velocity_margins(ends, peaks), ramp.floor)

    def slack(self, predicted: Rows, end_floor: Array, mid_floor: Array | None,
              stop: BrakingTest | None, past: np.ndarray | None, sample: Sample | None = None,
              enough: float = math.inf) -> float:
        """F(τ) of (S1), with ``stop`` = (1/(2θA), floors) of (S2) too, over the predicted
        ``(mids, ends, speeds, inner_x, inner_v)`` (Acceptance._check). With the ``sample``
        (and no margin broken already) a sphere clearance that its bound from the sample
        settles is not computed, nor a row's joint placements where all are
        (cpbc.kernels.sampled_guard.bounded_slack): F is the same, or with ``enough`` = 1
        exact where it is < 0 and a value in [0, F] where it is not."""
        mids, ends, speeds, inner_x, inner_v = predicted
        velocity = self._generic_velocity_margins(ends, speeds)
        inner = self._generic_velocity_margins(inner_x, inner_v) if self.nv else velocity[:0]
        config, rows, placements = self._no_config, self._no_config, self._no_placements
        slots, no_floor = self._everywhere, self._no_floor
        sigma = no_floor if stop is None else stop.floor
        cp, vp = self._config, self._velocity
        if mid_floor is not None:
            rows = self._configuration_rows(mids, ends, speeds, stop)
            config = np.empty((len(rows), self.nc))
            for at, k, c in self._generic_config:
                config[:, at:at + k] = c.values_along(rows)
            if sample is not None and past is None and self._spheres:
                slots = np.empty(len(rows), dtype=np.int64)
                f, marked = bounded_slack(
                    cp.plan, cp.ints, cp.floats, vp.plan, vp.ints, vp.floats, rows, ends,
                    speeds, inner_x, inner_v, config, velocity, inner, end_floor, mid_floor,
                    sigma, self._no_past, stop is not None, sample.x, sample.margins, enough,
                    slots)
                if not marked:
                    return f
                placements = self._placements(rows[slots >= 0])
            else:
                placements = self._placements(rows)
        return predicted_slack(cp.plan, cp.ints, cp.floats, vp.plan, vp.ints, vp.floats, rows,
                               placements, slots, ends, speeds, inner_x, inner_v, config,
                               velocity, inner, end_floor,
                               no_floor if mid_floor is None else mid_floor, sigma,
                               self._no_past if past is None else past, past is not None,
                               mid_floor is not None, stop is not None)

    def frozen_slack(self, frozen: Frozen, acc: Array, after: Array, end_floor: Array,
                     mid_floor: Array | None, stop: BrakingTest | None,
                     sample: Sample | None = None, enough: float = math.inf,
                     ramp: RampTest | None = None) -> float:
        """F of :meth:`frozen_positivity` alone."""
        return self.frozen_positivity(frozen, acc, after, end_floor, mid_floor, stop, sample,
                                      enough, ramp)[0]

    def frozen_positivity(self, frozen: Frozen, acc: Array, after: Array, end_floor: Array,
                          mid_floor: Array | None, stop: BrakingTest | None,
                          sample: Sample | None = None, enough: float = math.inf,
                          ramp: RampTest | None = None,
                          cushion: Array | None = None) -> tuple[float, float]:
        """:meth:`slack` over the prediction ``frozen`` makes from its accelerations ``acc``
        and ``after`` (Frozen.start), where every constraint packs (``fuses``) and no margin
        is broken already — and with ``ramp`` the lesser of it and :meth:`ramp_slack` —
        in one kernel call and, where a row needs its joint placements, those and a
        second (cpbc.kernels.frozen_slack): the same F, bit for bit, where it is exact. For
        an arm whose chain is compiled (JointChain) all of it is one call
        (frozen_chain_test: the placements of the marked rows made inside): 21.0 against
        23.9 µs at the median on the Panda bench's states under 1000 N·m/s with a ramp.
        Without one (a committed brake's test) the one call's 50 arguments cost 1.2 µs more
        where no row needs its placements (7.1 against 5.9 µs at the median), but the
        rescue's held steps need them: in the bench's tail a step holding the committed
        aimed brake took 150 µs against 179 with the calls apart.

        Returns (F, P). With the ``cushion`` δ of every margin and the chain compiled, P is
        (S0) of the same torque over the first prediction read from the margins F's test
        made, with its sign (Brakes.positivity's test: m ≥ δ, the ramp's share too), or NaN
        where a sphere clearance there was only bounded from the sample, below its cushion
        (cpbc.kernels.frozen_slack.first_positivity); else NaN. What it saves is the test:
        a spent step's reaches ask it of both (Brakes.spent)."""
        r, n, nc = frozen.rows, self.n, self.nc
        has_config = mid_floor is not None
        points = stop.points if stop is not None and has_config else 0
        work = np.empty(frozen_size(r, n, points, nc, self.nv))
        slots = np.empty((2 + points) * r, dtype=np.int64)
        start, period, per_speed, ramp_time = ((_AT_REST, 1.0, 0.0, 0.0) if stop is None else
                                               (stop.start, stop.period, stop.per_speed,
                                                stop.ramp))
        no_floor = self._no_floor
        mid = no_floor if mid_floor is None else mid_floor
        sigma = no_floor if stop is None else stop.floor
        cp, vp = self._config, self._velocity
        bounded = sample is not None
        at, margins = (sample.x, sample.margins) if sample is not None else (no_floor, no_floor)
        chain = self._chain
        if chain is not None:  # all of it in one call
            rs, rp, ri, rt, rm, rr, rf = _NO_RAMP if ramp is None else (
                ramp.start, ramp.period, ramp.inertia,
                ramp.inertia if ramp.to_joint is None else ramp.to_joint,
                ramp.to_joint is not None, ramp.rate, ramp.floor)
            f, _, kept = frozen_chain_test(
                frozen.x, frozen.dx, acc, after, frozen.h, frozen.travel, r, start, period,
                per_speed, ramp_time, points, cp.plan, cp.ints, cp.floats, vp.plan, vp.ints,
                vp.floats, end_floor, mid, sigma, has_config, stop is not None, bounded, at,
                margins, enough, nc, work, slots, chain.parents, chain.kinds, chain.axes,
                chain.rotations, chain.translations, chain.coordinates, chain.scale,
                ramp is not None, rs, rp, ri, rt, rm, rr, RAMP_SHARE, rf, cushion is not None,
                no_floor if cushion is None else cushion)
            return f, kept
        f, marked = frozen_test(frozen.x, frozen.dx, acc, after, frozen.h, frozen.travel, r,
                                start, period, per_speed, ramp_time, points, cp.plan, cp.ints,
                                cp.floats, vp.plan, vp.ints, vp.floats, end_floor, mid, sigma,
                                has_config, stop is not None, self._spheres, bounded, at,
                                margins, enough, nc, work, slots)
        if marked:
            rows = work[:len(slots) * n].reshape(len(slots), n)
            placements = self._placements(rows[slots >= 0] if bounded else rows)  # all: exact
            f = frozen_finish(cp.plan, cp.ints, cp.floats, work, r, n, points, nc, placements,
                              slots, end_floor, mid, sigma, has_config, stop is not None)
        if ramp is None:
            return f, math.nan
        to_joint = ramp.to_joint
        return min(f, frozen_ramp(vp.plan, vp.ints, vp.floats, work, r, n, points, nc,
                                  ramp.start, ramp.period, ramp.inertia,
                                  ramp.inertia if to_joint is None else to_joint,
                                  to_joint is not None, ramp.rate, RAMP_SHARE,
                                  ramp.floor)), math.nan

    def _configuration_rows(self, mids: Array, ends: Array, speeds: Array,
                            stop: BrakingTest | None) -> Array:
        """The configurations whose margins are tested: the mid-period ones, the ends and,
        with ``stop``, the points of the uniform brake's path (``configuration_rows``)."""
        rows = np.empty(((2 if stop is None else 2 + stop.points) * len(ends), self.n))
        if stop is None:
            configuration_rows(mids, ends, speeds, _AT_REST, 1.0, 0.0, 0.0, rows)
        else:
            configuration_rows(mids, ends, speeds, stop.start, stop.period, stop.per_speed,
                               stop.ramp, rows)
        return rows
