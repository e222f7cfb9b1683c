"""The meshcat viewer, checked as a person would: the exported view.html and the live and
replay pages are opened in headless Chromium, which must draw the scene (the canvas changes
when the run's objects are hidden) without logging an error. Also: every MuJoCo geom type
is drawn, clearances and colours are the geometry's, the server listens on 127.0.0.1 only.
"""

from __future__ import annotations

import io
import json
import re
import signal
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest
import umsgpack
import yaml
from PIL import Image

from cpbc.errors import ModelError
from cpbc.resources import viewer_dir
from cpbc.results.palette import clearance_colour
from cpbc.results.saved_run import load_run
from cpbc.results.sweep import SceneKinematics
from cpbc.run import main
from cpbc.viewer.browser import HeadlessChromium, find_chromium
from cpbc.viewer.page_data import packed, unpacked
from cpbc.viewer.recorder import CommandRecorder
from cpbc.viewer.scene import CaseScene, ViewSettings
from cpbc.viewer.server import MeshcatServer
from cpbc.viewer.shapes import geom_geometry, tube


def _ctrl_c_heard() -> None:
    """In the child before it starts: Ctrl-C as a terminal's foreground job hears it. A
    pytest started in the background by a shell without job control ignores SIGINT, and its
    children would inherit that (Python then installs no KeyboardInterrupt handler)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)

needs_chromium = pytest.mark.skipif(
    find_chromium() is None,
    reason="Debian's chromium is not installed (bash scripts/install.sh --test installs it)",
)
READY = "window.cpbc && window.cpbc.ready"
DURATION = 2.0
OBSTACLE = ([1.7, 1.0], 0.3)

SHAPES_XML = """
<mujoco>
  <asset><mesh name="tet" vertex="0 0 0  0.3 0 0  0 0.3 0  0 0 0.3"/></asset>
  <worldbody>
    <geom name="floor" type="plane" size="3 3 0.1"/>
    <geom name="ball" type="sphere" size="0.2" pos="1 1 0.5"/>
    <geom name="crate" type="box" size="0.1 0.2 0.3" pos="-1 1 0.5"/>
    <geom name="post" type="cylinder" size="0.1 0.4" pos="1 -1 0.5"/>
    <geom name="egg" type="ellipsoid" size="0.1 0.2 0.3" pos="-1 -1 0.5"/>
    <geom name="rock" type="mesh" mesh="tet" pos="0 1.5 0.2"/>
    <body name="arm">
      <joint name="j" type="hinge" axis="0 0 1"/>
      <geom name="bar" type="capsule" fromto="0 0 0 1 0 0" size="0.05"/>
      <site name="tip" pos="1 0 0"/>
    </body>
  </worldbody>
</mujoco>
"""


def scenario(folder: Path) -> Path:
    """Two seconds of the planar arm: PD runs its end point into an obstacle, CPBC keeps
    clear of it; two cases."""
    data = {
        "name": "viewer_short",
        "robot": {"model": "planar_2link", "coordinates": "absolute"},
        "simulation": {"duration": DURATION},
        "target": ["pi", "2*pi/3"],
        "cases": [
            {"name": "rest", "position": [0, 0]},
            {"name": "moving", "position": [0, 0], "velocity": [0.1, 0.05]},
        ],
        "constraints": [
            {"type": "point_outside_sphere", "name": "obstacle", "frame": "end_point",
             "centre": OBSTACLE[0], "radius": OBSTACLE[1]},
            {"type": "joint_rate_limit", "name": "link_rates", "bounds": [0.3, 0.2]},
        ],
        "controllers": [
            {"type": "pd", "name": "PD", "kp": 4, "kd": 20},
            {"type": "cpbc", "name": "CPBC", "kp": 4, "kd": 20,
             "shaping": {"type": "power", "alpha": 0.2}},
        ],
    }
    path = folder / "viewer_short.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def run_folder(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("viewer")
    out = folder / "out"
    code = main([str(scenario(folder)), "--out", str(out), "--quiet", "--workers", "1",
                 "--no-plots"])
    assert code == 0
    return out


def _pixels(png: bytes) -> np.ndarray:
    return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"), dtype=float)


def _assert_scene_drawn(browser: HeadlessChromium, shot: Path, root: str = "cpbc") -> None:
    """Screenshot, then hide the run's objects: the picture must change where they were."""
    browser.next_frames(3)
    with_scene = _pixels(browser.screenshot(shot))
    browser.evaluate(
        f'viewer.scene_tree.find(["meshcat", "{root}"]).object.visible = false; '
        "viewer.set_dirty(); true"
    )
    browser.next_frames(3)
    without = _pixels(browser.screenshot())
    changed = np.any(np.abs(with_scene - without) > 12, axis=2).mean()
    assert changed > 0.005, f"the scene covers only {changed:.2%} of the canvas"
    assert with_scene.std() > 10  # not a blank canvas


