"""Safe readers for files read back: design folders, configs, compositions.

A folder written by one run is read by the next (``verify``, ``render``,
``report``...), and anything in it may have been edited, truncated, or swapped
for a FIFO or a link to a device. Every reader here:

- reads regular files only: it stats the path first (a FIFO or a device is
  refused before it is opened), opens it non-blocking (a FIFO swapped in after
  the stat opens at once instead of waiting for a writer) and checks the open
  file again with fstat;
- knows how large the file may be before it reads any of it, and refuses a file
  beyond that or beyond the memory available;
- refuses everything else it cannot use with a :class:`SpecholoError` of one line
  naming the file.

:func:`load_arrays` reads an ``.npz`` one named array at a time: the shape and
dtype each ``.npy`` member declares in its header are checked against what the
caller expects before any array is loaded, the members' sizes are capped, object
arrays (pickles) are never loaded, and floats are checked finite where asked.
The arrays' own consistency (offsets within range and so on) is the caller's.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import stat
import struct
import tokenize
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import IO, Any

import numpy as np

from specholo._memory import available_memory, format_bytes
from specholo.errors import SpecholoError

#: Largest JSON file read, bytes. hologram.json lists every stipple (~130 bytes
#: each: 130 MB at 10^6 stipples, the largest design that fits in 8 GB), and
#: json.loads holds 4-5 times the text in Python objects, so a larger file
#: is none this program wrote and would exhaust the memory before it was read.
MAX_JSON_BYTES = 512 << 20
#: Largest TOML file read (a config or a composition), bytes: these are a page or
#: two of settings written by hand.
MAX_TOML_BYTES = 1 << 20
#: Largest picture read whole (a report embeds the folder's PNGs), bytes.
MAX_PICTURE_BYTES = 256 << 20
#: Most bytes of arrays one .npz may declare (uncompressed): ten times the grooves
#: of a 10^6-stipple design (5.7 GB). The memory available is the tighter bound
#: on most machines; this one holds where it cannot be found out.
MAX_ARRAY_BYTES = 64 << 30


def _kind(mode: int) -> str:
    """What a file that is not a regular file is, for a message."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a special file"


def one_line(exc: BaseException) -> str:
    """An exception's message as one short line."""
    text = " ".join(str(getattr(exc, "strerror", None) or exc).split())
    text = text or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _name(what: str, path: str | os.PathLike[str]) -> str:
    return f"{what} {os.fspath(path)}" if what else os.fspath(path)


def check_fits(path: str | os.PathLike[str], what: str, need: int) -> None:
    """Refuse reading that would need more memory than is available."""
    room = available_memory()
    if room is not None and need > room:
        raise SpecholoError(f"{_name(what, path)}: reading it would need ~{format_bytes(need)} "
                            f"of memory; this machine has {format_bytes(room)} available")


def open_regular(path: str | os.PathLike[str], what: str = "",
                 max_bytes: int | None = None) -> tuple[int, int]:
    """Open a regular file for reading: (descriptor, size in bytes).

    Raises:
        SpecholoError: missing, a folder, FIFO, device or socket, unreadable, or
            larger than ``max_bytes``.
    """
    name = _name(what, path)
    try:
        info = os.stat(path)
    except (OSError, ValueError) as exc:  # ValueError: a NUL byte in the path
        raise SpecholoError(f"cannot read {name}: {one_line(exc)}") from exc
    if not stat.S_ISREG(info.st_mode):
        # Reading a FIFO waits for a writer, and a device (/dev/zero) never ends.
        raise SpecholoError(f"{name} is {_kind(info.st_mode)}, not a regular file")
    try:
        # O_NONBLOCK: a FIFO put in the file's place since the stat opens at
        # once (and is refused below) instead of waiting for a writer; for a
        # regular file it changes nothing.
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except (OSError, ValueError) as exc:
        raise SpecholoError(f"cannot read {name}: {one_line(exc)}") from exc
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise SpecholoError(f"{name} is {_kind(info.st_mode)}, not a regular file")
        if max_bytes is not None and info.st_size > max_bytes:
            raise SpecholoError(f"{name} is {format_bytes(info.st_size)}, more than the "
                                f"{format_bytes(max_bytes)} such a file can be")
    except BaseException:
        os.close(fd)
        raise
    return fd, int(info.st_size)


