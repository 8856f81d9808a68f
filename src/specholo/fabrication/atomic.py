"""Atomic file writing: a reader sees the old file or the whole new one, never half."""

from __future__ import annotations

import contextlib
import os
import re
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO

#: Scratch files and folders open now (see :func:`scratch`).
_SCRATCH = [0]
#: The name of a temporary file of :func:`atomic_open` (or of an animation being
#: written): its writer's pid is in it, so that a later run can tell a killed
#: run's leftover from a file being written now.
PART_FILE = re.compile(r"\..+\.(?P<pid>\d+)-[a-z0-9_]+\.part(\.[A-Za-z0-9]+)?")


def part_prefix(path: str | os.PathLike[str]) -> str:
    """The start of a temporary file's name beside ``path`` (see :data:`PART_FILE`)."""
    return f".{Path(path).name}.{os.getpid()}-"


def pid_alive(pid: int) -> bool:
    """Whether a process ``pid`` runs (so its scratch files may be in use)."""
    if pid == os.getpid():
        return True
    if os.name != "posix":
        return True  # os.kill(pid, 0) would end it there: assume it runs
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OverflowError:
        return False  # beyond any pid
    except OSError:
        return True  # e.g. another user's process
    return True


@contextlib.contextmanager
def scratch() -> Iterator[None]:
    """Mark a stretch during which scratch files exist that an error, or a Ctrl-C,
    must remove on its way out; outside such stretches nothing is half-written
    and the process may simply end (:func:`scratch_open`)."""
    _SCRATCH[0] += 1
    try:
        yield
    finally:
        _SCRATCH[0] -= 1


def scratch_open() -> bool:
    """Whether any scratch file or folder exists now (inside :func:`scratch`)."""
    return _SCRATCH[0] > 0


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def public_mode(path: str | os.PathLike[str], directory: bool = False) -> None:
    """Give a scratch file or folder the permissions a plain create would have."""
    os.chmod(path, (0o777 if directory else 0o666) & ~_umask())


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike[str], mode: str = "w",
                encoding: str | None = "utf-8") -> Iterator[IO]:
    """Open a temporary file beside ``path``; on success rename it over ``path``.

    On any exception (including KeyboardInterrupt) the temporary file is removed
    and ``path`` is left untouched.

    Args:
        path: destination file.
        mode: ``"w"`` for text or ``"wb"`` for bytes.
        encoding: text encoding (ignored for binary mode).
    """
    path = Path(path)
    with scratch():
        fd, tmp = tempfile.mkstemp(prefix=part_prefix(path), suffix=".part", dir=path.parent)
        try:
            os.fchmod(fd, 0o666 & ~_umask())  # mkstemp's 0600 is for the scratch file only
            if "b" in mode:
                fh = os.fdopen(fd, mode)
            else:
                fh = os.fdopen(fd, mode, encoding=encoding, newline="\n")
            with fh:
                yield fh
                fh.flush()
                os.fsync(fh.fileno())
            os.replace(tmp, path)
        except BaseException as exc:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(tmp)
            if isinstance(exc, OSError) and exc.filename is None:
                exc.filename = str(path)  # a full disk's error names no file: name it
            raise