def _meshes(root: str) -> str:
    """JS: number of meshes under the meshcat node ``root`` (0 while it does not exist)."""
    return (
        "(() => { const node = viewer.scene.getObjectByName('meshcat'); if (!node) return 0;"
        f" const r = node.getObjectByName('{root}'); if (!r) return 0; let n = 0;"
        " r.traverse(o => { if (o.isMesh && o.visible) n++; }); return n; })()"
    )


# -- geometry -----------------------------------------------------------------------------------
def test_every_geom_type_is_drawn_and_planes_are_not():
    model = mujoco.MjModel.from_xml_string(SHAPES_XML)
    kin = SceneKinematics(model, np.eye(1), "tip")
    names = {kin.geom_names[g] for g in kin.obstacle_geoms}
    assert names == {"ball", "crate", "post", "egg", "rock"}
    assert [kin.geom_names[g] for g in kin.robot_geoms] == ["bar"]
    for g in range(model.ngeom):
        shape = geom_geometry(model, g)
        assert (shape is None) == (kin.geom_names[g] == "floor")
    bar = geom_geometry(model, model.geom("bar").id)
    # A capsule of radius 0.05 and half-length 0.5 along its local z-axis.
    assert np.ptp(bar.vertices, axis=0) == pytest.approx([0.1, 0.1, 1.1], abs=1e-6)
    rock = model.geom("rock").id
    assert len(geom_geometry(model, rock).vertices) == model.mesh_vertnum[model.geom_dataid[rock]]

    recorder = CommandRecorder()
    scene = CaseScene(kin, ["A", "B"], np.array([1.0]), np.array([0.0]))
    anim = scene.draw_runs(recorder.visualizer(), [])
    assert not anim.clips
    objects = [umsgpack.unpackb(c)["path"] for c in recorder.commands
               if umsgpack.unpackb(c)["type"] == "set_object"]
    for name in ("ball", "crate", "post", "egg", "rock"):
        assert f"/meshcat/cpbc/obstacles/{name}" in objects
    assert not any("floor" in p.rsplit("/", 1)[-1] for p in objects if "obstacles" in p)
    scene.draw_arm(recorder.visualizer(), "A")
    assert "/meshcat/cpbc/A/robot/arm/bar" in [
        umsgpack.unpackb(c)["path"] for c in recorder.commands
    ]


def test_named_obstacles_leave_other_world_geoms_as_scenery():
    model = mujoco.MjModel.from_xml_string(SHAPES_XML)
    kin = SceneKinematics(model, np.eye(1), "tip", obstacles=["ball", "rock"])
    assert [kin.geom_names[g] for g in kin.obstacle_geoms] == ["ball", "rock"]
    assert {kin.geom_names[g] for g in kin.static_geoms} == {"crate", "post", "egg"}
    assert kin.clearances(1.0)[1].shape == (2,)
    with pytest.raises(ModelError, match="world geoms"):
        SceneKinematics(model, np.eye(1), "tip", obstacles=["boulder"])
    with pytest.raises(ModelError, match="sites: \\['tip'\\]"):
        SceneKinematics(model, np.eye(1), "hand")


