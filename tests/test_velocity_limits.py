"""cpbc.model.velocity_limits: the FR3's position-dependent joint velocity limits (libfranka's
``rate_limiting.h``), the constant rate bounds that lie inside them on a joint range, a
scenario refused when its rate constraint reaches past them, and the hardware rules that
check every logged state against them."""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import numpy as np
import pytest
import yaml

from cpbc.errors import ParameterError, ScenarioError
from cpbc.hardware.__main__ import main
from cpbc.hardware.franka import FR3_LIMITS
from cpbc.hardware.rules import check_rules
from cpbc.model.arms import _FR3_RANGES, FR3_VELOCITY_LIMITS
from cpbc.model.velocity_limits import PositionDependentVelocity
from cpbc.scenario import build, load_scenario

SCENARIO = Path(__file__).resolve().parent / "scenarios" / "fr3_reach_ball.yaml"
LIMITS = FR3_VELOCITY_LIMITS
FCI = np.array(list(_FR3_RANGES.values()))


def test_fr3_limits_at_known_points() -> None:
    """Values worked by hand from the FCI's formula: the peak in the middle of a range,
    −c + √(k d) near an end, 0 (less the tolerance ε) at libfranka's ends."""
    middle = FCI.mean(axis=1)
    np.testing.assert_allclose(LIMITS.upper(middle), LIMITS.peak - 1e-3)
    np.testing.assert_allclose(LIMITS.lower(middle), -LIMITS.peak + 1e-3)
    q = middle.copy()
    q[0] = 2.7501 - 0.1  # joint 1, 0.1 rad below its end: −0.3 + √(12 · 0.1)
    assert LIMITS.upper(q)[0] == pytest.approx(-0.3 + np.sqrt(1.2) - 1e-3)
    assert LIMITS.lower(q)[0] == pytest.approx(-2.62 + 1e-3)  # away from the end: the peak
    q[5] = 0.54092 + 0.05  # joint 6 near its lower end: −0.35 + √(11 · 0.05) = 0.392
    assert LIMITS.lower(q)[5] == pytest.approx(0.35 - np.sqrt(0.55) + 1e-3)
    ends = LIMITS.upper(LIMITS.upper_end), LIMITS.lower(LIMITS.lower_end)
    np.testing.assert_allclose(ends[0], -1e-3)
    np.testing.assert_allclose(ends[1], 1e-3)
    # at the FCI's published ranges, joints 1 and 4 may not move toward their ends at all
    assert LIMITS.upper(FCI[:, 1])[0] < 0 and LIMITS.upper(FCI[:, 1])[3] < 0


def test_constant_bound_lies_inside_the_limits_on_the_range_and_is_tight() -> None:
    rng = np.random.default_rng(3)
    for _ in range(20):
        a, b = rng.uniform(FCI[:, 0], FCI[:, 1]), rng.uniform(FCI[:, 0], FCI[:, 1])
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        bound = LIMITS.constant_bound(lo, hi)
        grid = lo + np.linspace(0.0, 1.0, 2001)[:, None] * (hi - lo)
        upper, lower = LIMITS.upper(grid), LIMITS.lower(grid)
        positive = bound > 0
        assert np.all(bound[positive] <= upper.min(axis=0)[positive] + 1e-12)
        assert np.all(-bound[positive] >= lower.max(axis=0)[positive] - 1e-12)
        # tight: some point of the range allows no more (the nearer end's curve)
        tightest = np.minimum(upper.min(axis=0), -lower.max(axis=0))
        np.testing.assert_allclose(bound, np.maximum(tightest, 0.0), atol=1e-12)


def test_range_for_inverts_the_constant_bound() -> None:
    wanted = 0.5 * LIMITS.peak
    lo, hi = LIMITS.range_for(wanted)
    np.testing.assert_allclose(LIMITS.constant_bound(lo, hi), wanted, rtol=1e-12)
    # narrower than the FCI's ranges, and wider for a slower bound
    assert np.all(lo > FCI[:, 0]) and np.all(hi < FCI[:, 1])
    slow_lo, slow_hi = LIMITS.range_for(0.25 * LIMITS.peak)
    assert np.all(slow_lo < lo) and np.all(slow_hi > hi)