@contextlib.contextmanager
def open_file(path: str | os.PathLike[str], what: str = "",
              max_bytes: int | None = None) -> Iterator[IO[bytes]]:
    """A regular file opened for binary reading (see :func:`open_regular`)."""
    fd, _ = open_regular(path, what, max_bytes)
    with os.fdopen(fd, "rb") as fh:
        yield fh


def read_bytes(path: str | os.PathLike[str], max_bytes: int, what: str = "") -> bytes:
    """A regular file's bytes, at most ``max_bytes`` of them (else refused)."""
    fd, size = open_regular(path, what, max_bytes)
    with os.fdopen(fd, "rb") as fh:
        check_fits(path, what, size)
        try:
            # One byte more than the fstat found, to see a file that grew since
            # (asking for max_bytes would reserve that much memory up front).
            data = fh.read(size + 1)
        except MemoryError as exc:
            raise SpecholoError(f"{_name(what, path)}: out of memory reading it") from exc
        except OSError as exc:
            raise SpecholoError(f"cannot read {_name(what, path)}: {one_line(exc)}") from exc
    if len(data) > size:
        raise SpecholoError(f"{_name(what, path)} grew while it was read")
    return data


def read_text(path: str | os.PathLike[str], max_bytes: int, what: str = "") -> str:
    """A regular file's UTF-8 text (see :func:`read_bytes`)."""
    data = read_bytes(path, max_bytes, what)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecholoError(f"{_name(what, path)} is not UTF-8 text: {one_line(exc)}") from exc


def read_json(path: str | os.PathLike[str], max_bytes: int | None = None,
              what: str = "") -> Any:
    """A regular file's JSON, at most ``max_bytes`` (default :data:`MAX_JSON_BYTES`)
    of it (see :func:`read_bytes`); its structure is the caller's."""
    data = read_bytes(path, MAX_JSON_BYTES if max_bytes is None else max_bytes, what)
    try:
        return json.loads(data)
    except MemoryError as exc:
        raise SpecholoError(f"{_name(what, path)}: out of memory parsing it") from exc
    except RecursionError as exc:
        raise SpecholoError(f"{_name(what, path)} is not valid JSON: nested too deeply") from exc
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, huge integers
        raise SpecholoError(f"{_name(what, path)} is not valid JSON: {one_line(exc)}") from exc


def table(value: Any, where: str) -> dict[str, Any]:
    """``value`` if it is a JSON object, else a SpecholoError naming ``where``."""
    if not isinstance(value, dict):
        raise SpecholoError(f"{where} must be a table, got {type(value).__name__}")
    return value


def number(value: Any, where: str) -> float:
    """``value`` as a finite float if it is a JSON number, else a SpecholoError."""
    try:
        if isinstance(value, int | float) and not isinstance(value, bool) \
                and math.isfinite(float(value)):
            return float(value)
    except OverflowError:  # an integer beyond any float
        pass
    raise SpecholoError(f"{where} must be a finite number, got {str(value)[:40]!r}")