def test_clearance_is_the_distance_between_link_and_obstacle():
    model = mujoco.MjModel.from_xml_string(SHAPES_XML)
    kin = SceneKinematics(model, np.eye(1), "tip")
    kin.pose(np.array([0.0]))
    body, obstacle = kin.clearances(distmax=5.0)
    ball = [kin.geom_names[g] for g in kin.obstacle_geoms].index("ball")
    # Capsule axis from (0,0,0) to (1,0,0), radius 0.05; ball at (1,1,0.5), radius 0.2.
    assert obstacle[ball] == pytest.approx(np.sqrt(1.25) - 0.05 - 0.2, abs=1e-6)
    assert body[model.body("arm").id] == pytest.approx(obstacle.min())
    assert np.allclose(kin.traced_point(), [1, 0, 0])
    kin.pose(np.array([np.pi / 2]))
    assert np.allclose(kin.traced_point(), [0, 1, 0], atol=1e-12)
    capped = kin.clearances(distmax=0.1)[1]
    assert np.all(capped <= 0.1)


def test_tube_follows_the_path_at_its_radius():
    t = np.linspace(0, np.pi, 200)
    path = np.column_stack([np.cos(t), np.sin(t), np.zeros_like(t)])
    shape = tube(path, 0.01)
    v = shape.vertices.astype(float)
    # Every vertex lies 0.01 from the unit circle in the plane z = 0.
    dist = np.hypot(np.hypot(v[:, 0], v[:, 1]) - 1.0, v[:, 2])
    assert dist == pytest.approx(0.01, abs=1e-5)
    assert shape.faces.max() < len(v)
    assert tube(np.zeros((5, 3)), 0.01) is None


# -- the run's page ------------------------------------------------------------------------------
def _page_data(page: Path) -> dict:
    m = re.search(r"window\.CPBC_DATA = (\{.*?\});\n</script>", page.read_text(), re.S)
    assert m, "the page holds its data"
    return json.loads(m.group(1))


@pytest.mark.parametrize("shape", [(240, 3, 7), (400,), (0, 3)])
def test_page_arrays_unpack_to_their_single_precision_values(shape: tuple[int, ...]) -> None:
    """The page's arrays are packed with cpbc.results.packed's coding and deflated (view.js
    inflates them); unpacked, the mirror of view.js, gives the float32 values back, flat."""
    a = np.cumsum(np.random.default_rng(4).standard_normal(shape), axis=0)
    entry = packed(a)
    assert entry["stride"] == int(np.prod(shape[1:], dtype=int))
    np.testing.assert_array_equal(unpacked(entry), a.astype(np.float32).ravel())
    raw = bytes(range(256)) * 3
    assert unpacked(packed(raw)).tobytes() == raw


def test_the_run_has_one_self_contained_page_built_from_the_viewer_folder(run_folder):
    page = run_folder / "view.html"
    assert not list(run_folder.glob("*/view.html"))  # one page per run, not per case
    text = page.read_text()
    assert "MeshCat.Viewer" in text
    assert not re.search(r"""<(script|link|img)[^>]+(src|href)=["']?""", text)  # all inlined
    # the page, its script and style are the files of the top-level viewer/ folder
    for name in ("view.js", "view.css"):
        source = (viewer_dir() / name).read_text()
        assert source.strip() in text, name
    assert 100_000 < len(text) < 3_000_000


