"""One path from a design to its folder: every program in it read back by its check."""

from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

import pytest
from test_check import MACHINING, TOOL, hop_limits
from test_gcode import hopping_example

from specholo.errors import SpecholoError
from specholo.fabrication.programs.gcode import write_gcode
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
            stage_design(out, kind="flat") as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING)
        stage.check("hologram.gcode", hop_limits())
        write_gcode(stage.path / "relief.gcode", hopping_example(), TOOL, MACHINING)
        (stage.path / "hologram.json").write_text('{"design": "new"}')
    assert sorted(p.name for p in out.iterdir()) == ["hologram.json", "notes.txt"]
    assert (out / "hologram.json").read_text() == '{"design": "old"}'
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".holo")]


def test_checked_programs_are_published_and_unsafe_ones_are_not(tmp_path: Path) -> None:
    out = _old_folder(tmp_path)
    with stage_design(out, kind="flat") as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING,
                    header=hop_limits().header())
        report = stage.check("hologram.gcode")  # the limits in its own header
        (stage.path / "hologram.json").write_text('{"design": "new"}')
    assert report.ok and report.moves["G1"] == 7
    assert sorted(p.name for p in out.iterdir()) == ["hologram.gcode", "hologram.json",
                                                     "notes.txt", "run.json"]
    run = json.loads((out / "run.json").read_text())  # the file every kind shares
    assert run["kind"] == "flat" and run["software"]["specholo"] and run["seconds"]["writing"] >= 0
    # deeper than its limits allow: refused, the folder as it was
    before = (out / "hologram.gcode").read_bytes()
    with pytest.raises(SpecholoError, match="failed its safety check"), \
            stage_design(out, kind="flat") as stage:
        write_gcode(stage.path / "hologram.gcode", hopping_example(), TOOL, MACHINING)
        shallow = TOOL.depth / 2
        stage.check("hologram.gcode", dataclasses.replace(hop_limits(), max_depth=shallow,
                                                          groove_depth=shallow))
    assert (out / "hologram.gcode").read_bytes() == before
    # no limits given and none in the header: refused, not waved through
    with pytest.raises(SpecholoError, match="names no limits"), \
            stage_design(out, kind="flat") as stage:
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


def test_every_kind_writes_one_verify_schema(tmp_path: Path) -> None:
    """verify.json of any kind names the same figures under the same names, and a
    file written before the shared schema still gives them."""
    import json

    from specholo.folder import VERIFY_SCHEMA, read_verify_figures, write_verify_json

    flat = {"worst_p95_error": 0.157, "min_visibility": 0.98, "max_false_glints": 0.0}
    spin = {"worst_p95_mm": 0.31, "lowest_visibility": 0.9, "stray": 2}
    rows = [{"azimuth": -5.0}, {"azimuth": 0.0}, {"azimuth": 5.0}]
    for kind, summary, key in (("flat", flat, "azimuths"), ("spin", spin, "angles")):
        write_verify_json(tmp_path, kind, 5.0, summary, key, rows, {"source": "x"})
        record = json.loads((tmp_path / "verify.json").read_text())
        assert record["schema"] == VERIFY_SCHEMA and record["kind"] == kind
        assert record["rows"] == key and record[key] == rows and record["summary"] == summary
        worst = summary.get("worst_p95_error", summary.get("worst_p95_mm"))
        lowest = summary.get("min_visibility", summary.get("lowest_visibility"))
        assert record["figures"] == {"worst_p95_mm": worst, "lowest_visibility": lowest,
                                     "positions": 3}
        assert read_verify_figures(tmp_path / "verify.json") == record["figures"]
        # as written before the shared keys: the same figures
        (tmp_path / "old.json").write_text(json.dumps({"summary": summary, key: rows}))
        assert read_verify_figures(tmp_path / "old.json") == record["figures"]
    (tmp_path / "bad.json").write_text("[1]")
    with pytest.raises(SpecholoError, match="not a verification"):
        read_verify_figures(tmp_path / "bad.json")


def test_the_run_record_names_the_installed_versions() -> None:
    """Read from the .dist-info folders, the versions are importlib.metadata's."""
    from importlib import metadata

    from specholo.staging import software_versions

    versions = software_versions()
    for name in ("numpy", "numba", "trimesh", "matplotlib"):
        assert versions[name] == metadata.version(name)
