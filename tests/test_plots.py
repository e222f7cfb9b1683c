"""Figures of a run (cpbc.results.plots): every figure is written for every case, and what
it draws is the run's own data — the plotted peaks are the summary's peaks, the bounds are
the scenario's, the end-point path is the arm's forward kinematics."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import yaml
from matplotlib.lines import Line2D
from matplotlib.patches import Circle
from PIL import Image

from cpbc.results.plots import (
    envelope,
    lyapunov_figure,
    margins_figure,
    path_figure,
    positions_figure,
    rates_figure,
    torques_figure,
)
from cpbc.results.saved_run import SavedCase, SavedTrajectory, load_run
from cpbc.run import main

FIGURES = ("positions", "rates", "torques", "lyapunov", "margins", "path")
OBSTACLE = ([1.7, 1.0], 0.3)
RATE_BOUNDS = [0.3, 0.2]


def scenario(folder: Path, duration: float = 2.0) -> Path:
    """The thesis's planar arm for ``duration`` s: PD, CPBC and BPBC, two cases, an
    end-point obstacle that PD runs into, a relative-angle limit and link rate limits."""
    data = {
        "name": "plots_short",
        "robot": {"model": "planar_2link", "coordinates": "absolute"},
        "simulation": {"duration": duration, "timestep": 0.001},
        "target": ["pi", "2*pi/3"],
        "cases": [
            {"name": "rest", "position": [0, 0]},
            {"name": "moving", "position": [0, 0], "velocity": [0.1, 0.05]},
        ],
        "constraints": [
            {"type": "point_outside_sphere", "name": "obstacle", "frame": "end_point",
             "centre": OBSTACLE[0], "radius": OBSTACLE[1]},
            {"type": "linear_limit", "name": "relative_angle", "coefficients": [[-1, 1]],
             "lower": ["-17*pi/18"], "upper": ["17*pi/18"]},
            {"type": "joint_rate_limit", "name": "link_rates", "bounds": RATE_BOUNDS},
        ],
        "controllers": [
            {"type": "pd", "name": "PD", "kp": 4, "kd": 20},
            {"type": "cpbc", "name": "CPBC", "kp": 4, "kd": 20,
             "shaping": {"type": "power", "alpha": 0.2}},
            {"type": "bpbc", "name": "BPBC", "kp": [2, 10], "kd": [4, 20],
             "constraints": ["link_rates"], "shaping": {"type": "power", "alpha": 0.2}},
        ],
    }
    path = folder / "plots_short.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("plots")
    out = folder / "out"
    assert main([str(scenario(folder)), "--out", str(out), "--quiet", "--workers", "1"]) == 0
    return out


@pytest.fixture(scope="module")
def run(run_folder):
    return load_run(run_folder)


@pytest.fixture(scope="module")
def summaries(run_folder) -> dict[tuple[str, str], dict]:
    data = json.loads((run_folder / "summary.json").read_text())
    return {(s["case"], s["controller"]): s for s in data}


def _lines(ax, label: str) -> list[Line2D]:
    return [ln for ln in ax.get_lines() if ln.get_label() == label]


def test_every_figure_is_written_for_every_case(run_folder):
    for case in ("rest", "moving"):
        for name in FIGURES:
            path = run_folder / case / f"{name}.png"
            assert path.is_file(), path
            with Image.open(path) as im:
                assert im.format == "PNG"
                assert im.width >= 600 and im.height >= 300
                pixels = np.asarray(im.convert("L"), dtype=float)
            # Something was drawn: a blank canvas would be one grey level.
            assert pixels.std() > 5.0, path


def test_plotted_peak_rates_are_the_summary_peaks(run, summaries):
    for case in run.cases:
        fig = rates_figure(case)
        for k, ax in enumerate(fig.axes):
            for r in case.runs:
                (line,) = _lines(ax, r.controller)
                peak = np.max(np.abs(line.get_ydata()))
                # the file holds single precision; the summary's peak, rounded, is its peak
                assert peak == np.float32(summaries[case.name, r.controller]["peak_joint_rates"][k])
            bounds = sorted(
                float(ln.get_ydata()[0]) for ln in ax.get_lines() if ln.get_linestyle() == "--"
            )
            assert bounds == pytest.approx([-RATE_BOUNDS[k], RATE_BOUNDS[k]])


def test_rate_figure_shows_pd_crossing_and_bpbc_holding_the_bound(run, summaries):
    fig = rates_figure(run.case("rest"))
    ax = fig.axes[0]
    (pd,) = _lines(ax, "PD")
    (bpbc,) = _lines(ax, "BPBC")
    assert np.max(np.abs(pd.get_ydata())) > RATE_BOUNDS[0]
    assert np.max(np.abs(bpbc.get_ydata())) < RATE_BOUNDS[0]


def test_torque_figure_draws_the_norm_and_the_theoretical_bound(run, summaries):
    for case in run.cases:
        ax = torques_figure(case).axes[-1]
        for r in case.runs:
            s = summaries[case.name, r.controller]
            (line,) = _lines(ax, r.controller)
            # ‖τ‖ of the single-precision log against the double-precision summary
            assert np.max(line.get_ydata()) == pytest.approx(s["peak_torque_norm"], rel=1e-6)
            prefix = f"{r.controller} bound"
            bound = [ln for ln in ax.get_lines() if ln.get_label().startswith(prefix)]
            if s["torque_bound"] is None:
                assert not bound
            else:
                (b,) = bound
                assert b.get_ydata()[0] == pytest.approx(s["torque_bound"])
        assert any(summaries[case.name, c]["torque_bound"] for c in case.controllers)


def test_positions_figure_draws_the_target(run):
    case = run.case("rest")
    fig = positions_figure(case)
    for k, ax in enumerate(fig.axes):
        (target,) = _lines(ax, "target")
        assert target.get_ydata()[0] == pytest.approx(case.runs[0].target[k])
        (pd,) = _lines(ax, "PD")
        assert pd.get_ydata()[-1] == pytest.approx(case.runs[0].position[-1, k])


def test_lyapunov_figure_is_logarithmic_and_holds_v(run):
    case = run.case("rest")
    ax = lyapunov_figure(case).axes[0]
    assert ax.get_yscale() == "log"
    for r in case.runs:
        (line,) = _lines(ax, r.controller)
        assert np.nanmax(line.get_ydata()) == pytest.approx(np.nanmax(r.lyapunov))


def test_margins_figure_groups_the_constraints_by_type(run, summaries):
    case = run.case("rest")
    fig = margins_figure(case)
    first = case.runs[0]
    assert first.margin_types == ("clearance", "position", "rate", "rate")
    labels = [ax.get_ylabel() for ax in fig.axes]
    assert labels == ["position limits [rad]", "rate limits [rad/s]", "clearance [m]"]
    for ax, kind in zip(fig.axes, ("position", "rate", "clearance"), strict=True):
        names = [n for n, t in zip(first.margin_names, first.margin_types, strict=True)
                 if t == kind]
        for r in case.runs:
            for name in names:  # at most three of a type: each drawn and named
                (line,) = _lines(ax, f"{r.controller}: {name}")
                assert np.min(line.get_ydata()) == np.float32(
                    summaries["rest", r.controller]["min_margins"][name])
    # PD runs into the obstacle: its clearance [m] goes below zero in the figure
    (pd,) = _lines(fig.axes[2], "PD: obstacle")
    assert np.min(pd.get_ydata()) < 0
    # the thesis's obstacle is ‖p − c‖² − r² > 0; its margin is the distance d − r
    p = np.column_stack([np.cos(first.position).sum(axis=1), np.sin(first.position).sum(axis=1)])
    distance = np.linalg.norm(p - OBSTACLE[0], axis=1) - OBSTACLE[1]
    k = first.margin_names.index("obstacle")
    np.testing.assert_allclose(first.margins[:, k], distance, atol=2e-6)


def _synthetic_case(types: dict[str, int], limits: list[float] | None = None) -> SavedCase:
    """Two runs of a 7-joint arm with the given number of margins of each type."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 2.0, 2001)
    names = [f"{kind}[{i}]" for kind, count in types.items() for i in range(count)]
    kinds = [kind for kind, count in types.items() for _ in range(count)]
    runs = []
    for c, name in enumerate(("A", "B")):
        waves = np.sin(np.outer(t, 1 + np.arange(len(names))))
        margins = 0.2 + rng.random(len(names)) + 0.1 * waves
        margins[:, 5] -= 0.5 * c  # B comes nearest on column 5
        torque = 30 * np.sin(np.outer(t, np.ones(7)) * (1 + c))
        applied = torque if limits is None else np.clip(torque, -np.array(limits), limits)
        summary = {"controller": name, "case": "c", "status": "converged",
                   "enforced_constraints": [], "torque_limits": limits, "torque_bound": None}
        runs.append(SavedTrajectory(
            name, "c", t, np.zeros((len(t), 7)), np.zeros((len(t), 7)), torque.astype(np.float32),
            applied.astype(np.float32), margins.astype(np.float32), tuple(names), np.ones(len(t)),
            np.zeros(7), tuple(f"joint{i + 1}" for i in range(7)), "completed", summary,
            tuple(kinds), np.eye(7)))
    return SavedCase("c", tuple(runs))


