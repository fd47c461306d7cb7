"""``.npz`` archives read with every array checked from its header before it is allocated.

``numpy.load`` of an archive is lazy: a member is decompressed when it is indexed, so a bad
CRC, an object (pickled) array or a header that claims 4·10⁹ elements would surface later as
``BadZipFile``, numpy's ``allow_pickle`` message or a 30 GB allocation. :func:`open_npz` reads
each member's ``.npy`` header first (``numpy.lib.format``) and refuses, naming the file and
the array:

* an object dtype (a pickle can run code; consistid reads numbers and names only);
* a shape whose bytes exceed what the member holds (a corrupt or forged header);
* arrays whose total size exceeds :data:`BUDGET_BYTES` (memory checked before allocating);
* a large member that inflates more than :data:`BOMB_RATIO`-fold (a zip bomb).

Indexing the returned archive turns a decompression failure (bad CRC, truncation) into
:class:`~consistid.errors.DatasetError` naming the array.
"""

from __future__ import annotations

import math
import zipfile
import zlib
from pathlib import Path
from typing import Iterator

import numpy as np

from ..errors import DatasetError

__all__ = ["BUDGET_BYTES", "NpzArchive", "open_npz"]

#: The most bytes the arrays of one ``.npz`` log may take once loaded (8 GiB: an hour of a
#: 7-joint arm at 1 kHz takes about 1 GB).
BUDGET_BYTES = 8 * 2**30
#: A member larger than :data:`BOMB_BYTES` that inflates more than :data:`BOMB_RATIO`-fold is
#: refused before it is decompressed: measured signals (float64 with noise in their low bits)
#: deflate by less than 2×; only a forged member or a huge constant array inflates 100×.
BOMB_BYTES = 64 * 2**20
BOMB_RATIO = 100


def _header(zf: zipfile.ZipFile, info: zipfile.ZipInfo) -> tuple[tuple[int, ...], np.dtype, int]:
    """Shape, dtype and header length of the ``.npy`` member ``info``."""
    fmt = np.lib.format
    with zf.open(info) as fh:
        version = fmt.read_magic(fh)
        read = {(1, 0): fmt.read_array_header_1_0, (2, 0): fmt.read_array_header_2_0}.get(
            version)
        if read is None:
            raise ValueError(f".npy format version {version} is not supported")
        shape, _fortran, dtype = read(fh, max_header_size=10_000)
        return tuple(shape), dtype, fh.tell()


def _is_npy(path: Path) -> bool:
    try:
        with open(path, "rb") as fh:
            return fh.read(6) == b"\x93NUMPY"
    except OSError:
        return False


class NpzArchive:
    """The arrays of an ``.npz`` file whose headers :func:`open_npz` checked (``files``,
    ``in``, indexing by name; a context manager like ``numpy.load``'s)."""

    def __init__(self, path: Path, archive: "np.lib.npyio.NpzFile") -> None:
        self.path = path
        self._archive = archive
        self.files = list(archive.files)

    def __contains__(self, key: str) -> bool:
        return key in self.files

    def __iter__(self) -> Iterator[str]:
        return iter(self.files)

    def __getitem__(self, key: str) -> np.ndarray:
        try:
            return self._archive[key]
        except KeyError:
            raise
        except (zipfile.BadZipFile, zlib.error, ValueError, OSError, EOFError) as exc:
            raise DatasetError(f"{self.path.name}: array {key!r} cannot be read ({exc}); the "
                               "archive is corrupt or truncated: copy or export it again") \
                from None

    def close(self) -> None:
        self._archive.close()

    def __enter__(self) -> "NpzArchive":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_npz(path: str | Path) -> NpzArchive:
    """The ``.npz`` archive at ``path`` with every array's header checked (module docstring),
    or :class:`DatasetError` naming the file (a folder, a text file, a single ``.npy`` array,
    a truncated zip, an object array, a forged or oversized header)."""
    path = Path(path)
    if path.is_dir():
        raise DatasetError(f"{str(path)!r} is a folder, not an .npz file; name a file in it")
    total = 0
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                name = info.filename[:-4]
                shape, dtype, offset = _header(zf, info)
                if dtype.hasobject:
                    raise DatasetError(f"{path.name}: array {name!r} holds Python objects "
                                       f"(dtype {dtype}), which only a pickle can restore and "
                                       "a pickle can run code; consistid reads numeric and "
                                       "text arrays only: save plain arrays")
                size = math.prod(shape) * dtype.itemsize
                if size > info.file_size - offset:
                    raise DatasetError(f"{path.name}: array {name!r} claims shape {shape} "
                                       f"({size / 2**20:.6g} MiB) but holds "
                                       f"{(info.file_size - offset) / 2**20:.6g} MiB: the "
                                       "file is corrupt or forged")
                packed = max(info.compress_size, 1)
                if size > BOMB_BYTES and size > BOMB_RATIO * packed:
                    raise DatasetError(f"{path.name}: array {name!r} inflates "
                                       f"{packed / 2**20:.3g} MiB into {size / 2**20:.6g} MiB "
                                       f"({size / packed:.0f}-fold): a zip bomb, or an array "
                                       "of one repeated value no log holds; save the arrays "
                                       "again (np.savez)")
                total += size
    except DatasetError:
        raise
    except (zipfile.BadZipFile, ValueError, OSError, EOFError, zlib.error) as exc:
        if _is_npy(path):
            raise DatasetError(f"{path.name} holds a single array, not an .npz archive of "
                               "named arrays (t, q, dq, ddq, tau)") from None
        raise DatasetError(f"{path.name} is not a readable .npz archive ({exc})") from None
    if total > BUDGET_BYTES:
        raise DatasetError(f"{path.name}: its arrays take {total / 2**30:.3g} GiB once loaded, "
                           f"more than the {BUDGET_BYTES / 2**30:.3g} GiB budget "
                           "(consistid.data.npzfile.BUDGET_BYTES); split the log, or raise "
                           "the budget if the machine has the memory")
    try:
        archive = np.load(path, allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as exc:
        raise DatasetError(f"{path.name} is not a readable .npz archive ({exc})") from None
    if not hasattr(archive, "files"):
        raise DatasetError(f"{path.name} holds a single array, not an .npz archive of named "
                           "arrays (t, q, dq, ddq, tau)")
    return NpzArchive(path, archive)
