"""Output folders published whole or not at all.

Every job (``design``, ``compose``, ``spin``, ``steady``) and ``verify`` writes
its files through :func:`publish`: into a new folder staged beside the output
folder, which takes the output folder's place in one rename once everything is
written. The files of the existing folder that the job does not replace (the
user's own files and subfolders, and for ``verify`` the design's files) are
hard-linked into the stage first, so a reader sees the whole old folder or the
whole new one, never a mix, and a run that fails or is killed leaves the old
folder as it was.

Which files are specholo's is one registry (:data:`OUTPUT_NAMES`,
:func:`is_output`): a design replaces every one of them, so none of an older
design's files survives a new one, whichever job wrote it; any other name is
the user's and is kept. A kind of hologram adds the names it writes with
:func:`register_outputs` (the job registry does it for every job's ``files``),
so a new kind's files are specholo's without a change here.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import os
import re
import secrets
import shutil
import stat
import sys
from collections.abc import Callable, Collection, Iterable, Iterator
from pathlib import Path

from specholo.errors import SpecholoError
from specholo.fabrication.atomic import PART_FILE, pid_alive, scratch

#: Every file a specholo command writes into a design folder under its own name.
OUTPUT_NAMES = frozenset({
    # the design's data, which verify, render and the other commands read
    "hologram.json", "grooves.npz", "stipples.npz", "model.ply", "plate.npz", "run.json",
    # fabrication files (pipeline.FORMATS, fabrication.heightmap.RIDGED_FILES, spin's relief)
    "hologram.gcode", "hologram.svg", "hologram.dxf", "pattern.pdf", "relief.gcode",
    # a rigid holder's probe program and levelled program (specholo probe, level):
    # made from the design's program, they go with it
    "probe.gcode", "hologram_leveled.gcode",
    "hologram.stl", "heightmap.png", "heightmap.tif", "heightmap.json",
    # pictures written with the design
    "preview.png", "preview.gif",
    # verify
    "verify.json", "verify.png", "verify_cut.json",
    # what render, stereo, animate, report and view write by default: they show
    # the design they were made from, so they go with it
    "render.png", "stereo.png", "turntable.gif", "light.gif", "report.html", "view.html",
})
#: Names specholo writes by pattern: a composition's placed scenes.
OUTPUT_PATTERNS = (re.compile(r"scene_\d+\.ply"),)
#: The files ``verify`` writes (each kind writes some of them).
VERIFY_FILES = frozenset({"verify.json", "verify.png", "verify_cut.json"})

#: A folder staged by :func:`publish`, or an old one it moved aside, beside ``out``.
_SIBLING = re.compile(r"\.(?P<name>.+)\.(?P<kind>stage|old)-(?P<pid>\d+)-[0-9a-f]+")


#: Names the kinds of hologram registered (:func:`register_outputs`).
_REGISTERED: set[str] = set()


def register_outputs(names: Iterable[str]) -> None:
    """Add file names a kind of hologram writes to specholo's own: every later
    design drops them from a folder it replaces, as it drops the others."""
    _REGISTERED.update(names)


def is_output(name: str) -> bool:
    """Whether a file name is one specholo writes into a design folder."""
    return (name in OUTPUT_NAMES or name in _REGISTERED
            or any(p.fullmatch(name) for p in OUTPUT_PATTERNS))


def output_folder(out: str | os.PathLike[str]) -> Path:
    """The folder ``out`` names, symlinks resolved, or a one-line refusal.

    Raises:
        SpecholoError: an empty path, a symlink loop, a path that is not a
            folder, the root or a mount point (which cannot be swapped).
    """
    if not os.fspath(out):
        raise SpecholoError("the output folder is an empty path: name a folder "
                            "(. for the current one)")
    try:
        target = Path(out).resolve()
        if target.exists() and not target.is_dir():
            raise SpecholoError(f"{out} exists and is not a folder")
        mount = target.is_dir() and os.path.ismount(target)
    except RuntimeError as exc:  # Python 3.11: a symlink loop
        raise SpecholoError(f"output folder {out}: symlink loop") from exc
    except OSError as exc:
        if exc.errno == errno.ELOOP:
            raise SpecholoError(f"output folder {out}: symlink loop") from exc
        raise SpecholoError(f"bad output folder {os.fspath(out)!r}: "
                            f"{exc.strerror or exc}") from exc
    except ValueError as exc:  # a NUL byte in the path
        if isinstance(exc, SpecholoError):
            raise
        raise SpecholoError(f"bad output folder {os.fspath(out)!r}: {exc}") from exc
    if target == target.parent or mount:
        # the new folder is staged beside the old one and renamed over it
        raise SpecholoError(f"cannot write into {out}: it is a mount point; "
                            "name a folder inside it")
    return target


def check_out(out: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str] | None] = (),
              replaces: Collection[str] | None = None) -> Path:
    """Refuse, in one line, an output folder that :func:`publish` would refuse,
    before a long job runs. Returns the folder, resolved.

    Args:
        out: the output folder.
        inputs: the job's input files (None entries are skipped).
        replaces: the names the job owns in ``out`` (default: every output name).
    """
    target = output_folder(out)
    _check_inputs(out, target, inputs, _owner(replaces))
    if target.is_dir():
        _check_entries(out, target)
    _check_parent(out, target)
    _check_not_cwd(out, target)
    return target


def _check_not_cwd(out: str | os.PathLike[str], target: Path) -> None:
    """Refuse to replace the folder the process (and so the shell that started it)
    stands in: the new folder takes its place whole and the old one is removed,
    which would leave that shell in a removed folder, seeing nothing."""
    if _cwd_within(target) is not None:
        raise SpecholoError(
            f"{os.fspath(out)} is the folder you are in (or holds it), and it is replaced "
            f"whole, which would leave your shell in a removed folder: run this from "
            f"{target.parent} instead")


def _check_parent(out: str | os.PathLike[str], target: Path) -> None:
    """Refuse an output folder whose nearest existing parent is not a writable
    folder: the new folder is made, or staged, there."""
    try:
        above = target.parent
        while not above.exists() and above != above.parent:
            above = above.parent
        if not above.is_dir():
            raise SpecholoError(f"cannot create output folder {out}: {above} is not a folder")
        if not os.access(above, os.W_OK | os.X_OK):
            raise SpecholoError(f"cannot create output folder {out}: {above} is not writable")
    except OSError as exc:
        raise SpecholoError(f"bad output folder {os.fspath(out)!r}: {exc}") from exc


@contextlib.contextmanager
def publish(out: str | os.PathLike[str], inputs: Iterable[str | os.PathLike[str] | None] = (),
            replaces: Collection[str] | None = None) -> Iterator[Path]:
    """A new folder to write into, which replaces ``out`` whole once the block succeeds.

    On success the entries of ``out`` that the job does not own are carried
    over (hard links, subfolders recreated), then the new folder and ``out``
    are swapped in one rename and the old one removed. On any error or
    KeyboardInterrupt the new folder goes and ``out`` is untouched. Leftovers of
    killed runs beside ``out`` (and their temporary files in it) are removed
    first; a folder a killed run had moved aside is put back.

    Args:
        out: the output folder (created, with its parents, if missing; a
            symlink to a folder publishes into its target).
        inputs: the job's input files: none of them may be a file the job
            writes or drops.
        replaces: the names the job owns: those it does not write are dropped.
            Default: every specholo output (:func:`is_output`), as a design
            replaces all of an older design's files.

    Raises:
        SpecholoError: see :func:`check_out`; or the folder cannot be written.
    """
    owned = _owner(replaces)
    inputs = list(inputs)
    with scratch():
        target = output_folder(out)
        _check_not_cwd(out, target)
        _clean_leftovers(target)
        _check_inputs(out, target, inputs, owned)
        if target.is_dir():
            _check_entries(out, target)
        made, stage = _make_stage(out, target)
        swapped, old, cwd = False, None, None
        try:
            try:
                yield stage
                if target.is_dir():
                    _carry_over(out, target, stage, owned)
                    os.chmod(stage, stat.S_IMODE(target.stat().st_mode))
                cwd = _cwd_within(target)
                old = _swap(stage, target)
                swapped = True
            except OSError as exc:  # a full disk, a folder turned read-only
                raise SpecholoError(f"cannot write {out}: {_where(exc, stage, target, out)}"
                                    f"{exc.strerror or exc}") from exc
        finally:
            if swapped:
                try:
                    _follow_cwd(cwd, target)
                finally:
                    if old is not None:
                        _remove_old(old)
            else:
                _remove_tree(stage)
                for d in made:  # leave no folder behind that this run created
                    with contextlib.suppress(OSError):
                        d.rmdir()


def _owner(replaces: Collection[str] | None) -> Callable[[str], bool]:
    if replaces is None:
        return is_output
    names = frozenset(replaces)
    return names.__contains__


def _check_inputs(out: str | os.PathLike[str], target: Path,
                  inputs: Iterable[str | os.PathLike[str] | None],
                  owned: Callable[[str], bool]) -> None:
    """Refuse an input that is a file the job writes or drops in ``target``."""
    for path in inputs:
        if path is None:
            continue
        try:
            real = Path(path).resolve()
        except (OSError, RuntimeError, ValueError):
            continue  # its reader refuses it in its own words
        if real.parent == target and owned(real.name):
            raise SpecholoError(f"{os.fspath(path)} is an input of this run and would be "
                                f"overwritten in {os.fspath(out)}: choose another output "
                                "folder")


#: The files that make a folder specholo's: every design's hologram.json, and a
#: test coupon's coupon.json (a coupon has no design's hologram.json).
FOLDER_MARKERS = frozenset({"hologram.json", "coupon.json"})


def _check_entries(out: str | os.PathLike[str], target: Path) -> None:
    """Refuse a folder that is not specholo's yet holds specholo's file names,
    and an entry with such a name that is not a regular file."""
    try:
        names = sorted(e.name for e in os.scandir(target) if is_output(e.name))
        for name in names:
            if not stat.S_ISREG(os.lstat(target / name).st_mode):
                raise SpecholoError(f"{Path(out) / name} is not a regular file, where "
                                    "specholo writes one: move it away or choose another "
                                    "output folder")
    except OSError as exc:
        raise SpecholoError(f"cannot read output folder {out}: {exc.strerror or exc}") from exc
    if names and not FOLDER_MARKERS.intersection(names):
        raise SpecholoError(f"{out} is not a specholo folder (no hologram.json) but holds "
                            f"{names[0]}: choose another output folder")


def _clean_leftovers(target: Path) -> None:
    """Remove what killed runs left beside ``target`` and their temporary files
    in it; a folder one had moved aside comes back first if ``target`` is gone."""
    parent = target.parent
    try:
        siblings = [(m, e) for e in sorted(os.scandir(parent), key=lambda e: e.name)
                    if (m := _SIBLING.fullmatch(e.name)) and m["name"] == target.name]
    except OSError:
        return  # a parent that is missing or unreadable: nothing to clean
    # the old folders first: one of them may be the only copy of the output
    for m, entry in sorted(siblings, key=lambda s: s[0]["kind"] != "old"):
        if pid_alive(int(m["pid"])):
            continue
        with contextlib.suppress(OSError):
            if m["kind"] == "old" and not os.path.lexists(target):
                os.rename(entry.path, target)
            else:
                _remove_tree(Path(entry.path))
    if target.is_dir():
        with contextlib.suppress(OSError):
            for entry in os.scandir(target):
                m = PART_FILE.fullmatch(entry.name)
                if m and not pid_alive(int(m["pid"])):
                    with contextlib.suppress(OSError):
                        os.unlink(entry.path)


def _make_stage(out: str | os.PathLike[str], target: Path) -> tuple[list[Path], Path]:
    """Create the stage beside ``target`` (and any missing parents, listed deepest first)."""
    parent = target.parent
    try:
        made = [d for d in (parent, *parent.parents) if not d.exists()]
        parent.mkdir(parents=True, exist_ok=True)
        while True:
            stage = parent / f".{target.name}.stage-{os.getpid()}-{secrets.token_hex(4)}"
            try:
                stage.mkdir()
                return made, stage
            except FileExistsError:
                continue
    except OSError as exc:
        raise SpecholoError(f"cannot create output folder {out}: "
                            f"{exc.strerror or exc}") from exc


def _carry_over(out: str | os.PathLike[str], target: Path, stage: Path,
                owned: Callable[[str], bool]) -> None:
    """Link into the stage every entry of ``target`` the job neither wrote nor owns."""
    written = set(os.listdir(stage))
    for entry in sorted(os.scandir(target), key=lambda e: e.name):
        name = entry.name
        if is_output(name) and not entry.is_file(follow_symlinks=False):
            raise SpecholoError(f"{Path(out) / name} is not a regular file, where specholo "
                                "writes one: move it away or choose another output folder")
        if name in written or owned(name) or PART_FILE.fullmatch(name):
            continue
        _carry(Path(entry.path), stage / name, out, target)


def _carry(src: Path, dst: Path, out: str | os.PathLike[str], target: Path) -> None:
    """Hard-link ``src`` at ``dst`` (a copy where the file system refuses links);
    a folder is made anew and filled the same way."""
    st = os.lstat(src)
    if stat.S_ISDIR(st.st_mode):
        if st.st_dev != os.lstat(target).st_dev:
            # Its files cannot be linked, and removing the old folder would
            # empty the file system mounted there.
            raise SpecholoError(f"{Path(out) / src.relative_to(target)} is a mount point: "
                                "unmount it or choose another output folder")
        os.mkdir(dst)
        for entry in sorted(os.scandir(src), key=lambda e: e.name):
            _carry(Path(entry.path), dst / entry.name, out, target)
        os.chmod(dst, stat.S_IMODE(st.st_mode))  # last: it may forbid writing
        return
    try:
        if os.link in os.supports_follow_symlinks:
            os.link(src, dst, follow_symlinks=False)  # a symlink itself, not its target
        elif stat.S_ISLNK(st.st_mode):
            raise OSError(errno.ENOTSUP, "cannot link a symlink itself here")
        else:
            os.link(src, dst)
    except OSError:
        if stat.S_ISLNK(st.st_mode):
            os.symlink(os.readlink(src), dst)
        elif stat.S_ISREG(st.st_mode):
            shutil.copy2(src, dst, follow_symlinks=False)
        else:
            raise


def _where(exc: OSError, stage: Path, target: Path, out: str | os.PathLike[str]) -> str:
    """The file an error names, as the user knows it (in ``out``, not in the
    stage), followed by ": "; empty if it names none."""
    if not isinstance(exc.filename, str | bytes | os.PathLike) or not exc.filename:
        return ""
    path = Path(os.fsdecode(exc.filename))
    for root in (stage, target):
        if path == root or root in path.parents:
            return f"{Path(out) / path.relative_to(root)}: "
    return f"{path}: "


def _cwd_within(target: Path) -> Path | None:
    """The working directory's path below ``target``, if it is in there."""
    try:
        cwd = Path(os.getcwd())
    except OSError:
        return None
    return cwd.relative_to(target) if cwd == target or target in cwd.parents else None