def test_margins_of_a_7_joint_arm_with_40_pairs_fit_one_readable_figure():
    case = _synthetic_case({"position": 7, "rate": 7, "clearance": 44})
    fig = margins_figure(case)
    assert len(fig.axes) == 3  # one panel per type, not one per constraint
    width, height = fig.get_size_inches() * fig.dpi
    assert height < 1000 and width < 1300
    clearance = fig.axes[2]
    named = {ln.get_label().split(": ", 1)[1] for ln in clearance.get_lines()
             if ": " in ln.get_label()}
    assert len(named) == 3  # the three nearest their bounds, named
    margins = [r.margins[:, 14:] for r in case.runs]
    lowest = np.min([m.min(axis=0) for m in margins], axis=0)
    assert named == {f"clearance[{i}]" for i in np.argsort(lowest)[:3]}
    # the 41 others as a shaded range per controller whose lower edge is their minimum
    bands = clearance.collections
    assert len(bands) == 2
    others = [i for i in range(44) if f"clearance[{i}]" not in named]
    lower = bands[1].get_paths()[0].vertices[:, 1]
    assert lower.min() == pytest.approx(case.runs[1].margins[:, 14:][:, others].min(), rel=1e-6)
    legend = [t.get_text() for t in clearance.get_legend().get_texts()]
    assert "range of 41 others" in legend


