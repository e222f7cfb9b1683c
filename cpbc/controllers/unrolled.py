"""The CPBC law (and its safeguard's acceptance test) unrolled into straight-line scalar code.

On a small arm every numpy call costs more than the arithmetic it does: here about 1 µs per
call against some 40 ns per float operation, so the array law of cpbc.controllers.cpbc
spends most of a 2-link step in call overhead. At construction this module writes the same
formulas out over Python floats — every loop over n unrolled, every product with a constant
(the coordinate map, constraint rows, gains, cushions) folded in, zero coefficients dropped —
and compiles the source once. Pinocchio still computes D, C ẋ, g and the kinematics.

What is unrolled, for n ≤ ``MAX_JOINTS``:

- the law of CPBC and BPBC (Theorem 6.9 in the form of the class docstring of CPBC;
  Theorem 7.7) with quadratic or log-cosh potential, linear or tanh damping, any shaping;
- the constraints ``LinearLimit``, ``PointOutsideSphere`` (on the law's own model) and
  ``RateLimit``;
- the safeguard's test (S1) of the law's torque with the one-step frozen prediction
  (cpbc.controllers.safeguard, ``substeps == 1``).

Anything else keeps the array code, which stays the reference: the tests check that both
give the same torque, V and acceptance on random states. The generated function returns
None wherever the array code has something to say — a margin ≤ 0 or NaN (it raises the
named ConstraintViolation), a factorisation that is not positive definite (it falls back to
LU), a torque the safeguard must modify — and the caller then runs the array code.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
import pinocchio as pin

from cpbc.constraints.base import Array
from cpbc.constraints.linear_limit import LinearLimit
from cpbc.constraints.point_outside_sphere import PointOutsideSphere
from cpbc.constraints.rate_limit import RateLimit
from cpbc.controllers.shaping import Identity, Power
from cpbc.controllers.terms import LinearDamping, LogCoshPotential, QuadraticPotential, TanhDamping

if TYPE_CHECKING:
    from cpbc.constraints.base import ConfigurationConstraint
    from cpbc.controllers.cpbc import CPBC
    from cpbc.controllers.safeguard import Safeguard

MAX_JOINTS = 3  # beyond this the unrolled Cholesky and congruence outgrow their gain
Kernel = Callable[[Array, Array], "tuple[Array, float] | None"]


def _num(c: float) -> str:
    """A float literal that reads back exactly."""
    return repr(float(c))


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


class _Source:
    """Lines of one generated function and the constants it reads."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.lines: list[str] = []
        self.env: dict[str, object] = {
            "_array": np.array, "log": math.log, "exp": math.exp, "sqrt": math.sqrt,
            "tanh": math.tanh, "log1p": math.log1p, "_fsum": math.fsum, "_LN2": math.log(2.0),
        }
        self._count = 0

    def __call__(self, line: str) -> None:
        self.lines.append("    " + line)

    def fresh(self, prefix: str) -> str:
        self._count += 1
        return f"{prefix}{self._count}"

    def compile(self, name: str) -> Kernel:
        text = f"def {name}(x, dx):\n" + "\n".join(self.lines) + "\n"
        namespace = dict(self.env)
        exec(compile(text, f"<cpbc unrolled {name}>", "exec"), namespace)
        fn = namespace[name]
        fn.source = text  # type: ignore[attr-defined]
        return fn  # type: ignore[return-value]


def _supported(law: CPBC, configuration: Sequence[ConfigurationConstraint]) -> bool:
    model = law.model
    if model.n > MAX_JOINTS:
        return False
    if type(law.potential) not in (QuadraticPotential, LogCoshPotential):
        return False
    if type(law.damping) not in (LinearDamping, TanhDamping):
        return False
    for c in configuration:
        if type(c) is PointOutsideSphere:
            if c.model is not model:
                return False
        elif type(c) is not LinearLimit:
            return False
    return all(type(c) is RateLimit for c in law.constraints.velocity)


