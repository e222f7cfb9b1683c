"""The constrained laws (and the safeguard's acceptance test) unrolled into straight-line
scalar code for small arms.

On a small arm every numpy call costs more than the arithmetic it does: here about 1 µs per
call against some 40 ns per float operation, so the array law of cpbc.controllers.cpbc
spends most of a 2-link step in call overhead. At a law's first call this module writes the same
formulas out over Python floats — every loop over n unrolled, every product with a constant
(the coordinate map, constraint rows, gains, cushions) folded in, zero coefficients dropped —
and compiles the source once. Pinocchio still computes D, C ẋ, g and the kinematics.

What is unrolled, for arms of n ≤ ``MAX_JOINTS`` joints:

- the laws CPBC and BPBC (Theorem 6.9 in the form of CPBC's class docstring; Theorem 7.7),
  CPBC-KE and BPBC-KE (Corollaries 6.11, 7.8) with quadratic or log-cosh potential, linear
  or tanh damping and any shaping, and the re-centred barrier (6.57)/(6.63);
- the constraints ``LinearLimit``, ``PointOutsideSphere`` (on the law's own model),
  ``RateLimit`` and, for the KE laws, their ``KineticEnergyLimit``; any other configuration
  constraint (``Clearance``, with its vectorised pairs) is called as it is, its arrays
  unpacked into the scalar code;
- the safeguard's test (S1) of the law's torque with the one-step frozen prediction
  (cpbc.controllers.safeguard, ``substeps == 1``).

Linear solves are unrolled Cholesky factorisations up to ``SCALAR_SOLVE`` joints and LAPACK
beyond. Other laws keep their array code, which stays the reference: the tests check that
both give the same torque, V and acceptance on random states (2-, 3- and 7-joint arms).
The generated function returns None wherever the array code has something to say — a
margin ≤ 0 or NaN (it raises the named ConstraintViolation), a factorisation that is not
positive definite (it falls back to LU), a torque the safeguard must modify — and the
caller then runs the array code.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from cpbc.constraints.base import Array
from cpbc.constraints.kinetic_energy_limit import KineticEnergyLimit
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.constraints.point_outside_sphere import PointOutsideSphere
from cpbc.constraints.rate_limit import RateLimit
from cpbc.controllers.linalg import solve_spd
from cpbc.controllers.shaping import Identity, Power
from cpbc.controllers.terms import LinearDamping, LogCoshPotential, QuadraticPotential, TanhDamping

if TYPE_CHECKING:
    from cpbc.constraints.base import ConfigurationConstraint
    from cpbc.controllers.base import Controller
    from cpbc.controllers.safeguard import Safeguard

MAX_JOINTS = 7  # the generated code is tested on 2-, 3- and 7-joint arms
SCALAR_SOLVE = 3  # unrolled Cholesky up to this many joints, LAPACK beyond
Kernel = Callable[[Array, Array], "tuple[Array, float] | None"]


def _num(c: float) -> str:
    """A float literal that reads back exactly (an expression for ±inf)."""
    c = float(c)
    return repr(c) if math.isfinite(c) else f"float('{c}')"


def _lin(coeffs: Sequence[float], names: Sequence[str]) -> str:
    """Σ c_i·name_i with zero terms dropped and unit coefficients unwritten."""
    terms = []
    for c, name in zip(coeffs, names, strict=True):
        if c == 0.0:
            continue
        if c == 1.0:
            terms.append(f"+ {name}")
        elif c == -1.0:
            terms.append(f"- {name}")
        elif c < 0.0:
            terms.append(f"- {_num(-c)} * {name}")
        else:
            terms.append(f"+ {_num(c)} * {name}")
    if not terms:
        return "0.0"
    text = " ".join(terms)
    return text[2:] if text.startswith("+ ") else "-" + text[2:]


_ASSIGN = re.compile(r"^    ([A-Za-z_]\w*) = (.*)$")  # a top-level single-name assignment
_ATTRIBUTE = re.compile(r"[A-Za-z_]\w*\.[A-Za-z_]")
_NAME = re.compile(r"[A-Za-z_]\w*")


class _Source:
    """Lines of one generated function and the constants it reads."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.env: dict[str, object] = {
            "_array": np.array, "log": math.log, "exp": math.exp, "sqrt": math.sqrt,
            "tanh": math.tanh, "log1p": math.log1p, "_fsum": math.fsum, "_LN2": math.log(2.0),
            "_maximum": np.maximum,
        }
        self._count = 0

    def __call__(self, line: str) -> None:
        self.lines.append("    " + line)

    def fresh(self, prefix: str) -> str:
        self._count += 1
        return f"{prefix}{self._count}"

    def prune(self) -> None:
        """Drop assignments whose name nothing after them reads (walking back from the
        return), when their right side is pure arithmetic on names (no attribute: no
        Pinocchio or constraint call). Control flow and tuple unpacking always stay."""
        used: set[str] = set()
        kept: list[str] = []
        for line in reversed(self.lines):
            match = _ASSIGN.match(line)
            if match and match[1] not in used and not _ATTRIBUTE.search(match[2]):
                continue
            used.update(_NAME.findall(line))
            kept.append(line)
        self.lines = kept[::-1]

    def compile(self, name: str) -> Kernel:
        # The text holds only this module's names and float literals of the law's numbers
        # (never a string from a scenario), so compiling it runs nothing but the law.
        text = f"def {name}(x, dx):\n" + "\n".join(self.lines) + "\n"
        namespace = dict(self.env)
        exec(compile(text, f"<cpbc unrolled {name}>", "exec"), namespace)
        fn = namespace[name]
        fn.source = text  # type: ignore[attr-defined]
        return fn  # type: ignore[return-value]


