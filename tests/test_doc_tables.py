"""The documentation's measured tables are rendered from what the measuring commands wrote:
the benchmark's JSON document (cpbc.bench_report, tools/speed_table.py) and verify's reports
and documents (cpbc.reliability.report, tools/verify_table.py); every fragment a page includes
exists and is what its data renders to now."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from cpbc.bench_report import README_END, README_START, markdown, readme_table
from cpbc.reliability.report import campaign_table, fragment, plan_command, read_report
from cpbc.reliability.report import markdown as verify_markdown
from cpbc.reliability.verification import Plan, summarise
from tools import speed_table, verify_table

ROOT = Path(__file__).resolve().parents[1]
INCLUDE = re.compile(r'^\s*-{1,3}8<-{1,3}\s+"(?P<path>[^"]+)"\s*$')

BENCH = {
    "robot": "two_link", "torque_us": {"pd_gravity": 2.0, "cpbc": 5.0, "ts_cpbc": 9.0},
    "torque_us_range": {"pd_gravity": [1.9, 2.5], "cpbc": [4.5, 6.25]},
    "closed_loop_steps_per_second": {"pd_gravity": 50000.0, "cpbc": 9000.0},
    "closed_loop_bare_law_steps_per_second": {"cpbc": 30000.0},
    "cpbc_over_pd_gravity": 2.5, "governor_us": 0.44,
    "guard_us": {"prediction": 12.0, "acceptance": 3.5},
    "guard_us_range": {"prediction": [11.0, 14.0]},
    "notes": "two links",
    "made": {"command": "python -m cpbc.bench --json", "date": "2026-11-25 07:00 UTC",
             "cpbc": "0.1.0", "commit": "abc1234", "python": "3.11.7", "cores": 2,
             "load_average": [2.5, 1.25, 1.0], "blocks": 15, "calls_per_block": 64},
}


def test_the_speed_fragment_renders_every_entry_of_a_bench_document() -> None:
    text = markdown([BENCH], "python -m tools.speed_table")
    assert "`python -m cpbc.bench --json` on 2026-11-25 07:00 UTC, commit `abc1234`" in text
    assert "load average 2.50, 1.25, 1.00 (1, 5, 15 min)" in text
    assert "median of 15 blocks of 64 calls" in text
    assert "| two_link | pd_gravity | 2 | 1.9–2.5 | 1.00× | 50 000 | – |" in text
    assert "| two_link | cpbc | 5 | 4.5–6.25 | 2.50× | 9 000 | 30 000 |" in text
    # a line another helper adds: its median, no range, no loop, its ratio all the same
    assert "| two_link | ts_cpbc | 9 | – | 4.50× | – | – |" in text
    assert "reference governor, one step (`cpbc.reference.governor`): 0.44 µs" in text
    assert "| prediction | 12 | 11–14 |" in text and "| acceptance | 3.5 | – |" in text
    assert "cpbc_over_pd_gravity" not in text  # it is the table's CPBC ratio


def test_the_readme_block_keeps_pd_g_cpbc_and_what_the_arm_set_has_not() -> None:
    block = readme_table([BENCH])
    assert block.startswith(README_START) and block.endswith(README_END)
    rows = [line for line in block.splitlines() if line.startswith("| two_link |")]
    assert rows == ["| two_link | pd_gravity | 2 | 1.00× |", "| two_link | cpbc | 5 | 2.50× |",
                    "| two_link | ts_cpbc | 9 | 4.50× |"]
    # the README's Speed section is the one table (issue 39): breakdowns and single numbers
    # stay on the speed page
    assert "| prediction | 12 | 11–14 |" not in block
    assert "| prediction | 12 | 11–14 |" in markdown([BENCH], "python -m tools.speed_table")
    assert "reference governor" not in block


def _verify_doc() -> dict:
    plan = Plan("panda_cpbc_sphere", seed=0, states=3, rates=(1000.0, 100.0), horizon=0.5)

    def record(seed, rate, margin, cls="stoppable"):
        return {"controller": "CPBC", "type": "cpbc", "rate": rate, "seed": seed,
                "class": cls, "in_v": seed == 0, "violated": margin <= 0, "min_margin": margin,
                "constraint": "clearance[link|ball]", "end_time": 0.5, "outcome": "",
                "position": [0.0], "velocity": [0.0], "control_steps": 10, "acted": 1,
                "infeasible": 0, "at_limit": 0, "rescues": 2}
    records = [record(0, 1000.0, 0.1), record(1, 1000.0, 0.2), record(2, 1000.0, -1.0,
                                                                          "not_stoppable"),
               record(0, 100.0, -2e-3), record(1, 100.0, 0.3), record(2, 100.0, 0.4)]
    doc = summarise(plan, records)
    doc["conditions"] = {"integrator": "implicitfast", "timestep": 0.001,
                         "torque_limit": [12.0, 87.0], "safeguard": True,
                         "also_kept": ["clearance"], "coordinates": ["q"]}
    return doc


def test_a_verify_report_reads_back_as_the_tables_it_was_written_from() -> None:
    doc = _verify_doc()
    made, tables = read_report(verify_markdown([doc], "python -m cpbc.verify x", 90.0))
    assert made.startswith("Made by `python -m cpbc.verify x` with cpbc")
    assert made.endswith(" in 1.5 min.")
    assert tables == [campaign_table(doc)]
    row = tables[0].cells()[0]
    assert row["worst margin"] == "0.1 (clearance[link\\|ball])"  # the bar stays in its cell
    assert row["in V (violated)"] == "1 (0)"  # seed 0, stoppable, in V
    assert tables[0].cells()[1]["in V (violated)"] == "1 (1)"  # 100 Hz: seed 0 breaks


def test_the_conditions_name_the_safeguards_budgets_where_a_campaign_had_any() -> None:
    doc = _verify_doc()
    doc["conditions"]["budgets"] = {"tests": 6, "rescue": 8, "time_us": 300.0}
    rows = fragment([campaign_table(doc)], ["head"], "rows")
    assert "judged too), its step bounded to 6 tests, 8 model periods of rescue, 300 µs;" \
        in rows
    doc["conditions"]["budgets"] = {"tests": None, "rescue": None, "time_us": None}
    assert "its step bounded" not in fragment([campaign_table(doc)], ["head"], "rows")


def test_the_campaign_fragment_in_rows_and_by_rate() -> None:
    table = campaign_table(_verify_doc())
    rows = fragment([table], ["head"], "rows")
    assert "| panda_cpbc_sphere | CPBC | 1000 Hz | **0 / 2** | 0 | 1 (1) | 10.0% | 0 | 6 |" in rows
    assert "| panda_cpbc_sphere | CPBC | 100 Hz | 1 / 3 | 1 | 0 (0) | 10.0% | 0 | 6 |" in rows
    assert "- `panda_cpbc_sphere`: States: 3 (seeds 0…), horizon 0.5 s; physics implicitfast" \
        in rows
    by_rate = fragment([table], ["head"], "by-rate")
    assert "Each cell gives 1000 Hz / 100 Hz, in that order." in by_rate
    assert "| set-up | controller | stoppable runs | violations | deeper than 1e-6 |" in by_rate
    assert "| panda_cpbc_sphere | CPBC | 2 / 3 | 0 / 1 | 0 / 1 | 10.0% / 10.0% | 6 / 6 | " \
        "1 (1) / 0 (0) |" in by_rate


def test_a_json_document_without_its_command_is_named_by_its_plan(tmp_path) -> None:
    doc = _verify_doc()
    assert plan_command(doc) == ("python -m cpbc.verify panda_cpbc_sphere --states 3 --rates "
                                 "1000,100 --horizon 0.5")
    (tmp_path / "a.json").write_text(json.dumps(doc))
    made = dict(doc, made={"command": "python -m cpbc.verify panda_cpbc_sphere", "seconds": 75,
                           "date": "2026-11-25 07:00 UTC", "commit": "abc1234",
                           "cpbc": "0.1.0"})
    (tmp_path / "b.json").write_text(json.dumps({"campaigns": [doc], "made": made["made"]}))
    text = verify_table.render([tmp_path / "a.json", tmp_path / "b.json"], "by-rate")
    assert "its plan reads as `python -m cpbc.verify panda_cpbc_sphere --states 3" in text
    assert ("made by `python -m cpbc.verify panda_cpbc_sphere` on 2026-11-25 07:00 UTC in "
            "1.2 min, commit `abc1234`") in text
    assert text.count("| panda_cpbc_sphere | CPBC |") == 2


def _includes() -> dict[Path, list[str]]:
    found = {}
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").rglob("*.md"))]:
        names = [m["path"] for line in page.read_text(encoding="utf-8").splitlines()
                 if (m := INCLUDE.match(line))]
        if names:
            found[page] = names
    return found


def test_every_include_in_the_docs_names_an_existing_file() -> None:
    includes = _includes()
    assert includes, "no page includes a fragment"
    missing = [f"{page.relative_to(ROOT)}: {name}" for page, names in includes.items()
               for name in names if not (ROOT / name).is_file()]
    assert not missing, f"includes of files that do not exist: {missing}"
    included = {name for names in includes.values() for name in names}
    fragments = {str(p.relative_to(ROOT)) for p in (ROOT / "docs" / "tables").glob("*.md")}
    assert fragments <= included, f"fragments no page includes: {fragments - included}"


def test_the_speed_fragment_and_readme_block_are_what_the_stored_run_renders() -> None:
    stored = json.loads(speed_table.DATA.read_text(encoding="utf-8"))
    text, block = speed_table.render(stored["documents"], stored["command"])
    assert speed_table.FRAGMENT.read_text(encoding="utf-8") == text, \
        "docs/tables/speed.md is stale: python -m tools.speed_table --render-only"
    assert block in (ROOT / "README.md").read_text(encoding="utf-8"), \
        "README.md's speed table is stale: python -m tools.speed_table --render-only"


@pytest.mark.parametrize("path", sorted(verify_table.FRAGMENTS))
def test_the_campaign_fragments_are_what_their_reports_render(path: str) -> None:
    assert (ROOT / path).read_text(encoding="utf-8") == \
        verify_table.docs_fragments()[ROOT / path], \
        f"{path} is stale: python -m tools.verify_table --docs"


def test_bench_writes_its_markdown_from_the_document_it_prints(tmp_path, capsys) -> None:
    from cpbc.bench import main

    out = tmp_path / "speed.md"
    assert main(["--json", "--markdown", str(out), "--repeats", "2", "--loop-seconds",
                 "0.02"]) == 0
    document = json.loads(capsys.readouterr().out)
    assert out.read_text(encoding="utf-8") == markdown([document])
    assert all(low <= document["torque_us"][k] <= high
               for k, (low, high) in document["torque_us_range"].items())
    assert document["made"]["command"].startswith("python -m cpbc.bench --json --markdown")


def test_bench_refuses_a_markdown_path_in_a_missing_folder(tmp_path, capsys) -> None:
    from cpbc.bench import main

    assert main(["--markdown", str(tmp_path / "no" / "speed.md")]) == 2
    assert "--markdown" in capsys.readouterr().err
    assert not (tmp_path / "no").exists()


def test_the_franka_campaign_fragment_is_what_its_stored_run_renders() -> None:
    from tools import franka_campaign

    stored = json.loads((franka_campaign.OUT / franka_campaign.JSON_NAME).read_text("utf-8"))
    assert (franka_campaign.OUT / franka_campaign.TABLE_NAME).read_text("utf-8") == \
        franka_campaign.render(stored), \
        "docs/tables/franka-campaign.md is stale: python -m tools.franka_campaign --render-only"
    totals = stored["totals"]
    assert totals["reaches"] == len([r for r in stored["runs"] if r["kind"] == "reach"]) >= 50
    assert totals["paths"] >= 10
