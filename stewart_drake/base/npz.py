"""An ``.npz`` archive a user names, read without pickle and checked before any array is made
(:class:`CheckedNpz`).

Its bytes are read through :func:`~.fileio.read_checked`; the entries' sizes after decompression
are read from the archive's directory and bounded before anything is inflated (a few kB of zeros
deflate to gigabytes); each entry's ``.npy`` header (shape, dtype) is read and checked
against the bytes the entry holds before numpy allocates what it claims; objects, complex
numbers and records are refused (:data:`ALLOWED_DTYPE_KINDS`). Whatever a damaged archive raises
inside numpy, zipfile or zlib becomes one :class:`~stewart_drake.base.errors.CorruptFileError`
naming the file and what is wrong, and the typed accessors refuse an entry missing or of
another kind the same way.
"""

from __future__ import annotations

import io
import json
import math
import zipfile
from pathlib import Path

import numpy as np
from numpy.lib import format as npy_format

from .checks import check_memory, format_bytes
from .errors import CorruptFileError, InvalidConfigError
from .fileio import _describe, read_checked

#: The kinds of array an ``.npz`` of this tool may hold (numpy's ``dtype.kind``): booleans,
#: integers, floats and unicode text. Complex numbers would lose their imaginary part where a
#: float is read, objects need pickle.
ALLOWED_DTYPE_KINDS = "biufU"