class _Vec(str):
    """The name of an ndarray of ``size`` margins (an array constraint's, kept whole)."""

    size: int

    @classmethod
    def of(cls, name: str, size: int) -> _Vec:
        vec = cls(name)
        vec.size = size
        return vec


class _Arrays:
    """ndarrays of one state for Pinocchio (q = T⁻¹x) and for array constraints (x), each
    emitted once, when first asked for."""

    def __init__(self, emitter: _Emitter, xs: list[str], q: str | None = None,
                 x: str | None = None) -> None:
        self.emitter, self.xs, self._q, self._x = emitter, xs, q, x

    def q(self) -> str:
        if self._q is None:
            self._q = self.emitter.joint_array(self.xs, self._x)
        return self._q

    def x(self) -> str:
        if self._x is None:
            if self.emitter.identity:
                self._x = self.q()
            else:
                self._x = self.emitter.src.fresh("xa")
                self.emitter.src(f"{self._x} = _array(({', '.join(self.xs)},))")
        return self._x


# configuration constraints the emitter writes as scalar code; the others run their own
# array code inside it
_SCALAR_FORMS = (LinearLimit, PointOutsideSphere)


def _supported(law: Controller, configuration: Sequence[ConfigurationConstraint]) -> bool:
    """Whether the law, its constraints and ``configuration`` all have a scalar form here."""
    from cpbc.controllers.cpbc import CPBC
    from cpbc.controllers.cpbc_ke import CPBCKineticEnergy
    from cpbc.controllers.recentred import RecentredBarrier

    model = law.model
    if model.n > MAX_JOINTS or not isinstance(law, CPBC | CPBCKineticEnergy | RecentredBarrier):
        return False
    if not isinstance(law, RecentredBarrier) and (
        type(law.potential) not in (QuadraticPotential, LogCoshPotential)
        or type(law.damping) not in (LinearDamping, TanhDamping)
    ):
        return False
    # a configuration constraint without a scalar form runs its own array code inside
    if any(type(c) is PointOutsideSphere and c.model is not model for c in configuration):
        return False
    if isinstance(law, CPBCKineticEnergy):
        return type(law.energy) is KineticEnergyLimit and law.energy.model is model
    return all(type(c) is RateLimit for c in law.constraints.velocity)


def _matrix(src: _Source, a: list[list[str]], inertia: tuple[str, list[list[str]]] | None
            ) -> str:
    """An ndarray of the symmetric A (lower entries a[i][j], i ≥ j). With ``inertia`` = (the
    name of Pinocchio's D array, D's entry names) and A = D plus terms on the diagonal, a
    copy of that array with the terms added (the same numbers; building a 7 × 7 array from
    49 floats costs more than the solve)."""
    n = len(a)
    if inertia is not None:
        array, d = inertia
        off = all(a[max(i, j)][min(i, j)] == d[i][j] for i in range(n) for j in range(n) if i != j)
        extra = [a[i][i][len(d[i][i]) + 3:] if a[i][i].startswith(d[i][i] + " + ") else
                 "0.0" if a[i][i] == d[i][i] else None for i in range(n)]
        if off and None not in extra:
            if all(e == "0.0" for e in extra):
                return array
            name = src.fresh("A")
            src(f"{name} = {array}.copy()")
            src(f"{name}.reshape(-1)[::{n + 1}] += ({', '.join(extra)},)")
            return name
    rows = ", ".join("(" + ", ".join(a[max(i, j)][min(i, j)] for j in range(n)) + ",)"
                     for i in range(n))
    return f"_array(({rows},))"


def _cholesky_solve(src: _Source, a: list[list[str]], rhs: list[str], tag: str,
                    inertia: tuple[str, list[list[str]]] | None = None) -> list[str]:
    """Emit y = A⁻¹ rhs for symmetric A (lower entries a[i][j], i ≥ j) by Cholesky; the
    function returns None on a pivot that is not > 0 (the array code then uses LU). Beyond
    ``SCALAR_SOLVE`` unknowns LAPACK's (solve_spd) beats the unrolled factorisation
    (``inertia``: see _matrix)."""
    n = len(rhs)
    if n > SCALAR_SOLVE:
        src.env["_solve"] = solve_spd
        mat = _matrix(src, a, inertia)
        y = [f"{tag}y{i}" for i in range(n)]
        src(f"{', '.join(y)}, = _solve({mat}, _array(({', '.join(rhs)},))).tolist()")
        return y
    low = [[""] * n for _ in range(n)]
    for j in range(n):
        s = a[j][j] + "".join(f" - {low[j][k]} * {low[j][k]}" for k in range(j))
        piv = f"{tag}p{j}"
        src(f"{piv} = {s}")
        src(f"if not {piv} > 0.0:")
        src("    return None")
        low[j][j] = f"{tag}l{j}{j}"
        src(f"{low[j][j]} = sqrt({piv})")
        for i in range(j + 1, n):
            low[i][j] = f"{tag}l{i}{j}"
            s = a[i][j] + "".join(f" - {low[i][k]} * {low[j][k]}" for k in range(j))
            src(f"{low[i][j]} = ({s}) / {low[j][j]}")
    z = [f"{tag}z{i}" for i in range(n)]
    for i in range(n):
        s = rhs[i] + "".join(f" - {low[i][k]} * {z[k]}" for k in range(i))
        src(f"{z[i]} = ({s}) / {low[i][i]}")
    y = [f"{tag}y{i}" for i in range(n)]
    for i in reversed(range(n)):
        s = z[i] + "".join(f" - {low[k][i]} * {y[k]}" for k in range(i + 1, n))
        src(f"{y[i]} = ({s}) / {low[i][i]}")
    return y


