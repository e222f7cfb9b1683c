"""Where the built-in models, scenarios and the viewer page live (installed or source)."""

from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def _data_dir(name: str) -> Path:
    installed = _PACKAGE / "_data" / name  # placed there by the wheel build
    if installed.is_dir():
        return installed
    return _PACKAGE.parent / name  # source checkout / editable install


def models_dir() -> Path:
    """Folder holding the built-in model files (MJCF/URDF)."""
    return _data_dir("models")


def scenarios_dir() -> Path:
    """Folder holding the shipped YAML scenarios."""
    return _data_dir("scenarios")


def viewer_dir() -> Path:
    """Folder holding the run page's HTML, script and style (the top-level ``viewer/``)."""
    return _data_dir("viewer")


def builtin_models() -> dict[str, Path]:
    """Built-in robot names mapped to their model files."""
    return {p.stem: p for p in sorted(models_dir().glob("*.xml"))}
