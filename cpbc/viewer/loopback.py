"""The meshcat server process: meshcat's bridge with its web server on 127.0.0.1 only.

meshcat's own server binds its ZeroMQ socket to 127.0.0.1 but its web server to every
interface; this one serves the same page and websocket on 127.0.0.1 only, so a viewer is
never exposed to the network. ``python -m cpbc.viewer.loopback`` runs it in the foreground
and prints ``zmq_url=…`` and ``web_url=…``; :class:`cpbc.viewer.server.MeshcatServer`
starts and stops it.
"""

from __future__ import annotations

import contextlib
import os
from typing import Any

import tornado.ioloop
import tornado.web
from meshcat.servers.zmqserver import (
    VIEWER_HTML,
    VIEWER_ROOT,
    StaticFileHandlerNoCache,
    WebSocketHandler,
    ZMQWebSocketBridge,
)

LOOPBACK = "127.0.0.1"


class _LoopbackApplication(tornado.web.Application):
    def listen(self, port: int, address: str | None = None, **kwargs: Any) -> Any:
        return super().listen(port, address=LOOPBACK, **kwargs)


class _NoIcon(tornado.web.RequestHandler):
    """Browsers ask for /favicon.ico; answer with no content rather than a logged 404."""

    def get(self) -> None:
        self.set_status(204)


class LoopbackBridge(ZMQWebSocketBridge):
    """meshcat's ZeroMQ-to-websocket bridge with its web server bound to 127.0.0.1."""

    def __init__(self) -> None:
        super().__init__(host=LOOPBACK)

    def make_app(self) -> tornado.web.Application:
        return _LoopbackApplication(
            [
                (
                    r"/static/(.*)",
                    StaticFileHandlerNoCache,
                    {"path": VIEWER_ROOT, "default_filename": VIEWER_HTML},
                ),
                (r"/favicon.ico", _NoIcon),
                (r"/", WebSocketHandler, {"bridge": self}),
            ]
        )


def main() -> None:
    """Run the bridge until interrupted or orphaned, announcing its URLs on stdout.

    The server stops when the process that started it ends (it checks its parent every
    second), so a crashed or killed caller never leaves a server behind.
    """
    parent = os.getppid()
    bridge = LoopbackBridge()
    print(f"zmq_url={bridge.zmq_url}", flush=True)
    print(f"web_url={bridge.web_url}", flush=True)

    def stop_if_orphaned() -> None:
        if os.getppid() != parent:
            bridge.ioloop.stop()

    tornado.ioloop.PeriodicCallback(stop_if_orphaned, 1000).start()
    with contextlib.suppress(KeyboardInterrupt):
        bridge.run()


if __name__ == "__main__":
    main()
