"""The input bounds (cpbc.model.input_bounds): one value per scenario, checked once, and the
same object read by the safeguard, the CBF-QP peer and the plant."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cpbc.controllers.safeguard import Safeguard
from cpbc.model import InputBounds
from cpbc.peers import CBFQP
from cpbc.scenario import build, load_scenario
from cpbc.simulation.loop import ArmLoop

ROOT = Path(__file__).resolve().parents[1]


def test_bounds_are_checked_naming_the_argument() -> None:
    with pytest.raises(ValueError, match="period"):
        InputBounds(0.0)
    with pytest.raises(ValueError, match="period"):
        InputBounds(float("nan"))
    with pytest.raises(ValueError, match="torque"):
        InputBounds(0.001, np.array([87.0, -1.0]))
    with pytest.raises(ValueError, match="rate"):
        InputBounds(0.001, None, np.array([np.nan]))


def test_one_number_applies_to_every_joint_and_a_wrong_count_is_refused() -> None:
    """A single number bounds every joint of the arm the guard keeps; a count that is
    neither one nor one per joint is refused, naming the bound, when the guard is built."""
    path = ROOT / "tools" / "campaigns" / "fr3_sphere_rate.yaml"
    setup = build(*load_scenario(path))
    law = next(e for e in setup.controllers if not e.controller.constraints.empty).controller
    bounds = InputBounds(0.002, 10.0, np.array([1000.0]))
    assert bounds.step is not None and bounds.step.tolist() == [2.0]
    box = Safeguard(law, bounds).box
    assert box.torque_limit is not None and box.torque_limit.tolist() == [10.0] * 7
    assert box.rate_step is not None and box.rate_step.tolist() == [2.0] * 7
    assert InputBounds(0.001).step is None
    with pytest.raises(ValueError, match="rate"):
        Safeguard(law, InputBounds(0.001, 87.0, np.array([1000.0, 1000.0])))


def test_a_scenario_builds_its_bounds_once_and_every_reader_reads_them() -> None:
    """The FR3 past a ball under its torque box and its motors' rate limit (the rate
    campaign's set-up): the guard the loop runs, the plant's loop and a CBF-QP built on the
    same bounds all hold the one value the scenario built."""
    path = ROOT / "tools" / "campaigns" / "fr3_sphere_rate.yaml"
    setup = build(*load_scenario(path))
    bounds = setup.loop_settings.bounds
    assert bounds.torque is not None and bounds.rate is not None
    entry = next(e for e in setup.controllers if not e.controller.constraints.empty)
    guard = setup.controller(entry)
    assert isinstance(guard, Safeguard) and guard.bounds is bounds
    assert guard.box.rate_step is not None
    np.testing.assert_array_equal(guard.box.rate_step, bounds.rate * bounds.period)
    plant = setup.make_plant()
    arm = ArmLoop(plant, guard, setup.model.coordinates, setup.loop_settings, 10)
    assert arm.limit is bounds.torque and arm.period == bounds.period
    law = entry.controller
    peer = CBFQP(law.model, law.target, law.constraints, 100.0, 20.0, bounds=bounds)
    np.testing.assert_array_equal(peer.torque_limit, bounds.torque)