def test_torque_figure_draws_the_plant_limits_and_what_was_asked():
    limits = [20.0] * 7
    case = _synthetic_case({"rate": 7}, limits)
    fig = torques_figure(case)
    for ax in fig.axes[:7]:
        dashed = sorted(ln.get_ydata()[0] for ln in ax.get_lines() if ln.get_linestyle() == "--")
        assert dashed == pytest.approx([-20.0, 20.0])
        (applied,) = _lines(ax, "A")
        assert np.max(np.abs(applied.get_ydata())) == pytest.approx(20.0)
        (asked,) = _lines(ax, "A asked")
        assert np.max(np.abs(asked.get_ydata())) == pytest.approx(30.0, rel=1e-3)


def test_path_figure_is_the_end_point_path_with_the_obstacle(run):
    case = run.case("rest")
    kin = run.info.kinematics(run.model)
    ax = path_figure(case, kin).axes[0]
    (circle,) = [p for p in ax.patches if isinstance(p, Circle)]
    assert circle.center == pytest.approx(OBSTACLE[0])
    assert circle.get_radius() == pytest.approx(OBSTACLE[1])
    for r in case.runs:
        (line,) = _lines(ax, r.controller)
        xy = np.column_stack([line.get_xdata(), line.get_ydata()])
        # Absolute link angles of the unit-length arm: p = (Σ cos θ_k, Σ sin θ_k).
        theta = r.position[-1].astype(float)  # the logged (single-precision) angles
        assert xy[-1] == pytest.approx([np.cos(theta).sum(), np.sin(theta).sum()], abs=1e-9)
        assert xy[0] == pytest.approx([2.0, 0.0], abs=1e-9)


def test_no_plots_writes_no_figure_but_the_view(tmp_path):
    out = tmp_path / "out"
    code = main([str(scenario(tmp_path, duration=0.2)), "--out", str(out), "--quiet",
                 "--workers", "1", "--no-plots"])
    assert code == 0
    assert not list(out.rglob("*.png"))
    assert (out / "view.html").is_file()
    assert (out / "scene.mjb.gz").is_file()


def test_envelope_keeps_every_extreme_and_both_ends(rng):
    y = np.cumsum(rng.normal(size=100_001))
    y[rng.choice(len(y), 50, replace=False)] = np.nan
    idx = envelope(y, buckets=300)
    assert len(idx) <= 2 * 300 + 2
    assert idx[0] == 0 and idx[-1] == len(y) - 1
    assert np.all(np.diff(idx) > 0)
    assert np.nanmax(y[idx]) == np.nanmax(y)
    assert np.nanmin(y[idx]) == np.nanmin(y)
    short = np.arange(10.0)
    assert np.array_equal(envelope(short, buckets=300), np.arange(10))
