"""Ordinary bad inputs end in one line and exit 1, settings are never silently
changed, and a design that can cut little or nothing of its model says so."""

from __future__ import annotations

import errno
import json
import os
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from specholo.jobs.composition.design import parse_composition
from specholo_cli import INTERRUPTED
from specholo_cli.cli import FINISHED_INTERRUPTED, main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"


def _run(argv: list[object], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    """Exit status and stderr's lines of ``specholo argv``."""
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().err.strip().splitlines()


def _refused(argv: list[object], capsys: pytest.CaptureFixture[str], *words: str) -> str:
    """Run ``argv``; it must exit 1 with one line "error: ..." holding ``words``."""
    code, err = _run(argv, capsys)
    assert code == 1 and len(err) == 1 and err[0].startswith("error: "), (code, err)
    assert "internal error" not in err[0], err
    for w in words:
        assert w in err[0], err
    return err[0]


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file in ``folder`` (scratch files included) and its bytes."""
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


@pytest.fixture(scope="module")
def design_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("design") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "20"]) == 0
    return out


@pytest.fixture
def folder(design_folder: Path, tmp_path: Path) -> Path:
    """A fresh copy of the small design, for a command to write into."""
    return Path(shutil.copytree(design_folder, tmp_path / "holo"))


# ---------------------------------------------------------------- compositions


def _composition(tmp_path: Path, top: str = "", scene: str = 'model = "bunny.obj"') -> Path:
    shutil.copy(BUNNY, tmp_path / "bunny.obj")
    comp = tmp_path / "c.toml"
    count = "" if "stipples" in top.split("[")[0] else "stipples = 10\n"  # a few, unless set
    comp.write_text(f"{count}{top}\n[[scene]]\n{scene}\nsize = 30\ncenter_z = -25\n")
    return comp


@pytest.mark.parametrize("top, scene, words", [
    ("[light]\nelevation = 0", None, ("light.elevation = 0", "(0, 180)", "plate's plane")),
    ("[light]\nelevation = 180", None, ("light.elevation = 180",)),
    ("stipples = 1.9", None, ("stipples must be a whole number, got 1.9",)),
    ("seed = 2.5", None, ("seed must be a whole number",)),
    ("[machining]\naxes = 3.5", None, ("machining.axes must be a whole number",)),
    ("", 'model = "bunny.obj"\nstipples = 1.9', ("scene 1: stipples must be a whole number",)),
    ("stipples = true", None, ("stipples must be a whole number, got True",)),
    ('mode = 1', None, ("mode must be one of",)),
    ('[tool]\nradius = "0.1"', None, ("tool.radius must be a number",)),
    ("", "frames = 3", ("frames must be a file pattern",)),
    ("", "model = 3", ("model must be a file name",)),
    ("", 'model = "bunny.obj"\nshift = [1, true, 0]', ("shift must be 3 numbers",)),
], ids=["elevation-0", "elevation-180", "stipples-1.9", "seed-2.5", "axes-3.5",
        "scene-stipples-1.9", "stipples-bool", "mode-number", "radius-string", "frames-number",
        "model-number", "shift-bool"])
def test_a_composition_setting_of_the_wrong_type_or_range_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], top: str, scene: str | None,
        words: tuple[str, ...]) -> None:
    comp = _composition(tmp_path, top, scene or 'model = "bunny.obj"')
    out = tmp_path / "out"
    _refused(["compose", comp, "--out", out, "--frames", "0"], capsys, "composition", *words)
    assert not out.exists()


def test_a_given_setting_is_kept_not_replaced_by_its_default(tmp_path: Path) -> None:
    shutil.copy(BUNNY, tmp_path / "bunny.obj")
    comp = parse_composition(
        'mode = "light"\nstipples = 3.0\nseed = 0\n[viewer]\nheight = 0\nrange = 0\n'
        '[machining]\naxes = 4.0\nspindle = 0\n'
        '[[scene]]\nmodel = "bunny.obj"\ncenter_z = 0\nturn = 0\n', tmp_path)
    assert comp.scenes[0].stipples == 3 and comp.axes == 4 and comp.seed == 0
    assert comp.motion.eye_height == 0 and comp.motion.half_range == 0
    assert comp.scenes[0].center_z == 0 and comp.machining.spindle == 0


@pytest.mark.parametrize("pattern, words", [
    ("/etc/*", ("must match files in the composition's folder",)),
    ("", ("frames must be a file pattern",)),
    ("../*.obj", ("must match files in the composition's folder",)),
    ("**x", ("cannot use frames",)),
    ("nothing_*.obj", ("no file matches",)),
], ids=["absolute", "empty", "parent", "malformed", "no-match"])
def test_a_bad_frames_pattern_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                         pattern: str, words: tuple[str, ...]) -> None:
    comp = _composition(tmp_path, scene=f"frames = {json.dumps(pattern)}")
    out = tmp_path / "out"
    _refused(["compose", comp, "--out", out], capsys, *words)
    assert not out.exists()


def test_frames_never_reach_a_file_outside_the_composition_through_a_link(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "other").mkdir()
    shutil.copy(BUNNY, tmp_path / "other" / "secret.obj")
    work = tmp_path / "work"
    work.mkdir()
    (work / "frame_00.obj").symlink_to(tmp_path / "other" / "secret.obj")
    comp = _composition(work, scene='frames = "frame_*.obj"')
    _refused(["compose", comp, "--out", work / "out"], capsys, "outside the composition's folder")
    assert not (work / "out").exists()


def test_a_npy_height_field_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    np.save(tmp_path / "h.npy", np.zeros((8, 8)))
    comp = _composition(tmp_path, '[host]\nkind = "heightfield"\nfile = "h.npy"')
    _refused(["compose", comp, "--out", tmp_path / "out"], capsys, "need an .npz")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("nested", ["[" * 5000 + "]" * 5000, "{a=" * 5000 + "1" + "}" * 5000],
                         ids=["arrays", "tables"])
def test_deeply_nested_toml_in_a_composition_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str], nested: str) -> None:
    comp = tmp_path / "c.toml"
    comp.write_text(f"x = {nested}\n")
    _refused(["compose", comp, "--out", tmp_path / "out"], capsys, "nested too deeply")
    assert not (tmp_path / "out").exists()


# ---------------------------------------------------------------- designs that cut little


def test_a_design_whose_stipples_are_mostly_hidden_warns(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A soup of random triangles: nearly every stipple is hidden from every view
    by the others (or faces away) and gets no groove."""
    rng = np.random.default_rng(0)
    n = 20_000
    corners = rng.uniform(-1.0, 1.0, (3 * n, 3))
    faces = np.arange(3 * n).reshape(-1, 3) + 1
    soup = tmp_path / "soup.obj"
    soup.write_text("".join(f"v {x:.6f} {y:.6f} {z:.6f}\n" for x, y, z in corners)
                    + "".join(f"f {a} {b} {c}\n" for a, b, c in faces))
    out = tmp_path / "out"
    code, err = _run(["design", soup, "--out", out, "--stipples", 200], capsys)
    stats = json.loads((out / "hologram.json").read_text())["stats"]
    grooved = stats["stipples_with_grooves"]
    assert code == 0 and 0 < grooved < 100, (code, err, stats)
    assert err == [f"warning: {200 - grooved} of 200 stipples are hidden from every view and "
                   "have no groove (the model hides them or they face away from every eye); "
                   "if the model file is z-up (as CAD and slicer files are), add --up z "
                   "(--rotate-x and --rotate-y turn it further)"]
    assert stats["hidden_stipples"] == 200 - grooved


def test_a_design_where_no_stipple_gets_a_groove_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One triangle facing away from the viewer: every stipple is hidden."""
    back = tmp_path / "back.obj"
    back.write_text("v 0 0 0\nv 0 1 0\nv 1 0 0\nf 1 2 3\n")
    out = tmp_path / "out"
    _refused(["design", back, "--out", out, "--stipples", 20], capsys,
             "no stipple gets a groove: 20 are hidden from every view")
    assert list(tmp_path.iterdir()) == [back]


def test_a_normal_design_gives_no_coverage_warning(design_folder: Path) -> None:
    stats = json.loads((design_folder / "hologram.json").read_text())["stats"]
    assert stats["stipples_with_grooves"] > 10
    assert stats["hidden_stipples"] + stats["stipples_with_grooves"] == 20


# ---------------------------------------------------------------- files and folders


def test_a_garbage_off_file_is_refused_in_one_line(tmp_path: Path,
                                                   capsys: pytest.CaptureFixture[str]) -> None:
    model = tmp_path / "g.off"
    model.write_bytes(b"OFF\n\xff\xfe garbage \x00\x01\n")
    line = _refused(["design", model, "--out", tmp_path / "out"], capsys, "g.off")
    assert "charset_normalizer" not in line and "No module" not in line
    assert not (tmp_path / "out").exists()


def test_an_output_folder_that_is_a_symlink_loop_is_refused(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (tmp_path / "a").symlink_to(tmp_path / "b")
    (tmp_path / "b").symlink_to(tmp_path / "a")
    _refused(["design", BUNNY, "--out", tmp_path / "a", "--stipples", 10], capsys)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a", "b"]


@pytest.mark.parametrize("command, name", [("render", "pictures.png"),
                                           ("animate", "walk.gif")])
def test_a_picture_into_an_existing_folder_is_refused_before_rendering(
        folder: Path, capsys: pytest.CaptureFixture[str], command: str, name: str) -> None:
    target = folder / name
    target.mkdir()
    before = _snapshot(folder)
    t0 = time.perf_counter()
    _refused([command, folder, "--out", target], capsys, "is a folder")
    assert time.perf_counter() - t0 < 5
    assert _snapshot(folder) == before and not any(target.iterdir())


def test_verify_cut_with_an_stl_in_a_missing_folder_is_refused_at_once(
        folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    before = _snapshot(folder)
    t0 = time.perf_counter()
    _refused(["verify", folder, "--cut", "--stl", "/nonexist/x.stl"], capsys, "/nonexist")
    assert time.perf_counter() - t0 < 5  # before the cut is simulated
    assert _snapshot(folder) == before


@pytest.mark.parametrize("argv", [["verify", "{d}"],
                                  ["render", "{d}", "--width", "32", "--height", "32"],
                                  ["view", "{d}"]], ids=["verify", "render", "view"])
def test_a_full_disk_is_one_line_and_leaves_no_file(
        folder: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch,
        argv: list[str]) -> None:
    def full(fd: int) -> None:  # the disk fills as the file is made durable
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    before = _snapshot(folder)
    monkeypatch.setattr(os, "fsync", full)
    _refused([a.format(d=folder) for a in argv], capsys, "No space left on device")
    monkeypatch.undo()
    assert _snapshot(folder) == before  # nothing new, nothing half-written, no scratch


# ---------------------------------------------------------------- Ctrl-C at the end


def _exe() -> list[str]:
    """The ``specholo`` command as installed, else its function run by this Python."""
    script = Path(sys.executable).parent / "specholo"
    if script.exists():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from specholo_cli.cli import main; "
            "sys.exit(main())"]


def test_ctrl_c_as_a_finished_run_exits_is_never_silent(design_folder: Path,
                                                        tmp_path: Path) -> None:
    """Python's own exit took tenths of a second after the last line, with Ctrl-C
    back in the system's hands: the process died by the signal without a word."""
    for delay in (0.0, 0.1, 0.3):
        out = tmp_path / f"r{delay}.png"
        proc = subprocess.Popen([*_exe(), "render", str(design_folder), "--width", "32",
                                 "--height", "32", "--out", str(out)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
        assert proc.stdout is not None
        assert "render" in proc.stdout.readline()  # the run is done
        time.sleep(delay)
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=60)
        # Ended already; or one line: the command's last moments, or its exit.
        assert (proc.returncode, err) in ((0, ""), (130, INTERRUPTED + "\n"),
                                          (130, FINISHED_INTERRUPTED + "\n")), \
            (delay, proc.returncode, err)
        assert out.is_file()


@pytest.mark.parametrize("code, status, err", [(0, 130, FINISHED_INTERRUPTED + "\n"),
                                               (1, 1, "")])
def test_ctrl_c_after_the_run_says_its_outputs_are_complete(code: int, status: int,
                                                            err: str) -> None:
    """The handler for the moment between the run's end and the process's."""
    run = subprocess.run(
        [sys.executable, "-c", "from specholo_cli import cli; "
         f"cli._RESULT[0] = {code}; cli._sigint_after_run(2, None)"],
        capture_output=True, text=True, timeout=60)
    assert (run.returncode, run.stderr) == (status, err)
