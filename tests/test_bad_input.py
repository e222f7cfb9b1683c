"""Bad input, generated: every invalid scenario ends with exit code 2, a message naming the
field on stderr, no traceback and nothing written; a run that goes numerically wrong ends as
``diverged`` with its time, never as a NaN summary."""

from __future__ import annotations

import copy
import json
import math
from pathlib import Path

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cpbc.run import main
from tools.reliability.bad_input import BASE, VARIANTS, BadInput, answer, setting


def test_the_base_scenario_is_valid(tmp_path: Path) -> None:
    path = tmp_path / "base.yaml"
    path.write_text(yaml.safe_dump(BASE, sort_keys=False))
    assert main([str(path), "--out", str(tmp_path / "out"), "--quiet", "--no-plots"]) == 0


def test_variants_cover_every_kind_of_bad_input() -> None:
    kinds = {v.category for v in VARIANTS}
    assert {"wrong type", "wrong shape", "unknown key", "non-positive", "non-finite",
            "inadmissible", "model file", "file", "duplicate key", "length", "gains"} <= kinds
    assert len({v.name for v in VARIANTS}) == len(VARIANTS) >= 100


@pytest.mark.parametrize("variant", VARIANTS, ids=[v.name for v in VARIANTS])
def test_invalid_scenario_exits_2_naming_the_field(variant: BadInput, tmp_path: Path) -> None:
    a = answer(variant, tmp_path / variant.name)
    assert a.exit_code == 2, a.message
    assert a.names_field, f"{variant.field!r} not in {a.message!r}"
    assert not a.traceback, a.message
    assert a.left_behind == [], a.left_behind  # no output folder, no scratch folder


# Numeric fields of the base scenario and values none of them accepts.
NUMERIC_FIELDS = [
    ("simulation.duration", "simulation.duration"),
    ("simulation.timestep", "simulation.timestep"),
    ("simulation.control_period", "simulation.control_period"),
    ("simulation.torque_limit", "simulation.torque_limit"),
    ("simulation.noise.position", "simulation.noise.position"),
    ("simulation.noise.velocity", "simulation.noise.velocity"),
    ("robot.plant.mass_scale", "robot.plant.mass_scale"),
    ("robot.plant.damping", "robot.plant.damping"),
    ("constraints.0.radius", "constraints[0].radius"),
    ("constraints.2.bounds", "constraints[2].bounds"),
    ("constraints.3.limit", "constraints[3].limit"),
    ("controllers.1.kp", "controllers[1].kp"),
    ("controllers.1.kd", "controllers[1].kd"),
    ("controllers.2.xi", "controllers[2].xi"),
    ("controllers.2.gamma", "controllers[2].gamma"),
]
BAD_VALUES = st.one_of(
    st.floats(max_value=-1e-9, allow_nan=False, allow_infinity=False),
    st.sampled_from([0, 0.0, -0.0, float("nan"), float("inf"), float("-inf"), "x", "1/0",
                     None, True, {}, {"a": 1}, [[1]], [], [1, 2, 3, 4], "nan", "inf"]),
    st.text(alphabet="abcxyz_()[]{}'\"", min_size=1, max_size=8),
)


@settings(max_examples=40, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(field=st.sampled_from(NUMERIC_FIELDS), value=BAD_VALUES)
def test_fuzzed_numeric_fields_exit_2_naming_the_field(
    field: tuple[str, str], value: object, tmp_path_factory: pytest.TempPathFactory
) -> None:
    dotted, shown = field
    if value is None and dotted in ("simulation.control_period", "simulation.torque_limit"):
        return  # null is the documented default of these two
    non_negative = dotted.startswith("simulation.noise.") or dotted == "robot.plant.damping"
    if non_negative and type(value) in (int, float) and value == 0:
        return  # zero noise or plant damping is valid (those fields are non-negative)
    variant = BadInput("fuzz", "fuzz", shown, setting(dotted, value))
    a = answer(variant, tmp_path_factory.mktemp("fuzz"))
    assert a.exit_code == 2, (dotted, value, a.message)
    assert a.names_field, (dotted, value, a.message)
    assert not a.traceback and a.left_behind == []


def test_numerically_wrong_run_ends_as_diverged_with_its_time(tmp_path: Path, capsys,
                                                              monkeypatch) -> None:
    """Absurd gains blow MuJoCo's state up: status diverged, the time, no NaN in the files."""
    monkeypatch.chdir(tmp_path)  # MuJoCo may write MUJOCO_LOG.TXT into the working folder
    data = copy.deepcopy(BASE)
    data["simulation"].update(duration=0.5, torque_limit=None, noise=None, check_gains=False)
    data["robot"].pop("plant")
    data["controllers"] = [{"type": "pd", "name": "PD", "kp": 1e7, "kd": 1}]
    path = tmp_path / "wild.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = tmp_path / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 0
    text = (out / "summary.json").read_text()

    def no_constants(name: str) -> float:
        raise AssertionError(f"summary.json holds {name}")

    (run,) = json.loads(text, parse_constant=no_constants)
    assert run["status"] == "diverged"
    assert 0 < run["end_time"] < 0.5
    assert "diverged @" in capsys.readouterr().out
    for key in ("final_error", "peak_torque_norm", "end_time"):
        assert run[key] is None or math.isfinite(run[key])
