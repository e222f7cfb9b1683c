"""Measure the claims of Ngo (2007) §5.3.1 and §5.4.3 on the AeroSim Aerosonde ODE plant.

Run from the repository root:  python tools/part1_ch5_report.py
Prints the numbers that docs/PART1_CH5.md tabulates (about 3 minutes on one core). Uses the
product's plant, laws and reference loop, the ones ``python -m cpbc.run ch5_aerosonde`` runs.
"""

from __future__ import annotations

import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import fsolve

ROOT = Path(__file__).resolve().parent.parent
sys.path[:0] = [str(ROOT)]

from cpbc.backstepping.altitude_backstepping import TraditionalAltitudeLaw  # noqa: E402
from cpbc.backstepping.altitude_command import AltitudeCommand, TrackingLaw  # noqa: E402
from cpbc.backstepping.altitude_law import AltitudeLaw  # noqa: E402
from cpbc.backstepping.constrained_altitude import (  # noqa: E402
    ConstrainedAltitudeGains,
    ConstrainedAltitudeLaw,
)
from cpbc.simulation.trajectory import SystemTrajectory, run_system_reference  # noqa: E402
from cpbc.systems.aerosim import (  # noqa: E402
    GRAVITY,
    AerosondeParameters,
    aero_forces,
    full_throttle_thrust,
    isa_density,
)
from cpbc.systems.aerosonde import AerosondePlant  # noqa: E402

DEG = 180.0 / math.pi
SAMPLE = 0.05


def fly(law: AltitudeLaw, steps: tuple[tuple[float, float], ...], duration: float,
        plant: AerosondePlant | None = None) -> tuple[SystemTrajectory, AerosondePlant]:
    plant = replace(plant or AerosondePlant(), command_times=tuple(t for t, _ in steps))
    k = TrackingLaw(law, AltitudeCommand(100.0, steps))
    return run_system_reference(plant, k, plant.initial_state(100.0), duration, SAMPLE), plant


def crossing(t: np.ndarray, v: np.ndarray, level: float, after: float = 0.0) -> float:
    """First time ≥ ``after`` at which v reaches ``level`` (linear interpolation)."""
    idx = np.nonzero((t >= after) & (v >= level))[0]
    if not idx.size:
        return math.nan
    i = idx[0]
    if i == 0:
        return float(t[0])
    return float(t[i - 1] + (level - v[i - 1]) / (v[i] - v[i - 1]) * (t[i] - t[i - 1]))


def saturated_time(tr: SystemTrajectory, limit: float = 1.0) -> float:
    """Total time [s] the demanded elevator lies beyond the actuator's range."""
    return float(np.sum(np.abs(tr.input) >= limit) * SAMPLE)


def step_metrics(tr: SystemTrajectory, h0: float, h1: float, t0: float) -> dict[str, float]:
    t, h, vz = tr.time, tr.state[:, 0], tr.state[:, 1]
    sign = 1.0 if h1 > h0 else -1.0
    frac = (sign * (h - h0)) / abs(h1 - h0)
    t10, t90 = crossing(t, frac, 0.1, t0), crossing(t, frac, 0.9, t0)
    window = t >= t0
    i = int(np.argmax(sign * vz * window))
    return {"peak_vz": float(vz[i]), "t_peak": float(t[i]), "rise_10_90": t90 - t10,
            "t_90": t90 - t0, "t_within_1m": crossing(t, frac, 1.0 - 1.0 / abs(h1 - h0), t0) - t0,
            "overshoot": float(np.max(sign * (h[window] - h1), initial=-math.inf)),
            "alpha_max_deg": float(tr.state[:, 2].max() * DEG)}


def max_climb_rate(plant: AerosondePlant) -> float:
    """Steady climb at full throttle and 23 m/s: (α, δE, γ) balancing forces and moment."""
    p, v, rho = plant.parameters, plant.airspeed, isa_density(plant.altitude)
    thrust = full_throttle_thrust(p, rho, v)

    def residual(z: np.ndarray) -> list[float]:
        alpha, elevator, gamma = (float(c) for c in z)
        f = aero_forces(p, rho, v, alpha, 0.0, 0.0, elevator)
        return [thrust * math.cos(alpha) - f.drag - p.mass * GRAVITY * math.sin(gamma),
                thrust * math.sin(alpha) + f.lift - p.mass * GRAVITY * math.cos(gamma),
                f.moment]

    _, _, gamma = fsolve(residual, [0.09, -0.12, 0.1], xtol=1e-12)
    return v * math.sin(float(gamma))


