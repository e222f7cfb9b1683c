"""A stand-in for meshcat's server connection that records commands for a static page."""

from __future__ import annotations

from typing import Any, Protocol

import meshcat
import umsgpack  # type: ignore[import-untyped]  # u-msgpack-python ships no stubs


class _Command(Protocol):
    """A meshcat command (``meshcat.commands.SetObject`` and the like)."""

    def lower(self) -> dict[str, Any]: ...


class CommandRecorder:
    """Keeps every command a :class:`meshcat.Visualizer` sends, msgpack-encoded.

    The bytes are what meshcat's server would forward to a browser, so replaying them with
    ``viewer.handle_command_bytearray`` in a page rebuilds the same scene. Floats are packed
    in single precision (plenty for drawing; it halves the size of an animation).
    """

    def __init__(self) -> None:
        self.commands: list[bytes] = []

    def send(self, command: _Command) -> None:
        """Called by the Visualizer in place of its server window."""
        lowered = command.lower()
        self.commands.append(umsgpack.packb(lowered, force_float_precision="single"))

    def visualizer(self) -> meshcat.Visualizer:
        """A Visualizer whose commands land here instead of on a server."""
        return meshcat.Visualizer(window=self)
