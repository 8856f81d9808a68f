"""Everything read back from a design folder, a config or a composition is checked
before it is used, and refused in one line (exit 1, "error: ...") when it cannot be.

Tampered arrays (offsets that leave the vertices, NaN coordinates, ids beyond the
stipples), truncated and empty files, object arrays, and files that are FIFOs or
links to devices: never waited on, never read without end, never handed to the
compiled kernels. End to end through ``specholo_cli.cli.main``, run in a thread
with a timeout so that a read that blocks fails the test instead of hanging it;
the safe readers themselves in ``specholo.readback``; and folders written as they
always were still read.
"""

from __future__ import annotations

import contextlib
import io
import json
import os
import shutil
import stat
import subprocess
import sys
import threading
import time
import zipfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from legacy import old_settings

from specholo import readback
from specholo.errors import SpecholoError
from specholo.readback import ArraySpec, load_arrays, read_json
from specholo.toolpaths.grooves import Grooves
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
#: Seconds a refusal may take: it comes before any real work.
TIMEOUT = 60.0

#: The commands that read a flat design folder, with small pictures.
READERS: dict[str, list[str]] = {
    "verify": ["verify", "{d}", "--step", "5"],
    "render": ["render", "{d}", "--width", "32", "--height", "32"],
    "report": ["report", "{d}"],
    "view": ["view", "{d}"],
    "stereo": ["stereo", "{d}", "--width", "16", "--height", "16"],
    "animate": ["animate", "{d}", "--frames", "2", "--width", "16", "--height", "16"],
}


def _unblock(folder: Path) -> None:
    """Give any reader waiting on a FIFO under ``folder`` its end of file."""
    for p in folder.rglob("*"):
        with contextlib.suppress(OSError):
            if stat.S_ISFIFO(p.lstat().st_mode):
                os.close(os.open(p, os.O_WRONLY | os.O_NONBLOCK))


def cli(argv: list[object], timeout: float = TIMEOUT,
        unblock: Path | None = None) -> tuple[int, str, str]:
    """Run ``specholo argv`` in a thread: exit code, stdout, stderr. A command still
    running after ``timeout`` seconds fails the test (its FIFOs are then released)."""
    out, err = io.StringIO(), io.StringIO()
    result: dict[str, int] = {}

    def run() -> None:
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            result["code"] = main([str(a) for a in argv])

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    thread.join(timeout)
    if thread.is_alive():
        if unblock is not None:
            _unblock(unblock)
        thread.join(5.0)
        pytest.fail(f"specholo {' '.join(map(str, argv))} still running after {timeout:g} s")
    return result["code"], out.getvalue(), err.getvalue()


def refused(argv: list[object], *, names: str | None = None, unblock: Path | None = None
            ) -> str:
    """Run a command that must be refused: exit 1, one line "error: ..."; returns it."""
    t0 = time.perf_counter()
    code, _, err = cli(argv, unblock=unblock)
    lines = err.strip().splitlines()
    assert code == 1, (argv, code, err)
    assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)
    assert "internal error" not in err and "Traceback" not in err, (argv, err)
    assert time.perf_counter() - t0 < TIMEOUT
    if names is not None:
        assert names in lines[0], (argv, lines[0])
    return lines[0]


def _argv(command: str, folder: Path) -> list[object]:
    return [a.format(d=folder) for a in READERS[command]]


def _copy(folder: Path, tmp_path: Path) -> Path:
    out = tmp_path / folder.name
    shutil.copytree(folder, out)
    return out


def _rewrite(path: Path, change: Callable[[dict[str, np.ndarray]], None]) -> None:
    """Rewrite an .npz with ``change`` applied to its arrays (np.savez, as a user might)."""
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    change(arrays)
    np.savez(path, **arrays)


def _fifo(path: Path) -> None:
    path.unlink(missing_ok=True)
    os.mkfifo(path)


# ---------------------------------------------------------------- designs


@pytest.fixture(scope="module")
def flat(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("flat") / "flat"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "20"]) == 0
    return out


