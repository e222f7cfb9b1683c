"""The run's page, ``view.html``: the 3-D scene of every controller and the time plots under
one shared timeline, in one self-contained file.

The page, its script and its style are the files of the top-level ``viewer/`` folder
(``view.html``, ``view.js``, ``view.css``; shipped in the wheel, found through
cpbc.resources). Writing a run's page inlines them, meshcat's viewer script and the run's
data (cpbc.viewer.page_data) into one file, so it opens from disk in any browser with no
server and no network, and can be mailed on its own. meshcat's script (0.85 MB, the bulk of
a page) is inlined deflated, 0.29 MB in base64; view.js inflates and runs it.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import meshcat

from cpbc.errors import CpbcError
from cpbc.resources import viewer_dir
from cpbc.results.saved_run import SavedRun
from cpbc.viewer.page_data import packed, page_data
from cpbc.viewer.scene import ViewSettings

VIEW_FILE = "view.html"


def meshcat_js() -> str:
    """meshcat's bundled viewer script, as shipped with the meshcat package."""
    return (Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js").read_text()


def _packed_meshcat() -> str:
    """meshcat's script, deflated, in an element view.js runs it from; its licence line
    (the script's first) stays readable as an HTML comment."""
    text = meshcat_js()
    licence = text.partition("\n")[0].strip().removeprefix("/*!").removesuffix("*/").strip()
    deflated = packed(text.encode("utf-8"))["deflated"]
    return (f"<!-- meshcat viewer script: {html.escape(licence)} -->\n"
            f'<script id="meshcat-deflated" type="application/octet-stream">{deflated}</script>')


def _script(text: str) -> str:
    # Inside <script>, only "</script" (any case) ends the element early.
    return "<script>\n" + text.replace("</script", "<\\/script").replace(
        "</SCRIPT", "<\\/SCRIPT") + "\n</script>"


def _inline(page: str, tag: str, replacement: str) -> str:
    if tag not in page:
        raise CpbcError(f"{viewer_dir() / VIEW_FILE} lacks {tag}; reinstall cpbc")
    return page.replace(tag, replacement, 1)


def render_page(data: dict[str, object]) -> str:
    """The page with its style, scripts and ``data`` (as window.CPBC_DATA) inlined."""
    folder = viewer_dir()
    page = (folder / VIEW_FILE).read_text(encoding="utf-8")
    css = (folder / "view.css").read_text(encoding="utf-8")
    # JSON is a JavaScript expression; "</" is escaped so that no string ends the element.
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    page = _inline(page, '<link rel="stylesheet" href="view.css">', f"<style>\n{css}</style>")
    page = _inline(page, '<script src="meshcat.min.js"></script>', _packed_meshcat())
    page = _inline(page, '<script src="data.js"></script>',
                   _script(f"window.CPBC_DATA = {payload};"))
    page = _inline(page, '<script src="view.js"></script>',
                   _script((folder / "view.js").read_text(encoding="utf-8")))
    title = html.escape(f"cpbc: {data.get('title', '')}")
    return _inline(page, "<title>cpbc run</title>", f"<title>{title}</title>")


def write_view(
    run: SavedRun, folder: Path | None = None, settings: ViewSettings | None = None
) -> Path:
    """Write ``<folder>/view.html`` (the run's own folder when omitted); returns its path."""
    folder = run.folder if folder is None else Path(folder)
    path = folder / VIEW_FILE
    path.write_text(render_page(page_data(run, settings)), encoding="utf-8")
    return path
