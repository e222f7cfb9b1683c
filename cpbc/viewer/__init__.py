"""meshcat viewer of cpbc runs: self-contained run page, replay of a run folder, live view.

meshcat is imported in this package only.
"""

import warnings

with warnings.catch_warnings():
    # meshcat 0.3 imports pyzmq's deprecated zmq.eventloop.ioloop at import time.
    warnings.filterwarnings("ignore", "zmq.eventloop.ioloop is deprecated", DeprecationWarning)
    import meshcat  # noqa: F401

from cpbc.viewer.export import VIEW_FILE, write_view
from cpbc.viewer.scene import CaseScene, ViewSettings

__all__ = ["VIEW_FILE", "CaseScene", "ViewSettings", "write_view"]
