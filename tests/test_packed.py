"""cpbc.results.packed: lossless delta-coded float arrays in an .npz that numpy.load opens."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from cpbc.results.packed import CODED, decode, encode, load_npz, write_npz

README = Path(__file__).resolve().parents[1] / "README.md"


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


def test_file_round_trip_and_what_numpy_load_sees(tmp_path: Path) -> None:
    t = np.arange(2001) * 1e-3
    arrays = {
        "time": t,
        "position": np.stack([np.sin(t), np.cos(3 * t)], axis=1).astype(np.float32),
        "names": np.array(["a", "b"]),
        "outcome": np.array("ok"),
        "count": np.arange(4),
    }
    path = tmp_path / "log.npz"
    write_npz(path, arrays)
    back = load_npz(path)
    assert list(back) == list(arrays)
    for k, v in arrays.items():
        assert back[k].dtype == v.dtype and back[k].shape == v.shape
        np.testing.assert_array_equal(back[k], v)
    with np.load(path) as z:  # floats are coded members; everything else is as it was
        assert sorted(z.files) == sorted(["time" + CODED, "position" + CODED, "names",
                                          "outcome", "count"])
        assert z["position" + CODED].dtype == np.uint8
        np.testing.assert_array_equal(z["names"], arrays["names"])


def test_plain_npz_files_read_as_numpy_reads_them(tmp_path: Path) -> None:
    path = tmp_path / "plain.npz"
    np.savez_compressed(path, velocity=np.ones((3, 2), np.float32), names=np.array(["x"]))
    back = load_npz(path)
    np.testing.assert_array_equal(back["velocity"], np.ones((3, 2), np.float32))
    assert list(back["names"]) == ["x"]


def test_smooth_logs_are_much_smaller_than_deflated_plain_arrays(tmp_path: Path) -> None:
    """A damped oscillation sampled at 1 kHz, in single precision as a run's signals are:
    the coding must beat deflating the plain arrays by a wide margin."""
    t = np.arange(20_000) * 1e-3
    signals = {f"s{k}": (np.exp(-0.1 * t) * np.sin((k + 1) * t + k)).astype(np.float32)
               for k in range(6)}
    coded, plain = tmp_path / "coded.npz", tmp_path / "plain.npz"
    write_npz(coded, signals)
    np.savez_compressed(plain, **signals)
    assert coded.stat().st_size < plain.stat().st_size / 2


def test_the_readme_recipe_decodes_without_cpbc(tmp_path: Path) -> None:
    """The README's NumPy-only lines read a coded member back, bit for bit."""
    block = re.search(r"```python\n(# without cpbc.*?)```", README.read_text(), re.S)
    assert block, "README lacks the NumPy-only recipe for trajectory.npz"
    velocity = np.random.default_rng(3).standard_normal((300, 7)).astype(np.float32)
    path = tmp_path / "trajectory.npz"
    write_npz(path, {"velocity": velocity})
    scope: dict[str, object] = {"np": np, "path": path}
    exec(block.group(1), scope)  # the README's own lines, on a file written here
    np.testing.assert_array_equal(scope["velocity"], velocity)


