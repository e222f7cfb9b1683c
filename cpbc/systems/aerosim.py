"""The Aerosonde UAV as the AeroSim blockset describes it (longitudinal part): the public
parameters of its sample aircraft (``aerosondeconfig.m``, Unmanned Dynamics 2002; PART1 Ch. 5
§3.4), the ISA air density, the AeroSim coefficient model and the full-throttle thrust.

The thesis ran §5.3.1/§5.4.3 on this model and could not print its coefficients; the blockset's
sample file is public, so the numbers below are AeroSim's own (SI, derivatives per rad).

Coefficient model (AeroSim; α and V clipped to their bounds first, which is the only stall
model AeroSim has):

    C_L = C_L0 + C_Lα α + C_LδE δE + (c̄/2V)(C_Lα̇ α̇ + C_Lq q)
    C_D = C_Dmin + (C_L − C_Lmind)²/(π e AR) + |C_DδE δE|,   AR = b²/S
    C_M = C_M0 + C_Mα α + C_MδE δE + (c̄/2V)(C_Mα̇ α̇ + C_Mq q)
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cpbc.errors import CpbcError

#: standard gravity [m/s²] (the thesis does not print its g)
GRAVITY = 9.81

# International Standard Atmosphere, troposphere
_T0, _P0, _LAPSE, _R_AIR = 288.15, 101_325.0, 0.0065, 287.053


def isa_density(altitude: float) -> float:
    """ρ [kg/m³] of the ISA troposphere at ``altitude`` [m] (below 11 km)."""
    temperature = _T0 - _LAPSE * altitude
    pressure = _P0 * (temperature / _T0) ** (GRAVITY / (_LAPSE * _R_AIR))
    return pressure / (_R_AIR * temperature)


@dataclass(frozen=True)
class AerosondeParameters:
    """AeroSim's Aerosonde, longitudinal data (defaults: ``aerosondeconfig.m``, gross mass)."""

    wing_area: float = 0.55  # S [m²]
    chord: float = 0.189941  # c̄, mean aerodynamic chord [m]
    span: float = 2.8956  # b [m]
    mass: float = 13.5  # gross [kg] (8.5 empty)
    iyy: float = 1.135  # gross J_y [kg m²]
    alpha_bounds: tuple[float, float] = (-0.1, 0.3)  # AlphaBnd [rad]: the stall clip
    airspeed_bounds: tuple[float, float] = (15.0, 50.0)  # VaBnd [m/s]
    cl0: float = 0.23
    cl_alpha: float = 5.6106
    cl_elevator: float = 0.13
    cl_alpha_dot: float = 1.9724
    cl_q: float = 7.9543
    cl_min_drag: float = 0.23  # C_Lmind
    cd_min: float = 0.0434
    cd_elevator: float = 0.0135
    oswald: float = 0.75
    cm0: float = 0.135
    cm_alpha: float = -2.7397
    cm_elevator: float = -0.9918
    cm_alpha_dot: float = -10.3796
    cm_q: float = -38.2067
    # propeller: advance ratio J grid and C_T(J), C_P(J); radius [m]
    prop_j: tuple[float, ...] = (-1, 0, .1, .2, .3, .35, .4, .45, .5, .6, .7, .8, .9, 1, 1.2, 2)
    prop_ct: tuple[float, ...] = (.0492, .0286, .0266, .0232, .0343, .034, .0372, .0314, .0254,
                                  .0117, -.005, -.0156, -.0203, -.0295, -.04, -.1115)
    prop_cp: tuple[float, ...] = (.0199, .0207, .0191, .0169, .0217, .0223, .0254, .0235, .0212,
                                  .0146, .0038, -.005, -.0097, -.018, -.0273, -.0737)
    prop_radius: float = 0.254
    # engine: shaft power [W] at full throttle (MAP = 100 kPa column) against RPM
    engine_rpm: tuple[float, ...] = (1500, 2100, 2800, 3500, 4500, 5100, 5500, 6000, 7000)
    engine_power: tuple[float, ...] = (86.39, 224.31, 398.77, 531.45, 772.83, 993.37, 1059.76,
                                       1193.81, 1429.42)

    def __post_init__(self) -> None:
        for name in ("wing_area", "chord", "span", "mass", "iyy", "oswald", "prop_radius"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise CpbcError(f"Aerosonde parameter {name} = {value!r} must be > 0")

    @property
    def aspect_ratio(self) -> float:
        return self.span**2 / self.wing_area


@dataclass(frozen=True)
class AeroForces:
    """Lift, drag [N] and pitching moment [N m] at one state."""

    lift: float
    drag: float
    moment: float


def aero_forces(p: AerosondeParameters, rho: float, airspeed: float, alpha: float,
                alpha_dot: float, q: float, elevator: float) -> AeroForces:
    """The AeroSim coefficient model (module docstring) times q̄S (and c̄ for the moment)."""
    a = min(max(alpha, p.alpha_bounds[0]), p.alpha_bounds[1])  # stall: α saturates
    v = min(max(airspeed, p.airspeed_bounds[0]), p.airspeed_bounds[1])
    rate = p.chord / (2.0 * v)
    cl = (p.cl0 + p.cl_alpha * a + p.cl_elevator * elevator
          + rate * (p.cl_alpha_dot * alpha_dot + p.cl_q * q))
    cd = (p.cd_min + (cl - p.cl_min_drag) ** 2 / (math.pi * p.oswald * p.aspect_ratio)
          + abs(p.cd_elevator * elevator))
    cm = (p.cm0 + p.cm_alpha * a + p.cm_elevator * elevator
          + rate * (p.cm_alpha_dot * alpha_dot + p.cm_q * q))
    qs = 0.5 * rho * airspeed**2 * p.wing_area  # q̄S with the true airspeed
    return AeroForces(qs * cl, qs * cd, qs * p.chord * cm)


def full_throttle_thrust(p: AerosondeParameters, rho: float, airspeed: float) -> float:
    """T_max(V) [N]: thrust at the rpm where the full-throttle engine power equals the
    propeller's absorbed power C_P ρ n³ D⁵ (no engine dynamics; AeroSim's tables)."""
    diameter = 2.0 * p.prop_radius

    def propeller(n: float) -> tuple[float, float]:  # n [rev/s] → (thrust, power)
        j = airspeed / (n * diameter)
        ct = float(np.interp(j, p.prop_j, p.prop_ct))
        cp = float(np.interp(j, p.prop_j, p.prop_cp))
        return ct * rho * n**2 * diameter**4, cp * rho * n**3 * diameter**5

    def excess(n: float) -> float:
        return float(np.interp(60.0 * n, p.engine_rpm, p.engine_power)) - propeller(n)[1]

    # above the table's last rpm the engine's power is held (np.interp), so a light load
    # at low airspeed still finds its balance
    lo, hi = p.engine_rpm[0] / 60.0, 1.5 * p.engine_rpm[-1] / 60.0
    if excess(lo) * excess(hi) > 0:
        raise CpbcError(f"no full-throttle rpm balances the propeller at V = {airspeed:g} m/s")
    from scipy.optimize import brentq  # loaded when used (CLI start-up)

    return propeller(brentq(excess, lo, hi, xtol=1e-10))[0]