def _follow_cwd(cwd: Path | None, target: Path) -> None:
    """Keep a working directory that was in the old folder in the new one (the
    old one is about to be removed, and relative paths would lead nowhere)."""
    if cwd is None:
        return
    with contextlib.suppress(OSError):
        where = target / cwd
        os.chdir(where if where.is_dir() else target)


def _swap(stage: Path, target: Path) -> Path | None:
    """Put ``stage`` in ``target``'s place; return where the old folder went (None
    if there was none)."""
    if not os.path.lexists(target):
        os.rename(stage, target)
        return None
    if _exchange(stage, target):
        return stage
    # Two renames: a run killed between them leaves no ``target`` but the old
    # folder under this name, which the next run puts back (_clean_leftovers).
    old = target.parent / f".{target.name}.old-{os.getpid()}-{secrets.token_hex(4)}"
    os.rename(target, old)
    try:
        os.rename(stage, target)
    except BaseException:
        os.rename(old, target)
        raise
    return old


#: renameat2's flag that swaps its two paths.
_RENAME_EXCHANGE = 2
_AT_FDCWD = -100


def _renameat2() -> Callable[..., int] | None:
    """libc's renameat2 (Linux, glibc 2.28 and later), or None."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        fn = ctypes.CDLL(None, use_errno=True).renameat2
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    fn.restype = ctypes.c_int
    return fn  # type: ignore[no-any-return]


def _exchange(a: Path, b: Path) -> bool:
    """Swap two paths in one step; False where the system or file system cannot."""
    fn = _renameat2()
    if fn is None:
        return False
    if fn(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE) == 0:
        return True
    err = ctypes.get_errno()
    if err in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP):
        return False
    raise OSError(err, os.strerror(err), os.fspath(b))


def _remove_old(old: Path) -> None:
    """Remove the folder the new one replaced. A Ctrl-C meanwhile does not stop
    it: the new folder is out already, and the removal is quick."""
    try:
        _remove_tree(old)
    except KeyboardInterrupt:
        _remove_tree(old)
        raise


def _remove_tree(path: Path) -> None:
    """Remove a folder, also where a subfolder forbids writing (carried over as
    the user had it); what cannot go stays, and a later run removes it."""
    if not os.path.lexists(path):
        return
    try:
        shutil.rmtree(path)
        return
    except OSError:
        pass

    def open_up(d: str) -> None:  # never a symlink's target: only this tree's folders
        with contextlib.suppress(OSError):
            if not os.path.islink(d):
                os.chmod(d, stat.S_IMODE(os.lstat(d).st_mode) | stat.S_IRWXU)

    open_up(os.fspath(path))
    for where, dirs, _ in os.walk(path):  # top down: each folder opened before it is read
        for d in dirs:
            open_up(os.path.join(where, d))
    shutil.rmtree(path, ignore_errors=True)
