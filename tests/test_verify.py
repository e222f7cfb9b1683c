"""python -m cpbc.verify: seeded, reproducible by seed, the same counts on a local process pool
and on a Dask cluster (LocalCluster on the loopback interface only), bad arguments exit 2."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from cpbc.reliability.verification import Block, Mismatch, Plan, blocks, run_block, summarise
from cpbc.verify import main, run_campaign

# thesis_ch6 runs the bare laws (safeguard: false): at 100 Hz some states near the boundary break
TINY = Plan("thesis_ch6", seed=0, states=12, rates=(100.0,), horizon=0.3)


@pytest.fixture(scope="module")
def in_process():
    return run_campaign(TINY, workers=1, block=4)


def _counts(doc):
    return [(r["controller"], r["rate"], r["runs"], r["violations"], r["worst_margin"],
             [f["seed"] for f in r["failures"]], r["non_viable"]) for r in doc["results"]]


def test_campaign_counts_runs_and_failures_with_their_seeds(in_process):
    rows = in_process["results"]
    assert [r["controller"] for r in rows] == ["CPBC", "CPBC-alpha0.05"]  # PD enforces nothing
    for r in rows:
        classed = r["runs"] + sum(v["runs"] for v in r["non_viable"].values())
        assert classed == TINY.states
        assert r["violations"] == len(r["failures"]) >= 1  # the bare law at 100 Hz breaks
        assert r["worst_margin"] <= 0
        for f in r["failures"]:
            assert f["min_margin"] <= 0 and f["constraint"]
        # the starts in V are counted apart, their violations among the failures
        assert 0 <= r["in_v"]["runs"] <= r["runs"]
        assert r["in_v"]["violations"] == sum(bool(f["in_v"]) for f in r["failures"])


def test_a_failure_is_reproduced_by_its_seed_alone(in_process, tmp_path):
    failure = in_process["results"][0]["failures"][0]
    out = tmp_path / "again.json"
    code = main(["thesis_ch6", "--seeds", str(failure["seed"]), "--rates", "100",
                 "--horizon", "0.3", "--workers", "1", "--out", str(out)])
    assert code == 1  # a viable run was violated
    again = json.loads(out.read_text())["results"][0]
    assert again["violations"] == 1
    assert again["failures"][0] == failure


def test_local_pool_and_dask_cluster_give_the_same_counts(in_process):
    import distributed  # the test extra installs it (cpbc[cluster])
    pool = run_campaign(TINY, workers=2, block=4)
    assert _counts(pool) == _counts(in_process)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, host="127.0.0.1",
                                  dashboard_address=None, processes=True) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        on_cluster = run_campaign(TINY, cluster=cluster.scheduler_address, block=4)
    assert _counts(on_cluster) == _counts(in_process)


@pytest.mark.parametrize("args", [
    ["thesis_ch6", "--rates", "fast"],
    ["thesis_ch6", "--rates", "0"],
    ["thesis_ch6", "--rates", "3000"],  # not a whole number of 1 ms timesteps
    ["thesis_ch6", "--states", "0"],
    ["thesis_ch6", "--mismatch", "weight=0.1"],
    ["thesis_ch6", "--noise", "0.1"],
    ["no_such_scenario"],
    ["planar_2link_nothing.yaml"],
])
def test_bad_arguments_exit_2_and_write_nothing(args, tmp_path, capsys):
    out = tmp_path / "report.md"
    assert main([*args, "--workers", "1", "--out", str(out)]) == 2
    assert "error" in capsys.readouterr().err
    assert not out.exists()


def test_mismatch_and_noise_change_the_runs_and_are_recorded():
    clean = Plan("thesis_ch6", seed=0, states=3, rates=(100.0,), horizon=0.3)
    noisy = replace(clean, mismatch=Mismatch(mass=0.3, damping=0.1), noise=(0.001, 0.01))
    a = run_block(blocks(clean, ["CPBC"], 3)[0])
    b = run_block(blocks(noisy, ["CPBC"], 3)[0])
    assert [r["seed"] for r in a] == [r["seed"] for r in b] == [0, 1, 2]
    assert [r["position"] for r in a] == [r["position"] for r in b]  # the same states
    assert all(abs(p["final_error"] - q["final_error"]) > 1e-6 for p, q in zip(a, b, strict=True))
    doc = summarise(noisy, b)
    assert doc["plan"]["mismatch"]["mass"] == 0.3 and list(doc["plan"]["noise"]) == [0.001, 0.01]


def test_several_scenarios_make_one_report_with_their_conditions(tmp_path, monkeypatch):
    """The repository's docs/RELIABILITY.md is such a report: each campaign states its
    physics, its torque limits and whether the safeguard ran; the command is in the header."""
    monkeypatch.chdir(Path(__file__).resolve().parents[1])  # the repository, where tools/ is
    out = tmp_path / "report.md"
    code = main(["thesis_ch7", "tools/campaigns/planar_cpbc_box.yaml", "--states", "2",
                 "--rates", "100", "--horizon", "0.1", "--workers", "1", "--out", str(out)])
    text = out.read_text()
    assert code == 0
    assert "`python -m cpbc.verify thesis_ch7 tools/campaigns/planar_cpbc_box.yaml" in text
    sections = text.split("\n## ")[1:]
    assert [s.splitlines()[0] for s in sections] == ["thesis_ch7",
                                                     "tools/campaigns/planar_cpbc_box.yaml"]
    assert "torque limits none; safeguard on" in sections[0]
    assert "physics RK4 at 0.001 s; torque limits 2 N·m; safeguard on" in sections[1]
    assert "| BPBC | 100 Hz | 2 | 0 |" in sections[0] and "| CPBC | 100 Hz | 2 | 0 |" in sections[1]
    both = json.loads(_json(["thesis_ch7", "tools/campaigns/planar_cpbc_box.yaml"], tmp_path))
    assert [d["plan"]["scenario"].split("/")[-1] for d in both["campaigns"]] == [
        "thesis_ch7", "planar_cpbc_box.yaml"]
    assert both["campaigns"][1]["conditions"]["torque_limit"] == [2.0, 2.0]


def _json(scenarios, tmp_path):
    out = tmp_path / "report.json"
    main([*scenarios, "--states", "1", "--rates", "100", "--horizon", "0.05", "--workers", "1",
          "--out", str(out)])
    return out.read_text()


def test_an_output_folder_that_does_not_exist_is_refused_before_any_run(tmp_path, capsys):
    assert main(["thesis_ch7", "--out", str(tmp_path / "missing" / "r.md")]) == 2
    assert "--out" in capsys.readouterr().err and not (tmp_path / "missing").exists()


def test_a_constraint_only_the_safeguard_keeps_is_judged_too():
    """BPBC-KE enforces its energy bound only; its safeguard keeps the joint ranges too, so a
    run that goes past one is violated (seed 1: joint 2 at 0.997 of its limit, moving in at
    0.35 rad/s with 2 N m actuators, is lost). It used to count as kept."""
    path = Path(__file__).resolve().parents[1] / "tools/campaigns/planar_laws_box.yaml"
    plan = Plan(str(path), seed=0, states=1, rates=(1000.0,), horizon=0.3)
    (record,) = run_block(Block(plan, "BPBC-KE", 1000.0, (1,)))
    assert record["class"] == "not_stoppable"
    assert record["violated"] and record["constraint"] == "position[joint2]"


def test_a_part_one_scenario_is_refused_with_the_reason(capsys):
    assert main(["ch3_rwp", "--states", "1"]) == 2
    err = capsys.readouterr().err
    assert "Part I system scenario" in err and "unknown key" not in err


def test_a_clearance_pairs_bar_does_not_split_a_report_cell():
    from cpbc.reliability.report import markdown_cell

    cell = markdown_cell("0.01 (clearance[panda_hand|ball])")
    assert cell == "0.01 (clearance[panda_hand\\|ball])"


def test_one_rule_counts_runs_at_or_below_zero_and_deeper_than_the_tolerance():
    def record(seed, margin, acted, infeasible=0):
        return {"controller": "QP", "type": "cbf_qp", "rate": 1000.0, "seed": seed,
                "class": "stoppable", "in_v": seed != 2, "violated": margin <= 0,
                "min_margin": margin,
                "constraint": "c", "end_time": 0.5, "outcome": "", "position": [0.0],
                "velocity": [0.0], "control_steps": 10, "acted": acted,
                "infeasible": infeasible, "at_limit": 0}
    records = [record(0, 0.1, 2), record(1, -3e-13, 5), record(2, -2e-3, 10, 4)]
    row = summarise(TINY, records)["results"][0]
    assert (row["runs"], row["violations"], row["deep_violations"]) == (3, 2, 1)
    assert row["worst_depth"] == pytest.approx(2e-3) and row["tolerance"] == 1e-6
    assert row["filter_share"] == pytest.approx(17 / 30) and row["infeasible_steps"] == 4
    assert row["in_v"] == {"runs": 2, "violations": 1}  # seed 2 starts outside V


def test_the_ur5_circle_keeps_the_floor_of_its_scene():
    """The UR5 circle's scene has a floor (10 cm below the base) that its laws were not told
    of: from seeds 2, 3 and 16 the task-space law swept a link into it, and the contact, which
    neither the law nor its safeguard models, kicked a joint rate past its bound (up to
    0.2 rad/s deep at 1 kHz). The scenario now lists the floor's clearance, which the law
    monitors and its safeguard keeps (as in ur5_bpbc): the same states of seeds 2 and 16 are
    kept, and seed 3's state (its upper arm's cover 3 cm inside the clearance, in contact with
    the floor 3 ms in) is no longer drawn."""
    plan = Plan("ur5_circle", seed=0, states=3, rates=(1000.0,), horizon=2.0)
    records = run_block(Block(plan, "TS-CPBC", 1000.0, (2, 3, 16)))
    assert [r["class"] for r in records] == ["stoppable"] * 3
    for r in records:
        assert not r["violated"], (r["seed"], r["constraint"], r["min_margin"])


def test_a_brake_that_rests_on_something_the_law_does_not_keep_does_not_make_a_state_stoppable(
        tmp_path):
    """With the UR5 circle's floor left out of its constraints, seed 3 starts with the upper
    arm 3 ms above the floor: the uniform brake 'stopped' it in the true plant only by resting
    it on the floor, a force outside the torque box, and the state was classed stoppable. A
    brake's run that touches anything (contact or joint range stop) no longer counts."""
    yaml = pytest.importorskip("yaml")
    root = Path(__file__).resolve().parents[1]
    doc = yaml.safe_load((root / "scenarios/ur5_circle.yaml").read_text())
    doc["constraints"] = [c for c in doc["constraints"] if c["type"] != "clearance"]
    for c in doc["controllers"]:
        c.pop("constraints", None)
    path = tmp_path / "ur5_circle_floor_unkept.yaml"
    path.write_text(yaml.safe_dump(doc))
    plan = Plan(str(path), seed=0, states=1, rates=(1000.0,), horizon=0.05)
    (record,) = run_block(Block(plan, "TS-CPBC", 1000.0, (3,)))
    assert record["class"] == "not_stoppable" and record["brake"] is None