def whole(value: Any, where: str) -> int:
    """``value`` if it is a JSON integer, else a SpecholoError naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise SpecholoError(f"{where} must be a whole number, got {str(value)[:40]!r}")
    return value


@contextlib.contextmanager
def settings_from(path: str | os.PathLike[str]) -> Iterator[None]:
    """Settings being read from a file: a refusal names the file, and a missing
    key or a value of the wrong type (which the settings' own checks meet as a
    KeyError, TypeError or ValueError) becomes a refusal too."""
    name = os.fspath(path)
    try:
        yield
    except SpecholoError as exc:
        raise SpecholoError(f"{name}: {exc}") from exc
    except KeyError as exc:
        raise SpecholoError(f"{name} lacks {exc.args[0] if exc.args else 'a key'!r}") from exc
    except (TypeError, ValueError, ArithmeticError, IndexError) as exc:
        raise SpecholoError(f"{name}: bad setting: {one_line(exc)}") from exc


# ---------------------------------------------------------------- arrays


@dataclass(frozen=True)
class ArraySpec:
    """What one array of an ``.npz`` must be.

    Attributes:
        shape: its length along each axis, None where any length will do.
        dtype: what it is converted to (no copy when it is that already): a
            float dtype accepts any float array, an integer dtype any integer
            array (values beyond it are refused), bool only bools.
        finite: refuse NaN and infinities (floats).
        optional: the array may be missing.
    """

    shape: tuple[int | None, ...]
    dtype: Any = np.float64
    finite: bool = False
    optional: bool = False


#: Elements checked at a time (finite values, integer ranges): a pass over a
#: large array then needs a few MB beside it instead of a copy of it.
CHUNK = 1 << 20


def all_finite(a: np.ndarray) -> bool:
    """Whether every value of a float array is finite, a chunk at a time."""
    flat = a.reshape(-1)
    return all(bool(np.isfinite(flat[i:i + CHUNK]).all()) for i in range(0, flat.size, CHUNK))


def bounded(a: np.ndarray, limit: float) -> bool:
    """Whether every value of a float array is finite and at most ``limit`` in
    magnitude, a chunk at a time (NaN fails the comparison, as it should)."""
    flat = a.reshape(-1)
    return all(bool(np.abs(flat[i:i + CHUNK]).max() <= limit)
               for i in range(0, flat.size, CHUNK))


def within(a: np.ndarray, lo: float, hi: float) -> bool:
    """Whether every value of an array lies in [lo, hi], a chunk at a time."""
    flat = a.reshape(-1)
    for i in range(0, flat.size, CHUNK):
        part = flat[i:i + CHUNK]
        if part.size and (part.min() < lo or part.max() > hi):
            return False
    return True


def check_offsets(offsets: np.ndarray, end: int, where: str) -> None:
    """Refuse path offsets (paths + 1,) into ``end`` items unless they run from 0 to
    ``end`` and never decrease: compiled loops index items offsets[j] up to
    offsets[j + 1] unchecked. A chunk at a time."""
    if offsets.ndim != 1 or len(offsets) == 0 or offsets.dtype.kind not in "iu":
        raise SpecholoError(f"{where}: offsets must be integers, one more than the paths")
    if int(offsets[0]) != 0 or int(offsets[-1]) != end:
        raise SpecholoError(f"{where}: offsets must run from 0 to the {end} items they index, "
                            f"got {int(offsets[0])} to {int(offsets[-1])}")
    for i in range(0, len(offsets) - 1, CHUNK):
        part = offsets[i:i + CHUNK + 1]
        down = np.flatnonzero(part[1:] < part[:-1])
        if len(down):
            raise SpecholoError(f"{where}: offsets decrease after path {i + int(down[0])}: "
                                "paths must follow each other")


def _header(fh: IO[bytes]) -> tuple[tuple[int, ...], bool, np.dtype[Any]]:
    """Shape, Fortran order and dtype from an .npy member's header."""
    fmt = np.lib.format
    version = fmt.read_magic(fh)
    # Version 3 only adds UTF-8 field names (structured dtypes, never used here).
    if version not in ((1, 0), (2, 0)):
        raise ValueError(f".npy format version {version[0]}.{version[1]} is not read here")
    read = fmt.read_array_header_1_0 if version == (1, 0) else fmt.read_array_header_2_0
    try:
        return read(fh)
    except (SyntaxError, tokenize.TokenError, RecursionError, TypeError, KeyError) as exc:
        # numpy parses the header's dict literal with Python's tokenizer, which
        # reports a malformed one in its own ways.
        raise ValueError(f"malformed .npy header: {one_line(exc)}") from exc


def _accepts(want: np.dtype[Any], got: np.dtype[Any]) -> bool:
    if want.kind == "f":
        return got.kind == "f"
    if want.kind in "iu":
        return got.kind in "iu"
    return got.kind == want.kind


