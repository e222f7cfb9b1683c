"""The run page (view.html) of a Part I system: the MJCF's bodies posed from the logged MuJoCo
coordinates, and rendered in headless Chromium."""

from __future__ import annotations

import json
import re
from pathlib import Path

import mujoco
import numpy as np
import pytest
import yaml

from cpbc.resources import models_dir, scenarios_dir
from cpbc.results import LOG_FILE, load_log
from cpbc.run import main
from cpbc.viewer.browser import HeadlessChromium, find_chromium
from cpbc.viewer.page_data import unpacked

needs_chromium = pytest.mark.skipif(
    find_chromium() is None,
    reason="Debian's chromium is not installed (bash scripts/install.sh --test installs it)",
)
READY = "window.cpbc && window.cpbc.ready"


def _run(folder: Path, name: str, duration: float, cases: list[str]) -> Path:
    data = yaml.safe_load((scenarios_dir() / f"{name}.yaml").read_text())
    data["simulation"]["duration"] = duration
    data["cases"] = [c for c in data["cases"] if c["name"] in cases]
    path = folder / f"{name}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    out = folder / "out"
    assert main([str(path), "--out", str(out), "--quiet", "--no-plots"]) == 0
    return out


def _page_data(page: Path) -> dict:
    m = re.search(r"window\.CPBC_DATA = (\{.*?\});\n</script>", page.read_text(), re.S)
    assert m, "the page holds its data"
    return json.loads(m.group(1))


@pytest.fixture(scope="module")
def car(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory.mktemp("car"), "ch3_suspension", 0.3, ["fig3.6"])


def test_quarter_car_page_moves_the_body_by_the_logged_travel(car: Path) -> None:
    """The sprung body's height on the page is z_s = z_us + x3 of the run at each frame."""
    data = _page_data(car / "view.html")
    case = data["cases"][0]
    assert case["name"] == "fig3.6"
    assert [c["name"] for c in case["controllers"]] == ["barrier", "unconstrained"]
    bodies = [b["name"] for b in data["bodies"]]
    assert {"unsprung", "sprung"} <= set(bodies)
    run = case["controllers"][0]
    pose = unpacked(run["pose"]).reshape(run["frames"], len(bodies), 7)
    z = load_log(car / LOG_FILE, "fig3.6", "barrier")
    time, state = z["time"], z["state"]
    frames = np.arange(run["frames"]) / data["fps"]
    sprung, unsprung = bodies.index("sprung"), bodies.index("unsprung")
    travel = np.interp(frames, time, state[:, 2])
    height = pose[:, sprung, 2] - pose[:, unsprung, 2]
    model = mujoco.MjModel.from_xml_path(str(models_dir() / "systems" / "quarter_car.xml"))
    rest = model.body("sprung").pos[2] - model.body("unsprung").pos[2]
    assert np.abs(travel).max() > 0.05  # the bump moves it
    assert np.allclose(height - rest, travel, atol=2e-3)  # frames fall between samples
    positions = [p["label"] for p in case["plots"][0]["panels"]]
    assert positions == ["wheel_z [m]", "body_z [m]"]


@needs_chromium
def test_system_pages_render(car: Path, tmp_path: Path) -> None:
    rwp = _run(tmp_path, "ch3_rwp", 1.0, ["fig3.9"])
    for folder, case in ((car, "fig3.6"), (rwp, "fig3.9")):
        with HeadlessChromium(width=900, height=600) as browser:
            browser.open((folder / "view.html").as_uri(), READY, timeout=90)
            assert browser.evaluate("cpbc.case") == case
            meshes = browser.evaluate(
                "(() => { let n = 0; viewer.scene.getObjectByName('meshcat')"
                ".getObjectByName('cpbc').traverse(o => { if (o.isMesh && o.visible) n++; });"
                " return n; })()")
            assert meshes >= 2
            browser.next_frames(3)
            shot = np.frombuffer(browser.screenshot(tmp_path / f"{case}.png"), dtype=np.uint8)
            assert shot.size > 10_000


def test_replaying_a_system_run_says_to_open_its_page(car: Path, capsys) -> None:
    """python -m cpbc.viewer replays arm runs; on a Part I run it used to ask for the scene
    files and to run the scenario again, which writes none."""
    from cpbc.viewer.__main__ import main as viewer

    assert viewer([str(car), "--export"]) == 2
    err = capsys.readouterr().err
    assert "Part I system run" in err and "view.html" in err


@pytest.fixture(scope="module")
def chain(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _run(tmp_path_factory.mktemp("chain"), "ch4_integrator_chain", 30.0, ["fig4.1"])


def test_integrator_chain_page_plots_the_states_against_their_bounds(chain: Path) -> None:
    """The chain is only its ODE: its page has no body, and shows the four states (ξ2, ξ3,
    ξ4 with their bounds ±2.5, ±12, ±700) and the input, from the run's log."""
    data = _page_data(chain / "view.html")
    assert data["bodies"] == []
    (case,) = data["cases"]
    assert [g["title"] for g in case["plots"]] == ["States", "Input", "Margins by type"]
    states = case["plots"][0]["panels"]
    assert [p["label"] for p in states] == ["xi1 [-]", "xi2 [-]", "xi3 [-]", "xi4 [-]"]
    bounds = [sorted(line["y"] for line in p["lines"] if line["label"] != "target")
              for p in states]
    assert bounds == [[], [-2.5, 2.5], [-12.0, 12.0], [-700.0, 700.0]]
    z = load_log(chain / LOG_FILE, "fig4.1", "barrier")
    series = case["series"][0]
    xi1 = unpacked(series["columns"]["position0"])
    shown = unpacked(series["time"])
    logged = np.interp(shown, z["time"], z["state"][:, 0])
    assert np.abs(xi1 - logged).max() < 1e-3 * np.abs(logged).max()  # its samples, single
    u = unpacked(series["columns"]["torque0"])
    assert np.abs(u).max() == pytest.approx(np.abs(z["input"]).max(), rel=1e-6)


@needs_chromium
def test_integrator_chain_page_renders(chain: Path, tmp_path: Path) -> None:
    with HeadlessChromium(width=900, height=600) as browser:
        browser.open((chain / "view.html").as_uri(), READY, timeout=90)
        assert browser.evaluate("cpbc.case") == "fig4.1"
        browser.next_frames(3)
        shot = np.frombuffer(browser.screenshot(tmp_path / "chain.png"), dtype=np.uint8)
        assert shot.size > 10_000


def test_a_system_page_plots_its_one_input_once(car: Path) -> None:
    """The input has one panel, named as the system names it (not a zero column per
    MuJoCo coordinate)."""
    (case,) = _page_data(car / "view.html")["cases"]
    assert [g["title"] for g in case["plots"]] == ["Positions", "Rates", "Input",
                                                   "Margins by type"]
    assert [p["label"] for p in case["plots"][2]["panels"]] == ["u [m/s²]"]