def test_page_plots_keep_every_peak_of_the_run(run_folder):
    """The plotted curves are thinned; every extreme of the run stays in them."""
    data = _page_data(run_folder / "view.html")
    summaries = {(s["case"], s["controller"]): s
                 for s in json.loads((run_folder / "summary.json").read_text())}
    for case in data["cases"]:
        titles = [g["title"] for g in case["plots"]]
        assert titles == ["Positions", "Rates", "Torques applied", "Margins by type"]
        margin_panels = case["plots"][3]["panels"]
        assert [p["label"] for p in margin_panels] == ["rate limits [rad/s]", "clearance [m]"]
        for run, series in zip(case["controllers"], case["series"], strict=True):
            s = summaries[case["name"], run["name"]]
            time = unpacked(series["time"])
            assert time[0] == 0 and time[-1] == pytest.approx(DURATION)
            assert len(time) < 2000  # thinned: 2 s at 1 kHz is 2001 samples
            for k in range(2):
                rates = np.abs(unpacked(series["columns"][f"velocity{k}"]))
                assert rates.max() == np.float32(s["peak_joint_rates"][k])
            for i, name in enumerate(("obstacle", "rate[theta1]", "rate[theta2]")):
                low = unpacked(series["columns"][f"m{i}"]).min()
                assert low == np.float32(s["min_margins"][name])


@needs_chromium
def test_page_renders_and_one_timeline_scrubs_scene_and_plots(run_folder, tmp_path):
    run = load_run(run_folder)
    case = run.case("rest")
    with HeadlessChromium(width=1200, height=760) as browser:
        browser.open((run_folder / "view.html").as_uri(), READY, timeout=90)
        assert browser.evaluate("cpbc.case") == "rest"
        assert browser.evaluate("cpbc.duration") == pytest.approx(DURATION)
        # Two links per arm, two arms and the target pose, the obstacle, traces and markers.
        assert browser.evaluate(_meshes("cpbc")) >= 2 * 3 + 1 + 2 + 2
        # the page inflates its arrays to exactly what was packed (view.js against unpacked)
        data = _page_data(run_folder / "view.html")
        for key in ("pose", "tip", "clearance"):
            shown = browser.evaluate(f"Array.from(cpbc.data.cases[0].controllers[1].{key})")
            np.testing.assert_array_equal(np.float32(shown),
                                          unpacked(data["cases"][0]["controllers"][1][key]))
        shown = browser.evaluate("Array.from(cpbc.data.cases[0].series[0].columns.m0)")
        np.testing.assert_array_equal(np.float32(shown),
                                      unpacked(data["cases"][0]["series"][0]["columns"]["m0"]))

        # At the frame where PD's outer link is nearest the obstacle, the page poses it there
        # and colours it as the clearance says (red when touching, its own blue far away).
        kin = run.info.kinematics(run.model)
        settings = ViewSettings()
        pd = case.runs[0]
        frames = np.arange(int(DURATION * settings.fps) + 1) / settings.fps
        sweep = kin.sweep(pd.time, pd.position, frames, settings.warn_distance)
        link2 = run.model.body("link2").id
        k = int(np.argmin(sweep.body_clearance[:, link2]))
        assert sweep.body_clearance[k, link2] < 0.5 * settings.warn_distance  # PD gets close
        expected = clearance_colour("#1f77b4", sweep.body_clearance[k, link2],
                                    settings.warn_distance)
        assert browser.evaluate(f"cpbc.seek({frames[k]})") == pytest.approx(frames[k])
        node = 'viewer.scene_tree.find(["meshcat", "cpbc", "rest", "PD", "robot", "link2"])'
        position = browser.evaluate(f"{node}.object.position.toArray()")
        assert position == pytest.approx(sweep.body_position[k, link2].tolist(), abs=1e-5)
        colour = browser.evaluate(
            f"(() => {{ let c; {node}.object.traverse(o => {{ if (o.isMesh) c = o.material.color;"
            " }); return [c.r, c.g, c.b]; })()"
        )
        assert colour == pytest.approx(expected.tolist(), abs=0.02)
        assert colour[0] > colour[2]  # reddened

        # The same timeline moves the plots' cursor: a dark line down the plot at t only.
        browser.evaluate("cpbc.showTab(1)")  # rates
        assert browser.evaluate("cpbc.panels") == ["theta1 [rad/s]", "theta2 [rad/s]"]
        height = browser.evaluate("document.querySelector('#panels canvas').clientHeight")
        for t in (0.5, 1.5):
            browser.evaluate(f"cpbc.seek({t})")
            x = browser.evaluate("cpbc.cursorX(0)")
            assert browser.evaluate(_cursor_rows(x)) > 0.6 * height
            assert browser.evaluate(_cursor_rows(x + 40)) < 0.2 * height

        browser.evaluate("cpbc.selectCase('moving')")
        visible = browser.evaluate(
            "['rest', 'moving'].map(c => viewer.scene_tree.find(['meshcat', 'cpbc', c])"
            ".object.visible)"
        )
        assert visible == [False, True]
        assert "case 'moving'" in browser.evaluate("document.getElementById('legend').textContent")

        _assert_scene_drawn(browser, tmp_path / "view.png")
        assert not browser.log.errors, browser.log.errors
        remote = [u for u in browser.log.requests if not u.startswith(("file:", "data:", "blob:"))]
        assert not remote, f"the page fetched {remote}"


