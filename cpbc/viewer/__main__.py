"""``python -m cpbc.viewer RUN_DIR``: replay a saved run in meshcat, re-export it, or screenshot it.

* default: serve every case of the run on a loopback meshcat server (one case visible at a
  time; toggle cases in the control panel's scene tree), print the URL, wait for Ctrl-C;
* ``--export``: rewrite the run's self-contained page, ``view.html``, in the run folder;
* ``--screenshot PNG``: a picture of ``view.html`` showing a case at time ``--at``, taken
  with headless Chromium.

Exit codes: 0 done, 2 bad input (not a run folder, unknown case, no Chromium).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from meshcat.animation import Animation

from cpbc.errors import CpbcError
from cpbc.results.saved_run import SavedRun, load_run
from cpbc.viewer.browser import HeadlessChromium
from cpbc.viewer.export import VIEW_FILE, write_view
from cpbc.viewer.scene import ROOT, CaseScene, ViewSettings, set_animation
from cpbc.viewer.server import MeshcatServer


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="python -m cpbc.viewer",
        description="Replay a run folder written by python -m cpbc.run in meshcat.",
    )
    p.add_argument("run", type=Path, help="run folder (holds summary.json, scene.mjb.gz, …)")
    p.add_argument("--case", help="case to show first (default: the first case)")
    p.add_argument(
        "--frame", help="site or body whose path is traced when serving (default: the run's)"
    )
    p.add_argument("--fps", type=float, default=ViewSettings.fps,
                   help="animation frames per simulated second")
    p.add_argument("--warn-distance", type=float, default=ViewSettings.warn_distance,
                   help="clearance [m] below which links and obstacles redden")
    mode = p.add_mutually_exclusive_group()
    mode.add_argument("--export", action="store_true",
                      help="rewrite the run's view.html instead of serving")
    mode.add_argument("--screenshot", type=Path, metavar="PNG",
                      help="save a headless-Chromium screenshot of view.html showing the case")
    p.add_argument("--at", type=float, help="animation time of the screenshot [s] (default: end)")
    p.add_argument("--size", default="1280x800", help="screenshot size WxH [px]")
    return p


def serve(run: SavedRun, first: str, frame: str | None, settings: ViewSettings) -> None:
    """Draw every case on a loopback server and keep serving until interrupted."""
    info = run.info if frame is None else dataclasses.replace(run.info, trace_frame=frame)
    kin = info.kinematics(run.model)
    with MeshcatServer() as server:
        vis = server.visualizer()
        anim = Animation()
        for case in run.cases:
            r0 = case.runs[0]
            scene = CaseScene(kin, case.controllers, r0.target, r0.position[0], settings,
                              root=f"{ROOT}/{case.name}")
            anim.clips.update(scene.draw_runs(vis, case.runs).clips)
            vis[f"{ROOT}/{case.name}"].set_property("visible", case.name == first)
        set_animation(vis, anim, play=True)
        print(f"meshcat viewer of {run.folder} (case '{first}'): {server.web_url}", flush=True)
        print("other cases: tick them under Scene > meshcat > cpbc; Ctrl-C to stop", flush=True)
        try:
            while True:
                time.sleep(3600)
        except KeyboardInterrupt:
            pass


def screenshot(run: SavedRun, case: str, png: Path, at: float | None, size: str) -> None:
    """Open ``<run>/view.html`` headless on ``case``, seek to ``at`` and save a PNG."""
    page = run.folder / VIEW_FILE
    if not page.is_file():
        raise CpbcError(f"{page} does not exist; write it with --export first")
    try:
        width, height = (int(v) for v in size.lower().split("x"))
    except ValueError:
        raise CpbcError(f"--size must look like 1280x800, got '{size}'") from None
    with HeadlessChromium(width=width, height=height) as browser:
        browser.open(page.resolve().as_uri(), "window.cpbc && window.cpbc.ready")
        browser.evaluate(f"cpbc.selectCase({json.dumps(case)})")
        t = "cpbc.duration" if at is None else repr(float(at))
        browser.evaluate(f"cpbc.pause(); cpbc.seek({t}); true")
        browser.next_frames(3)
        browser.screenshot(png)
        if browser.log.errors:
            raise CpbcError("the page logged errors:\n" + "\n".join(browser.log.errors))


def main(argv: Sequence[str] | None = None) -> int:
    args = _parser().parse_args(argv)
    try:
        settings = ViewSettings(fps=args.fps, warn_distance=args.warn_distance)
        run = load_run(args.run)
        case = run.case(args.case).name if args.case else run.cases[0].name
        if args.export:
            print(write_view(run, settings=settings))
        elif args.screenshot:
            screenshot(run, case, args.screenshot, args.at, args.size)
            print(args.screenshot)
        else:
            serve(run, case, args.frame, settings)
    except (CpbcError, ValueError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
