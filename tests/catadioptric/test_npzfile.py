"""NpzWriter: .npz files with members filled in place, read back by numpy and zipfile."""

import zipfile

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from catadioptric import npzfile
from catadioptric.npzfile import NpzWriter

DTYPES = [np.float64, np.float32, np.int32, np.int64, np.uint8, bool]


def test_mapped_and_added_members_read_back_exactly(tmp_path):
    rng = np.random.default_rng(0)
    maps = rng.normal(size=(7, 5, 3))
    maps[2, 3] = np.nan
    ids = rng.integers(-1, 4, size=(7, 5)).astype(np.int32)
    mask = ids >= 0
    path = tmp_path / "x.npz"
    with NpzWriter(path, mapped={"maps": ((7, 5, 3), np.float64), "dist": ((7, 5), np.float32)}) as npz:
        assert isinstance(npz.arrays["maps"], np.memmap)
        npz.arrays["maps"][...] = maps
        npz.arrays["dist"][...] = 2.5
        npz.add("ids", ids)
        npz.add("mask", mask)
        npz.close(order=["ids", "mask", "dist", "maps"])
    with zipfile.ZipFile(path) as zf:
        assert zf.testzip() is None  # every CRC checks out
        info = {i.filename: i for i in zf.infolist()}
        assert [i.filename for i in zf.infolist()] == ["ids.npy", "mask.npy", "dist.npy", "maps.npy"]
        assert info["maps.npy"].compress_type == zipfile.ZIP_STORED
        assert info["ids.npy"].compress_type == zipfile.ZIP_DEFLATED
    got = np.load(path)
    assert got.files == ["ids", "mask", "dist", "maps"]
    np.testing.assert_array_equal(got["maps"], maps)  # NaN compares equal here
    assert got["dist"].dtype == np.float32 and (got["dist"] == 2.5).all()
    assert got["ids"].dtype == np.int32 and (got["ids"] == ids).all()
    assert got["mask"].dtype == bool and (got["mask"] == mask).all()


def test_mapped_data_is_64_byte_aligned(tmp_path):
    with NpzWriter(tmp_path / "x.npz", mapped={"a": ((3,), np.uint8), "bb": ((5, 2), np.float64),
                                               "c": ((4,), np.int32)}) as npz:
        for arr in npz.arrays.values():
            assert arr.offset % 64 == 0
            assert arr.ctypes.data % arr.dtype.alignment == 0


def test_same_arrays_same_bytes(tmp_path):
    def write(path):
        with NpzWriter(path, mapped={"m": ((4, 4), np.float64)}) as npz:
            npz.arrays["m"][...] = np.arange(16.0).reshape(4, 4)
            npz.add("i", np.arange(10))
    write(tmp_path / "a.npz")
    write(tmp_path / "b.npz")
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.sampled_from(DTYPES), st.lists(st.integers(0, 6), min_size=0, max_size=3),
                          st.booleans()), min_size=1, max_size=4),
       st.integers(0, 2**32 - 1))
def test_any_members_round_trip(tmp_path_factory, members, seed):
    rng = np.random.default_rng(seed)
    path = tmp_path_factory.mktemp("npz") / "x.npz"
    arrays = {f"m{i}": (rng.normal(size=shape) * 100).astype(dtype) for i, (dtype, shape, _) in enumerate(members)}
    mapped = {name: (a.shape, a.dtype) for (name, a), (_, _, m) in zip(arrays.items(), members) if m}
    with NpzWriter(path, mapped=mapped) as npz:
        for name, a in arrays.items():
            if name in mapped:
                npz.arrays[name][...] = a
            else:
                npz.add(name, a)
    with zipfile.ZipFile(path) as zf:
        assert zf.testzip() is None
    got = np.load(path)
    assert sorted(got.files) == sorted(arrays)
    for name, a in arrays.items():
        assert got[name].dtype == a.dtype and got[name].shape == a.shape
        np.testing.assert_array_equal(got[name], a)


def test_too_large_is_refused_before_anything_is_mapped(tmp_path, monkeypatch):
    monkeypatch.setattr(npzfile, "MAX_BYTES", 1000)
    with pytest.raises(ValueError, match="exceed"):
        NpzWriter(tmp_path / "x.npz", mapped={"a": ((200,), np.float64)})
    with NpzWriter(tmp_path / "y.npz") as npz, pytest.raises(ValueError, match="exceed"):
        npz.add("a", np.zeros(200))


def test_an_error_inside_the_block_leaves_no_valid_archive(tmp_path):
    path = tmp_path / "x.npz"
    with pytest.raises(RuntimeError):
        with NpzWriter(path, mapped={"a": ((4,), np.float64)}) as npz:
            npz.arrays["a"][...] = 1.0
            raise RuntimeError("boom")
    assert not zipfile.is_zipfile(path)  # no central directory: the caller deletes it
