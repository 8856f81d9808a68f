"""A design folder being written: published whole, and only with every program checked.

Every job writes its design through :func:`stage_design`, the one path from a
design to a folder. It stages the folder (:func:`specholo.folders.publish`:
every older specholo file goes, the user's files stay), and before the folder
is published it looks at every machine program the job wrote: each must have
been read back by its safety check through :meth:`Stage.check`. A job that
writes a program and forgets its check publishes nothing, so no kind of
hologram can keep a program no check has read. It also writes the one file
every kind shares, ``run.json`` (:func:`run_record`): when and how the design
was made, with which software; a job may write a fuller one itself.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from specholo.errors import SpecholoError

#: The suffixes of machine programs: each such file in a stage must be checked.
PROGRAM_SUFFIXES = frozenset({".gcode", ".ngc", ".nc", ".tap"})


@dataclass
class Stage:
    """The folder a job writes into before it is published.

    Attributes:
        path: the staged folder.
        checked: program name -> what its check found (its report or figures).
    """

    path: Path
    checked: dict[str, Any] = field(default_factory=dict)

    def check(self, name: str, limits: Any = None,
              check: Callable[[Path], Any] | None = None) -> Any:
        """Read the program ``name`` back through its safety check.

        Args:
            name: the program's file name in the stage.
            limits: :class:`~specholo.fabrication.check.Limits` to check a flat
                program against (None: the limits in its own header).
            check: a check of the job's own instead (a curved host's), given the
                program's path; it raises :class:`SpecholoError` on a violation.

        Returns:
            The check's report (or the job's check's figures).

        Raises:
            SpecholoError: the program breaks a limit, or names no limits.
        """
        from specholo.fabrication.check import check_program, limits_from_header

        path = self.path / name
        if check is not None:
            found = check(path)
        else:
            if limits is None:
                limits = limits_from_header(path)
                if limits is None:
                    raise SpecholoError(f"{name} names no limits to check it against: "
                                        "nothing written")
            found = check_program(path, limits)
        self.checked[name] = found
        return found

    def save_grooves(self, grooves: Any) -> None:
        """``grooves.npz``: any kind's grooves (``Grooves``, ``ConformingGrooves``),
        through their own ``save``."""
        from specholo.fabrication.atomic import atomic_open

        with atomic_open(self.path / "grooves.npz", "wb", encoding=None) as fh:
            grooves.save(fh)

    def save_arrays(self, name: str, **arrays: Any) -> None:
        """A compressed ``.npz`` of named arrays (``stipples.npz``); read back
        with :func:`specholo.readback.load_arrays`."""
        import numpy as np

        from specholo.fabrication.atomic import atomic_open

        with atomic_open(self.path / name, "wb", encoding=None) as fh:
            np.savez_compressed(fh, **arrays)

    def save_model(self, mesh: Any, name: str = "model.ply") -> None:
        """The placed model (a ``trimesh.Trimesh``) as PLY, read back by
        :func:`specholo.scene.loading.read_mesh`."""
        from specholo.fabrication.atomic import atomic_open

        with atomic_open(self.path / name, "wb", encoding=None) as fh:
            fh.write(mesh.export(file_type="ply"))

    def save_record(self, kind: str, record: dict[str, Any], name: str = "hologram.json",
                    sort_keys: bool = True,
                    dump: Callable[[dict[str, Any], Any], None] | None = None) -> None:
        """The design's record (``hologram.json``), opening with the header every
        kind's has (:func:`specholo.folder.hologram_header`): its kind and schema.

        Args:
            kind: the kind, as ``run.json`` names it.
            record: the rest, the settings under ``settings``.
            name: the file's name (a coupon's is ``coupon.json``).
            sort_keys: keys after the header in sorted order.
            dump: writes the record to the open file itself (a flat design
                streams its stipples); default ``json.dump`` with indent 1.
        """
        from specholo.fabrication.atomic import atomic_open
        from specholo.folder import hologram_header

        with atomic_open(self.path / name) as fh:
            whole = {**hologram_header(kind), **record}
            if dump is not None:
                dump(whole, fh)
            else:
                json.dump(whole, fh, indent=1, sort_keys=sort_keys)

    def unchecked(self) -> list[str]:
        """The programs in the stage that no check has read, by name."""
        return sorted(p.name for p in self.path.iterdir()
                      if p.suffix.lower() in PROGRAM_SUFFIXES and p.name not in self.checked)


def software_versions() -> dict[str, str]:
    """Versions of specholo, Python and the libraries a design's numbers depend on."""
    import platform

    from specholo import __version__

    versions = {"specholo": __version__, "python": platform.python_version()}
    names = ("numpy", "scipy", "numba", "trimesh", "embreex", "ezdxf", "matplotlib", "pillow")
    found = _installed(names)
    for name in names:
        if name in found:
            versions[name] = found[name]
    return versions