def _cursor_rows(x: float) -> str:
    """JS: how many pixel rows of column x of the first plot are dark grey (the cursor's
    colour; the curves are coloured, the grid light)."""
    return (
        "(() => { const c = document.querySelector('#panels canvas');"
        " const d = window.devicePixelRatio || 1;"
        f" const img = c.getContext('2d').getImageData(Math.round({x} * d), 0, 1, c.height).data;"
        " let n = 0; for (let i = 0; i < img.length; i += 4) {"
        " const hi = Math.max(img[i], img[i + 1], img[i + 2]);"
        " const lo = Math.min(img[i], img[i + 1], img[i + 2]);"
        " if (img[i + 3] > 200 && hi < 90 && hi - lo < 20) n++; } return n / d; })()"
    )


# -- servers ------------------------------------------------------------------------------------
def _listeners(port: int) -> set[str]:
    """Addresses listening on TCP ``port``, from /proc/net/tcp and tcp6 (Linux)."""
    out = set()
    for table, width in (("/proc/net/tcp", 8), ("/proc/net/tcp6", 32)):
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, hex_port = local.split(":")
            if state == "0A" and int(hex_port, 16) == port:
                out.add(address if len(address) == width else "?")
    return out


def _read_url(proc: subprocess.Popen, pattern: str) -> str:
    """The URL the process prints, however slow the machine; fails once its output ends."""
    assert proc.stdout is not None
    for line in proc.stdout:
        m = re.search(pattern, line)
        if m:
            return m.group(1)
    proc.kill()
    raise AssertionError(f"no URL printed; stderr:\n{proc.stderr.read() if proc.stderr else ''}")


def _wait_for_line(proc: subprocess.Popen, text: str) -> None:
    """Until the process prints ``text``; fails once its output ends."""
    assert proc.stdout is not None
    for line in proc.stdout:
        if text in line:
            return
    raise AssertionError(f"'{text}' never printed")


def _stop(proc: subprocess.Popen) -> int:
    proc.send_signal(signal.SIGINT)
    try:
        return proc.wait(timeout=30)
    finally:
        if proc.poll() is None:
            proc.kill()