class _Emitter:
    """Writes the law's scalar code into a _Source."""

    def __init__(self, law: Controller, src: _Source) -> None:
        self.law = law
        self.src = src
        model = law.model
        self.n = n = model.n
        self.t_inv = model.coordinates.inverse.tolist()
        self.identity = model.coordinates.is_identity
        src.env.update(
            _model=model.model, _data=model.data, _crba=pin.crba, _nle=pin.nonLinearEffects,
            _grav=pin.computeGeneralizedGravity, _fj=pin.computeFrameJacobian,
            _fk=pin.framesForwardKinematics, _LWA=pin.ReferenceFrame.LOCAL_WORLD_ALIGNED,
            _oMf=model.data.oMf,  # a live view of the frame placements, taken once
        )
        self.x = [f"x{i}" for i in range(n)]
        self.v = [f"v{i}" for i in range(n)]
        self.inertia: tuple[str, list[list[str]]] | None = None  # see _matrix
        # with a dict (the safeguard's emitter): the values at x of array constraints, taken
        # with their barrier terms (barrier_terms_and_value), by id of the constraint
        self.sample_values: dict[int, _Vec] | None = None

    # -- coordinates -------------------------------------------------------------------------
    def joint_array(self, names: list[str], array_name: str | None) -> str:
        """An ndarray q = T⁻¹ x for Pinocchio (the given array itself with identity T)."""
        if self.identity and array_name is not None:
            return array_name
        q = self.src.fresh("q")
        parts = ", ".join(_lin(row, names) for row in self.t_inv)
        self.src(f"{q} = _array(({parts},))")
        return q

    def to_x(self, joint: list[str]) -> list[str]:
        """Covector T⁻ᵀ w from a joint-coordinate covector w."""
        n = self.n
        return [_lin([self.t_inv[i][a] for i in range(n)], joint) for a in range(n)]

    # -- dynamics ----------------------------------------------------------------------------
    def dynamics(self, q: str, dq: str | None, gravity: bool = True
                 ) -> tuple[list[list[str]], list[str], list[str]]:
        """D (symmetric, names), g and C ẋ + f in x-coordinates (g only with ``gravity``,
        C ẋ + f only with dq)."""
        src, n, ti = self.src, self.n, self.t_inv
        tag = src.fresh("D")
        d = [[""] * n for _ in range(n)]
        if self.identity:  # D's upper triangle unpacked in one statement
            array = src.fresh("Ma")
            src(f"{array} = _crba(_model, _data, {q})")
            for a in range(n):
                for b in range(a, n):
                    d[a][b] = d[b][a] = f"{tag}_{a}{b}"
            names = [d[i][j] if j >= i else "_" for i in range(n) for j in range(n)]
            src(f"{', '.join(names)}, = {array}.reshape(-1).tolist()")
            if n > SCALAR_SOLVE:  # D's array is kept for LAPACK (_matrix)
                self.inertia = (array, d)
            return self._gravity_and_bias(q, dq, gravity, d)
        m = src.fresh("M")
        src(f"{m} = _crba(_model, _data, {q}).tolist()")
        mij = [[f"{m}[{min(i, j)}][{max(i, j)}]" for j in range(n)] for i in range(n)]
        for a in range(n):
            for b in range(a, n):
                coeff: dict[str, float] = {}
                for i in range(n):
                    for j in range(n):
                        c = ti[i][a] * ti[j][b]
                        if c:
                            coeff[mij[i][j]] = coeff.get(mij[i][j], 0.0) + c
                name = f"{tag}_{a}{b}"
                src(f"{name} = {_lin(list(coeff.values()), list(coeff.keys()))}")
                d[a][b] = d[b][a] = name
        return self._gravity_and_bias(q, dq, gravity, d)

    def _gravity_and_bias(self, q: str, dq: str | None, gravity: bool, d: list[list[str]]
                          ) -> tuple[list[list[str]], list[str], list[str]]:
        src, n = self.src, self.n
        if not gravity:
            return d, [], []
        g_q = [f"g{i}" for i in range(n)]
        src(f"{', '.join(g_q)}, = _grav(_model, _data, {q}).tolist()")
        g = [f"gx{a}" for a in range(n)]
        for a, expr in enumerate(self.to_x(g_q)):
            src(f"{g[a]} = {expr}")
        c: list[str] = []
        if dq is not None:
            h_q = [f"h{i}" for i in range(n)]
            src(f"{', '.join(h_q)}, = _nle(_model, _data, {q}, {dq}).tolist()")
            for i in range(n):
                src(f"{h_q[i]} -= {g_q[i]}")
            fd = self.law.model.viscous_friction.tolist() if self.law.model.has_friction else None
            for a, expr in enumerate(self.to_x(h_q)):
                extra = f" + ({_lin(fd[a], self.v)})" if fd is not None else ""
                src(f"cx{a} = {expr}{extra}")
                c.append(f"cx{a}")
        return d, g, c

    # -- constraints -------------------------------------------------------------------------
    def linear_limit(self, con: LinearLimit, x: list[str], grad: list[list[str]] | None
                     ) -> list[str]:
        src, out = self.src, []
        for row, lo, up in zip(con.rows.tolist(), con.lower.tolist(), con.upper.tolist(),
                               strict=True):
            y, phi = src.fresh("y"), src.fresh("phi")
            src(f"{y} = {_lin(row, x)}")
            src(f"{phi} = ({y} - {_num(lo)}) * ({_num(up)} - {y})")
            if grad is not None:
                w = src.fresh("w")
                src(f"{w} = ({_num(lo + up)} - 2.0 * {y}) / {phi}")
                for a in range(self.n):
                    if row[a]:
                        grad[a].append(f"{_num(row[a])} * {w}")
            out.append(phi)
        return out

    def _point(self, con: PointOutsideSphere) -> tuple[list[str], list[str] | None]:
        """Names of the constraint's point and of its offset r from the frame's origin
        (None without an offset), after the frame is placed."""
        src = self.src
        place = src.fresh("P")
        src(f"{place} = _oMf[{con.frame_id}]")
        p = [src.fresh("p") for _ in range(3)]
        src(f"{', '.join(p)}, = {place}.translation.tolist()")
        if con.offset is None:
            return p, None
        rot = src.fresh("R")
        src(f"{rot} = {place}.rotation.tolist()")
        o = con.offset.tolist()
        r = [src.fresh("r") for _ in range(3)]
        for k in range(3):
            src(f"{r[k]} = {_lin(o, [f'{rot}[{k}][{m}]' for m in range(3)])}")
            src(f"{p[k]} += {r[k]}")
        return p, r

    def point_outside_sphere(self, con: PointOutsideSphere, q: str,
                             grad: list[list[str]] | None) -> list[str]:
        src = self.src
        if grad is not None:
            jac = src.fresh("J")
            src(f"{jac} = _fj(_model, _data, {q}, {con.frame_id}, _LWA).tolist()")
        else:
            src(f"_fk(_model, _data, {q})")
        p, rr = self._point(con)
        d = [src.fresh("d") for _ in range(3)]
        for k, (pk, ck) in enumerate(zip(p, con.centre.tolist(), strict=True)):
            src(f"{d[k]} = {pk} - {_num(ck)}" if ck else f"{d[k]} = {pk}")
        phi = src.fresh("phi")
        src(f"{phi} = {d[0]} * {d[0]} + {d[1]} * {d[1]} + {d[2]} * {d[2]} - {_num(con._r2)}")
        if grad is None:
            return [phi]
        # ∂p/∂q column c: v_c − r × ω_c (with an offset r from the frame's origin)
        wq = []
        for col in range(self.n):
            v = [f"{jac}[{k}][{col}]" for k in range(3)]
            if rr is not None:
                om = [f"{jac}[{k}][{col}]" for k in range(3, 6)]
                v = [f"({v[0]} - ({rr[1]} * {om[2]} - {rr[2]} * {om[1]}))",
                     f"({v[1]} - ({rr[2]} * {om[0]} - {rr[0]} * {om[2]}))",
                     f"({v[2]} - ({rr[0]} * {om[1]} - {rr[1]} * {om[0]}))"]
            w = src.fresh("wq")
            src(f"{w} = {d[0]} * {v[0]} + {d[1]} * {v[1]} + {d[2]} * {v[2]}")
            wq.append(w)
        s = src.fresh("s")
        src(f"{s} = 2.0 / {phi}")
        for a, expr in enumerate(self.to_x(wq)):
            if expr != "0.0":
                grad[a].append(f"({expr}) * {s}")
        return [phi]

    def rate_limit(self, con: RateLimit, v: list[str], weight: list[list[list[str]]] | None
                   ) -> list[str]:
        src, out = self.src, []
        for row, omega in zip(con.rows.tolist(), con._omega.tolist(), strict=True):
            y, psi = src.fresh("y"), src.fresh("psi")
            src(f"{y} = {_lin(row, v)}")
            src(f"{psi} = {_num(omega)} - 0.5 * {y} * {y}")
            if weight is not None:
                ip = src.fresh("ip")
                src(f"{ip} = 1.0 / {psi}")
                for a in range(self.n):
                    for b in range(self.n):
                        c = row[a] * row[b]
                        if c:
                            weight[a][b].append(f"{_num(c)} * {ip}" if c != 1.0 else ip)
            out.append(psi)
        return out

    def configuration(self, cons: Sequence[ConfigurationConstraint], x: list[str],
                      arrays: _Arrays, grad: list[list[str]] | None, vectors: bool = False
                      ) -> list[str]:
        """φ of each constraint at x (with ``grad``: the barrier's φ, its gradient terms
        appended to ``grad``); with ``vectors`` an array constraint's values stay one
        ndarray (a _Vec name) instead of k scalar names."""
        out: list[str] = []
        for c in cons:
            if type(c) is LinearLimit:
                out += self.linear_limit(c, x, grad)
            elif type(c) is PointOutsideSphere:
                out += self.point_outside_sphere(c, arrays.q(), grad)
            elif vectors:
                name = _Vec.of(self.src.fresh("phiv"), len(c.names))
                self.src(f"{name} = {self.constant(c)}.value({arrays.x()})")
                out.append(name)
            else:
                out += self.array_constraint(c, arrays.x(), grad)
        return out

    def configuration_at_two(self, cons: Sequence[ConfigurationConstraint], xa: list[str],
                             xb: list[str]) -> tuple[list[str], list[str]]:
        """``configuration(cons, …, vectors=True)`` at two states; an array constraint's
        values at both come from one ``values_along`` call."""
        arrays_a, arrays_b = _Arrays(self, xa), _Arrays(self, xb)
        out_a: list[str] = []
        out_b: list[str] = []
        for c in cons:
            if type(c) in _SCALAR_FORMS:
                out_a += self.configuration([c], xa, arrays_a, None)
                out_b += self.configuration([c], xb, arrays_b, None)
                continue
            both = self.src.fresh("pv")
            states = ", ".join(f"({', '.join(z)},)" for z in (xa, xb))
            self.src(f"{both} = {self.constant(c)}.values_along(_array(({states},)))")
            for k, out in enumerate((out_a, out_b)):
                name = _Vec.of(self.src.fresh("phiv"), len(c.names))
                self.src(f"{name} = {both}[{k}]")
                out.append(name)
        return out_a, out_b

    def constant(self, value: object) -> str:
        """A name for an object the generated code reads."""
        name = self.src.fresh("_k")
        self.src.env[name] = value
        return name

    def array_constraint(self, con: ConfigurationConstraint, x: str,
                         grad: list[list[str]] | None) -> list[str]:
        """A constraint without a scalar form (Clearance): its own array code, unpacked."""
        src = self.src
        obj = self.constant(con)
        names = [src.fresh("phi") for _ in con.names]
        if grad is None:
            src(f"{', '.join(names)}, = {obj}.value({x}).tolist()")
            return names
        arr, b = src.fresh("pa"), src.fresh("b")
        if self.sample_values is not None and x == "x":
            value = _Vec.of(src.fresh("phiv"), len(con.names))
            src(f"{arr}, {b}, {value} = {obj}.barrier_terms_and_value({x})")
            self.sample_values[id(con)] = value
        else:
            src(f"{arr}, {b} = {obj}.barrier_terms({x})")
        src(f"{', '.join(names)}, = {arr}.tolist()")
        src(f"{b} = {b}.tolist()")
        for a in range(self.n):
            grad[a].append(f"{b}[{a}]")
        return names

    @staticmethod
    def all_positive(src: _Source, margins: list[str]) -> None:
        """Return None unless every margin is > 0 (False for NaN too)."""
        if margins:
            src(f"if not ({' and '.join(f'{m} > 0.0' for m in margins)}):")
            src("    return None")

    def velocity_values(self, cons: Sequence[object], q: Callable[[], str], v: list[str]
                        ) -> list[str]:
        """ψ of rate and kinetic-energy limits at a state (``q()`` places Pinocchio's q)."""
        out: list[str] = []
        for con in cons:
            if isinstance(con, RateLimit):
                out += self.rate_limit(con, v, None)
            else:
                out.append(self.kinetic_energy_limit(con, q(), v))  # type: ignore[arg-type]
        return out

    def kinetic_energy_limit(self, con: KineticEnergyLimit, q: str, v: list[str]) -> str:
        d, _, _ = self.dynamics(q, None, gravity=False)
        psi = self.src.fresh("psi")
        self.src(f"{psi} = {_num(con.limit)} - {self.kinetic(d, v)}")
        return psi

    def kinetic(self, d: list[list[str]], v: list[str]) -> str:
        """½ vᵀ D v as an expression."""
        n = self.n
        terms = [f"{d[a][a]} * {v[a]} * {v[a]}" for a in range(n)]
        terms += [f"2.0 * {d[a][b]} * {v[a]} * {v[b]}" for a in range(n) for b in range(a + 1, n)]
        return "0.5 * (" + " + ".join(terms) + ")"

    # -- the laws ----------------------------------------------------------------------------
    def begin(self, coriolis: bool) -> tuple[str, list[list[str]], list[str], list[str]]:
        """Unpack the state and emit the dynamics: q, D, g and (with ``coriolis``) C ẋ + f."""
        self.src(f"{', '.join(self.x)}, = x.tolist()")
        self.src(f"{', '.join(self.v)}, = dx.tolist()")
        q = self.joint_array(self.x, "x")
        dq = self.joint_array(self.v, "dx") if coriolis else None
        d, g, c = self.dynamics(q, dq)
        return q, d, g, c

    def potential_and_damping(self) -> tuple[str, list[str], list[str]]:
        """U, ∂U/∂x̃ and the damping force as expressions (errors e_i emitted)."""
        src, n, law = self.src, self.n, self.law
        kp, kd, xd = law.kp.tolist(), law.kd.tolist(), law.target.tolist()
        e = [f"e{i}" for i in range(n)]
        for i in range(n):
            src(f"{e[i]} = x{i} - {_num(xd[i])}")
        if isinstance(law.potential, LogCoshPotential):
            xi = law.potential.xi.tolist()
            pot = " + ".join(
                f"{_num(kp[i] / xi[i])} * (abs({_num(xi[i])} * {e[i]}) + "
                f"log1p(exp(-2.0 * abs({_num(xi[i])} * {e[i]}))) - _LN2)" for i in range(n))
            grad_u = [f"{_num(kp[i])} * tanh({_num(xi[i])} * {e[i]})" for i in range(n)]
        else:
            pot = "0.5 * (" + " + ".join(f"{_num(kp[i])} * {e[i]} * {e[i]}" for i in range(n)) + ")"
            grad_u = [f"{_num(kp[i])} * {e[i]}" for i in range(n)]
        if isinstance(law.damping, TanhDamping):
            gam = law.damping.gamma.tolist()
            damp = [f"{_num(kd[i])} * tanh({_num(gam[i])} * v{i})" for i in range(n)]
        else:
            damp = [f"{_num(kd[i])} * v{i}" for i in range(n)]
        return pot, grad_u, damp

    def shaped(self, lsum: str) -> tuple[str, str]:
        """r(ΦΨ) and log s(ΦΨ) as expressions of lsum = log ΦΨ."""
        shaping = self.law.shaping
        if type(shaping) is Identity:
            return "1.0", lsum
        if type(shaping) is Power:
            return _num(shaping.alpha), f"{_num(shaping.alpha)} * {lsum}"
        self.src.env["_ratio"], self.src.env["_log_s"] = shaping.ratio, shaping.log_s
        return f"_ratio({lsum})", f"_log_s({lsum})"

    def log_sum(self, margins: list[str]) -> str:
        if not margins:
            return "0.0"
        return f"_fsum(({', '.join(f'log({m})' for m in margins)},))"

    def solve_law(self, d: list[list[str]], g: list[str], c: list[str], a: list[str],
                  scale: str, weight: list[list[list[str]]]) -> list[str]:
        """τ = g + c + D (D + scale·Π)⁻¹ (a − c)."""
        n, src = self.n, self.src
        rhs = [f"r{i}" for i in range(n)]
        for i in range(n):
            src(f"{rhs[i]} = {a[i]} - {c[i]}")
        mat = [[d[i][j] + (f" + {scale} * ({' + '.join(weight[i][j])})" if weight[i][j] else "")
                for j in range(n)] for i in range(n)]
        y = _cholesky_solve(src, mat, rhs, "k", self.inertia)
        tau = [f"tau{i}" for i in range(n)]
        for i in range(n):
            src(f"{tau[i]} = {g[i]} + {c[i]} + " + " + ".join(
                f"{d[i][j]} * {y[j]}" for j in range(n)))
        return tau

    def emit_law(self, coriolis: bool) -> tuple[list[str], list[list[str]], list[str], list[str]]:
        """Emit τ and V (named ``V``); returns τ, D, the bias C ẋ + g + f (with
        ``coriolis``) and the margins in the constraint set's order."""
        from cpbc.controllers.cpbc_ke import CPBCKineticEnergy
        from cpbc.controllers.recentred import RecentredBarrier

        if isinstance(self.law, CPBCKineticEnergy):
            return self.emit_energy_law(coriolis)
        if isinstance(self.law, RecentredBarrier):
            return self.emit_recentred()
        return self.emit_cpbc()

    def emit_cpbc(self) -> tuple[list[str], list[list[str]], list[str], list[str]]:
        """Theorem 6.9 / 7.7 in the form of CPBC's class docstring."""
        src, n, law = self.src, self.n, self.law
        q, d, g, c = self.begin(coriolis=True)
        grad: list[list[str]] = [[] for _ in range(n)]
        weight: list[list[list[str]]] = [[[] for _ in range(n)] for _ in range(n)]
        here = _Arrays(self, self.x, q, "x")
        phis = self.configuration(law.constraints.configuration, self.x, here, grad)
        psis: list[str] = []
        for con in law.constraints.velocity:
            psis += self.rate_limit(con, self.v, weight)  # type: ignore[arg-type]
        self.all_positive(src, phis + psis)
        src(f"lsum = {self.log_sum(phis + psis)}")
        pot, grad_u, damp = self.potential_and_damping()
        src(f"lag = {self.kinetic(d, self.v)} + {pot}")
        ratio, log_s = self.shaped("lsum")
        src(f"rho = {ratio} * lag")
        a = []
        for i in range(n):
            b = f" + rho * ({' + '.join(grad[i])})" if grad[i] else ""
            a.append(f"-({grad_u[i]}) - {damp[i]}{b}")
        if law.constraints.velocity:
            tau = self.solve_law(d, g, c, a, "rho", weight)
        else:
            tau = [f"tau{i}" for i in range(n)]
            for i in range(n):
                src(f"{tau[i]} = {g[i]} + {a[i]}")
        src(f"V = exp(log(lag) - {log_s}) if lag > 0.0 else 0.0")
        return tau, d, [f"({g[i]} + {c[i]})" for i in range(n)], phis + psis

    def emit_energy_law(self, coriolis: bool
                        ) -> tuple[list[str], list[list[str]], list[str], list[str]]:
        """Corollary 6.11 / 7.8: τ = g + [−(∂U/∂x̃ + damping) + ρ b_φ] / (1 + ρ/ψ)."""
        src, n, law = self.src, self.n, self.law
        q, d, g, c = self.begin(coriolis)
        src(f"kin = {self.kinetic(d, self.v)}")
        src(f"psi = {_num(law.energy.limit)} - kin")  # type: ignore[attr-defined]
        grad: list[list[str]] = [[] for _ in range(n)]
        here = _Arrays(self, self.x, q, "x")
        phis = self.configuration(law.constraints.configuration, self.x, here, grad)
        self.all_positive(src, [*phis, "psi"])
        src(f"lsum = {self.log_sum(phis)} + log(psi)" if phis else "lsum = log(psi)")
        pot, grad_u, damp = self.potential_and_damping()
        src(f"lag = kin + {pot}")
        ratio, log_s = self.shaped("lsum")
        src(f"rho = {ratio} * lag")
        src("den = 1.0 + rho / psi")
        tau = [f"tau{i}" for i in range(n)]
        for i in range(n):
            b = f" + rho * ({' + '.join(grad[i])})" if grad[i] else ""
            src(f"{tau[i]} = {g[i]} + (-({grad_u[i]}) - {damp[i]}{b}) / den")
        src(f"V = exp(log(lag) - {log_s}) if lag > 0.0 else 0.0")
        bias = [f"({g[i]} + {c[i]})" for i in range(n)] if coriolis else []
        return tau, d, bias, [*phis, "psi"]

    def emit_recentred(self) -> tuple[list[str], list[list[str]], list[str], list[str]]:
        """The re-centred barrier law (6.57)/(6.63) and its V (6.61)."""
        src, n, law = self.src, self.n, self.law
        q, d, g, c = self.begin(coriolis=True)
        here = _Arrays(self, self.x, q, "x")
        phis = self.configuration(law.constraints.configuration, self.x, here, None)
        weight: list[list[list[str]]] = [[[] for _ in range(n)] for _ in range(n)]
        psis: list[str] = []
        for con in law.constraints.velocity:
            psis += self.rate_limit(con, self.v, weight)  # type: ignore[arg-type]
        joints = law.joints.tolist()  # type: ignore[attr-defined]
        centre = law.centre.tolist()  # type: ignore[attr-defined]
        width2 = (law.half_width**2).tolist()  # type: ignore[attr-defined]
        kp, kd = law.kp.tolist(), law.kd.tolist()
        z = [f"z{k}" for k in range(len(joints))]
        gap = [f"gap{k}" for k in range(len(joints))]
        for k, j in enumerate(joints):
            src(f"{z[k]} = x{j} - {_num(centre[k])}")
            src(f"{gap[k]} = {_num(width2[k])} - {z[k]} * {z[k]}")
        self.all_positive(src, gap + phis + psis)
        # f = ½ zᵀK z / Φ and ∇f (6.54)–(6.55), Φ = Π gap_k / w_k²
        src("inv_phi = exp(-_fsum((" + ", ".join(
            f"log({gap[k]} / {_num(width2[k])})" for k in range(len(joints))) + ",)))")
        src("energy = " + " + ".join(f"{_num(kp[j])} * {z[k]} * {z[k]}"
                                      for k, j in enumerate(joints)))
        grad = ["0.0"] * n
        for k, j in enumerate(joints):
            grad[j] = f"({_num(kp[j])} * {z[k]} + energy * {z[k]} / {gap[k]}) * inv_phi"
        target = law._grad_target.tolist()  # type: ignore[attr-defined]
        xd = law.target.tolist()
        tau = [f"tau{i}" for i in range(n)]
        if psis:
            src(f"kin = {self.kinetic(d, self.v)}")
            src(f"lsum = {self.log_sum(psis)}")
            src("big_psi = exp(lsum)")
            a = [f"-{_num(kd[i])} * v{i} - big_psi * ({grad[i]} - {_num(target[i])})"
                 for i in range(n)]
            tau = self.solve_law(d, g, c, a, "kin", weight)
            src("kin = kin / big_psi")
        else:
            for i in range(n):
                src(f"{tau[i]} = {g[i]} - {_num(kd[i])} * v{i} - {grad[i]} + {_num(target[i])}")
            src(f"kin = {self.kinetic(d, self.v)}")
        src(f"V = kin + 0.5 * energy * inv_phi - {_num(law._f_target)} - ("  # type: ignore[attr-defined]
            + " + ".join(f"{_num(target[i])} * (x{i} - {_num(xd[i])})" for i in range(n)) + ")")
        return tau, d, [f"({g[i]} + {c[i]})" for i in range(n)], phis + psis


