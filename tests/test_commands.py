"""Every command, run from one table: each ends with status 0, writes what it
says, and prints no traceback. A command missing from the table fails here."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from specholo.errors import SpecholoError
from specholo_cli.app import cli
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"

#: command -> (arguments, files it writes in {out}, or text it prints).
#: {design} is a written design, {out} a new folder.
COMMANDS: dict[str, tuple[list[str], list[str]]] = {
    "design": ([str(BUNNY), "--out", "{out}", "--stipples", "40", "--formats",
                "gcode,svg,dxf,pdf"],
               ["hologram.gcode", "hologram.svg", "hologram.dxf", "pattern.pdf",
                "preview.png", "hologram.json"]),
    "verify": (["{design}", "--step", "5"], ["verify.json", "verify.png"]),
    "check": (["{design}/hologram.gcode"], ["against the limits in its header"]),
    "render": (["{design}", "--width", "64", "--height", "48"], ["render.png"]),
    "animate": (["{design}", "--frames", "2", "--width", "48", "--height", "48"],
                ["turntable.gif"]),
    "stereo": (["{design}", "--width", "48", "--height", "48"], ["stereo.png"]),
    "report": (["{design}"], ["report.html"]),
    "view": (["{design}"], ["view.html"]),
    "compose": (["{toml}", "--out", "{out}", "--frames", "0", "--step", "15"],
                ["hologram.gcode", "verify.json", "preview.png"]),
    "spin": ([str(BUNNY), "--out", "{out}", "--stipples", "30", "--frames", "0",
              "--step", "30"], ["hologram.gcode", "verify.json", "hologram.svg"]),
    "steady": ([str(BUNNY), "--out", "{out}", "--stipples", "12", "--step", "2"],
               ["hologram.gcode", "verify.json", "preview.png"]),
    "studio": (["--help"], ["127.0.0.1"]),
    # probe and level need a rigid holder's design and a probe log: run end to
    # end in tests/test_holders.py; here their help.
    "probe": (["--help"], ["G38.2 grid"]),
    "level": (["--help"], ["probed under it"]),
    "coupon": (["--out", "{out}", "--rungs", "3", "--stipples", "3"],
               ["coupon.json", "sheet.pdf", "hologram.gcode", "hologram.svg"]),
}

COMPOSITION = f"""
mode = "walk"
stipples = 30
[host]
kind = "plane"
[light]
elevation = 45
[viewer]
distance = 600
range = 30
[tool]
radius = 0.05
depth = 0.02
[[scene]]
model = "{BUNNY.as_posix()}"
size = 30
center_z = -20
"""


def test_the_table_has_every_command() -> None:
    assert set(COMMANDS) == set(cli.commands)


@pytest.fixture(scope="module")
def design(small_design: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("commands") / "design"
    shutil.copytree(small_design, folder)
    return folder


@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_runs(command: str, design: Path, tmp_path: Path, capsys) -> None:
    toml = tmp_path / "scene.toml"
    toml.write_text(COMPOSITION)
    out = tmp_path / "out"
    args, expected = COMMANDS[command]
    argv = [command, *(a.format(design=design, out=out, toml=toml) for a in args)]
    code = main(argv)
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "Traceback" not in printed.out + printed.err
    where = out if "{out}" in args else design
    if "{out}" in args:  # a design: every file it wrote is one its kind names
        from specholo.folders import is_output
        from specholo.jobs import job_of

        job = job_of(out)
        written = {p.name for p in out.iterdir()}
        assert all(map(is_output, written))
        assert {n for n in written if not n.startswith("scene_")} <= job.files
        # its main file opens with the header, naming the kind its run.json names
        import json

        from specholo.folder import HOLOGRAM_SCHEMA

        main_file = out / ("coupon.json" if job.kind == "coupon" else "hologram.json")
        head = json.loads(main_file.read_text())
        assert (head["kind"], head["schema"]) == (job.kind, HOLOGRAM_SCHEMA)
        assert json.loads((out / "run.json").read_text())["kind"] == job.kind
    for item in expected:
        if "." in item and " " not in item and not item.startswith("127"):
            assert (where / item).is_file(), f"{command} did not write {item}"
        else:
            assert item in printed.out + printed.err


@pytest.mark.parametrize("command", ["design", "compose", "steady"])
def test_each_kind_draws_its_preview_again_from_its_folder(command: str, design: Path,
                                                            tmp_path: Path) -> None:
    """A job loads the folder it wrote and draws the same preview from it, byte
    for byte: the folder holds everything its picture needs."""
    from specholo.jobs import job_of
    from specholo.jobs.base import publish_files, quiet

    toml = tmp_path / "scene.toml"
    toml.write_text(COMPOSITION)
    out = tmp_path / "out"
    args, _ = COMMANDS[command]
    assert main([command, *(a.format(design=design, out=out, toml=toml) for a in args)]) == 0
    job = job_of(out)
    assert job.kind == {"design": "flat", "compose": "composition"}.get(command, command)
    job.load(out)
    files = job.preview(out, quiet)
    before = {name: (out / name).read_bytes() for name in files if (out / name).is_file()}
    assert "preview.png" in before
    again = tmp_path / "again"
    again.mkdir()
    for write in files.values():
        write(again)
    for name, data in before.items():
        assert (again / name).read_bytes() == data, name
    publish_files(out, {"preview.png": files["preview.png"]})  # published whole, the same
    assert (out / "preview.png").read_bytes() == before["preview.png"]
    with pytest.raises(SpecholoError, match="published with its design"):
        publish_files(out, {"hologram.gcode": lambda into: None})
