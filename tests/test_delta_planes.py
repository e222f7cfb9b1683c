"""cpbc.results.delta_planes: the page's lossless coding of float arrays, and the logs of
earlier versions (trajectory.npz of coded members) read back."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from cpbc.results.delta_planes import CODED, decode, encode, load_earlier_log


def _bits(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=a.dtype.newbyteorder("<")).view(f"<u{a.itemsize}")


EDGES = np.array([np.nan, -0.0, 0.0, np.inf, -np.inf, 1e-45, -3.4e38, 1.0, -1.0], np.float32)


@pytest.mark.parametrize("a", [
    EDGES,
    EDGES.astype(np.float64),
    np.random.default_rng(1).standard_normal((500, 3, 2)).astype(np.float32),
    np.random.default_rng(2).standard_normal((7,)).astype(">f8"),  # big-endian in, little out
    np.zeros((0, 4), np.float32),
    np.array([2.5]),
], ids=["edges32", "edges64", "3d", "big-endian", "empty", "one"])
def test_decode_gives_back_every_bit(a: np.ndarray) -> None:
    planes = encode(a)
    assert planes.dtype == np.uint8 and planes.shape == (a.itemsize, *a.shape)
    back = decode(planes)
    assert back.shape == a.shape and back.dtype == a.dtype.newbyteorder("=")
    np.testing.assert_array_equal(_bits(back), _bits(a))


def test_an_earlier_versions_log_reads_back(tmp_path: Path) -> None:
    """Coded members NAME.deltas decode to NAME; plain members read as numpy.load reads them."""
    t = np.arange(2001) * 1e-3
    position = np.stack([np.sin(t), np.cos(3 * t)], axis=1).astype(np.float32)
    path = tmp_path / "trajectory.npz"
    np.savez_compressed(path, **{"time" + CODED: encode(t), "position" + CODED: encode(position),
                                 "names": np.array(["a", "b"]), "outcome": np.array("ok")})
    back = load_earlier_log(path)
    np.testing.assert_array_equal(back["time"], t)
    np.testing.assert_array_equal(back["position"], position)
    assert back["position"].dtype == np.float32
    assert list(back["names"]) == ["a", "b"] and str(back["outcome"]) == "ok"


def test_smooth_signals_deflate_much_smaller_coded() -> None:
    """A damped oscillation sampled at 1 kHz in single precision, as the page sends it: the
    coding must beat deflating the plain floats by a wide margin."""
    import zlib

    t = np.arange(20_000) * 1e-3
    signal = (np.exp(-0.1 * t) * np.sin(3 * t)).astype(np.float32)
    coded = len(zlib.compress(encode(signal).tobytes(), 6))
    assert coded < len(zlib.compress(signal.tobytes(), 6)) / 2
