"""Output folders published whole or not at all, and inputs never overwritten."""

from __future__ import annotations

import errno
import json
import os
import shutil
import stat
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from specholo import folders
from specholo.errors import SpecholoError
from specholo.fabrication.atomic import atomic_open
from specholo.folders import is_output, publish
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
TINY = ["--stipples", "20"]
DEAD = 99_999_999  # beyond any pid the kernel hands out


def run(argv: list[Any], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def snapshot(folder: Path) -> dict[str, bytes | None]:
    """Every entry below ``folder``: a file's bytes, None for a folder."""
    return {str(p.relative_to(folder)): None if p.is_dir() else p.read_bytes()
            for p in sorted(folder.rglob("*"))}


def hidden(folder: Path) -> list[str]:
    """Names a run may leave behind: stages, moved-aside folders, temporary files."""
    return sorted(p.name for p in folder.iterdir() if p.name.startswith("."))


def refused(code: int, err: str, *words: str) -> None:
    lines = err.strip().splitlines()
    assert code == 1 and len(lines) == 1 and lines[0].startswith("error: "), err
    assert all(w in lines[0] for w in words), err


# ---------------------------------------------------------------- the registry


def test_every_file_a_job_writes_is_in_the_registry() -> None:
    from specholo.fabrication.heightmap import PLATE_FILE, RIDGED_FILES
    from specholo.jobs.flat.folder import FORMATS

    for name in (*FORMATS.values(), *RIDGED_FILES.values(), PLATE_FILE, "scene_0.ply",
                 "scene_12.ply", *folders.VERIFY_FILES):
        assert is_output(name), name
    for name in ("notes.txt", "scene_x.ply", "model.obj", "hologram.json.bak", ".hologram.json"):
        assert not is_output(name), name


# ---------------------------------------------------------------- publish itself

OLD = {"hologram.json": b"old", "grooves.npz": b"old", "verify.json": b"old",
       "notes.txt": b"mine", "sub/a.txt": b"mine too", "sub/deeper/b.txt": b"deep"}
NEW = {"hologram.json": b"new", "stipples.npz": b"new", "preview.png": b"new"}


def make(folder: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        (folder / name).parent.mkdir(parents=True, exist_ok=True)
        (folder / name).write_bytes(data)


def job(out: Path, inputs: tuple[Path, ...] = ()) -> None:
    """A design that writes NEW (each file through atomic_open, as the jobs do)."""
    with publish(out, inputs) as stage:
        for name, data in NEW.items():
            with atomic_open(stage / name, "wb", encoding=None) as fh:
                fh.write(data)


@pytest.fixture
def old(tmp_path: Path) -> Path:
    out = tmp_path / "holo"
    make(out, OLD)
    return out


def expected_new() -> dict[str, bytes | None]:
    return {**NEW, "notes.txt": b"mine", "sub": None, "sub/a.txt": b"mine too",
            "sub/deeper": None, "sub/deeper/b.txt": b"deep"}


def test_where_links_are_refused_the_user_s_files_are_copied(
        old: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (old / "notes link").symlink_to("notes.txt")

    def refuse(*args: Any, **kwargs: Any) -> None:
        raise OSError(errno.EPERM, os.strerror(errno.EPERM))

    monkeypatch.setattr(folders.os, "link", refuse)
    job(old)
    monkeypatch.undo()
    assert snapshot(old) == {**expected_new(), "notes link": b"mine"}
    assert os.readlink(old / "notes link") == "notes.txt"


def test_a_new_folder_replaces_the_specholo_files_and_keeps_the_others(old: Path) -> None:
    inode = (old / "sub" / "a.txt").stat().st_ino
    job(old)
    assert snapshot(old) == expected_new()
    assert (old / "sub" / "a.txt").stat().st_ino == inode  # linked, not copied
    assert hidden(old.parent) == []
    job(old.parent / "fresh")
    assert snapshot(old.parent / "fresh") == NEW


def _raise_on_call(n: int, fn: Callable[..., Any]) -> Callable[..., Any]:
    """``fn``, but the ``n``-th call (from 0) raises KeyboardInterrupt instead."""
    calls = [0]

    def wrapped(*args: Any, **kwargs: Any) -> Any:
        calls[0] += 1
        if calls[0] == n + 1:
            raise KeyboardInterrupt
        return fn(*args, **kwargs)

    return wrapped


KILLS = [*(("write", k) for k in range(len(NEW))),
         *(("carry", k) for k in range(5)),  # notes.txt, sub, sub/a.txt, sub/deeper, b.txt
         ("chmod", 0), ("chmod", 2), ("before swap", 0), ("exchange", 0), ("second rename", 1),
         ("after swap", 0), ("removing the old folder", 0)]


@pytest.mark.parametrize("where, n", KILLS, ids=[f"{w}-{n}" for w, n in KILLS])
def test_a_kill_at_any_step_leaves_the_old_folder_or_the_new_one(
        old: Path, monkeypatch: pytest.MonkeyPatch, where: str, n: int) -> None:
    before = snapshot(old)
    if where == "write":
        monkeypatch.setattr(tempfile, "mkstemp", _raise_on_call(n, tempfile.mkstemp))
    elif where == "carry":
        monkeypatch.setattr(folders, "_carry", _raise_on_call(n, folders._carry))
    elif where == "chmod":  # the carried folders' modes, then the new folder's
        monkeypatch.setattr(folders.os, "chmod", _raise_on_call(n, os.chmod))
    elif where == "before swap":
        monkeypatch.setattr(folders, "_swap", _raise_on_call(n, folders._swap))
    elif where == "exchange":
        monkeypatch.setattr(folders, "_exchange", _raise_on_call(n, folders._exchange))
    elif where == "second rename":  # where no rename swaps two folders at once
        monkeypatch.setattr(folders, "_exchange", lambda a, b: False)
        monkeypatch.setattr(folders.os, "rename", _raise_on_call(n, os.rename))
    elif where == "after swap":
        monkeypatch.setattr(folders, "_follow_cwd", _raise_on_call(n, folders._follow_cwd))
    else:
        monkeypatch.setattr(folders, "_remove_tree", _raise_on_call(n, folders._remove_tree))
    with pytest.raises(KeyboardInterrupt):
        job(old)
    monkeypatch.undo()
    swapped = where in ("after swap", "removing the old folder")
    assert snapshot(old) == (expected_new() if swapped else before)
    assert hidden(old.parent) == [] and hidden(old) == []


def test_without_an_exchanging_rename_the_folders_swap_in_two_renames(
        old: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(folders, "_exchange", lambda a, b: False)
    job(old)
    assert snapshot(old) == expected_new() and hidden(old.parent) == []


def test_an_error_in_the_job_leaves_the_old_folder(old: Path) -> None:
    before = snapshot(old)
    with pytest.raises(SpecholoError, match="holo/hologram.json: No space left"), \
            publish(old) as stage:
        (stage / "hologram.json").write_text("new")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(stage / "hologram.json"))
    assert snapshot(old) == before and hidden(old.parent) == []


def test_a_mount_point_inside_the_folder_is_refused(old: Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    """Removing the old folder would empty the file system mounted there."""
    before = snapshot(old)
    real = os.lstat

    def lstat(path: Any, *args: Any, **kwargs: Any) -> os.stat_result:
        st = real(path, *args, **kwargs)
        if Path(path) == old / "sub":
            fields = list(st)
            fields[stat.ST_DEV] += 1
            return os.stat_result(fields)
        return st

    monkeypatch.setattr(folders.os, "lstat", lstat)
    with pytest.raises(SpecholoError, match="holo/sub is a mount point"):
        job(old)
    monkeypatch.undo()
    assert snapshot(old) == before and hidden(old.parent) == []


def test_a_killed_runs_leftovers_are_removed_by_the_next_run(old: Path) -> None:
    parent = old.parent
    make(parent / f".holo.stage-{DEAD}-ab12", {"hologram.json": b"half"})
    make(parent / f".holo.old-{DEAD}-cd34", {"hologram.json": b"older"})
    live = parent / f".holo.stage-{os.getppid()}-ef56"  # a run still going
    live.mkdir()
    other = parent / f".other.stage-{DEAD}-ab12"  # another folder's
    other.mkdir()
    make(old, {f".preview.png.{DEAD}-k2x9_abc.part": b"half",
               f".turntable.gif.{DEAD}-q8r7s6t5.part.gif": b"half"})
    job(old)
    assert snapshot(old) == expected_new()
    assert hidden(parent) == sorted([live.name, other.name])


def test_a_folder_moved_aside_by_a_killed_run_comes_back_first(old: Path) -> None:
    """Killed between the two renames: no folder, the old one under another name."""
    parent = old.parent
    aside = parent / f".holo.old-{DEAD}-cd34"
    old.rename(aside)
    make(parent / f".holo.stage-{DEAD}-ab12", {"hologram.json": b"the new one, unpublished"})
    job(old)
    assert snapshot(old) == expected_new()  # the user's files are back, in the new folder
    assert hidden(parent) == []


def test_an_input_among_the_files_a_job_writes_is_refused(old: Path) -> None:
    before = snapshot(old)
    for model in (old / "grooves.npz", old / "verify.json"):
        with pytest.raises(SpecholoError, match="is an input of this run"):
            job(old, (model,))
    job(old, (old / "notes.txt", old / "sub" / "a.txt"))  # the user's own: carried over
    assert snapshot(old) == expected_new() != before


@pytest.mark.parametrize("setup, message", [
    (lambda out: (out / "preview.png").mkdir(), "is not a regular file"),
    (lambda out: (out / "preview.png").symlink_to(out / "notes.txt"), "is not a regular file"),
    (lambda out: (out / "hologram.json").unlink(), "not a specholo folder"),
])
def test_a_folder_that_is_not_specholos_to_replace_is_refused(
        old: Path, setup: Callable[[Path], None], message: str) -> None:
    setup(old)
    before = snapshot(old)
    with pytest.raises(SpecholoError, match=message):
        job(old)
    assert snapshot(old) == before and hidden(old.parent) == []


def test_verify_replaces_only_its_own_files(old: Path) -> None:
    want = snapshot(old)
    with publish(old, replaces={"verify.json", "verify.png"}) as stage:
        (stage / "verify.png").write_bytes(b"new")
    del want["verify.json"]
    want["verify.png"] = b"new"
    assert snapshot(old) == want


# ---------------------------------------------------------------- the commands


@pytest.fixture(scope="module")
def flat(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A tiny flat design, verified, for copying."""
    out = tmp_path_factory.mktemp("flat") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), *TINY]) == 0
    assert main(["verify", str(out), "--step", "5"]) == 0
    return out


@pytest.fixture
def design_folder(flat: Path, tmp_path: Path) -> Path:
    out = tmp_path / "holo"
    shutil.copytree(flat, out)
    return out


def test_a_steady_design_over_a_flat_ones_folder_keeps_none_of_its_files(
        design_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    make(design_folder, {"notes.txt": b"mine", "sub/a.txt": b"mine too"})
    flat_files = {p.name for p in design_folder.iterdir()} - {"notes.txt", "sub"}
    assert {"hologram.svg", "grooves.npz", "model.ply", "run.json", "verify.png"} <= flat_files
    code, _, err = run(["steady", BUNNY, "--out", design_folder, "--stipples", "8",
                        "--step", "5"], capsys)
    assert code == 0, err
    names = {p.name for p in design_folder.iterdir()}
    assert names == {"hologram.gcode", "hologram.json", "stipples.npz", "verify.json",
                     "preview.png", "run.json", "notes.txt", "sub"}
    assert json.loads((design_folder / "hologram.json").read_text())["design"] == "steady"
    assert (design_folder / "sub" / "a.txt").read_bytes() == b"mine too"
    assert hidden(design_folder.parent) == []


def test_each_kind_over_another_s_folder_leaves_only_its_own_files(
        design_folder: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    make(design_folder, {"notes.txt": b"mine", "sub/a.txt": b"mine too"})
    comp = tmp_path / "c.toml"
    comp.write_text(f'stipples = 20\n[[scene]]\nmodel = "{BUNNY}"\nsize = 30\n'
                    'center_z = -25\n')
    for argv, files in (
            (["compose", comp, "--step", "15", "--frames", "2"],
             {"hologram.json", "grooves.npz", "stipples.npz", "scene_0.ply", "hologram.gcode",
              "verify.json", "preview.png", "preview.gif", "run.json"}),
            (["spin", BUNNY, "--stipples", "20", "--step", "30", "--frames", "2"],
             {"hologram.json", "grooves.npz", "stipples.npz", "model.ply", "hologram.gcode",
              "relief.gcode", "hologram.svg", "verify.json", "preview.gif", "run.json"}),
            (["design", BUNNY, *TINY, "--formats", "gcode,dxf"],
             {"hologram.json", "grooves.npz", "stipples.npz", "model.ply", "hologram.gcode",
              "hologram.dxf", "preview.png", "run.json"})):
        code, _, err = run([*argv, "--out", design_folder], capsys)
        assert code == 0, (argv, err)
        assert {p.name for p in design_folder.iterdir()} == files | {"notes.txt", "sub"}, argv
        assert all(map(is_output, files))
        assert (design_folder / "sub" / "a.txt").read_bytes() == b"mine too"
        assert hidden(design_folder.parent) == [] and hidden(design_folder) == []


def test_a_design_over_its_own_model_is_refused(tmp_path: Path,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    import trimesh

    proj = tmp_path / "proj"
    proj.mkdir()
    trimesh.load(BUNNY).export(proj / "model.ply")
    model = (proj / "model.ply").read_bytes()
    code, _, err = run(["design", proj / "model.ply", "--out", proj, *TINY], capsys)
    refused(code, err, "model.ply is an input of this run")
    # A design folder's placed model as the model of the next design: the same.
    code, _, err = run(["design", BUNNY, "--out", proj / "holo", *TINY], capsys)
    assert code == 0, err
    placed = (proj / "holo" / "model.ply").read_bytes()
    for argv in (["design", proj / "holo" / "model.ply", "--out", proj / "holo", *TINY],
                 ["design", BUNNY, "--out", proj / "holo", "--config",
                  proj / "holo" / "hologram.json", *TINY],
                 ["steady", proj / "holo" / "model.ply", "--out", proj / "holo"],
                 ["spin", BUNNY, proj / "holo" / "model.ply", "--out", proj / "holo"]):
        code, _, err = run(argv, capsys)
        refused(code, err, "is an input of this run")
    assert (proj / "model.ply").read_bytes() == model
    assert (proj / "holo" / "model.ply").read_bytes() == placed
    assert sorted(p.name for p in proj.iterdir()) == ["holo", "model.ply"]


def test_a_composition_s_model_in_the_folder_it_writes_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    import trimesh

    trimesh.load(BUNNY).export(tmp_path / "scene_0.ply")
    make(tmp_path, {"hologram.json": b"{}"})
    comp = tmp_path / "c.toml"
    comp.write_text('stipples = 20\n[[scene]]\nmodel = "scene_0.ply"\n')
    before = snapshot(tmp_path)
    code, _, err = run(["compose", comp, "--out", tmp_path], capsys)
    refused(code, err, "scene_0.ply is an input of this run")
    assert snapshot(tmp_path) == before


def test_an_empty_out_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    for argv in (["design", BUNNY, "--out", "", *TINY], ["steady", BUNNY, "--out", ""],
                 ["spin", BUNNY, "--out", ""], ["compose", BUNNY, "--out", ""]):
        code, _, err = run(argv, capsys)
        refused(code, err, "--out is empty")
    assert list(tmp_path.iterdir()) == []


def test_a_subfolder_named_like_an_output_is_refused(design_folder: Path,
                                                     capsys: pytest.CaptureFixture[str]) -> None:
    (design_folder / "preview.png").unlink()
    (design_folder / "preview.png").mkdir()
    (design_folder / "preview.png" / "mine.txt").write_text("mine")
    before = snapshot(design_folder)
    for argv in (["design", BUNNY, "--out", design_folder, *TINY],
                 ["verify", design_folder]):
        code, _, err = run(argv, capsys)
        refused(code, err, "preview.png is not a regular file")
        assert snapshot(design_folder) == before and hidden(design_folder.parent) == []


def test_a_folder_with_output_names_and_no_hologram_json_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    make(tmp_path / "photos", {"preview.png": b"my holiday", "x.jpg": b"x"})
    before = snapshot(tmp_path)
    code, _, err = run(["design", BUNNY, "--out", tmp_path / "photos", *TINY], capsys)
    refused(code, err, "not a specholo folder", "preview.png")
    assert snapshot(tmp_path) == before


def test_out_as_the_current_folder_or_a_symlink_to_one(
        design_folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    (design_folder / "notes.txt").write_text("mine")
    before = snapshot(design_folder)
    # The folder the shell stands in is replaced whole by a design or a
    # verification: the shell would be left in a removed folder, so it is refused.
    monkeypatch.chdir(design_folder)
    code, _, err = run(["design", BUNNY, "--out", ".", *TINY, "--seed", "1"], capsys)
    refused(code, err, "the folder you are in", f"run this from {design_folder.parent}")
    code, _, err = run(["verify", "."], capsys)
    refused(code, err, "the folder you are in")
    (design_folder / "sub").mkdir()
    monkeypatch.chdir(design_folder / "sub")
    code, _, err = run(["design", BUNNY, "--out", "..", *TINY], capsys)
    refused(code, err, "the folder you are in")
    (design_folder / "sub").rmdir()
    assert snapshot(design_folder) == before
    monkeypatch.chdir(tmp_path)
    link = tmp_path / "link"
    link.symlink_to(design_folder)
    code, _, err = run(["design", BUNNY, "--out", link, *TINY], capsys)
    assert code == 0, err
    assert link.is_symlink() and (design_folder / "notes.txt").read_text() == "mine"
    assert not (design_folder / "verify.json").exists()
    assert hidden(tmp_path) == []
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    code, _, err = run(["design", BUNNY, "--out", tmp_path / "a", *TINY], capsys)
    refused(code, err, "symlink loop")


@pytest.mark.parametrize("failure, status", [
    (OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)), 1), (KeyboardInterrupt(), 130)])
def test_a_failed_verify_leaves_the_old_verification(
        design_folder: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str], failure: BaseException, status: int) -> None:
    from specholo.preview.chart import ChartDrawer

    before = snapshot(design_folder)
    assert {"verify.json", "verify.png"} <= set(before)

    def full_disk(*args: Any, **kwargs: Any) -> None:
        raise failure  # verify.json is written by then, verify.png is not

    monkeypatch.setattr(ChartDrawer, "plot_verification", full_disk)
    code, _, err = run(["verify", design_folder, "--step", "2.5"], capsys)
    assert code == status and err.count("\n") == 1, err
    assert snapshot(design_folder) == before
    assert hidden(design_folder.parent) == []


def test_a_kill_at_any_write_of_a_design_leaves_the_older_one(
        design_folder: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    from specholo.jobs.flat.folder import DesignConfig, design, write_design

    d = design(BUNNY, DesignConfig(stipples=12, seed=3))
    before = snapshot(design_folder)
    calls = []
    real = tempfile.mkstemp

    def counting(*args: Any, **kwargs: Any) -> Any:
        calls.append(1)
        return real(*args, **kwargs)

    scratch = design_folder.parent / "scratch"
    write_design(d, scratch, ("gcode", "svg", "dxf"))
    monkeypatch.setattr(tempfile, "mkstemp", counting)
    write_design(d, scratch, ("gcode", "svg", "dxf"))
    monkeypatch.undo()
    assert len(calls) >= 5
    new = snapshot(scratch)
    for k in range(len(calls)):
        monkeypatch.setattr(tempfile, "mkstemp", _raise_on_call(k, real))
        with pytest.raises(KeyboardInterrupt):
            write_design(d, design_folder, ("gcode", "svg", "dxf"))
        monkeypatch.undo()
        assert snapshot(design_folder) == before, k
        assert hidden(design_folder.parent) == [], k
    write_design(d, design_folder, ("gcode", "svg", "dxf"))
    after = snapshot(design_folder)
    assert {k: v for k, v in after.items() if k != "run.json"} == \
        {k: v for k, v in new.items() if k != "run.json"}