def _installed(names: tuple[str, ...]) -> dict[str, str]:
    """The versions of those installed packages, from their ``.dist-info``
    folders, one listing of each folder on the path (``importlib.metadata``
    searches the whole path once a name: 40 ms for these eight); a package
    installed any other way is asked of ``importlib.metadata``."""
    found: dict[str, str] = {}
    for entry in sys.path:
        try:
            listing = os.listdir(entry or ".")
        except OSError:
            continue
        for fn in listing:
            if not fn.endswith(".dist-info"):
                continue
            project, _, version = fn[: -len(".dist-info")].rpartition("-")
            key = project.lower().replace("_", "-")
            if key in names and key not in found:
                found[key] = version
    missing = [name for name in names if name not in found]
    if missing:
        from importlib import metadata  # (itself a few tens of ms to import)

        for name in missing:
            try:
                found[name] = metadata.version(name)
            except metadata.PackageNotFoundError:
                continue
    return found


def numba_threads() -> int | None:
    """The threads numba's kernels run on, or None without numba."""
    try:
        import numba
    except ImportError:
        return None
    return int(getattr(numba.config, "NUMBA_NUM_THREADS"))  # noqa: B009 - set at run time


def run_record(kind: str, command: list[str] | None, seconds: dict[str, Any],
               settings: dict[str, Any] | None = None) -> dict[str, Any]:
    """What ``run.json`` records of one run: the kind, when, how it was asked
    for, with which software and threads, and how long each stage took. It is
    the one file of a design folder that differs between two runs of the same
    design."""
    import platform

    from specholo import __version__

    record: dict[str, Any] = {
        "kind": kind, "specholo_version": __version__,
        "command": list(sys.argv if command is None else command)}
    if settings is not None:
        record["settings"] = settings
    record.update({
        "software": software_versions(),
        "platform": {"system": platform.platform(), "numba_threads": numba_threads()},
        "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "seconds": seconds})
    return record


@contextlib.contextmanager
def stage_design(out: str | os.PathLike[str],
                 inputs: Iterable[str | os.PathLike[str] | None] = (), *,
                 kind: str, command: list[str] | None = None) -> Iterator[Stage]:
    """A :class:`Stage` that replaces ``out`` whole once the block succeeds and
    every program in it has passed its check.

    Args:
        out: the output folder.
        inputs: the job's input files, which ``out`` must not hold as files a
            design writes.
        kind: the kind of hologram, for ``run.json``: what the job registry
            tells the folder's kind by (``specholo.jobs.job_of``).
        command: the command line, for ``run.json`` (None: ``sys.argv``).

    Raises:
        SpecholoError: a program in the stage was not checked (nothing is
            published), or see :func:`specholo.folders.publish`.
    """
    from specholo.fabrication.atomic import atomic_open
    from specholo.folders import publish

    started = time.perf_counter()
    with publish(out, inputs) as tmp:
        stage = Stage(Path(tmp))
        yield stage
        missed = stage.unchecked()
        if missed:
            raise SpecholoError(f"{missed[0]} was written but not read back by the safety "
                                "check: nothing written")
        if not (stage.path / "run.json").exists():
            with atomic_open(stage.path / "run.json") as fh:
                json.dump(run_record(kind, command,
                                     {"writing": time.perf_counter() - started}), fh, indent=1)