def load_arrays(path: str | os.PathLike[str], spec: dict[str, ArraySpec],
                max_bytes: int | None = None) -> dict[str, np.ndarray]:
    """Read the named arrays of an ``.npz`` as ``spec`` says they must be.

    Every header is checked (shape, dtype, and that the member holds exactly the
    bytes it declares) and the sizes added up against ``max_bytes`` (default
    :data:`MAX_ARRAY_BYTES`; the file itself too) and the memory available
    before any array is loaded. Members not in ``spec`` are not read.

    Returns:
        The arrays by name (optional ones only where present), C-contiguous, of
        the spec's dtypes.

    Raises:
        SpecholoError: anything unlike the spec, or an unreadable file.
    """
    if max_bytes is None:
        max_bytes = MAX_ARRAY_BYTES
    name = os.fspath(path)
    fd, _ = open_regular(path, "", max_bytes)
    with os.fdopen(fd, "rb") as fh:
        try:
            with zipfile.ZipFile(fh) as zf:
                found = {}
                for key, want in spec.items():
                    try:
                        member = zf.getinfo(f"{key}.npy")
                    except KeyError:
                        if want.optional:
                            continue
                        raise SpecholoError(f"{name} holds no array {key!r}") from None
                    found[key] = member
                total = sum(m.file_size for m in found.values())
                if total > max_bytes:
                    raise SpecholoError(f"{name} declares {format_bytes(total)} of arrays, "
                                        f"more than the {format_bytes(max_bytes)} it can hold")
                check_fits(path, "", total)
                for key, member in found.items():
                    _check_member(zf, member, key, spec[key], name)
                out = {}
                for key, member in found.items():
                    # The header was checked to declare exactly the member's bytes, so
                    # read_array reads it to its end, where zipfile checks its CRC.
                    with zf.open(member) as part:
                        arr = np.lib.format.read_array(part, allow_pickle=False)
                    out[key] = _convert(arr, spec[key], key, name)
                return out
        except SpecholoError:
            raise
        except MemoryError as exc:
            raise SpecholoError(f"{name}: out of memory reading it") from exc
        except (zipfile.BadZipFile, zlib.error, struct.error, EOFError, OSError, ValueError,
                NotImplementedError, RuntimeError, OverflowError) as exc:
            # BadZipFile: not a zip, truncated, a CRC that does not match;
            # struct.error: a zip record cut short; NotImplementedError: a
            # compression method zipfile lacks; RuntimeError: an encrypted member.
            raise SpecholoError(f"{name} is not a readable .npz file: {one_line(exc)}") from exc


def _check_member(zf: zipfile.ZipFile, member: zipfile.ZipInfo, key: str, want: ArraySpec,
                  name: str) -> None:
    """Check one member's header against its spec, without reading its data."""
    with zf.open(member) as part:
        shape, _, dtype = _header(part)
        header = part.tell()
    if dtype.hasobject or dtype.fields is not None or dtype.subdtype is not None:
        raise SpecholoError(f"{name}: array {key!r} is of dtype {dtype}, not plain numbers")
    target = np.dtype(want.dtype)
    if not _accepts(target, dtype):
        raise SpecholoError(f"{name}: array {key!r} is of dtype {dtype}, expected {target}")
    if len(shape) != len(want.shape) or any(
            w is not None and w != s for w, s in zip(want.shape, shape, strict=True)):
        expected = "(" + ", ".join("n" if w is None else str(w) for w in want.shape) + \
            ("," if len(want.shape) == 1 else "") + ")"
        raise SpecholoError(f"{name}: array {key!r} has shape {shape}, expected {expected}")
    nbytes = math.prod(shape) * dtype.itemsize
    if header + nbytes != member.file_size:
        raise SpecholoError(f"{name}: array {key!r} declares {nbytes} bytes of data but holds "
                            f"{member.file_size - header}")


def _convert(arr: np.ndarray, want: ArraySpec, key: str, name: str) -> np.ndarray:
    target = np.dtype(want.dtype)
    if target.kind in "iu" and arr.dtype != target and arr.size:
        info = np.iinfo(target)
        if not within(arr, info.min, info.max):
            raise SpecholoError(f"{name}: array {key!r} holds values beyond {target}")
    if arr.dtype != target or not arr.flags.c_contiguous:  # never for the files written
        arr = arr.astype(target, order="C")
    if want.finite and target.kind == "f" and not all_finite(arr):
        raise SpecholoError(f"{name}: array {key!r} holds NaN or infinite values")
    return arr


# ---------------------------------------------------------------- meshes


