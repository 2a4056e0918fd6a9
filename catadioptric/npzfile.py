"""`NpzWriter`: an .npz whose largest members can be memory-mapped while they are computed.

`np.savez` copies each finished array into the file. For `simulate`'s float64 ray maps (92 MB at
1600×1200) that copy, and the fresh page-cache memory it lands in, cost about as much as the render
itself. An `NpzWriter` lays the file out first: each *mapped* member is stored uncompressed, its
.npy header written and its data 64-byte aligned, and is handed out as an `np.memmap` for the
renderer (or anything else) to fill in place. Members `add`ed later are written after them
(floating-point stored, integers and masks deflated, as `simulate` always did). `close` fills in the
CRCs and writes the central directory. The result is an ordinary zip archive of .npy files: `np.load`
reads it, `zipfile` verifies its CRCs. Dates are fixed (1980-01-01), so the same arrays give the
same bytes.
"""

from __future__ import annotations

import io
import struct
import zlib
from pathlib import Path

import numpy as np

__all__ = ["NpzWriter", "MAX_BYTES"]

MAX_BYTES = 0xFFFFFFFF - (1 << 20)
"""Largest archive written (just under 4 GiB, so no Zip64 records are needed)."""

DEFLATE_LEVEL = 3
"""zlib level of deflated members: ids and masks are mostly runs; level 3 deflates a 1600×1200
`object_id` in 9 ms (35 kB), the default level 6 in 22 ms (8 kB)."""

_LOCAL = struct.Struct("<4s2B4HL2L2H")  # local file header
_CENTRAL = struct.Struct("<4s4B4HL2L5H2L")  # central directory entry
_END = struct.Struct("<4s4H2LH")  # end of central directory
_VERSION = 20  # zip 2.0: deflate
_UNIX = 3
_DOS_DATE = (0 << 9) | (1 << 5) | 1  # 1980-01-01
_DOS_TIME = 0
_STORED, _DEFLATED = 0, 8
_ALIGN = 64
_PAD_ID = 0xD935  # the padding extra field of Android's zipalign: readers skip it
_CRC_AT = 14  # offset of the CRC in a local header


def _npy_header(shape, dtype: np.dtype) -> bytes:
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": np.lib.format.dtype_to_descr(dtype), "fortran_order": False, "shape": tuple(shape)})
    return buf.getvalue()


