"""How a run's figures are shared between the processes that draw them."""

from cpbc.results.drawing import figure_weight, share_out
from cpbc.results.saved_run import FIGURES


def _ur5_jobs() -> tuple[list[tuple[str, str]], list[float]]:
    """One case of a 6-joint arm with position, rate and clearance margins (ur5_bpbc)."""
    jobs = [("rest", name) for name in FIGURES]
    return jobs, [figure_weight(name, 6, 3) for _, name in jobs]


def test_every_figure_is_drawn_once():
    jobs, weights = _ur5_jobs()
    parts = share_out(jobs, weights, (0.5, 0.5))
    assert sorted(j for part in parts for j in part) == sorted(jobs)


def test_two_helpers_get_about_half_the_work_each():
    # halving the list by position gave one helper positions, torques and margins: 19 of 30
    jobs, weights = _ur5_jobs()
    parts = share_out(jobs, weights, (0.5, 0.5))
    loads = [sum(weights[jobs.index(j)] for j in part) for part in parts]
    assert max(loads) - min(loads) <= min(weights)


def test_uneven_shares_are_kept_to_within_one_figure():
    jobs = [(f"case{k}", name) for k in range(3) for name in FIGURES]
    weights = [figure_weight(name, 7, 2) for _, name in jobs]
    theirs, ours = share_out(jobs, weights, (0.65, 0.35))
    load = sum(weights[jobs.index(j)] for j in theirs)
    assert abs(load - 0.65 * sum(weights)) <= max(weights)
    assert len(theirs) + len(ours) == len(jobs)


def test_weights_follow_the_panels():
    assert figure_weight("torques", 7, 3) == figure_weight("rates", 7, 3) + 1
    assert figure_weight("margins", 7, 4) == 5
    assert figure_weight("lyapunov", 7, 4) == figure_weight("path", 7, 4) == 2