def test_bad_parameters_name_the_argument() -> None:
    with pytest.raises(ParameterError) as found:
        one = np.ones(1)
        PositionDependentVelocity(one, 0.1 * one, one, one, 2.0 * one)
    assert found.value.parameter == "lower_end"
    with pytest.raises(ParameterError) as found:
        PositionDependentVelocity(np.ones(2), 0.1 * one, one, one, 0.0 * one)
    assert found.value.parameter == "offset"


def _scenario(tmp_path: Path, **rates: object) -> Path:
    data = yaml.safe_load(SCENARIO.read_text())
    data["constraints"][1].update(rates)
    path = tmp_path / "rates.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def test_from_model_rate_bounds_lie_inside_the_limits_on_the_scenarios_range(
        tmp_path: Path) -> None:
    setup = build(*load_scenario(SCENARIO))
    data = yaml.safe_load(SCENARIO.read_text())
    lo, hi = (np.array(data["constraints"][0][k]) for k in ("lower", "upper"))
    bounds = np.array(setup.rate_bounds, dtype=float)
    np.testing.assert_allclose(bounds, np.minimum(LIMITS.peak, LIMITS.constant_bound(lo, hi)))
    grid = lo + np.linspace(0.0, 1.0, 501)[:, None] * (hi - lo)
    assert np.all(bounds <= LIMITS.upper(grid)) and np.all(-bounds >= LIMITS.lower(grid))
    half = build(*load_scenario(_scenario(tmp_path, scale=0.5)))
    np.testing.assert_allclose(np.array(half.rate_bounds, dtype=float), 0.5 * bounds)


def test_a_rate_constraint_past_the_limits_is_refused_naming_the_field(
        tmp_path: Path) -> None:
    # the FCI's whole ranges: joint 1's limit falls to 0 at their ends
    data = yaml.safe_load(SCENARIO.read_text())
    data["constraints"][0].update(lower="from_model", upper="from_model")
    path = tmp_path / "whole.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ScenarioError, match=r"^constraints\[1\]\.bounds: fr3_joint1: "
                       r"the robot's position-dependent velocity limit"):
        build(*load_scenario(path))
    # a bound given past what the scenario's range allows (1.31 rad/s on joint 2)
    with pytest.raises(ScenarioError, match=r"^constraints\[1\]\.bounds: fr3_joint2: .* "
                       r"allows 1\.31 rad/s .* the bound is 1\.4"):
        build(*load_scenario(_scenario(tmp_path, bounds=[1.3, 1.4, 1.3, 1.3, 2, 2, 2])))
    # through the CLI: one line, exit 2, nothing written
    out = tmp_path / "run"
    err = io.StringIO()
    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
        code = main([str(path), "--backend", "lockstep", "--out", str(out)])
    assert code == 2 and err.getvalue().startswith("error: constraints[1].bounds: fr3_joint1")
    assert err.getvalue().count("\n") == 1 and not out.exists()


def test_rules_check_every_state_against_the_position_dependent_limits() -> None:
    q = np.tile(FCI.mean(axis=1), (3, 1))
    q[1, 0] = 2.7501 - 0.1  # joint 1 near its end: 0.795 rad/s allowed toward it
    dq = np.zeros((3, 7))
    dq[0, 0] = 2.0  # fine in the middle of the range
    dq[1, 0] = 0.8  # past 0.795 − 0.001 near the end
    dq[2, 6] = -5.3  # past joint 7's peak
    commands = np.zeros((3, 7))
    margins = np.ones((3, 1))
    report = check_rules(commands, FR3_LIMITS, margins, ("m",), q, dq)
    assert report.velocity_over == 2 and not report.kept
    assert report.velocity_headroom is not None
    assert report.velocity_headroom[0] == pytest.approx(-0.3 + np.sqrt(1.2) - 1e-3 - 0.8)
    assert report.velocity_headroom[6] == pytest.approx(5.26 - 1e-3 - 5.3)
    assert "2 states past the position-dependent velocity limits" in report.describe()
    dq[1:] = 0.0
    assert check_rules(commands, FR3_LIMITS, margins, ("m",), q, dq).kept