def section_figures() -> None:
    plant = AerosondePlant()
    model = plant.design_model()
    trad, cons = TraditionalAltitudeLaw(model), ConstrainedAltitudeLaw(model)
    print("## design model and plant")
    a0, d0 = model.trim()
    print(f"design trim α0 = {a0 * DEG:.3f}°, δE0 = {d0 * DEG:.3f}°; plant trim α, δE, T = "
          f"{plant.trim[0] * DEG:.3f}°, {plant.trim[1] * DEG:.3f}°, {plant.trim[2]:.3f} N")
    print(f"steady full-throttle climb at 23 m/s: v_z = {max_climb_rate(plant):.3f} m/s")

    print("\n## Fig 5.1 (traditional, 150 m at 10 s, 130 m at 100 s), 200 s")
    tr, _ = fly(trad, ((10.0, 150.0), (100.0, 130.0)), 200.0)
    m = step_metrics(tr.__class__(**{**tr.__dict__, "time": tr.time[tr.time < 100],
                                     "state": tr.state[tr.time < 100],
                                     "input": tr.input[tr.time < 100]}), 100.0, 150.0, 10.0)
    print({k: round(v, 3) for k, v in m.items()})
    h = tr.state[:, 0]
    print(f"h(99.95) = {h[tr.time <= 99.95][-1]:.3f}, h(200) = {h[-1]:.3f}, min v_z after 100 s "
          f"{tr.state[tr.time >= 100, 1].min():.3f}, elevator beyond ±1 rad for "
          f"{saturated_time(tr):.2f} s, peak demand {np.abs(tr.input).max() * DEG:.0f}°")

    print("\n## Fig 5.3 (traditional, 200 m at 10 s), 60 s; and larger steps")
    for target in (200.0, 225.0, 250.0, 275.0, 300.0, 400.0, 500.0):
        tr, _ = fly(trad, ((10.0, target),), 100.0)
        a = tr.state[:, 2]
        speed = np.hypot(tr.state[:, 1], tr.state[:, 5])
        print(f"+{target - 100:.0f} m: α max {a.max() * DEG:.2f}° at {tr.time[a.argmax()]:.2f} s, "
              f"first α ≥ 0.3 at {crossing(tr.time, a, 0.3):.2f} s, min V {speed.min():.2f} m/s, "
              f"h(100 s) = {tr.state[-1, 0]:.1f} m, min h {tr.state[:, 0].min():.1f}, "
              f"max v_z {tr.state[:, 1].max():.2f}, min v_z {tr.state[:, 1].min():.2f}")

    print("\n## Figs 5.5/5.7 (constrained, +100 m / +400 m at 10 s)")
    print(f"predicted plateau (design model) c1 + z2* = {cons.climb_plateau():.4f} m/s")
    for target, duration in ((200.0, 100.0), (500.0, 300.0)):
        tr, _ = fly(cons, ((10.0, target),), duration)
        m = step_metrics(tr, 100.0, target, 10.0)
        vz, t, h = tr.state[:, 1], tr.time, tr.state[:, 0]
        mid = (h > 100 + 0.2 * (target - 100)) & (h < 100 + 0.8 * (target - 100))
        plateau = float(np.median(vz[mid]))
        print(f"+{target - 100:.0f} m: {tr.outcome}; max |v_z| {np.abs(vz).max():.4f}, plateau "
              f"{plateau:.4f} (±{np.ptp(vz[mid]) / 2:.4f}), v_z ≥ 90 % of it "
              f"{crossing(t, vz, 0.9 * plateau, 10.0) - 10.0:.2f} s after the step; "
              f"{ {k: round(v, 3) for k, v in m.items()} }; elevator beyond ±1 rad "
              f"{saturated_time(tr):.2f} s (peak {np.abs(tr.input).max() * DEG:.0f}°); "
              f"time-optimal at 3.5 m/s: {(target - 100) / 3.5:.1f} s")


def section_k3() -> None:
    print("\n## k3 sweep (constrained, +100 m at 10 s, 100 s)")
    plant = AerosondePlant()
    model = plant.design_model()
    for k3 in (0.5, 0.2, 0.1, 0.05, 0.02, 0.01):
        law = ConstrainedAltitudeLaw(model, ConstrainedAltitudeGains(k3=k3))
        tr, _ = fly(law, ((10.0, 200.0),), 100.0)
        vz, h = tr.state[:, 1], tr.state[:, 0]
        mid = (h > 120) & (h < 180)
        plateau = float(np.median(vz[mid])) if mid.any() else math.nan
        m = step_metrics(tr, 100.0, 200.0, 10.0)
        print(f"k3 = {k3}: predicted {law.climb_plateau():.3f}, measured {plateau:.3f}, max v_z "
              f"{vz.max():.3f}, α max {tr.state[:, 2].max() * DEG:.2f}°, t_within_1m "
              f"{m['t_within_1m']:.1f} s, overshoot {m['overshoot']:.2f} m, elevator beyond "
              f"±1 rad {saturated_time(tr):.2f} s, outcome {tr.outcome} {tr.violated or ''} "
              f"at {tr.end_time:.2f} s")


def section_sensitivity() -> None:
    print("\n## sensitivity to the unstated ρ (design model) and mass (plant and design model)")
    for mass in (13.5, 11.0, 8.5):
        for rho in (None, 1.225):
            plant = AerosondePlant(AerosondeParameters(mass=mass))
            model = plant.design_model(rho=rho)
            trad, cons = TraditionalAltitudeLaw(model), ConstrainedAltitudeLaw(model)
            t51, _ = fly(trad, ((10.0, 150.0),), 60.0, plant)
            m51 = step_metrics(t51, 100.0, 150.0, 10.0)
            t53, _ = fly(trad, ((10.0, 200.0),), 40.0, plant)
            t55, _ = fly(cons, ((10.0, 200.0),), 50.0, plant)
            vz = t55.state[:, 1]
            print(f"m = {mass}, ρ = {rho or isa_density(100.0):.4f}: Fig5.1 peak v_z "
                  f"{m51['peak_vz']:.3f} at {m51['t_peak']:.2f} s, 10-90 % rise "
                  f"{m51['rise_10_90']:.2f} s, t_90 {m51['t_90']:.2f} s, h(60) "
                  f"{t51.state[-1, 0]:.2f}; Fig5.3 α max {t53.state[:, 2].max() * DEG:.2f}°; "
                  f"Fig5.5 plateau {np.median(vz[(t55.time > 30)]):.3f} (predicted "
                  f"{cons.climb_plateau():.3f}), max v_z {vz.max():.3f}, α max "
                  f"{t55.state[:, 2].max() * DEG:.2f}°")


if __name__ == "__main__":
    section_figures()
    section_k3()
    section_sensitivity()
