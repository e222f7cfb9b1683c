"""A Part I margin has one definition — the distance of the constrained quantity to its nearer
bound, in its unit (ConstrainedQuantity.margins) — and the three readers agree on it: the
summary (cpbc.results.system_metrics), the margins history the figure draws
(cpbc.viewer.system_outputs, cpbc.results.plots) and the page (view.html). Checked on every
shipped Part I scenario, cut short here, against the logged values themselves; the Aerosonde's
stall interval is asymmetric, so there a margin read off the smaller bound's magnitude
(min(−lower, upper) − |α|, as the page once did) would differ."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

from cpbc.margin_kinds import BY_KEY, OTHER
from cpbc.resources import scenarios_dir
from cpbc.results.plots import margins_figure
from cpbc.scenario.load import load_any
from cpbc.scenario.runner import run_systems
from cpbc.scenario.schema import SystemScenario
from cpbc.scenario.system_build import build_system
from cpbc.viewer.page_data import unpacked
from cpbc.viewer.system_outputs import saved_system_run, write_system_outputs

# every shipped scenario with a system: block, and how long its runs last here [s]
SHIPPED = sorted(p.stem for p in scenarios_dir().glob("*.yaml")
                 if "system" in yaml.safe_load(p.read_text(encoding="utf-8")))
DURATION = {"ch3_suspension": 0.3, "ch3_rwp": 5.0, "ch4_integrator_chain": 20.0,
            "ch5_aerosonde": 40.0}


def test_every_shipped_part1_scenario_is_checked() -> None:
    assert set(SHIPPED) == set(DURATION)


def _page_data(page: Path) -> dict[str, Any]:
    m = re.search(r"window\.CPBC_DATA = (\{.*?\});\n</script>", page.read_text(), re.S)
    assert m, "the page holds its data"
    return json.loads(m.group(1))


@pytest.fixture(scope="module", params=SHIPPED)
def part1(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Any:
    name = request.param
    folder = tmp_path_factory.mktemp(name)
    data = yaml.safe_load((scenarios_dir() / f"{name}.yaml").read_text(encoding="utf-8"))
    data["simulation"]["duration"] = DURATION[name]
    for case in data["cases"]:  # the Aerosonde's altitude commands within the shorter run
        if "commands" in case:
            case["commands"] = [c for c in case["commands"] if c["time"] < DURATION[name]]
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    scenario, source = load_any(path)
    assert isinstance(scenario, SystemScenario)
    setup = build_system(scenario, source)
    results = run_systems(setup)
    page = write_system_outputs(folder, setup, results, plots=False)
    return name, setup, results, saved_system_run(folder, setup, results), _page_data(page)


def test_summary_history_figure_and_page_read_one_margin(part1: Any) -> None:
    _, setup, results, saved, page = part1
    for c, case in enumerate(setup.cases):
        runs = [r for r in results if r.case == case.name]
        quantities = case.plant.constrained
        saved_case = saved.cases[c]
        page_case = page["cases"][c]
        (margin_group,) = [g for g in page_case["plots"] if g["title"] == "Margins by type"]
        for r, traj, series in zip(runs, saved_case.runs, page_case["series"], strict=True):
            assert traj.controller == r.controller
            s = r.summary
            for k, q in enumerate(quantities):
                # the logged values themselves: nearer of the two bounds, at the worst sample
                v = (r.trajectory.input if q.source == "input"
                     else r.trajectory.state[:, q.index])
                v = v[np.isfinite(v)]
                expected = min(float(v.min()) - q.lower, q.upper - float(v.max()))
                assert s.min_margins[q.name] == pytest.approx(expected, rel=1e-12, abs=1e-12)
                assert float(np.nanmin(traj.margins[:, k])) == pytest.approx(
                    expected, rel=1e-12, abs=1e-12)
                # a real type, in the quantity's unit, the same in the summary and the history
                kind = BY_KEY[s.margin_types[q.name]]
                assert kind is q.margin_type and kind is not OTHER
                assert traj.margin_types[k] == kind.key and s.margin_units[q.name] == kind.unit
                # the page: its panel of that type, the column's smallest sample (thinning
                # keeps each bucket's extremes; single precision)
                label = f"{kind.label} [{kind.unit}]" if kind.unit else kind.label
                (panel,) = [p for p in margin_group["panels"] if p["label"] == label]
                if k in panel["named"]:
                    lowest = float(np.nanmin(unpacked(series["columns"][f"m{k}"])))
                    assert lowest == pytest.approx(expected, rel=1e-6, abs=1e-6)
                else:  # drawn in the range of the type's others: their lower envelope
                    lowest = float(np.nanmin(unpacked(series["columns"][f"lo{label}"])))
                    assert lowest <= expected + 1e-6 * max(1.0, abs(expected))
        # the figure: one panel per type present, labelled with its unit
        fig = margins_figure(saved_case)
        assert fig is not None
        labels = {ax.get_ylabel() for ax in fig.axes if ax.get_ylabel()}
        assert labels == {f"{q.margin_type.label} [{q.margin_type.unit}]" if q.margin_type.unit
                          else q.margin_type.label for q in quantities}


def test_the_stall_margin_is_to_the_nearer_of_its_asymmetric_bounds(part1: Any) -> None:
    name, setup, results, _, _ = part1
    if name != "ch5_aerosonde":
        pytest.skip("the Aerosonde's stall interval is the asymmetric one")
    alpha = next(q for q in setup.cases[0].plant.constrained if q.name == "alpha")
    assert alpha.lower != -alpha.upper and alpha.margin_type.unit == "rad"
    differs = 0
    for r in results:
        a = r.trajectory.state[:, alpha.index]
        a = a[np.isfinite(a)]
        nearer = min(float(a.min()) - alpha.lower, alpha.upper - float(a.max()))
        symmetric = min(-alpha.lower, alpha.upper) - float(np.abs(a).max())
        assert r.summary.min_margins["alpha"] == pytest.approx(nearer, rel=1e-12)
        differs += not np.isclose(nearer, symmetric)
    assert differs  # the asymmetric bound matters on these runs
