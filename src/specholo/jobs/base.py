"""The interface every kind of hologram implements, and the one way to run it.

In the style of the hosts' :class:`~specholo.hosts.surfaces.Host` protocol one
level up: a job turns the command's settings into its own
(:meth:`Job.configure`, degrees converted there once), designs
(:meth:`Job.design`), writes its folder (:meth:`Job.write`, through
:func:`specholo.staging.stage_design`, which publishes nothing while a program
in it is unchecked), knows its folders (:meth:`Job.holds`) and verifies them
(:meth:`Job.verify`), returning a :class:`Verification`: the figures as a table
and lines to print, and the files to write, which
:func:`publish_verification` publishes together (all or none). :func:`run`
does the same steps for every kind.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

from specholo.errors import SpecholoError

if TYPE_CHECKING:
    from specholo.optics.spread import Spread
    from specholo.preview.source import PictureSource

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
        spread: the light's size and the surface's gloss, every glint a
            streak (:mod:`specholo.simulation.streaks`); None: every glint a point.
    """

    step_deg: float = 5.0
    from_gcode: bool = False
    cut: bool = False
    cut_method: str | None = None
    resolution: float | None = None
    stl: Path | None = None
    spread: Spread | None = None


@dataclass(frozen=True)
class Table:
    """Figures to print as a table: a title, column names and rows of text."""

    title: str
    columns: list[str]
    rows: list[list[str]]


@dataclass(frozen=True)
class Summary:
    """What a design says once its folder is written: lines for the terminal,
    warnings (each one line, for the error stream) and, for the kinds that
    verify as they design, the verification's table."""

    lines: list[str]
    warnings: list[str]
    table: Table | None = None


@dataclass(frozen=True)
class WriteOptions:
    """How a design is written (each kind takes what it uses).

    Attributes:
        formats: fabrication files to write (None: the kind's default).
        command: the command line, recorded in ``run.json`` (None: ``sys.argv``).
        step_deg: largest step between the positions verified with the design,
            degrees (None: the kind's default).
        frames: frames of an animated preview (None: the kind's default).
    """

    formats: tuple[str, ...] | None = None
    command: list[str] | None = None
    step_deg: float | None = None
    frames: int | None = None


