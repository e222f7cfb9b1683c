"""A scenario to start from, for any arm: its joint ranges and limits, PD + gravity and CPBC.

The target is the middle of every joint's range (0 where a joint has none) unless the caller
gives one (``cpbc.robot`` lowers it where the motors cannot carry the arm there), the case
starts a little off it toward the middle of the ranges, the gains are physical (ω_n, ζ; see
cpbc.scenario.gain_check), and the admissible set is the arm's own: the position ranges of the
joints that have one and, when every joint declares one, half its rate limits. For an arm
whose velocity limits fall toward the ends of its ranges (the fr3), the ranges are narrowed
to where those limits allow half the peak velocity, and the rate bounds are what they allow
there (``from_model``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cpbc.arrays import Array


@dataclass(frozen=True)
class JointLimits:
    """What a model declares about its driven joints, in their order.

    Attributes:
        names: joint names, shape (n,).
        lower, upper: position range [rad or m], ±inf where there is none.
        velocity: rate limit [rad/s or m/s], inf where there is none.
        effort: effort limit [N·m or N], inf where there is none.
        kept: for an arm with position-dependent velocity limits, the range (lower,
            upper) inside its own on which they allow half the peak velocity, else None.
    """

    names: tuple[str, ...]
    lower: Array
    upper: Array
    velocity: Array
    effort: Array
    kept: tuple[Array, Array] | None = None

    @property
    def bounded(self) -> list[int]:
        """Indices of the joints with a position range."""
        return [i for i in range(len(self.names))
                if np.isfinite(self.lower[i]) and np.isfinite(self.upper[i])]


def _round(values: Array) -> list[float]:
    return [round(float(v), 4) for v in values]


def home(limits: JointLimits, target: Array | None = None) -> tuple[Array, Array]:
    """A target (by default mid-range, 0 where unbounded) and a start 0.1 rad (at most a
    quarter of the range) off it on every joint, toward the middle of the range (below it
    from the middle itself)."""
    lo, hi = limits.lower, limits.upper
    finite = np.isfinite(lo) & np.isfinite(hi)
    middle = np.where(finite, 0.5 * (np.where(finite, lo, 0) + np.where(finite, hi, 0)), 0.0)
    target = middle if target is None else np.asarray(target, dtype=float)
    width = np.where(finite, hi - lo, np.inf)
    toward = np.where(target > middle, -1.0, np.where(target < middle, 1.0, -1.0))
    start = target + toward * np.minimum(0.1, 0.25 * width)
    return np.array(_round(target)), np.array(_round(start))


def skeleton(model: str, limits: JointLimits, duration: float = 5.0,
             omega_n: float = 10.0, zeta: float = 1.0, target: Array | None = None) -> dict:
    """A valid scenario (as a dict for YAML) of the arm ``model`` (a name or a path), toward
    ``target`` (by default mid-range, see :func:`home`)."""
    target, start = home(limits, target)
    constraints: list[dict] = []
    bounded = limits.bounded
    if bounded:
        entry: dict = {"type": "joint_position_limit", "name": "joint_ranges",
                       "lower": "from_model", "upper": "from_model"}
        if limits.kept is not None:  # rounded inward: the bounds stay inside the limits
            entry["lower"] = [float(v) for v in np.ceil(limits.kept[0][bounded] * 1e3) / 1e3]
            entry["upper"] = [float(v) for v in np.floor(limits.kept[1][bounded] * 1e3) / 1e3]
        if len(bounded) < len(limits.names):
            entry["joints"] = [limits.names[i] for i in bounded]
        constraints.append(entry)
    if np.all(np.isfinite(limits.velocity)):
        constraints.append({"type": "joint_rate_limit", "name": "joint_rates",
                            "bounds": "from_model",
                            "scale": 0.5 if limits.kept is None else 1.0})
    controllers: list[dict] = [
        {"type": "pd_gravity", "name": "PD_gravity", "omega_n": omega_n, "zeta": zeta},
    ]
    if constraints:
        controllers.append({"type": "cpbc", "name": "CPBC", "omega_n": omega_n, "zeta": zeta,
                            "shaping": {"type": "power", "alpha": 0.2}})
    return {
        "name": _safe_name(model),
        "description": f"starting point for {model}: edit the target, cases and gains",
        "robot": {"model": model},
        "simulation": {"duration": duration, "timestep": 0.001},
        "target": _round(target),
        "cases": [{"name": "start", "position": _round(start)}],
        "constraints": constraints,
        "controllers": controllers,
    }


def _safe_name(model: str) -> str:
    stem = model.replace("\\", "/").rsplit("/", 1)[-1].rsplit(".", 1)[0]
    name = "".join(c if c.isalnum() or c in "_.+-" else "_" for c in stem).lstrip("_.+-")
    return (name or "arm") + "_start"