class Unrolled:
    """Mixin for the laws above: ``torque`` and ``evaluate`` from the scalar code where it
    runs, else from the law's ``torque_arrays`` and ``evaluate_arrays``. The scalar code is
    built at the first call (when subclasses have set their potential and damping) from the
    law's numbers then: a law is not changed after it is built (its gains and target are
    read-only arrays)."""

    _unrolled: Kernel | bool | None = False
    _unrolled_torque: Kernel | bool | None = False  # the same without V (``torque``)

    def unrolled(self, x: Array, dx: Array) -> tuple[Array, float] | None:
        """τ and V from the scalar code, or None where the array code must run."""
        kernel = self._unrolled
        if kernel is False:
            kernel = self._unrolled = unrolled_law(self)  # type: ignore[arg-type]
        return None if kernel is None else kernel(x, dx)  # type: ignore[operator]

    def torque(self, x: Array, dx: Array) -> Array:
        kernel = self._unrolled_torque
        if kernel is False:
            kernel = self._unrolled_torque = unrolled_law(self, False)  # type: ignore[arg-type]
        fast = None if kernel is None else kernel(x, dx)  # type: ignore[operator]
        return fast if fast is not None else self.torque_arrays(x, dx)

    def evaluate(self, x: Array, dx: Array) -> tuple[Array, float]:
        fast = self.unrolled(x, dx)
        return fast if fast is not None else self.evaluate_arrays(x, dx)

    def torque_arrays(self, x: Array, dx: Array) -> Array:  # pragma: no cover - per law
        raise NotImplementedError

    def evaluate_arrays(self, x: Array, dx: Array) -> tuple[Array, float]:  # pragma: no cover
        raise NotImplementedError


