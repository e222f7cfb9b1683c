"""Where the built-in models and scenarios live, for installed and source checkouts alike."""

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


def builtin_models() -> dict[str, Path]:
    """Built-in robot names mapped to their model files."""
    return {p.stem: p for p in sorted(models_dir().glob("*.xml"))}
