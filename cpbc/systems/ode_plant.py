"""What a Part-I system is to the rest of the product: a plant description.

An :class:`OdePlant` names the law's state x and input u, lists its constrained quantities with
their bounds, and gives the ODE ẋ = f(x, u, t) (the continuous-time reference; for a system
with no mechanics to simulate, such as the integrator chain of §4.4, the only plant). A
:class:`Plant` is an OdePlant with a MuJoCo model: it also reads x from MuJoCo (qpos, qvel and
time), writes u into ``ctrl`` (and any prescribed exogenous input before every physics step).
Neither holds simulator state of its own.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Literal

import mujoco
import numpy as np

from cpbc.arrays import Array
from cpbc.errors import CpbcError, ModelError
from cpbc.margin_kinds import STATE, MarginType

State = tuple[float, ...]


@dataclass(frozen=True)
class ConstrainedQuantity:
    """A state or input component that must stay in (lower, upper).

    Attributes:
        name: e.g. "x3" or "tau".
        lower, upper: the open interval of allowed values.
        source: "state" (x[index]) or "input" (u).
        index: component of x (ignored for inputs).
        margin_type: the type of its margin, with its unit (cpbc.margin_kinds): the results
            group and label the margins by it.
        limit: a limit of the plant, not a constraint of the problem (an actuator that
            saturates, the stall): reported with its bound, and its crossing named
            (``RunSummary.system.limits_reached``), but no run is ``constraint_violated`` by it.
    """

    name: str
    lower: float
    upper: float
    source: Literal["state", "input"] = "state"
    index: int = 0
    margin_type: MarginType = STATE
    limit: bool = False

    def __post_init__(self) -> None:
        if self.source not in ("state", "input"):
            raise CpbcError(f"source must be 'state' or 'input', not {self.source!r}")
        if not self.lower < self.upper:
            raise CpbcError(f"{self.name}: empty interval ({self.lower}, {self.upper})")

    def value(self, x: State, u: float) -> float:
        """The quantity at state x and input u."""
        return u if self.source == "input" else x[self.index]

    @property
    def unit(self) -> str:
        return self.margin_type.unit

    def values(self, states: Array, inputs: Array) -> Array:
        """The quantity along a run: states (N, n) and inputs (N,) → (N,)."""
        return np.asarray(inputs if self.source == "input" else states[:, self.index], float)

    def margins(self, states: Array, inputs: Array) -> Array:
        """The margin along a run, the one definition the summary, the figures and the page
        read: the distance to the nearer bound, min(v − lower, upper − v), in the quantity's
        unit (> 0 inside, 0 on a bound, < 0 past it)."""
        v = self.values(states, inputs)
        return np.minimum(v - self.lower, self.upper - v)

    def margin(self, x: State, u: float) -> float:
        """The margin (:meth:`margins`) at state x and input u."""
        return float(self.margins(np.asarray([x], float), np.asarray([u], float))[0])


class OdePlant(ABC):
    """A Part-I system as an ODE: its state and input names, constraints and ẋ = f(x, u, t)."""

    #: names of the components of the law's state x
    state_names: tuple[str, ...]
    #: name and unit of the law's input u
    input_name: str
    #: whether MuJoCo can simulate it: not an ODE with no MJCF (the integrator chain)
    physics: ClassVar[bool] = False

    @property
    @abstractmethod
    def constrained(self) -> tuple[ConstrainedQuantity, ...]:
        """The constrained quantities with their bounds."""

    @abstractmethod
    def rhs(self, x: State, u: float, t: float) -> State:
        """ẋ = f(x, u, t), the continuous-time reference."""

    def breakpoints(self) -> tuple[float, ...]:
        """Times where f has a kink in t (integrate an ODE piecewise there); none by default."""
        return ()


class Plant(OdePlant):
    """A Part-I system with a MuJoCo model: its MJCF and the maps between x, u and MuJoCo."""

    #: False when the MJCF only replays logged states (the ODE is the plant, e.g. an aircraft
    #: whose forces depend on α̇): the MuJoCo backend refuses it
    physics: ClassVar[bool] = True

    @property
    @abstractmethod
    def mjcf(self) -> Path:
        """The MJCF file."""

    def load(self) -> mujoco.MjModel:
        """Compile the MJCF and check that it matches this description."""
        if not self.mjcf.is_file():
            raise ModelError(f"model file {self.mjcf} is missing")
        model = mujoco.MjModel.from_xml_path(str(self.mjcf))
        self.verify(model)
        return model

    @abstractmethod
    def verify(self, model: mujoco.MjModel) -> None:
        """Raise :class:`~cpbc.errors.ModelError` unless ``model`` matches this plant."""

    @abstractmethod
    def read_state(self, model: mujoco.MjModel, data: mujoco.MjData) -> State:
        """The law's state x from ``data.qpos``, ``data.qvel`` and ``data.time``."""

    @abstractmethod
    def write_state(self, model: mujoco.MjModel, data: mujoco.MjData, x: State) -> None:
        """Set qpos/qvel so that :meth:`read_state` gives x at ``data.time``."""

    @abstractmethod
    def write_input(self, model: mujoco.MjModel, data: mujoco.MjData, u: float) -> None:
        """Write the law's input u into ``data.ctrl``."""

    def before_step(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Set prescribed (exogenous) inputs for the coming physics step; none by default."""


def check_close(what: str, model_value: float, expected: float, rtol: float = 1e-6) -> None:
    """:class:`ModelError` unless the model's value matches the description's."""
    if not math.isclose(model_value, expected, rel_tol=rtol):
        raise ModelError(
            f"{what}: the MJCF gives {model_value:.9g}, the plant expects {expected:.9g}"
        )