def _cholesky_solve(src: _Source, a: list[list[str]], rhs: list[str], tag: str) -> list[str]:
    """Emit y = A⁻¹ rhs for symmetric A (lower entries a[i][j], i ≥ j) by Cholesky; the
    function returns None on a pivot that is not > 0 (the array code then uses LU)."""
    n = len(rhs)
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

    def __init__(self, law: CPBC, src: _Source) -> None:
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
        )
        self.x = [f"x{i}" for i in range(n)]
        self.v = [f"v{i}" for i in range(n)]

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
    def dynamics(self, q: str, dq: str | None) -> tuple[list[list[str]], list[str], list[str]]:
        """D (symmetric, names), g and C ẋ + f in x-coordinates (C ẋ + f only with dq)."""
        src, n, ti = self.src, self.n, self.t_inv
        m = src.fresh("M")
        src(f"{m} = _crba(_model, _data, {q}).tolist()")
        mij = [[f"{m}[{min(i, j)}][{max(i, j)}]" for j in range(n)] for i in range(n)]
        d = [[""] * n for _ in range(n)]
        for a in range(n):
            for b in range(a, n):
                coeff: dict[str, float] = {}
                for i in range(n):
                    for j in range(n):
                        c = ti[i][a] * ti[j][b]
                        if c:
                            coeff[mij[i][j]] = coeff.get(mij[i][j], 0.0) + c
                name = f"D{a}{b}"
                src(f"{name} = {_lin(list(coeff.values()), list(coeff.keys()))}")
                d[a][b] = d[b][a] = name
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

    def _point(self, con: PointOutsideSphere) -> tuple[str, str]:
        """Position names of the constraint's point, after the frame is placed."""
        src = self.src
        place = src.fresh("P")
        src(f"{place} = _data.oMf[{con.frame_id}]")
        p = [src.fresh("p") for _ in range(3)]
        src(f"{', '.join(p)}, = {place}.translation.tolist()")
        if con.offset is None:
            return place, ", ".join(p)
        rot = src.fresh("R")
        src(f"{rot} = {place}.rotation.tolist()")
        o = con.offset.tolist()
        r = [src.fresh("r") for _ in range(3)]
        for k in range(3):
            src(f"{r[k]} = {_lin(o, [f'{rot}[{k}][{m}]' for m in range(3)])}")
            src(f"{p[k]} += {r[k]}")
        return place, ", ".join(p) + "|" + ", ".join(r)

    def point_outside_sphere(self, con: PointOutsideSphere, q: str,
                             grad: list[list[str]] | None) -> list[str]:
        src = self.src
        if grad is not None:
            jac = src.fresh("J")
            src(f"{jac} = _fj(_model, _data, {q}, {con.frame_id}, _LWA).tolist()")
        else:
            src(f"_fk(_model, _data, {q})")
        _, names = self._point(con)
        p, _, r = names.partition("|")
        d = [src.fresh("d") for _ in range(3)]
        for k, (pk, ck) in enumerate(zip(p.split(", "), con.centre.tolist(), strict=True)):
            src(f"{d[k]} = {pk} - {_num(ck)}" if ck else f"{d[k]} = {pk}")
        phi = src.fresh("phi")
        src(f"{phi} = {d[0]} * {d[0]} + {d[1]} * {d[1]} + {d[2]} * {d[2]} - {_num(con._r2)}")
        if grad is None:
            return [phi]
        # ∂p/∂q column c: v_c − r × ω_c (with an offset r from the frame's origin)
        rr = r.split(", ") if r else None
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

    def configuration(self, cons: Sequence[ConfigurationConstraint], x: list[str], q: str,
                      grad: list[list[str]] | None) -> list[str]:
        out: list[str] = []
        for c in cons:
            if isinstance(c, LinearLimit):
                out += self.linear_limit(c, x, grad)
            else:
                out += self.point_outside_sphere(c, q, grad)  # type: ignore[arg-type]
        return out

    @staticmethod
    def all_positive(src: _Source, margins: list[str]) -> None:
        """Return None unless every margin is > 0 (False for NaN too)."""
        if margins:
            src(f"if not ({' and '.join(f'{m} > 0.0' for m in margins)}):")
            src("    return None")

    # -- the law -----------------------------------------------------------------------------
    def emit_law(self) -> tuple[list[str], list[list[str]], list[str], list[str], str]:
        """Emit τ (names) and V; returns τ, D, g + c (the bias), the margins and V."""
        src, n, law = self.src, self.n, self.law
        src(f"{', '.join(self.x)}, = x.tolist()")
        src(f"{', '.join(self.v)}, = dx.tolist()")
        q = self.joint_array(self.x, "x")
        dq = self.joint_array(self.v, "dx")
        d, g, c = self.dynamics(q, dq)
        grad: list[list[str]] = [[] for _ in range(n)]
        weight: list[list[list[str]]] = [[[] for _ in range(n)] for _ in range(n)]
        phis = self.configuration(law.constraints.configuration, self.x, q, grad)
        psis: list[str] = []
        for con in law.constraints.velocity:
            psis += self.rate_limit(con, self.v, weight)  # type: ignore[arg-type]
        self.all_positive(src, phis + psis)
        logs = f"_fsum(({', '.join(f'log({m})' for m in phis + psis)},))" if phis or psis \
            else "0.0"
        src(f"lsum = {logs}")
        # potential, damping and L
        kp, kd, xd = law.kp.tolist(), law.kd.tolist(), law.target.tolist()
        e = [f"e{i}" for i in range(n)]
        for i in range(n):
            src(f"{e[i]} = x{i} - {_num(xd[i])}")
        if isinstance(law.potential, LogCoshPotential):
            xi = law.potential.xi.tolist()
            pot = " + ".join(
                f"{_num(kp[i] / xi[i])} * (abs({_num(xi[i])} * {e[i]}) + "
                f"log1p(exp(-2.0 * abs({_num(xi[i])} * {e[i]}))) - _LN2)" for i in range(n))
            dU = [f"{_num(kp[i])} * tanh({_num(xi[i])} * {e[i]})" for i in range(n)]
        else:
            pot = "0.5 * (" + " + ".join(f"{_num(kp[i])} * {e[i]} * {e[i]}" for i in range(n)) + ")"
            dU = [f"{_num(kp[i])} * {e[i]}" for i in range(n)]
        if isinstance(law.damping, TanhDamping):
            gam = law.damping.gamma.tolist()
            damp = [f"{_num(kd[i])} * tanh({_num(gam[i])} * v{i})" for i in range(n)]
        else:
            damp = [f"{_num(kd[i])} * v{i}" for i in range(n)]
        dv = [f"dv{a}" for a in range(n)]
        for a in range(n):
            src(f"{dv[a]} = " + " + ".join(f"{d[a][b]} * v{b}" for b in range(n)))
        src("lag = 0.5 * (" + " + ".join(f"v{a} * {dv[a]}" for a in range(n)) + f") + {pot}")
        shaping = law.shaping
        if type(shaping) is Identity:
            src("rho = lag")
        elif type(shaping) is Power:
            src(f"rho = {_num(shaping.alpha)} * lag")
        else:
            src.env["_ratio"] = shaping.ratio
            src("rho = _ratio(lsum) * lag")
        a_terms = []
        for i in range(n):
            b = f" + rho * ({' + '.join(grad[i])})" if grad[i] else ""
            a_terms.append(f"-({dU[i]}) - {damp[i]}{b}")
        tau = [f"tau{i}" for i in range(n)]
        if not law.constraints.velocity:
            for i in range(n):
                src(f"{tau[i]} = {g[i]} + {a_terms[i]}")
        else:
            rhs = [f"r{i}" for i in range(n)]
            for i in range(n):
                src(f"{rhs[i]} = {a_terms[i]} - {c[i]}")
            mat = [[d[i][j] + (f" + rho * ({' + '.join(weight[i][j])})" if weight[i][j] else "")
                    for j in range(n)] for i in range(n)]
            y = _cholesky_solve(src, mat, rhs, "k")
            for i in range(n):
                src(f"{tau[i]} = {g[i]} + {c[i]} + " + " + ".join(
                    f"{d[i][j]} * {y[j]}" for j in range(n)))
        if type(shaping) is Identity:
            log_s = "lsum"
        elif type(shaping) is Power:
            log_s = f"{_num(shaping.alpha)} * lsum"
        else:
            src.env["_log_s"] = shaping.log_s
            log_s = "_log_s(lsum)"
        src(f"V = exp(log(lag) - {log_s}) if lag > 0.0 else 0.0")
        bias = [f"({g[i]} + {c[i]})" if c else g[i] for i in range(n)]
        return tau, d, bias, phis + psis, "V"