class NpzWriter:
    """Write an .npz at `path`; `mapped` = {name: (shape, dtype)} members to fill in place.

    `arrays[name]` are the mapped members' `np.memmap`s; `add(name, array)` appends a member;
    `close(order)` finishes the archive (a `with` block closes it if the body did not, and on an
    error just closes the file: the caller removes it).
    """

    def __init__(self, path, mapped: dict | None = None):
        self.path = Path(path)
        self._members: list[dict] = []
        self._file = open(self.path, "w+b")
        self.arrays: dict[str, np.memmap] = {}
        self.closed = False
        try:
            self._map(mapped or {})
        except BaseException:
            self._file.close()
            raise

    def _map(self, mapped: dict) -> None:
        offset = 0
        layout = []
        for name, (shape, dtype) in mapped.items():
            dtype = np.dtype(dtype)
            fname = f"{name}.npy".encode()
            npy = _npy_header(shape, dtype)
            nbytes = int(np.prod(shape, dtype=np.int64)) * dtype.itemsize
            pad = (-(offset + _LOCAL.size + len(fname) + 4 + len(npy))) % _ALIGN
            extra = struct.pack("<HH", _PAD_ID, pad) + bytes(pad)
            data_at = offset + _LOCAL.size + len(fname) + len(extra) + len(npy)
            layout.append((name, shape, dtype, fname, extra, npy, nbytes, offset, data_at))
            offset = data_at + nbytes
        if offset > MAX_BYTES:
            raise ValueError(f"{self.path}: mapped members of {offset} bytes exceed the {MAX_BYTES}-byte limit")
        self._file.truncate(offset)
        for name, shape, dtype, fname, extra, npy, nbytes, at, data_at in layout:
            size = len(npy) + nbytes
            self._file.seek(at)
            self._file.write(_LOCAL.pack(b"PK\003\004", _VERSION, 0, 0, _STORED, _DOS_TIME, _DOS_DATE, 0, size, size,
                                         len(fname), len(extra)) + fname + extra + npy)
            self._members.append(dict(name=name, fname=fname, at=at, method=_STORED, crc=None, csize=size,
                                      usize=size, npy=npy))
        self._file.flush()
        for name, shape, dtype, *_, data_at in layout:
            self.arrays[name] = np.memmap(self._file, dtype=dtype, mode="r+", offset=data_at, shape=tuple(shape))
        self._end = offset

    def add(self, name: str, array) -> None:
        """Append `name`.npy: floating-point arrays stored, everything else deflated."""
        arr = np.asarray(array)
        if not arr.flags.c_contiguous:
            arr = arr.copy(order="C")  # (np.ascontiguousarray would also turn 0-d into 1-d)
        if arr.dtype.hasobject:
            raise ValueError(f"{name}: object arrays cannot be written")
        fname = f"{name}.npy".encode()
        npy = _npy_header(arr.shape, arr.dtype)
        data = memoryview(arr.reshape(-1)).cast("B")
        crc = zlib.crc32(data, zlib.crc32(npy))
        if np.issubdtype(arr.dtype, np.floating):
            method, parts = _STORED, [npy, data]
        else:
            z = zlib.compressobj(DEFLATE_LEVEL, zlib.DEFLATED, -15)
            method, parts = _DEFLATED, [z.compress(npy) + z.compress(data) + z.flush()]
        csize, usize = sum(len(p) for p in parts), len(npy) + len(data)
        if self._end + _LOCAL.size + len(fname) + csize > MAX_BYTES:
            raise ValueError(f"{self.path}: adding {name} would exceed the {MAX_BYTES}-byte limit")
        self._file.seek(self._end)
        self._file.write(_LOCAL.pack(b"PK\003\004", _VERSION, 0, 0, method, _DOS_TIME, _DOS_DATE, crc, csize, usize,
                                     len(fname), 0) + fname)
        for p in parts:
            self._file.write(p)
        self._members.append(dict(name=name, fname=fname, at=self._end, method=method, crc=crc, csize=csize,
                                  usize=usize, npy=npy))
        self._end = self._file.tell()

    def close(self, order=None) -> None:
        """CRCs of the mapped members, then the central directory (members in `order` if given)."""
        for m in self._members:
            if m["crc"] is None:
                arr = self.arrays[m["name"]]  # read back through the same pages: no msync needed
                m["crc"] = zlib.crc32(memoryview(np.asarray(arr).reshape(-1)).cast("B"), zlib.crc32(m["npy"]))
                self._file.seek(m["at"] + _CRC_AT)
                self._file.write(struct.pack("<L", m["crc"]))
        rank = {name: i for i, name in enumerate(order or [])}
        members = sorted(self._members, key=lambda m: rank.get(m["name"], len(rank)))
        directory = b"".join(
            _CENTRAL.pack(b"PK\001\002", _VERSION, _UNIX, _VERSION, 0, 0, m["method"], _DOS_TIME, _DOS_DATE, m["crc"],
                          m["csize"], m["usize"], len(m["fname"]), 0, 0, 0, 0, 0o644 << 16, m["at"]) + m["fname"]
            for m in members)
        self._file.seek(self._end)
        self._file.write(directory)
        self._file.write(_END.pack(b"PK\005\006", 0, 0, len(members), len(members), len(directory), self._end, 0))
        self._file.truncate()
        self._file.close()
        self.closed = True

    def __enter__(self) -> "NpzWriter":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc_type is None:
            if not self.closed:
                self.close()
        else:
            self._file.close()
        return False
