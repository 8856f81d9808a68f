"""The interface every kind of hologram implements, and what verifying one returns.

In the style of the hosts' :class:`~specholo.hosts.surfaces.Host` protocol one
level up: a job knows its folders (:meth:`Job.holds`) and verifies them
(:meth:`Job.verify`), returning a :class:`Verification`: the figures as a table
and lines to print, and the files to write, which
:func:`publish_verification` publishes together (all or none).
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from specholo.errors import SpecholoError

#: Told what a long step is doing ("simulating eye pairs..."), for a status line.
Status = Callable[[str], None]


def quiet(_: str) -> None:
    """A :data:`Status` that shows nothing."""


@dataclass(frozen=True)
class VerifyOptions:
    """What ``verify`` was asked for.

    Attributes:
        step_deg: largest step between simulated positions, degrees.
        from_gcode: verify the grooves parsed from hologram.gcode.
        cut: also verify the plate as hologram.gcode cuts it.
        cut_method: ``"survival"`` or ``"field"`` (None: the default for the rest).
        resolution: height-field cut sample spacing, mm (None: the default).
        stl: where to write the cut plate as an STL, or None.
    """

    step_deg: float = 5.0
    from_gcode: bool = False
    cut: bool = False
    cut_method: str | None = None
    resolution: float | None = None
    stl: Path | None = None


@dataclass(frozen=True)
class Table:
    """Figures to print as a table: a title, column names and rows of text."""

    title: str
    columns: list[str]
    rows: list[list[str]]


@dataclass(frozen=True)
class Summary:
    """What a design says once its folder is written: lines for the terminal and
    warnings (each one line, for the error stream)."""

    lines: list[str]
    warnings: list[str]


@dataclass
class Verification:
    """What verifying a folder found.

    Attributes:
        lines: sentences to print (after the table, if any).
        table: the figures per position, or None.
        files: file name -> a function writing that file into a given folder.
    """

    lines: list[str]
    table: Table | None = None
    files: dict[str, Callable[[Path], object]] = field(default_factory=dict)

    def write(self, folder: Path) -> None:
        """Write every file into ``folder`` (a staged folder, or one not yet published)."""
        for write in self.files.values():
            write(folder)


class Job(Protocol):
    """One kind of hologram.

    Attributes:
        kind: the kind's name (``"flat"``, ``"ridged"``, ...).
        title: the kind in a sentence ("a turning-plate design").
        verified_on: what its verification reads, for the refusal of options
            it has no use for ("its grooves").
        pictures: the picture commands that draw it (of :data:`PICTURE_COMMANDS`).
        own_pictures: what it draws itself when it is designed ("preview.gif"),
            named when a picture command does not serve it.
    """

    kind: str
    title: str
    verified_on: str
    pictures: frozenset[str]
    own_pictures: str

    def holds(self, folder: Path) -> bool:
        """Whether ``folder`` holds a design of this kind."""
        ...

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        """Simulate the viewers of the design in ``folder``; nothing is written."""
        ...


#: The commands that draw a designed folder.
PICTURE_COMMANDS = frozenset({"render", "animate", "stereo", "report", "view"})


def refuse_picture(job: Job, folder: Path, command: str) -> None:
    """Refuse, in one line, a picture command that does not draw this kind."""
    if command not in job.pictures:
        served = ", ".join(sorted(job.pictures))
        raise SpecholoError(
            f"{folder} holds {job.title}: `specholo {command}` does not draw it; its pictures "
            f"are {job.own_pictures}" + (f" and `specholo {served}`" if served else "")
            + "; `specholo verify` checks it")


def refuse_cut_options(job: Job, options: VerifyOptions) -> None:
    """Refuse ``--from-gcode`` and ``--cut`` for the kinds that are verified otherwise."""
    if options.from_gcode or options.cut:
        raise SpecholoError(f"{job.title} is verified on {job.verified_on}; --from-gcode and "
                            "--cut are for flat-plate designs")


def publish_verification(folder: str | os.PathLike[str], v: Verification) -> None:
    """Publish a verification's files into ``folder`` together (all or none)."""
    from specholo.folders import publish

    with publish(folder, replaces=set(v.files)) as stage:
        v.write(stage)