@dataclass
class Designed:
    """A job's design, not yet written, and lines it has to say about how it was
    found (e.g. each density tried), which lead its summary."""

    design: Any
    notes: list[str] = field(default_factory=list)


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
        pictures: the picture commands that draw it (of :data:`PICTURE_COMMANDS`),
            through :meth:`picture_source`.
        own_pictures: what it draws itself when it is designed ("preview.gif"),
            named when a picture command does not serve it.
        design_step: for a kind verified as it is designed, the step between
            verified positions, degrees: (default, lowest, highest); else None.
        preview_frames: the default frames of its animated preview, or None.
        files: the file names it writes into a folder (the registry makes
            them specholo's, :func:`specholo.folders.register_outputs`).
    """

    kind: str
    title: str
    verified_on: str
    pictures: frozenset[str]
    own_pictures: str
    design_step: tuple[float, float, float] | None
    preview_frames: int | None
    files: frozenset[str]

    def configure(self, values: Mapping[str, Any], inputs: Sequence[Path]) -> Any:
        """The kind's settings from the command's (or TOML's) names and units
        (degrees, converted here once), checked; ``inputs`` are the model files."""
        ...

    def check_options(self, config: Any, options: WriteOptions) -> None:
        """Refuse, before the design runs, write options the kind cannot honour
        (a format it does not write)."""
        ...

    def design(self, inputs: Sequence[Path], config: Any, status: Status) -> Designed:
        """Design the hologram of ``inputs``; nothing is written."""
        ...

    def write(self, designed: Designed, out: Path, inputs: Sequence[Path | None],
              options: WriteOptions, status: Status) -> Summary:
        """Write the folder whole (:func:`specholo.staging.stage_design`) and say
        what it holds; ``inputs`` may not be files the design writes in ``out``."""
        ...

    def holds(self, folder: Path) -> bool:
        """Whether ``folder`` holds a design of this kind."""
        ...

    def load(self, folder: Path) -> Any:
        """The design in ``folder``, read back and checked (one line on a bad file)."""
        ...

    def preview(self, folder: Path, status: Status) -> dict[str, Callable[[Path], object]]:
        """The pictures the kind draws when it is designed, drawn again from the
        folder's files: name -> a function writing it into a given folder (see
        :func:`publish_files`). The same bytes as the design wrote, with its
        default settings."""
        ...

    def verify(self, folder: Path, options: VerifyOptions, status: Status) -> Verification:
        """Simulate the viewers of the design in ``folder``; nothing is written."""
        ...

    def picture_source(self, folder: Path) -> PictureSource:
        """The design in ``folder``, read back and checked, as the picture commands
        draw it: its setup, plate, glints and motion."""
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
    """Refuse ``--from-gcode``, ``--cut``, ``--light-size`` and ``--roughness``
    for the kinds that are verified otherwise."""
    if options.from_gcode or options.cut:
        raise SpecholoError(f"{job.title} is verified on {job.verified_on}; --from-gcode and "
                            "--cut are for flat-plate designs")
    refuse_spread(job, options)


def refuse_spread(job: Job, options: VerifyOptions) -> None:
    """Refuse ``--light-size`` and ``--roughness`` for a kind whose glints are not
    found on grooves (streaks are followed along a flat plate's grooves)."""
    if options.spread is not None:
        raise SpecholoError(f"{job.title} is verified on {job.verified_on} with point glints; "
                            "--light-size and --roughness are for grooved flat-plate designs")


def publish_verification(folder: str | os.PathLike[str], v: Verification) -> None:
    """Publish a verification's files into ``folder`` together (all or none)."""
    publish_files(folder, v.files)


def publish_files(folder: str | os.PathLike[str],
                  files: Mapping[str, Callable[[Path], object]]) -> None:
    """Write files (name -> a function writing it into a folder) into a design's
    folder together: all or none, the rest of the folder kept as it was. Never
    a machine program: those go with their design (:mod:`specholo.staging`)."""
    from specholo.folders import publish
    from specholo.staging import PROGRAM_SUFFIXES

    if any(Path(name).suffix.lower() in PROGRAM_SUFFIXES for name in files):
        raise SpecholoError("a machine program is published with its design, not alone")
    with publish(folder, replaces=set(files)) as stage:
        for write in files.values():
            write(stage)


def run(job: Job, inputs: Sequence[Path], values: Mapping[str, Any], out: Path,
        options: WriteOptions | None = None, status: Status = quiet,
        other_inputs: Sequence[Path | None] = (), precompile: bool = False) -> Summary:
    """Design and write one hologram of any kind, the same steps for every kind:
    the settings checked, the output folder checked before the (long) design,
    the design, then its folder written whole with every program checked.

    Args:
        job: the kind (one of :data:`specholo.jobs.JOBS`).
        inputs: the model files (a composition's TOML for a composition).
        values: the settings by the command's names, in its units.
        out: the output folder.
        options: how to write it.
        status: told what a long step is doing.
        other_inputs: further files read (a config file), which ``out`` may not
            hold as files a design writes.
        precompile: on a first run (numba's cache cold), compile a grooved
            design's later kernels in a second process while its first stages
            run (:mod:`specholo._precompile`); for a command, which ends with
            the design, not for a caller that runs more after it.
    """
    from specholo import _precompile
    from specholo.folders import check_out

    options = write_options(job, options or WriteOptions())
    config = job.configure(values, inputs)
    job.check_options(config, options)
    every = [*inputs, *other_inputs]
    check_out(out, every)
    helper = _precompile.start(config) if precompile and _grooved(config) else None
    try:
        designed = job.design(inputs, config, status)
        return job.write(designed, out, every, options, status)
    finally:
        _precompile.stop(helper)


def _grooved(config: Any) -> bool:
    """Whether a design's settings make a plate of grooves found one stipple
    count at a time (what :mod:`specholo._precompile` compiles for)."""
    return (getattr(config, "method", "ridged") in ("striped", "hyperbola", "arc")
            and getattr(config, "visibility", None) is None)


def refuse_formats(job: Job, options: WriteOptions) -> None:
    """Refuse ``formats`` for a kind that always writes the same files."""
    if options.formats is not None:
        raise SpecholoError(f"{job.title} writes its own files; formats are for "
                            "`specholo design`")


def write_options(job: Job, options: WriteOptions) -> WriteOptions:
    """``options`` checked for ``job`` before anything long runs, its defaults
    filled in: the verification step and the preview's frames."""
    import math
    from dataclasses import replace

    step, frames = options.step_deg, options.frames
    if job.design_step is not None:
        default, low, high = job.design_step
        step = default if step is None else step
        if not (math.isfinite(step) and low <= step <= high):
            raise SpecholoError(f"step must be in [{low:g}, {high:g}] degrees, got {step}")
    if job.preview_frames is not None:
        frames = job.preview_frames if frames is None else frames
        if not 0 <= frames <= 1000:
            raise SpecholoError(f"frames must be in [0, 1000], got {frames}")
    return replace(options, step_deg=step, frames=frames)