@pytest.fixture(scope="module")
def spin(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("spin") / "spin"
    assert main(["spin", str(BUNNY), "--out", str(out), "--stipples", "20", "--frames", "0",
                 "--step", "30"]) == 0
    return out


@pytest.fixture(scope="module")
def steady(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("steady") / "steady"
    assert main(["steady", str(BUNNY), "--out", str(out), "--stipples", "20",
                 "--step", "2"]) == 0
    return out


@pytest.fixture(scope="module")
def composed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = tmp_path_factory.mktemp("composed")
    comp = work / "c.toml"
    comp.write_text(f'stipples = 8\nstep = 2\n[viewer]\nrange = 10\n[[scene]]\n'
                    f'model = "{BUNNY}"\nsize = 30\ncenter_z = -25\n')
    out = work / "composed"
    assert main(["compose", str(comp), "--out", str(out), "--step", "15",
                 "--frames", "0"]) == 0
    return out


@pytest.fixture(scope="module")
def ridged(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("ridged") / "ridged"
    assert main(["design", str(BUNNY), "--out", str(out), "--method", "ridged",
                 "--stipples", "20", "--view-range", "8", "--elevation-range", "4",
                 "--raster", "0.05", "--formats", "png"]) == 0
    return out


# ---------------------------------------------------------------- grooves.npz


def _offsets_minus_100(a: dict[str, np.ndarray]) -> None:
    a["offsets"] = a["offsets"] - 100


def _offset_1e12(a: dict[str, np.ndarray]) -> None:
    a["offsets"][5] = 10**12


def _nan_vertex(a: dict[str, np.ndarray]) -> None:
    a["vertices"][3, 0] = np.nan


# The three reproduced crashes: a glibc abort (exit 134), a segfault (139) and a
# numba TypingError of 12 lines.
REPRODUCED = {"offsets -100": _offsets_minus_100, "offset 1e12": _offset_1e12,
              "NaN vertices": _nan_vertex}


@pytest.mark.parametrize("command", sorted(READERS))
@pytest.mark.parametrize("case", sorted(REPRODUCED))
def test_tampered_grooves_are_refused_by_every_reader(flat: Path, tmp_path: Path, case: str,
                                                      command: str) -> None:
    folder = _copy(flat, tmp_path)
    _rewrite(folder / "grooves.npz", REPRODUCED[case])
    refused(_argv(command, folder), names="grooves.npz")


def _set(key: str, value: object) -> Callable[[dict[str, np.ndarray]], None]:
    def change(a: dict[str, np.ndarray]) -> None:
        a[key] = value  # type: ignore[assignment]
    return change


def _drop(key: str) -> Callable[[dict[str, np.ndarray]], None]:
    def change(a: dict[str, np.ndarray]) -> None:
        del a[key]
    return change


def _item(key: str, index: tuple[int, ...] | int, value: float) -> Callable[
        [dict[str, np.ndarray]], None]:
    def change(a: dict[str, np.ndarray]) -> None:
        a[key] = a[key].astype(float) if np.isnan(value) else a[key].copy()
        a[key][index] = value
    return change


@pytest.mark.parametrize(("change", "says"), [
    (_item("bulges", 7, np.inf), "bulges"),
    (_item("bulges", 7, 1e300), "bulges"),
    (_item("vertices", (2, 1), 1e300), "vertices"),
    (_item("stipple", 0, 20), "stipple ids"),
    (_item("stipple", 0, -1), "stipple ids"),
    (lambda a: a.update(offsets=a["offsets"][::-1].copy()), "offsets"),
    (lambda a: a.update(offsets=a["offsets"].astype(float)), "'offsets' is of dtype float64"),
    (lambda a: a.update(vertices=np.zeros((5, 3))), "'vertices' has shape (5, 3)"),
    (lambda a: a.update(bulges=a["bulges"][:-1]), "bulges"),
    (lambda a: a.update(stipple=a["stipple"][:-1]), "stipple ids"),
    (lambda a: a.update(stipple=np.array([None] * len(a["stipple"]))), "not plain numbers"),
    (_drop("bulges"), "holds no array 'bulges'"),
    (_set("vertices", np.float64(1.0)), "'vertices' has shape ()"),
], ids=["inf bulge", "huge bulge", "huge vertex", "stipple id beyond", "negative stipple id",
        "offsets reversed", "float offsets", "3D vertices", "bulges short", "ids short",
        "object ids", "no bulges", "scalar vertices"])
def test_grooves_unlike_any_design_are_refused(flat: Path, tmp_path: Path,
                                                change: Callable[[dict[str, np.ndarray]], None],
                                                says: str) -> None:
    folder = _copy(flat, tmp_path)
    _rewrite(folder / "grooves.npz", change)
    for command in ("verify", "render"):
        assert says in refused(_argv(command, folder), names="grooves.npz")


@pytest.mark.parametrize("command", sorted(READERS))
@pytest.mark.parametrize("cut", [0, 100, 0.5, -30])
def test_truncated_grooves_are_refused(flat: Path, tmp_path: Path, command: str,
                                       cut: float) -> None:
    folder = _copy(flat, tmp_path)
    path = folder / "grooves.npz"
    raw = path.read_bytes()
    path.write_bytes(raw[:int(len(raw) * cut) if isinstance(cut, float) else cut])
    refused(_argv(command, folder), names="grooves.npz")


# ---------------------------------------------------------------- stipples.npz


@pytest.mark.parametrize(("change", "says"), [
    (None, "not a readable .npz"),
    (_item("points", (4, 2), np.nan), "NaN"),
    (_item("normals", (4, 2), np.inf), "NaN or infinite"),
    (_item("points", (0, 0), 1e300), "points"),
    (lambda a: a.update(points=a["points"][:, :2].copy()), "'points' has shape (20, 2)"),
    (lambda a: a.update(normals=a["normals"][:3]), "3 normals for 20 points"),
    (lambda a: a.update(points=np.zeros((0, 3)), normals=np.zeros((0, 3))), "stipple ids"),
    (_drop("normals"), "holds no array 'normals'"),
], ids=["empty file", "NaN point", "inf normal", "huge point", "2D points", "few normals",
        "no stipples", "no normals"])
def test_bad_stipples_are_refused(flat: Path, tmp_path: Path,
                                  change: Callable[[dict[str, np.ndarray]], None] | None,
                                  says: str) -> None:
    folder = _copy(flat, tmp_path)
    path = folder / "stipples.npz"
    if change is None:
        path.write_bytes(b"")  # item 9: an empty stipples.npz ended in "internal error"
    else:
        _rewrite(path, change)
    for command in sorted(READERS):
        assert says in refused(_argv(command, folder))


# ---------------------------------------------------------------- hologram.json


@pytest.mark.parametrize("command", sorted(READERS))
@pytest.mark.parametrize("kind", ["/dev/zero", "FIFO"])
def test_hologram_json_that_never_ends_is_refused_at_once(flat: Path, tmp_path: Path,
                                                          kind: str, command: str) -> None:
    folder = _copy(flat, tmp_path)
    meta = folder / "hologram.json"
    meta.unlink()
    if kind == "FIFO":
        os.mkfifo(meta)
    else:
        meta.symlink_to("/dev/zero")
    line = refused(_argv(command, folder), names="hologram.json", unblock=folder)
    assert ("a FIFO" if kind == "FIFO" else "a device") in line


def test_a_sparse_hologram_json_beyond_the_cap_is_not_read(flat: Path, tmp_path: Path) -> None:
    folder = _copy(flat, tmp_path)
    with open(folder / "hologram.json", "r+b") as fh:
        fh.truncate(readback.MAX_JSON_BYTES + 1)  # a hole: no disk, and nothing read
    assert "more than" in refused(_argv("verify", folder), names="hologram.json")


@pytest.mark.parametrize(("edit", "says"), [
    (lambda info: [info], "must be a table"),
    (lambda info: {k: v for k, v in info.items() if k != "settings"}, "holds no settings"),
    (lambda info: {**info, "settings": {**info["settings"], "size": -5}}, "size"),
    (lambda info: {**info, "settings": {**info["settings"], "stipples": "many"}}, "stipples"),
    (lambda info: {**info, "settings": {**info["settings"], "colour": 1}}, "colour"),
    (lambda info: {**info, "settings": [1, 2]}, "settings"),
    (lambda info: {**info, "settings": {**info["settings"], "view_distance": float("nan")}},
     "view"),
], ids=["a list", "no settings", "negative size", "text stipples", "unknown setting",
        "settings a list", "NaN distance"])
def test_hologram_json_settings_are_checked(flat: Path, tmp_path: Path,
                                            edit: Callable[[dict[str, object]], object],
                                            says: str) -> None:
    folder = _copy(flat, tmp_path)
    meta = folder / "hologram.json"
    meta.write_text(json.dumps(edit(json.loads(meta.read_text()))))
    for command in ("verify", "render", "report", "view"):
        assert says in refused(_argv(command, folder), names="hologram.json")


@pytest.mark.parametrize("text", [b"", b"{", b"\xff\xfe", b"[" * 100_000, b"1" * 5000])
def test_hologram_json_that_is_not_json_is_refused(flat: Path, tmp_path: Path,
                                                   text: bytes) -> None:
    folder = _copy(flat, tmp_path)
    (folder / "hologram.json").write_bytes(text)
    for command in ("verify", "render", "report"):
        refused(_argv(command, folder))


@pytest.mark.parametrize(("edit", "says"), [
    (lambda info: {**info, "stats": {}}, "lacks 'stipples'"),
    (lambda info: {**info, "plate": {"groove_extent_mm": "wide"}}, "cannot show"),
    (lambda info: {**info, "stats": {**info["stats"], "paths": "many"}}, "cannot show"),
    (lambda info: {**info, "tool": None}, "cannot show"),
], ids=["no stats", "extent a string", "paths a string", "no tool"])
def test_report_refuses_figures_it_cannot_show(flat: Path, tmp_path: Path,
                                               edit: Callable[[dict[str, object]], object],
                                               says: str) -> None:
    folder = _copy(flat, tmp_path)
    meta = folder / "hologram.json"
    meta.write_text(json.dumps(edit(json.loads(meta.read_text()))))
    assert says in refused(_argv("report", folder))
    assert not (folder / "report.html").exists()


@pytest.mark.parametrize("verify", [
    {"summary": {}}, {"summary": 3, "azimuths": []}, {"azimuths": [{"azimuth": "left"}]},
    [1, 2], "text"])
def test_report_refuses_a_verify_json_it_cannot_show(flat: Path, tmp_path: Path,
                                                      verify: object) -> None:
    folder = _copy(flat, tmp_path)
    (folder / "verify.json").write_text(json.dumps(verify))
    refused(_argv("report", folder), names=str(folder))


def test_report_refuses_a_fifo_verify_json(flat: Path, tmp_path: Path) -> None:
    folder = _copy(flat, tmp_path)
    _fifo(folder / "verify.json")
    refused(_argv("report", folder), names="verify.json", unblock=folder)


# ---------------------------------------------------------------- other files


@pytest.mark.parametrize("name", ["grooves.npz", "stipples.npz", "model.ply"])
@pytest.mark.parametrize("command", ["verify", "render", "stereo", "animate", "view", "report"])
def test_a_fifo_or_device_in_the_folder_is_refused(flat: Path, tmp_path: Path, name: str,
                                                   command: str) -> None:
    folder = _copy(flat, tmp_path)
    _fifo(folder / name)
    refused(_argv(command, folder), names=name, unblock=folder)
    (folder / name).unlink()
    (folder / name).symlink_to("/dev/zero")
    refused(_argv(command, folder), names=name)


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero", "folder"])
def test_verify_from_gcode_refuses_a_program_that_is_not_a_file(flat: Path, tmp_path: Path,
                                                                kind: str) -> None:
    folder = _copy(flat, tmp_path)
    program = folder / "hologram.gcode"
    program.unlink()
    if kind == "FIFO":
        os.mkfifo(program)
    elif kind == "folder":
        program.mkdir()
    else:
        program.symlink_to("/dev/zero")
    refused(["verify", folder, "--from-gcode"], names="hologram.gcode", unblock=folder)


def test_verify_from_gcode_refuses_stipple_ids_beyond_the_stipples(flat: Path,
                                                                   tmp_path: Path) -> None:
    folder = _copy(flat, tmp_path)
    program = folder / "hologram.gcode"
    text = program.read_text()
    assert "(stipple 3)" in text
    program.write_text(text.replace("(stipple 3)", "(stipple 99)"))
    assert "below the 20 stipples" in refused(["verify", folder, "--from-gcode"],
                                              names="hologram.gcode")


@pytest.mark.parametrize("damage", ["faces beyond", "NaN vertex", "truncated", "garbage"])
def test_a_damaged_model_ply_is_refused(flat: Path, tmp_path: Path, damage: str) -> None:
    import trimesh

    folder = _copy(flat, tmp_path)
    path = folder / "model.ply"
    mesh = trimesh.load(path, force="mesh", process=False)
    if damage == "faces beyond":
        faces = mesh.faces.copy()
        faces[0, 0] = len(mesh.vertices) + 5
        path.write_bytes(trimesh.Trimesh(mesh.vertices, faces, process=False).export(
            file_type="ply"))
    elif damage == "NaN vertex":
        vertices = mesh.vertices.copy()
        vertices[1, 2] = np.nan
        path.write_bytes(trimesh.Trimesh(vertices, mesh.faces, process=False).export(
            file_type="ply"))
    elif damage == "truncated":
        path.write_bytes(path.read_bytes()[:len(path.read_bytes()) // 2])
    else:
        path.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99999999999\n"
                         b"property float x\nend_header\n\x00\x01")
    for command in ("verify", "render"):
        refused(_argv(command, folder), names="model.ply")


# ---------------------------------------------------------------- configs, compositions


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero", "folder"])
def test_a_config_that_is_not_a_file_is_refused(tmp_path: Path, kind: str) -> None:
    config = tmp_path / "c.toml"
    if kind == "FIFO":
        os.mkfifo(config)
    elif kind == "folder":
        config.mkdir()
    else:
        config.symlink_to("/dev/zero")
    refused(["design", BUNNY, "--out", tmp_path / "out", "--config", config, "--stipples", "5"],
            names="config file", unblock=tmp_path)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero", "folder", "sparse"])
def test_a_composition_that_is_not_a_small_file_is_refused(tmp_path: Path, kind: str) -> None:
    comp = tmp_path / "c.toml"
    if kind == "FIFO":
        os.mkfifo(comp)
    elif kind == "folder":
        comp.mkdir()
    elif kind == "sparse":
        with open(comp, "wb") as fh:
            fh.truncate(readback.MAX_TOML_BYTES + 1)
    else:
        comp.symlink_to("/dev/zero")
    refused(["compose", comp, "--out", tmp_path / "out"], names="composition", unblock=tmp_path)
    assert not (tmp_path / "out").exists()


def test_a_fifo_model_or_height_field_in_a_composition_is_refused(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "model.obj")
    os.mkfifo(tmp_path / "hf.npz")
    comp = tmp_path / "c.toml"
    comp.write_text('[[scene]]\nmodel = "model.obj"\n')
    refused(["compose", comp, "--out", tmp_path / "out"], names="model.obj", unblock=tmp_path)
    comp.write_text(f'[host]\nkind = "heightfield"\nfile = "hf.npz"\n'
                    f'[[scene]]\nmodel = "{BUNNY}"\n')
    refused(["compose", comp, "--out", tmp_path / "out"], names="hf.npz", unblock=tmp_path)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize(("arrays", "says"), [
    ({"x": np.arange(6.0), "y": np.arange(6.0)}, "holds no array 'z'"),
    ({"x": np.arange(6.0), "y": np.arange(6.0), "z": np.full((6, 6), np.nan)}, "NaN"),
    ({"x": np.arange(6.0), "y": np.arange(6.0), "z": np.zeros(36)}, "'z' has shape (36,)"),
    ({"x": np.array([None] * 6), "y": np.arange(6.0), "z": np.zeros((6, 6))},
     "not plain numbers"),
], ids=["no z", "NaN heights", "flat z", "object x"])
def test_a_bad_height_field_is_refused(tmp_path: Path, arrays: dict[str, np.ndarray],
                                       says: str) -> None:
    np.savez(tmp_path / "hf.npz", **arrays)  # type: ignore[arg-type]
    comp = tmp_path / "c.toml"
    comp.write_text(f'[host]\nkind = "heightfield"\nfile = "hf.npz"\n'
                    f'[[scene]]\nmodel = "{BUNNY}"\n')
    assert says in refused(["compose", comp, "--out", tmp_path / "out"], names="hf.npz")


# ---------------------------------------------------------------- the other folders


def test_a_turning_plate_folder_is_checked(spin: Path, tmp_path: Path) -> None:
    for name in ("hologram.json", "grooves.npz", "stipples.npz", "model.ply"):
        folder = _copy(spin, tmp_path / name)
        _fifo(folder / name)
        refused(["verify", folder], unblock=folder)
    cases: list[tuple[str, Callable[[Path], None], str]] = [
        ("side", lambda f: _rewrite(f / "stipples.npz", _item("side", 0, 5)), "disagree"),
        ("path side", lambda f: _rewrite(f / "stipples.npz",
                                         lambda a: a.update(path_side=a["path_side"][1:])),
         "disagree"),
        ("coef", lambda f: _rewrite(f / "stipples.npz", _item("coef", (0, 0), np.nan)),
         "NaN"),
        ("no coef", lambda f: _rewrite(f / "stipples.npz", _drop("coef")), "'coef'"),
        ("half the tracks", lambda f: _rewrite(
            f / "stipples.npz", lambda a: a.update(track_phi=np.zeros(4))), "disagree"),
        ("offsets", lambda f: _rewrite(f / "grooves.npz", _offsets_minus_100), "offsets"),
        ("ids", lambda f: _rewrite(f / "grooves.npz", _item("stipple", 0, 99)), "stipple ids"),
        ("turns", lambda f: _edit_settings(f, "turns", 1.5), "turns"),
        ("samples", lambda f: _edit_settings(f, "samples", "many"), "samples"),
        ("elevation", lambda f: _edit_settings(f, "view_elevation", None), "view_elevation"),
        ("unknown", lambda f: _edit_settings(f, "elevation_deg", 45.0), "elevation_deg"),
        ("tilts", lambda f: _edit_json(f, "tilts_deg", [1.0]), "tilts_deg"),
        ("tool", lambda f: _edit_settings(f, "tool_radius", -1), "radius"),
        ("no settings", lambda f: _edit_json(f, "settings", None), "settings"),
        # a folder written before the settings had the command's names
        ("old turns", lambda f: _old_config(f, "turns", 1.5), "turns"),
        ("old samples", lambda f: _old_config(f, "samples", "many", "setup"), "samples"),
        ("old elevation", lambda f: _old_config(f, "elevation_deg", None, "setup"),
         "elevation_deg"),
        ("old tool", lambda f: _old_config(f, "tool", {"radius": -1, "depth": 0.1}), "radius"),
    ]
    for label, damage, says in cases:
        folder = _copy(spin, tmp_path / label)
        damage(folder)
        assert says in refused(["verify", folder]), label


def _edit_json(folder: Path, key: str, value: object) -> None:
    meta = folder / "hologram.json"
    info = json.loads(meta.read_text())
    info[key] = value
    meta.write_text(json.dumps(info))


def _del_json(folder: Path, key: str) -> None:
    meta = folder / "hologram.json"
    info = json.loads(meta.read_text())
    del info[key]
    meta.write_text(json.dumps(info))


def _edit_settings(folder: Path, key: str, value: object) -> None:
    meta = folder / "hologram.json"
    info = json.loads(meta.read_text())
    info["settings"][key] = value
    meta.write_text(json.dumps(info))


def _old_config(folder: Path, key: str, value: object, table: str | None = None) -> None:
    """As a folder written before the settings had the command's names, one value changed."""
    info = old_settings(folder)
    (info["config"] if table is None else info["config"][table])[key] = value
    (folder / "hologram.json").write_text(json.dumps(info))


def test_a_steady_image_folder_is_checked(steady: Path, tmp_path: Path) -> None:
    for name in ("hologram.json", "stipples.npz"):
        folder = _copy(steady, tmp_path / name)
        _fifo(folder / name)
        refused(["verify", folder], unblock=folder)
    cases: list[tuple[str, Callable[[Path], None], str]] = [
        ("eye", lambda f: _rewrite(f / "stipples.npz", _item("eye", 0, 2)), "disagree"),
        ("stipple", lambda f: _rewrite(f / "stipples.npz", _item("stipple", 0, 999)),
         "disagree"),
        ("offsets", lambda f: _rewrite(f / "stipples.npz", _offsets_minus_100), "offsets"),
        ("reversed", lambda f: _rewrite(f / "stipples.npz", lambda a: a.update(
            offsets=np.concatenate([[0], a["offsets"][1:-1][::-1], a["offsets"][-1:]]))),
         "offsets decrease"),
        ("centres", lambda f: _rewrite(f / "stipples.npz", _item("centres", (0, 0), np.inf)),
         "NaN"),
        ("radius", lambda f: _rewrite(f / "stipples.npz", _item("radius", 0, np.nan)),
         "disagree"),
        ("dropped", lambda f: _rewrite(f / "stipples.npz", _set("dropped", np.zeros(3, np.int64))),
         "'dropped' has shape (3,)"),
        ("shape", lambda f: _edit_settings(f, "shape", "round"), "shape"),
        ("sweep", lambda f: _edit_settings(f, "light_sweep", "wide"), "light_sweep"),
        ("old shape", lambda f: _old_config(f, "shape", "round"), "shape"),
        ("old range", lambda f: _old_config(f, "light_sweep_deg", "wide", "setup"),
         "light_sweep_deg"),
    ]
    for label, damage, says in cases:
        folder = _copy(steady, tmp_path / label)
        damage(folder)
        assert says in refused(["verify", folder]), label


def test_a_composed_folder_is_checked(composed: Path, tmp_path: Path) -> None:
    for name in ("hologram.json", "grooves.npz", "stipples.npz"):
        folder = _copy(composed, tmp_path / name)
        _fifo(folder / name)
        refused(["verify", folder], unblock=folder)
    cases: list[tuple[str, Callable[[Path], None], str]] = [
        ("ids", lambda f: _rewrite(f / "grooves.npz", _item("stipple", 0, 8)), "ids"),
        ("family", lambda f: _rewrite(f / "grooves.npz", _item("family", 0, 7)), "ids"),
        ("NaN", lambda f: _rewrite(f / "grooves.npz", _item("point", (0, 1), np.nan)), "NaN"),
        ("short", lambda f: _rewrite(f / "grooves.npz",
                                     lambda a: a.update(state=a["state"][1:])), "lengths"),
        ("text", lambda f: _edit_json(f, "settings", {"text": 5, "base": "."}), "strings"),
        ("bad text", lambda f: _edit_json(f, "settings", {"text": "x = [", "base": "."}),
         "TOML"),
        # a folder written before every kind's settings were "settings"
        ("old text", lambda f: (_edit_json(f, "settings", None), _del_json(f, "settings"),
                                _edit_json(f, "composition", {"text": 5, "base": "."})),
         "strings"),
        ("truncated", lambda f: (f / "stipples.npz").write_bytes(b"PK\x03\x04"), "npz"),
    ]
    for label, damage, says in cases:
        folder = _copy(composed, tmp_path / label)
        damage(folder)
        assert says in refused(["verify", folder]), label


def test_a_ridged_folder_is_checked(ridged: Path, tmp_path: Path) -> None:
    for name in ("plate.npz", "stipples.npz", "hologram.json", "model.ply"):
        folder = _copy(ridged, tmp_path / name)
        _fifo(folder / name)
        for command in ("verify", "render", "view"):
            refused(_argv(command, folder), unblock=folder)
    cases: list[tuple[str, Callable[[Path], None], str]] = [
        ("labels", lambda f: _rewrite(f / "plate.npz", _item("labels", (5, 5), 20)),
         "does not match"),
        ("labels below", lambda f: _rewrite(f / "plate.npz", _item("labels", (5, 5), -7)),
         "does not match"),
        ("raster", lambda f: _rewrite(f / "plate.npz", _set("resolution", np.float64(1e-300))),
         "raster"),
        ("heights", lambda f: _rewrite(f / "plate.npz", _item("z", (3, 3), np.nan)), "NaN"),
        ("origin", lambda f: _rewrite(f / "plate.npz", _set("origin", np.zeros(3))),
         "'origin' has shape (3,)"),
        ("labels shape", lambda f: _rewrite(f / "plate.npz", _set("labels", np.zeros(
            (2, 2), np.int32))), "labels"),
    ]
    for label, damage, says in cases:
        folder = _copy(ridged, tmp_path / label)
        damage(folder)
        for command in ("verify", "render"):
            assert says in refused(_argv(command, folder), names="plate.npz"), label


# ---------------------------------------------------------------- folders as written


def test_folders_as_written_are_read(flat: Path, spin: Path, steady: Path, composed: Path,
                                     ridged: Path, tmp_path: Path) -> None:
    for folder in (flat, spin, steady, composed, ridged):
        folder = _copy(folder, tmp_path / folder.name)
        code, _, err = cli(["verify", folder, "--step", "5"])
        assert code == 0, (folder, err)
    flat = tmp_path / "flat" / "flat"
    for command in ("render", "report", "stereo", "view"):
        code, _, err = cli(_argv(command, flat))
        assert code == 0, (command, err)
    assert cli(["verify", flat, "--from-gcode", "--step", "5"])[0] == 0


def test_grooves_saved_by_savez_compressed_load_alike(flat: Path, tmp_path: Path) -> None:
    """Turning-plate designs write grooves with np.savez_compressed: the same arrays."""
    g = Grooves.load(flat / "grooves.npz")
    path = tmp_path / "g.npz"
    np.savez_compressed(path, vertices=g.vertices, bulges=g.bulges, offsets=g.offsets,
                        stipple=g.stipple)
    h = Grooves.load(path, stipples=20)
    for a, b in ((g.vertices, h.vertices), (g.bulges, h.bulges), (g.offsets, h.offsets),
                 (g.stipple, h.stipple)):
        np.testing.assert_array_equal(a, b)
        assert b.dtype == a.dtype and b.flags.c_contiguous and b.flags.writeable


# ---------------------------------------------------------------- the readers


def test_read_json_refuses_what_is_not_a_small_regular_file(tmp_path: Path) -> None:
    os.mkfifo(tmp_path / "fifo.json")
    (tmp_path / "zero.json").symlink_to("/dev/zero")
    (tmp_path / "big.json").write_text("[" + "1," * 100 + "1]")
    for path, says in ((tmp_path / "fifo.json", "a FIFO"), (tmp_path / "zero.json", "a device"),
                       (tmp_path, "a folder"), (tmp_path / "missing.json", "No such file"),
                       (tmp_path / "big.json", "more than")):
        with pytest.raises(SpecholoError, match=says):
            read_json(path, max_bytes=100)
    assert read_json(tmp_path / "big.json") == [1] * 101


def test_open_regular_refuses_a_fifo_swapped_in_after_the_stat(tmp_path: Path,
                                                               monkeypatch) -> None:
    """The stat says a regular file; by the open a FIFO stands there: it opens without
    waiting for a writer (O_NONBLOCK) and fstat refuses it."""
    fifo = tmp_path / "swapped"
    os.mkfifo(fifo)
    real_stat = os.stat

    def stale_stat(path, *args, **kwargs):  # type: ignore[no-untyped-def]
        if Path(path) == fifo:
            return real_stat(__file__)
        return real_stat(path, *args, **kwargs)

    monkeypatch.setattr(readback.os, "stat", stale_stat)
    t0 = time.perf_counter()
    with pytest.raises(SpecholoError, match="a FIFO"):
        readback.read_bytes(fifo, 1000)
    assert time.perf_counter() - t0 < 5


def _npy(shape: tuple[int, ...], dtype: str, data: bytes, fortran: bool = False) -> bytes:
    """An .npy member: a version 1.0 header declaring ``shape``, then ``data``."""
    buf = io.BytesIO()
    np.lib.format.write_array_header_1_0(
        buf, {"descr": dtype, "fortran_order": fortran, "shape": shape})
    return buf.getvalue() + data


def test_load_arrays_checks_every_header_before_loading(tmp_path: Path) -> None:
    spec = {"a": ArraySpec((None, 2)), "b": ArraySpec((None,), np.int64)}
    path = tmp_path / "x.npz"

    def write(members: dict[str, bytes]) -> None:
        with zipfile.ZipFile(path, "w") as zf:
            for k, v in members.items():
                zf.writestr(f"{k}.npy", v)

    good_b = _npy((3,), "<i8", np.arange(3).tobytes())
    # 10^12 rows declared over 32 bytes: refused from the header, nothing allocated
    write({"a": _npy((10**12, 2), "<f8", bytes(32)), "b": good_b})
    with pytest.raises(SpecholoError, match="declares 16000000000000 bytes of data but holds 32"):
        load_arrays(path, spec)
    write({"a": _npy((2, 2), "<f8", bytes(32)), "b": _npy((3,), "<f8", bytes(24))})
    with pytest.raises(SpecholoError, match="'b' is of dtype float64, expected int64"):
        load_arrays(path, spec)
    write({"a": _npy((2, 2), "<f8", bytes(32)), "b": _npy((3,), "<c16", bytes(48))})
    with pytest.raises(SpecholoError, match="'b' is of dtype complex128"):
        load_arrays(path, spec)
    write({"a": _npy((2, 2), "<f8", bytes(32)), "b": b"\x93NUMPY\x01\x00\x05\x00{'de"})
    with pytest.raises(SpecholoError, match="not a readable .npz"):
        load_arrays(path, spec)
    # a member declaring less than it holds
    write({"a": _npy((2, 2), "<f8", bytes(40)), "b": good_b})
    with pytest.raises(SpecholoError, match="declares 32 bytes of data but holds 40"):
        load_arrays(path, spec)
    write({"a": _npy((2, 2), "<f8", bytes(32)), "b": good_b})
    with pytest.raises(SpecholoError, match="more than"):
        load_arrays(path, spec, max_bytes=100)
    out = load_arrays(path, spec)
    assert out["a"].shape == (2, 2) and out["b"].tolist() == [0, 1, 2]


def test_load_arrays_never_unpickles(tmp_path: Path) -> None:
    marker = tmp_path / "unpickled"
    path = tmp_path / "x.npz"
    np.savez(path, a=np.array([_Planted(str(marker))], dtype=object))
    with pytest.raises(SpecholoError, match="not plain numbers"):
        load_arrays(path, {"a": ArraySpec((None,))})
    assert not marker.exists()


class _Planted:
    """Unpickling one would write a file."""

    def __init__(self, path: str) -> None:
        self.path = path

    def __reduce__(self):  # type: ignore[no-untyped-def]
        return (Path(self.path).write_text, ("x",))


def test_load_arrays_converts_other_layouts(tmp_path: Path) -> None:
    path = tmp_path / "x.npz"
    a = np.asfortranarray(np.arange(6.0).reshape(3, 2)).astype(">f8")
    np.savez(path, a=a, b=np.arange(3, dtype=np.int16), c=np.array([1.0, np.nan]),
             d=np.array(7, dtype=np.uint64))
    out = load_arrays(path, {"a": ArraySpec((3, 2)), "b": ArraySpec((None,), np.int64),
                             "c": ArraySpec((2,)), "d": ArraySpec((), np.int64),
                             "e": ArraySpec((None,), optional=True)})
    np.testing.assert_array_equal(out["a"], np.arange(6.0).reshape(3, 2))
    assert out["a"].dtype == np.float64 and out["a"].flags.c_contiguous
    assert out["b"].dtype == np.int64 and out["d"].shape == () and int(out["d"]) == 7
    assert "e" not in out
    with pytest.raises(SpecholoError, match="'c' holds NaN"):
        load_arrays(path, {"c": ArraySpec((2,), finite=True)})
    np.savez(path, d=np.array([2**64 - 1], dtype=np.uint64))
    with pytest.raises(SpecholoError, match="beyond int64"):
        load_arrays(path, {"d": ArraySpec((1,), np.int64)})
    with pytest.raises(SpecholoError, match="expected \\(n, 2\\)"):
        load_arrays(path, {"d": ArraySpec((None, 2), np.int64)})


# ---------------------------------------------------------------- a fresh process


def test_the_console_script_refuses_a_fifo_at_once(flat: Path, tmp_path: Path) -> None:
    """In a process of its own, with nothing to release the FIFO: one line, exit 1."""
    folder = _copy(flat, tmp_path)
    _fifo(folder / "hologram.json")
    exe = shutil.which("specholo") or str(Path(sys.executable).parent / "specholo")
    if not Path(exe).exists():
        pytest.skip("console script not installed")
    try:
        r = subprocess.run([exe, "render", str(folder)], capture_output=True, text=True,
                           timeout=120)
    finally:
        _unblock(folder)
    assert r.returncode == 1
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("error: "), r.stderr
    assert "FIFO" in r.stderr


@pytest.mark.parametrize("kind", ["FIFO", "/dev/zero"])
def test_check_refuses_a_program_that_is_not_a_file(tmp_path: Path, kind: str) -> None:
    program = tmp_path / "prog.ngc"
    if kind == "FIFO":
        os.mkfifo(program)
    else:
        program.symlink_to("/dev/zero")
    refused(["check", program, "--plate-width", "50", "--plate-height", "50",
             "--max-depth", "0.1"], names="prog.ngc", unblock=tmp_path)
