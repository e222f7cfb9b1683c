"""Self-contained ``view.html``: meshcat's viewer, the scene and its animation in one file.

The page inlines meshcat's ``main.min.js`` and the recorded scene commands, so it opens from
disk in any browser with no server and no network. meshcat's control panel (open) has the
animation's play, pause, reset, time and time-scale controls; a small legend names the
controllers in their colours and shows the animation time.
"""

from __future__ import annotations

import base64
import html
import json
from collections.abc import Sequence
from pathlib import Path

import meshcat

from cpbc.results.saved_run import SavedCase, SavedRun
from cpbc.viewer.recorder import CommandRecorder
from cpbc.viewer.scene import CaseScene, ViewSettings, set_animation

VIEW_FILE = "view.html"

_PAGE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>{title}</title>
<style>
  body {{ margin: 0; }}
  #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
  #cpbc-legend {{
    position: absolute; left: 10px; top: 10px; padding: 8px 12px; border-radius: 6px;
    background: rgba(255, 255, 255, 0.85); font: 13px/1.45 sans-serif; color: #222;
    pointer-events: none; max-width: 40vw;
  }}
  #cpbc-legend .swatch {{
    display: inline-block; width: 14px; height: 4px; margin: 0 6px 3px 0;
    vertical-align: middle;
  }}
  #cpbc-legend .note {{ color: #555; font-size: 11px; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="cpbc-legend">{legend}<div id="cpbc-time"></div></div>
<script>
{meshcat_js}
</script>
<script>
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));
window.cpbc = {{ready: false, duration: {duration}, commands: 0}};
(function () {{
  const commands = {commands};
  for (const text of commands) {{
    const raw = atob(text);
    const bytes = new Uint8Array(raw.length);
    for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
    viewer.handle_command_bytearray(bytes);
    window.cpbc.commands += 1;
  }}
  viewer.gui.open();
  const clock = document.getElementById("cpbc-time");
  function tick() {{
    clock.textContent = "t = " + viewer.animator.time.toFixed(2) + " s of "
      + window.cpbc.duration.toFixed(2) + " s";
    requestAnimationFrame(tick);
  }}
  tick();
  window.cpbc.ready = true;
}})();
</script>
</body>
</html>
"""


def meshcat_js() -> str:
    """meshcat's bundled viewer script, as shipped with the meshcat package."""
    return (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text()


def static_page(
    commands: Sequence[bytes], title: str, legend_html: str = "", duration: float = 0.0
) -> str:
    """An HTML page that replays recorded meshcat commands on load."""
    encoded = json.dumps([base64.b64encode(c).decode("ascii") for c in commands])
    # "</script" cannot occur in base64 or JSON of base64, but the viewer script is inlined.
    js = meshcat_js().replace("</script", "<\\/script")
    return _PAGE.format(
        title=html.escape(title),
        legend=legend_html,
        meshcat_js=js,
        commands=encoded,
        duration=json.dumps(float(duration)),
    )


def legend(scene: CaseScene, title: str, statuses: dict[str, str] | None = None) -> str:
    """The legend's HTML: title, one colour swatch per controller, and how to read colours."""
    rows = [f"<b>{html.escape(title)}</b>"]
    for c in scene.controllers:
        status = f" — {html.escape(statuses[c])}" if statuses and c in statuses else ""
        rows.append(
            f'<div><span class="swatch" style="background:{scene.colours[c]}"></span>'
            f"{html.escape(c)}{status}</div>"
        )
    rows.append(
        '<div><span class="swatch" style="background:#3a3a3a;opacity:.4"></span>target pose</div>'
    )
    if scene.kin.obstacle_geoms:
        rows.append(
            f'<div class="note">links and obstacles turn red as their clearance falls from '
            f"{scene.settings.warn_distance:g} m to 0</div>"
        )
    return "".join(rows)


def case_view(
    run: SavedRun, case: SavedCase, settings: ViewSettings | None = None
) -> tuple[CaseScene, CommandRecorder, float]:
    """Draw a case of a saved run into a recorder; returns the scene, commands and duration."""
    kin = run.info.kinematics(run.model)
    first = case.runs[0]
    scene = CaseScene(kin, case.controllers, first.target, first.position[0], settings)
    recorder = CommandRecorder()
    vis = recorder.visualizer()
    anim = scene.draw_runs(vis, case.runs)
    set_animation(vis, anim, play=True)
    duration = max(float(r.time[-1]) for r in case.runs)
    return scene, recorder, duration


def write_case_view(
    run: SavedRun, case: SavedCase, path: Path, settings: ViewSettings | None = None
) -> Path:
    """Write one case's self-contained page to ``path``."""
    scene, recorder, duration = case_view(run, case, settings)
    title = f"{run.info.scenario or run.folder.name} — case '{case.name}'"
    statuses = {r.controller: str(r.summary.get("status", "")) for r in case.runs}
    page = static_page(
        recorder.commands, f"cpbc: {title}", legend(scene, title, statuses), duration
    )
    path.write_text(page, encoding="utf-8")
    return path


def write_views(
    run: SavedRun, folder: Path | None = None, settings: ViewSettings | None = None
) -> list[Path]:
    """Write ``<folder>/<case>/view.html`` for every case of a run; returns the paths."""
    folder = run.folder if folder is None else Path(folder)
    out = []
    for case in run.cases:
        (folder / case.name).mkdir(parents=True, exist_ok=True)
        out.append(write_case_view(run, case, folder / case.name / VIEW_FILE, settings))
    return out