def unrolled_law(law: CPBC) -> Kernel | None:
    """``f(x, ẋ) -> (τ, V)`` for CPBC/BPBC on a small arm, or None when something in the law
    has no scalar form (the law then keeps its array code)."""
    if not _supported(law, law.constraints.configuration):
        return None
    src = _Source(law.model.n)
    em = _Emitter(law, src)
    tau, _, _, _, v = em.emit_law()
    src(f"return _array(({', '.join(tau)},)), {v}")
    return src.compile("unrolled_law")


def unrolled_guard(guard: Safeguard) -> Kernel | None:
    """``f(x, ẋ) -> (τ, V)``: the wrapped law's torque when it passes the safeguard's test
    (S1) on the one-step frozen prediction, else None (the safeguard then runs its full
    search). Only for laws ``unrolled_law`` covers, ``substeps == 1`` and extra constraints
    that have a scalar form."""
    from cpbc.controllers.cpbc import CPBC  # the laws import this module

    law = guard.law
    if not isinstance(law, CPBC) or guard.substeps != 1:
        return None
    extra = guard.guarded.configuration[len(law.constraints.configuration):]
    if not _supported(law, (*law.constraints.configuration, *extra)):
        return None
    n = law.model.n
    src = _Source(n)
    em = _Emitter(law, src)
    tau, d, bias, margins, v = em.emit_law()
    if extra:  # their margins at x, between the law's configuration and velocity ones
        cfg_law = sum(len(c.names) for c in law.constraints.configuration)
        now = em.configuration(extra, em.x, em.joint_array(em.x, "x"), None)
        margins = margins[:cfg_law] + now + margins[cfg_law:]
    h = guard.period
    nc = guard._n_config
    cushion = guard.cushion.tolist()
    keep, keep_half = guard.keep, guard.keep_half
    floor, floor_mid = [], []
    for i, m in enumerate(margins):
        f = src.fresh("fl")
        src(f"{f} = {_num(cushion[i])} + {_num(keep)} * ({m} - {_num(cushion[i])})")
        if guard._extra:
            src(f"{f} = max({f}, 1e-300)")
        floor.append(f)
        if i < nc:
            fm = src.fresh("fm")
            src(f"{fm} = {_num(cushion[i])} + {_num(keep_half)} * ({m} - {_num(cushion[i])})")
            if guard._extra:
                src(f"{fm} = max({fm}, 1e-300)")
            floor_mid.append(fm)
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
    acc = _cholesky_solve(src, [[d[i][j] for j in range(n)] for i in range(n)], rhs, "a")
    half, hh, eighth = 0.5 * h, 0.5 * h * h, 0.125 * h * h
    x1 = [src.fresh("xe") for _ in range(n)]
    v1 = [src.fresh("ve") for _ in range(n)]
    for i in range(n):
        src(f"{x1[i]} = (x{i} + {_num(h)} * v{i}) + {_num(hh)} * {acc[i]}")
        src(f"{v1[i]} = v{i} + {_num(h)} * {acc[i]}")
    configuration = (*law.constraints.configuration, *extra)
    def placed(xs: list[str]) -> str:  # Pinocchio's q only where a point needs it
        points = any(type(c) is PointOutsideSphere for c in configuration)
        return em.joint_array(xs, None) if points else ""

    ends = em.configuration(configuration, x1, placed(x1), None)
    for con in law.constraints.velocity:
        ends += em.rate_limit(con, v1, None)  # type: ignore[arg-type]
    checks = [f"{m} / {f} >= 1.0" for m, f in zip(ends, floor, strict=True)]
    if nc:
        xm = [src.fresh("xm") for _ in range(n)]
        for i in range(n):
            src(f"{xm[i]} = (x{i} + {_num(half)} * v{i}) + {_num(eighth)} * {acc[i]}")
        mids = em.configuration(configuration, xm, placed(xm), None)
        checks += [f"{m} / {f} >= 1.0" for m, f in zip(mids, floor_mid, strict=True)]
    src(f"if not ({' and '.join(checks)}):")
    src("    return None")
    src(f"return _array(({', '.join(tau)},)), {v}")
    return src.compile("unrolled_guard")