def unrolled_law(law: Controller, lyapunov: bool = True) -> Kernel | None:
    """``f(x, ẋ) -> (τ, V)`` for CPBC, BPBC, CPBC-KE, BPBC-KE or the re-centred barrier on a
    small arm (without ``lyapunov``: τ alone, and nothing computed only for V), or None when
    something in the law has no scalar form (the law then keeps its array code)."""
    if not _supported(law, law.constraints.configuration):
        return None
    src = _Source()
    tau, _, _, _ = _Emitter(law, src).emit_law(coriolis=False)
    if lyapunov:
        src(f"return _array(({', '.join(tau)},)), V")
        return src.compile("unrolled_law")
    src(f"return _array(({', '.join(tau)},))")
    src.prune()
    return src.compile("unrolled_torque")


def _kept(margin: str, floor: str) -> str:
    """The test m ≥ floor of (S1), written as the array guard's m / floor ≥ 1 for a scalar
    (the same answer for floor > 0, NaN failing both) and elementwise for a _Vec."""
    if isinstance(margin, _Vec):
        return f"({margin} >= {floor}).all()"
    return f"{margin} / {floor} >= 1.0"


def unrolled_guard(guard: Safeguard) -> Kernel | None:
    """``f(x, ẋ) -> (τ, V)``: the wrapped law's torque when it passes the safeguard's test
    (S1) on the one-step frozen prediction, else None (the safeguard then runs its full
    search). Only for laws ``unrolled_law`` covers and ``substeps == 1``; extra constraints
    without a scalar form (Clearance) run their own array code inside, like the law's."""
    law = guard.law
    extra = guard.guarded.configuration[len(law.constraints.configuration):]
    if guard.substeps != 1 or not _supported(law, (*law.constraints.configuration, *extra)):
        return None
    n = law.model.n
    src = _Source()
    em = _Emitter(law, src)
    em.sample_values = {}
    tau, d, bias, barrier = em.emit_law(coriolis=True)
    # the margins at x: the law's barrier values where they are the margins, else (a
    # localised barrier, Clearance's φ̃) the constraint's own values; then the extra ones
    # (an array constraint's margins stay one ndarray, a _Vec, through floors and checks)
    here = _Arrays(em, em.x, None, "x")
    margins, at = [], 0
    for c in law.constraints.configuration:
        k = len(c.names)
        if c.barrier_is_margin:
            margins += barrier[at:at + k]
        elif id(c) in em.sample_values:
            margins.append(em.sample_values[id(c)])
        else:
            margins += em.configuration([c], em.x, here, None, vectors=True)
        at += k
    margins += em.configuration(extra, em.x, here, None, vectors=True) + barrier[at:]
    h = guard.period
    nc = guard._n_config
    keep, keep_half = guard.keep, guard.keep_half
    floor, floor_mid = [], []
    at = 0
    for m in margins:  # the floors of (S1): δ + e^{−κh}(m − δ), and e^{−κh/2} at mid-period
        k = m.size if isinstance(m, _Vec) else 1
        shares = [(floor, keep)] + ([(floor_mid, keep_half)] if at < nc else [])
        if isinstance(m, _Vec):
            delta = em.constant(guard.cushion[at:at + k].copy())
            for out, share in shares:
                f = src.fresh("flv")
                src(f"{f} = {delta} + {_num(share)} * ({m} - {delta})")
                if guard._extra:
                    src(f"{f} = _maximum({f}, 1e-300)")
                out.append(_Vec.of(f, k))
        else:
            delta = _num(float(guard.cushion[at]))
            for out, share in shares:
                f = src.fresh("fl")
                src(f"{f} = {delta} + {_num(share)} * ({m} - {delta})")
                if guard._extra:
                    src(f"{f} = max({f}, 1e-300)")
                out.append(f)
        at += k
    # the torque the plant receives, and the predicted acceleration D⁻¹(τ − C ẋ − g − f)
    held = tau
    if guard.torque_limit is not None:
        t_mat = law.model.coordinates.matrix.tolist()
        lim = np.broadcast_to(guard.torque_limit, (n,)).tolist()
        tq = []
        for j in range(n):
            name = src.fresh("tq")
            col = [t_mat[a][j] for a in range(n)]  # τ_q = Tᵀ τ
            src(f"{name} = min(max({_lin(col, tau)}, {_num(-lim[j])}), {_num(lim[j])})")
            tq.append(name)
        held = []
        for expr in em.to_x(tq):
            name = src.fresh("th")
            src(f"{name} = {expr}")
            held.append(name)
    rhs = []
    for i in range(n):
        name = src.fresh("ra")
        src(f"{name} = {held[i]} - {bias[i]}")
        rhs.append(name)
    acc = _cholesky_solve(src, [[d[i][j] for j in range(n)] for i in range(n)], rhs, "a",
                          em.inertia)
    half, hh, eighth = 0.5 * h, 0.5 * h * h, 0.125 * h * h
    x1 = [src.fresh("xe") for _ in range(n)]
    v1 = [src.fresh("ve") for _ in range(n)]
    for i in range(n):
        src(f"{x1[i]} = (x{i} + {_num(h)} * v{i}) + {_num(hh)} * {acc[i]}")
        src(f"{v1[i]} = v{i} + {_num(h)} * {acc[i]}")
    configuration = (*law.constraints.configuration, *extra)
    end = _Arrays(em, x1)
    mids: list[str] = []
    if nc:
        xm = [src.fresh("xm") for _ in range(n)]
        for i in range(n):
            src(f"{xm[i]} = (x{i} + {_num(half)} * v{i}) + {_num(eighth)} * {acc[i]}")
        ends, mids = em.configuration_at_two(configuration, x1, xm)
    else:
        ends = []
    ends += em.velocity_values(law.constraints.velocity, end.q, v1)
    checks = [_kept(m, f) for m, f in zip(ends, floor, strict=True)]
    checks += [_kept(m, f) for m, f in zip(mids, floor_mid, strict=True)]
    src(f"if not ({' and '.join(checks)}):")
    src("    return None")
    src(f"return _array(({', '.join(tau)},)), V")
    return src.compile("unrolled_guard")
