"""The command line end to end: the main job, verification, and bad input."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"
FAST = ["--stipples", "300", "--view-range", "45"]


def run(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def designed(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("holo") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), *FAST]) == 0
    return out


def test_design_writes_every_output(designed: Path):
    names = {p.name for p in designed.iterdir()}
    assert {"hologram.gcode", "hologram.svg", "hologram.json", "preview.png",
            "grooves.npz", "stipples.npz", "model.ply"} <= names
    assert not [n for n in names if n.endswith(".part") or n.startswith(".")]
    info = json.loads((designed / "hologram.json").read_text())
    assert info["settings"]["method"] == "striped"
    assert len(info["stipples"]) == 300
    s = info["stipples"][0]
    assert {"id", "x", "y", "z", "visible_deg"} <= set(s)
    # The model was placed as asked: largest side 60 mm, centre at z = -40.
    zs = [st["z"] for st in info["stipples"]]
    assert -71 < min(zs) and max(zs) < -9


def test_gcode_names_the_stipple_before_every_path(designed: Path):
    lines = (designed / "hologram.gcode").read_text().splitlines()
    plunges = [i for i, line in enumerate(lines) if re.match(r"G1 Z-", line)]
    assert plunges
    for i in plunges:
        before = lines[i - 2]
        assert re.fullmatch(r"\(stipple \d+\)", before), before


def test_verify_meets_the_striped_targets(designed: Path, capsys):
    code, out, _ = run(["verify", designed], capsys)
    assert code == 0
    assert "worst p95 error" in out
    report = json.loads((designed / "verify.json").read_text())
    rows = report["azimuths"]
    assert len(rows) >= 19  # steps of at most 5 degrees over +-45
    assert max(r["p95_error"] for r in rows) <= 0.3
    assert min(r["visibility"] for r in rows) >= 0.97
    assert max(r["false_glints"] for r in rows) <= 0.01
    assert (designed / "verify.png").stat().st_size > 1000


def test_verify_from_gcode_agrees(designed: Path, capsys):
    code, _, _ = run(["verify", designed, "--from-gcode"], capsys)
    assert code == 0
    report = json.loads((designed / "verify.json").read_text())
    assert report["source"] == "hologram.gcode"
    assert max(r["p95_error"] for r in report["azimuths"]) <= 0.3


def test_classic_arc_drifts_off_axis(tmp_path: Path, capsys):
    out = tmp_path / "arc"
    assert main(["design", str(BUNNY), "--out", str(out), "--method", "arc", *FAST]) == 0
    run(["verify", out], capsys)
    rows = json.loads((out / "verify.json").read_text())["azimuths"]
    centre = min(rows, key=lambda r: abs(r["azimuth"]))
    edge = max(rows, key=lambda r: abs(r["azimuth"]))
    assert edge["p95_error"] > 10 * centre["p95_error"]


def test_config_file_supplies_options(tmp_path: Path, capsys):
    cfg = tmp_path / "c.toml"
    cfg.write_text('stipples = 50\nmethod = "hyperbola"\nlight-elevation = 40.0\n')
    out = tmp_path / "o"
    code, _, err = run(["design", BUNNY, "--out", out, "--config", cfg], capsys)
    assert code == 0, err
    info = json.loads((out / "hologram.json").read_text())
    assert info["settings"]["method"] == "hyperbola"
    assert info["settings"]["light_elevation"] == 40.0
    assert len(info["stipples"]) == 50


def test_model_straddling_the_plate(tmp_path: Path, capsys):
    out = tmp_path / "o"
    code, _, err = run(["design", BUNNY, "--out", out, "--center-z", "0", "--stipples", "200"],
                       capsys)
    assert code == 0, err
    code, _, _ = run(["verify", out], capsys)
    rows = json.loads((out / "verify.json").read_text())["azimuths"]
    assert max(r["p95_error"] for r in rows) <= 0.3


@pytest.mark.parametrize("extra", [
    ["--light-distance", "500"],  # a point light
    ["--eye-height", "120", "--view-distance", "450"],
    ["--light-elevation", "30", "--view-range", "30"],
])
def test_other_setups_verify(tmp_path: Path, capsys, extra: list[str]):
    out = tmp_path / "o"
    code, _, err = run(["design", BUNNY, "--out", out, "--stipples", "150", *extra], capsys)
    assert code == 0, err
    code, _, _ = run(["verify", out], capsys)
    rows = json.loads((out / "verify.json").read_text())["azimuths"]
    assert max(r["p95_error"] for r in rows) <= 0.3
    assert min(r["visibility"] for r in rows) >= 0.95


def test_point_cloud_and_a_fresh_design_replaces_old_results(tmp_path: Path, capsys):
    import numpy as np
    import trimesh

    cloud = tmp_path / "bunny.xyz"
    np.savetxt(cloud, trimesh.load(BUNNY).sample(5000, seed=1))
    out = tmp_path / "o"
    assert run(["design", cloud, "--out", out, "--stipples", "100"], capsys)[0] == 0
    assert run(["verify", out], capsys)[0] == 0
    rows = json.loads((out / "verify.json").read_text())["azimuths"]
    assert max(r["p95_error"] for r in rows) <= 0.3
    assert not (out / "model.ply").exists()  # nothing to hide a cloud's points
    # Designing again into the folder drops the old verification, and a cloud
    # after a mesh drops the mesh that would otherwise hide its points.
    assert run(["design", BUNNY, "--out", out, "--stipples", "50"], capsys)[0] == 0
    assert not (out / "verify.json").exists()
    assert (out / "model.ply").exists()
    assert run(["design", cloud, "--out", out, "--stipples", "50"], capsys)[0] == 0
    assert not (out / "model.ply").exists()


def _bad_inputs(tmp_path: Path) -> list[list[str]]:
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    corrupt = tmp_path / "corrupt.stl"
    corrupt.write_bytes(b"solid x\nfacet normal garbage\n\x00\x01")
    nan = tmp_path / "nan.obj"
    nan.write_text("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n")
    toml = tmp_path / "bad.toml"
    toml.write_text("stipples = 'many'\n")
    unknown = tmp_path / "unknown.toml"
    unknown.write_text("colour = 3\n")
    m = str(BUNNY)
    return [
        ["design", str(tmp_path / "missing.obj")],
        ["design", str(empty)],
        ["design", str(corrupt)],
        ["design", str(nan)],
        ["design", m, "--light-elevation", "-10"],
        ["design", m, "--light-elevation", "nan"],
        ["design", m, "--light-distance", "-5"],
        ["design", m, "--view-range", "90"],
        ["design", m, "--view-distance", "-600"],
        ["design", m, "--stipples", "-5"],
        ["design", m, "--stipples", "0"],
        ["design", m, "--size", "0"],
        ["design", m, "--band", "-1"],
        ["design", m, "--depth", "2"],
        ["design", m, "--center-z", "700"],
        ["design", m, "--frobnicate", "3"],
        ["design", m, "--config", str(toml)],
        ["design", m, "--config", str(unknown)],
        ["design", m, "--method", "spiral"],
        ["design", m, "--visibility", "1.5"],
        ["design", m, "--visibility", "0.8", "--spacing", "2"],
        ["design", m, "--visibility", "0.8", "--method", "ridged"],
        ["verify", str(tmp_path)],
    ]


def test_bad_input_one_line_error_and_no_output(tmp_path: Path, capsys):
    for argv in _bad_inputs(tmp_path):
        out = tmp_path / "out"
        full = argv + ["--out", str(out)] if argv[0] == "design" else argv
        code, stdout, err = run(full, capsys)
        assert code != 0, argv
        lines = err.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)
        assert "Traceback" not in err
        assert not out.exists(), argv
        leftovers = [p for p in tmp_path.iterdir() if p.name.startswith(".out")]
        assert not leftovers, argv


def test_failed_run_leaves_existing_output_untouched(tmp_path: Path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "hologram.gcode").write_text("old")
    code, _, _ = run(["design", BUNNY, "--out", out, "--stipples", "-1"], capsys)
    assert code != 0
    assert (out / "hologram.gcode").read_text() == "old"


@pytest.mark.skipif(shutil.which("specholo") is None and not
                    (Path(sys.executable).parent / "specholo").exists(),
                    reason="console script not installed")
def test_console_script_exit_code(tmp_path: Path):
    exe = shutil.which("specholo") or str(Path(sys.executable).parent / "specholo")
    r = subprocess.run([exe, "design", str(tmp_path / "nope.obj"), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert r.returncode != 0
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("error: ")


@pytest.mark.skipif(not Path("/usr/bin/rs274").exists(),
                    reason="LinuxCNC's interpreter /usr/bin/rs274 is missing")
def test_designed_gcode_runs_in_linuxcnc(designed: Path):
    from test_gcode import check_canon, run_rs274

    from specholo.jobs.flat.folder import load_design

    loaded = load_design(designed)
    canon = run_rs274(designed / "hologram.gcode")
    setup = loaded.config.setup()
    # The interpreter cuts the grooves that verification checked: same arcs,
    # centres, directions, depths, rapids and feeds (at the design's depth,
    # which goes on past the tip's sphere, where the round model stops).
    from specholo.setup import Tool

    # The drag tip's spring holder cuts at its preload and hops at its lift
    # (Holder.program); check_canon reads only the tool's depth.
    holder = loaded.config.holder_setup()
    assert holder is not None and holder.spring
    depth, machining = holder.program(loaded.config.depth_mm, setup.machining)
    cut = Tool(max(setup.tool.radius, depth), depth)
    check_canon(canon, loaded.grooves, cut, machining)


def test_spacing_option(tmp_path: Path, capsys):
    out = tmp_path / "o"
    code, _, err = run(["design", BUNNY, "--out", out, "--spacing", "4"], capsys)
    assert code == 0, err
    info = json.loads((out / "hologram.json").read_text())
    import numpy as np
    from scipy.spatial import cKDTree

    pts = np.array([[s["x"], s["y"], s["z"]] for s in info["stipples"]])
    assert len(pts) > 50
    d, _ = cKDTree(pts).query(pts, k=2)
    assert d[:, 1].min() >= 4.0 - 1e-9


@pytest.mark.parametrize("stipples", [[], [{"id": 0, "x": 1.5, "y": -2.0, "z": -3.25,
                                            "visible_deg": [[-45.0, 1e-7], [3.0, 45.0]]},
                                           {"id": 1, "x": 0.1, "y": 0.2, "z": 0.3,
                                            "visible_deg": []}]])
def test_design_json_reads_back_as_written_with_a_stipple_a_line(stipples):
    import io

    from specholo.jobs.flat.folder import dump_design_json

    info = {"settings": {"a": 1, "name": "}, {"}, "stipples": stipples,
            "machining": {"hours": 0.5, "notes": ["x", None]}}
    fh = io.StringIO()
    dump_design_json(info, fh)
    assert json.loads(fh.getvalue()) == info
    lines = fh.getvalue().splitlines()
    assert sum(line.startswith('  {"id": ') for line in lines) == len(stipples)


@pytest.mark.parametrize("n", [0, 1, 7, 20])
def test_design_json_stipples_written_a_block_at_a_time(n, monkeypatch):
    """Stipples made a few at a time give the bytes of the whole list at once."""
    import io

    import numpy as np

    from specholo.jobs.flat.folder import StippleRows, dump_design_json
    from specholo.toolpaths.common import make_runs

    rng = np.random.default_rng(n)
    points = rng.normal(0.0, 10.0, (n, 3))
    ids = np.sort(rng.integers(0, max(n, 1), 3 * n))  # some with no run, some with several
    start = rng.uniform(-0.8, 0.0, len(ids))
    runs = make_runs(points, ids, start, start + 0.3)
    rows = StippleRows(points, runs)
    whole = [row for block in rows.blocks(10**6) for row in block]
    assert [r["id"] for r in whole] == list(range(n))
    assert sum(len(r["visible_deg"]) for r in whole) == len(ids)
    info = {"settings": {"a": 1}, "stipples": rows, "machining": {"hours": 0.5}}
    fh_blocks, fh_list = io.StringIO(), io.StringIO()
    original = StippleRows.blocks
    monkeypatch.setattr(StippleRows, "blocks", lambda self, size=3: original(self, 3))
    dump_design_json(info, fh_blocks)
    dump_design_json({**info, "stipples": whole}, fh_list)
    assert fh_blocks.getvalue() == fh_list.getvalue()
    assert json.loads(fh_blocks.getvalue())["stipples"] == whole
