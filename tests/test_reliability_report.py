"""docs/ROBUSTNESS.md's text: runs that broke a constraint after the arm touched something
the law does not enforce are counted apart, and what was touched is named."""

from __future__ import annotations

from tools.reliability.findings import _sampled
from tools.reliability.report import _after_touch


def _scenario(touched: dict[str, int]) -> dict[str, object]:
    guarded = {"period": 0.01, "safeguard": True, "runs": 10, "violated": 4,
               "with_contact": sum(touched.values()), "touched": touched}
    bare = {"period": 0.01, "safeguard": False, "runs": 10, "violated": 6, "with_contact": 0}
    return {"states": 10, "nonviable_drawn": 0, "nonviable_rows": [], "rows": [guarded, bare]}


def test_table_cell_names_what_was_touched_most_first() -> None:
    row = {"with_contact": 3, "touched": {"joint stop elbow_joint": 1, "floor": 2}}
    assert _after_touch(row) == " (3 after a touch: floor 2, joint stop elbow_joint 1)"
    assert _after_touch({"with_contact": 0}) == ""


def test_finding_sums_the_touches_over_scenarios_and_keeps_the_rest_apart() -> None:
    data = {"a": _scenario({"floor": 2}), "b": _scenario({"floor": 1, "self": 1})}
    text = _sampled(data)[0]
    assert "100 Hz: **8** with the safeguard" in text
    assert "4 of them after touching something the law does not enforce — floor 3, self 1" in text
    assert "; 4 otherwise" in text and "12 without" in text
