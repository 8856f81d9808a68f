"""One path from a design to its folder: every program in it read back by its check."""

from __future__ import annotations

import ast
import dataclasses
from pathlib import Path

import pytest
from test_check import MACHINING, TOOL, hop_limits
from test_gcode import hopping_example

from specholo.errors import SpecholoError
from specholo.fabrication.gcode import write_gcode
from specholo.staging import stage_design

SRC = Path(__file__).resolve().parents[1] / "src" / "specholo"


def _old_folder(tmp_path: Path) -> Path:
    out = tmp_path / "holo"
    out.mkdir()
    (out / "hologram.json").write_text('{"design": "old"}')
    (out / "notes.txt").write_text("mine")
    return out


def test_a_program_nobody_checked_publishes_nothing(tmp_path: Path) -> None:
    out = _old_folder(tmp_path)
    with pytest.raises(SpecholoError, match="relief.gcode was written but not read back"), \
            stage_design(out) as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING)
        stage.check("hologram.gcode", hop_limits())
        write_gcode(stage.path / "relief.gcode", hopping_example(), TOOL, MACHINING)
        (stage.path / "hologram.json").write_text('{"design": "new"}')
    assert sorted(p.name for p in out.iterdir()) == ["hologram.json", "notes.txt"]
    assert (out / "hologram.json").read_text() == '{"design": "old"}'
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".holo")]


def test_checked_programs_are_published_and_unsafe_ones_are_not(tmp_path: Path) -> None:
    out = _old_folder(tmp_path)
    with stage_design(out) as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING,
                    header=hop_limits().header())
        report = stage.check("hologram.gcode")  # the limits in its own header
        (stage.path / "hologram.json").write_text('{"design": "new"}')
    assert report.ok and report.moves["G1"] == 7
    assert sorted(p.name for p in out.iterdir()) == ["hologram.gcode", "hologram.json",
                                                     "notes.txt"]
    # deeper than its limits allow: refused, the folder as it was
    before = (out / "hologram.gcode").read_bytes()
    with pytest.raises(SpecholoError, match="failed its safety check"), \
            stage_design(out) as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING)
        shallow = TOOL.depth / 2
        stage.check("hologram.gcode", dataclasses.replace(hop_limits(), max_depth=shallow,
                                                          groove_depth=shallow))
    assert (out / "hologram.gcode").read_bytes() == before
    # no limits given and none in the header: refused, not waved through
    with pytest.raises(SpecholoError, match="names no limits"), stage_design(out) as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING)
        stage.check("hologram.gcode")


def test_every_design_folder_is_written_through_the_stage() -> None:
    """Only the staging module and the verification's publisher call publish():
    a job that wrote its folder by itself could skip the programs' check."""
    callers = set()
    for f in SRC.rglob("*.py"):
        for node in ast.walk(ast.parse(f.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "id", None) == "publish":
                callers.add(f.relative_to(SRC).as_posix())
    assert callers == {"staging.py", "jobs/base.py"}
