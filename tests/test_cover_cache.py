"""The disk cache of link covers: what it returns is what the fit returns, and any change
of the fit's inputs fits again."""

from __future__ import annotations

import numpy as np
import pytest

from cpbc.constraints import cover_cache
from cpbc.constraints.cover_cache import cached_cover, cover_key
from cpbc.constraints.covering import cover_links
from cpbc.model.loading import load_arm


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("CPBC_CACHE_DIR", str(tmp_path))
    return tmp_path / "covers"


def _same(a, b) -> None:
    assert [(p.name, p.frame) for p in a] == [(p.name, p.frame) for p in b]
    for p, q in zip(a, b, strict=True):
        np.testing.assert_array_equal(p.start, q.start)
        np.testing.assert_array_equal(p.end, q.end)
        assert p.radius == q.radius


def test_a_cached_cover_is_the_fitted_one_and_skips_the_fit(cache, monkeypatch) -> None:
    arm = load_arm("ur5")
    fitted = cover_links(arm.model, arm.collision_model)
    first = cached_cover(arm.model, arm.collision_model)
    _same(first, fitted)
    assert len(list(cache.glob("*.npz"))) == 1

    def no_fit(*args, **kwargs):
        raise AssertionError("fitted although cached")

    monkeypatch.setattr(cover_cache, "cover_links", no_fit)
    _same(cached_cover(arm.model, arm.collision_model), fitted)


def test_every_input_of_the_fit_is_in_the_key() -> None:
    arm = load_arm("ur5")
    m, c = arm.model, arm.collision_model
    base = cover_key(m, c, None, 0.0, "spheres", 0.01)
    assert base == cover_key(m, c, None, 0.0, "spheres", 0.01)
    others = {
        cover_key(m, c, ["wrist_1_link"], 0.0, "spheres", 0.01),
        cover_key(m, c, None, 0.01, "spheres", 0.01),
        cover_key(m, c, None, 0.0, "capsules", 0.01),
        cover_key(m, c, None, 0.0, "spheres", 0.005),
        cover_key(m, load_arm("ur10").collision_model, None, 0.0, "spheres", 0.01),
    }
    assert base not in others and len(others) == 5
    moved = c.copy()
    g = moved.geometryObjects[2]
    g.placement.translation = g.placement.translation + np.array([0.0, 0.0, 1e-6])
    moved.geometryObjects[2] = g
    assert cover_key(m, moved, None, 0.0, "spheres", 0.01) != base


def test_a_damaged_cache_file_is_fitted_again(cache) -> None:
    arm = load_arm("ur5")
    fitted = cached_cover(arm.model, arm.collision_model)
    (path,) = cache.glob("*.npz")
    path.write_bytes(b"not a zip file")
    _same(cached_cover(arm.model, arm.collision_model), fitted)
    assert np.load(path)["radii"].shape == (len(fitted),)