class CheckedNpz:
    """Every array of an ``.npz`` archive (``allow_pickle=False``), with typed accessors.

    Args:
        path: the file.  kind: what it should be, for messages ("ANN tuner weights file").
        remedy: what the user can do about a bad one (appended to every message).
        max_bytes: the most its entries may hold together after decompression (and the file
            on disk), bytes: a few kB of zeros deflate to megabytes, so each entry's size is
            read from the archive's directory and bounded before it is decompressed.
    Raises:
        CorruptFileError: the bytes are not an ``.npz`` archive whose every entry numpy can
            read without pickle (empty, truncated, random bytes, a bad CRC, a single ``.npy``
            array, entries larger than ``max_bytes``); an entry of objects, complex numbers or
            records (:data:`ALLOWED_DTYPE_KINDS`), or whose header claims more bytes than it
            holds (refused before numpy allocates them); not a regular file.
        InvalidConfigError: entries larger than the memory available.
        OSError: the file cannot be read.
    """

    def __init__(self, path, kind: str, remedy: str = "", max_bytes: float = 4e9):
        self.path, self.kind, self.remedy = Path(path), kind, remedy
        raw = read_checked(self.path, kind, max_bytes, remedy)
        if not raw:
            raise self.corrupt("it is empty")
        if raw[:6] == b"\x93NUMPY":
            raise self.corrupt("it holds one .npy array, not an .npz archive")
        if raw[:4] not in (b"PK\x03\x04", b"PK\x05\x06"):  # an entry, or an empty archive
            # numpy would try anything else as a pickle: refuse it here, unread.
            raise self.corrupt("not a readable .npz archive (not a zip archive)")
        try:
            self._check_entries(raw, max_bytes)
            with np.load(io.BytesIO(raw), allow_pickle=False) as data:
                self.arrays = {name: data[name] for name in data.files}
        except InvalidConfigError:  # CorruptFileError, or too large
            raise
        except Exception as err:  # noqa: BLE001 - bytes in memory: any failure
            raise self.corrupt(f"not a readable .npz archive ({_describe(err)})") from None

    def _check_entries(self, raw: bytes, max_bytes: float) -> None:
        """Refuse, before any array is made, entries that are not ``.npy`` arrays of numbers
        or text, whose decompressed sizes (the archive's directory says them; zipfile never
        inflates an entry past its stated size) exceed ``max_bytes`` or the memory, or whose
        header claims more bytes (shape times item size) than the entry holds: numpy
        allocates what the header says before it reads a byte of data."""
        with zipfile.ZipFile(io.BytesIO(raw)) as archive:
            infos = archive.infolist()
            sizes = {info.filename: info.file_size for info in infos}
            total = sum(sizes.values())
            if total > max_bytes:
                name = max(sizes, key=sizes.__getitem__)
                raise self.corrupt(
                    f"its entries hold {format_bytes(total)} after decompression "
                    f"({name!r}: {format_bytes(sizes[name])}), over the bound of "
                    f"{format_bytes(max_bytes)} for this kind of file"
                )
            for info in infos:
                self._check_header(archive, info)
        check_memory(f"reading {self.path}", total, "free some memory")

    def _check_header(self, archive: zipfile.ZipFile, info: zipfile.ZipInfo) -> None:
        """Read the ``.npy`` header of one entry (a few hundred bytes) and check it."""
        name = info.filename.removesuffix(".npy")
        if not info.filename.endswith(".npy"):
            raise self.corrupt(f"the entry {info.filename!r} is not an .npy array")
        with archive.open(info) as f:
            version = npy_format.read_magic(f)
            if version == (1, 0):
                shape, _, dtype = npy_format.read_array_header_1_0(f)
            else:  # 2.0 and 3.0 differ from 1.0 only in the header's length field
                shape, _, dtype = npy_format.read_array_header_2_0(f)
            header_bytes = f.tell()
        if dtype.hasobject or dtype.kind not in ALLOWED_DTYPE_KINDS:
            raise self.corrupt(
                f"the entry {name!r} holds {dtype} values: this file holds numbers and text "
                f"only (no objects, no complex numbers)"
            )
        claimed = math.prod(int(n) for n in shape) * dtype.itemsize
        if claimed > info.file_size - header_bytes:
            raise self.corrupt(
                f"the entry {name!r} claims shape {tuple(shape)} of {dtype} "
                f"({format_bytes(claimed)}) but holds {format_bytes(info.file_size)}"
            )

    def corrupt(self, problem: str) -> CorruptFileError:
        """The error to raise for this file."""
        return CorruptFileError(self.path, self.kind, problem, self.remedy)

    def __contains__(self, name: str) -> bool:
        return name in self.arrays

    def _entry(self, name: str) -> np.ndarray:
        if name not in self.arrays:
            raise self.corrupt(f"the entry {name!r} is missing")
        return self.arrays[name]

    def array(self, name: str) -> np.ndarray:
        """Entry ``name`` as a float64 array (numbers only; shape and finiteness are the
        caller's to check)."""
        a = self._entry(name)
        if a.dtype.kind not in "biuf":
            raise self.corrupt(f"the entry {name!r} holds {a.dtype} values, not numbers")
        return a.astype(np.float64)

    def integers(self, name: str) -> np.ndarray:
        """Entry ``name`` as an int64 array (integers only: a float entry is refused)."""
        a = self._entry(name)
        if a.dtype.kind not in "biu":
            raise self.corrupt(f"the entry {name!r} holds {a.dtype} values, not integers")
        return a.astype(np.int64)

    def texts(self, name: str) -> tuple[str, ...]:
        """Entry ``name`` as a tuple of strings (a 1-d unicode array)."""
        a = self._entry(name)
        if a.dtype.kind != "U" or a.ndim != 1:
            raise self.corrupt(
                f"the entry {name!r} must be a list of strings, has {a.dtype} shape {a.shape}"
            )
        return tuple(str(v) for v in a)

    def number(self, name: str) -> float:
        """Entry ``name`` as one float (a 0-d or 1-element numeric array)."""
        a = self.array(name)
        if a.size != 1:
            raise self.corrupt(f"the entry {name!r} must be one number, has shape {a.shape}")
        return float(a.reshape(()))

    def integer(self, name: str) -> int:
        """Entry ``name`` as one integer."""
        v = self.number(name)
        if not (np.isfinite(v) and v == int(v)):
            raise self.corrupt(f"the entry {name!r} must be an integer, got {v!r}")
        return int(v)

    def text(self, name: str) -> str:
        """Entry ``name`` as one string (a 0-d unicode array)."""
        a = self._entry(name)
        if a.dtype.kind != "U" or a.size != 1:
            raise self.corrupt(
                f"the entry {name!r} must be one string, has {a.dtype} shape {a.shape}"
            )
        return str(a.reshape(()))

    def json(self, name: str, kind: type = dict):
        """Entry ``name`` (a string) parsed as JSON, which must be a ``kind``."""
        text = self.text(name)
        try:
            value = json.loads(text)
        except (ValueError, RecursionError) as err:
            raise self.corrupt(f"the entry {name!r} is not JSON ({_describe(err)})") from None
        if not isinstance(value, kind):
            raise self.corrupt(
                f"the entry {name!r} must be a JSON {kind.__name__}, got {type(value).__name__}"
            )
        return value