@needs_chromium
def test_live_view_streams_the_run_on_loopback(tmp_path):
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "cpbc.run", str(scenario(tmp_path)), "--out", str(out), "--view",
         "--quiet", "--no-plots"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_heard,
    )
    try:
        url = _read_url(proc, r"meshcat viewer \(live\): (http://\S+)")
        assert url.startswith("http://127.0.0.1:")
        port = int(url.split(":")[2].split("/")[0])
        # The web server listens on the loopback interface only (no 0.0.0.0 or :: socket).
        if Path("/proc/net/tcp").is_file():
            assert _listeners(port) == {"0100007F"}
        with HeadlessChromium(width=1000, height=700) as browser:
            # Arms of both controllers appear while the first runs are streamed.
            browser.open(url, _meshes("cpbc") + " >= 8", timeout=60)
            started = browser.evaluate(
                'viewer.scene_tree.find(["meshcat", "cpbc", "rest", "PD", "trace"])'
                ".object.children.length"
            )
            assert started >= 1
            _wait_for_line(proc, "still serving")
            # The replay animation of the finished runs is loaded (a loaded machine may take
            # a while to parse it).
            browser.wait_until("viewer.animator.duration > 0", timeout=60)
            assert browser.evaluate("viewer.animator.duration") == pytest.approx(DURATION)
            _assert_scene_drawn(browser, tmp_path / "live.png")
            assert not browser.log.errors, browser.log.errors
        assert _stop(proc) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert (out / "view.html").is_file()
    assert not list(out.rglob("*.png"))


@needs_chromium
def test_replay_serves_a_saved_run(run_folder, tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-m", "cpbc.viewer", str(run_folder), "--case", "moving"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=_ctrl_c_heard,
    )
    try:
        url = _read_url(proc, r"\(case 'moving'\): (http://127\.0\.0\.1:\S+)")
        with HeadlessChromium(width=900, height=600) as browser:
            browser.open(url, _meshes("cpbc") + " >= 8", timeout=60)
            visible = browser.evaluate(
                "['rest', 'moving'].map(c => viewer.scene_tree.find(['meshcat', 'cpbc', c])"
                ".object.visible)"
            )
            assert visible == [False, True]
            assert browser.evaluate("viewer.animator.duration") == pytest.approx(DURATION)
            _assert_scene_drawn(browser, tmp_path / "replay.png")
            assert not browser.log.errors, browser.log.errors
        assert _stop(proc) == 0
    finally:
        if proc.poll() is None:
            proc.kill()


@needs_chromium
def test_replay_cli_exports_and_screenshots(run_folder, tmp_path):
    page = run_folder / "view.html"
    before = page.stat().st_mtime_ns
    cli = [sys.executable, "-m", "cpbc.viewer", str(run_folder)]
    subprocess.run([*cli, "--export", "--warn-distance", "0.3"], check=True, capture_output=True)
    assert page.stat().st_mtime_ns > before
    assert _page_data(page)["warnDistance"] == 0.3
    png = tmp_path / "shot.png"
    subprocess.run([*cli, "--screenshot", str(png), "--case", "moving", "--at", "1.0",
                    "--size", "640x400"], check=True, capture_output=True)
    with Image.open(png) as im:
        assert im.size == (640, 400)
    bad = subprocess.run([*cli, "--case", "nope", "--export"], capture_output=True, text=True)
    assert bad.returncode == 2
    assert "no case 'nope'" in bad.stderr


def test_replay_cli_rejects_a_folder_that_is_not_a_run(tmp_path):
    r = subprocess.run([sys.executable, "-m", "cpbc.viewer", str(tmp_path), "--export"],
                       capture_output=True, text=True)
    assert r.returncode == 2
    assert "summary.json" in r.stderr


def test_server_listens_on_loopback_only():
    if not Path("/proc/net/tcp").is_file():
        pytest.skip("needs Linux's /proc/net/tcp to list listening sockets")
    with MeshcatServer() as server:
        web = int(server.web_url.split(":")[2].split("/")[0])
        zmq = int(server.zmq_url.rsplit(":", 1)[1])
        assert server.web_url.startswith("http://127.0.0.1:")
        assert _listeners(web) == {"0100007F"}
        assert _listeners(zmq) == {"0100007F"}
        pid = server.pid
    assert pid is not None
    assert not Path(f"/proc/{pid}").exists() or "zombie" in Path(f"/proc/{pid}/status").read_text()
