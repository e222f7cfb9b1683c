"""cpbc: constrained passivity-based control of robot manipulators (Ngo 2007, Chapters 6–7)."""

__version__ = "0.1.0"
