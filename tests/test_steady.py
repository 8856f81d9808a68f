"""A still viewer under a sun that moves a little: scoops whose glints stay put."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
from legacy import old_settings
from test_gcode import needs_rs274, run_rs274

from specholo.jobs.steady.design import (
    SteadyConfig,
    design_steady_job,
    load_steady_folder,
    write_steady,
)
from specholo.setup import Tool
from specholo.simulation.steady import find_steady_glints, verify_steady
from specholo.toolpaths.steady import SteadySetup, design_steady, tool_tips, unit_half
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parent.parent / "examples" / "bunny.obj"
TOOL = Tool(0.05, 0.02)


def _points(n: int, rng: np.random.Generator) -> np.ndarray:
    return np.stack([rng.uniform(-20, 20, n), rng.uniform(-20, 20, n),
                     rng.uniform(-30, -5, n)], axis=1)


def test_scoop_glint_stays_put_and_mirrors_the_light() -> None:
    rng = np.random.default_rng(0)
    pts = _points(80, rng)
    setup = SteadySetup()
    d = design_steady(pts, setup, TOOL)
    assert d.dropped == 0 and d.n_cuts == 160
    eyes = setup.eyes()
    for e in range(2):
        ref = None
        for el in np.radians([40.0, 42.5, 45.0, 47.5, 50.0]):
            light = setup.light(el)
            g = find_steady_glints(d, eyes[e], light, TOOL)
            own = d.eye[g.cut] == e
            assert own.all() and len(g.cut) == len(pts)  # one glint per stipple, its own
            order = np.argsort(d.stipple[g.cut])
            x = g.point[order]
            # the wall's normal there is h: the light reflects into the eye
            n = unit_half(x, eyes[e], light)
            out = 2 * (n @ light)[:, None] * n - light
            to_eye = (eyes[e] - x) / np.linalg.norm(eyes[e] - x, axis=1, keepdims=True)
            np.testing.assert_allclose(out, to_eye, atol=1e-9)
            assert np.all(x[:, 2] < 0)  # on a wall inside the cut
            if ref is None:
                ref = x
            # from 40 to 50 degrees of light the glint moves by a tenth of a millimetre
            assert np.percentile(np.linalg.norm(x - ref, axis=1), 95) < 0.15
    # at the middle of the range both glints lie on the sightlines through the stipple
    reps = verify_steady(d, TOOL, np.array([45.0]))
    assert reps[0].p95_mm < 1e-3 and reps[0].stray == 0


def test_flat_grooves_drift_and_scoops_do_not() -> None:
    rng = np.random.default_rng(1)
    pts = _points(60, rng)
    setup = SteadySetup()
    els = np.array([44.0, 45.0, 46.0])
    scoop = verify_steady(design_steady(pts, setup, TOOL), TOOL, els)
    flat = verify_steady(design_steady(pts, setup, TOOL, "flat"), TOOL, els)
    assert max(r.drift_p95_mm for r in scoop) < 0.2
    assert all(r.stray == 0 and r.visibility == 1.0 for r in scoop)
    # the plain groove's glint runs along it: the image moves by millimetres or is lost
    lost_or_moved = [r.visibility < 0.5 or r.drift_p95_mm > 2.0 for r in flat[::2]]
    assert all(lost_or_moved)


def test_over_the_range_no_eye_sees_the_others_scoops() -> None:
    rng = np.random.default_rng(2)
    setup = SteadySetup(light_sweep=math.radians(8.0))
    d = design_steady(_points(100, rng), setup, TOOL)
    reps = verify_steady(d, TOOL, np.linspace(37.0, 53.0, 9))
    assert sum(r.stray for r in reps) == 0
    assert min(r.visibility for r in reps) == 1.0
    assert d.dropped < 10


@needs_rs274
def test_folder_gcode_cuts_the_scoops_and_reverifies(tmp_path: Path) -> None:
    cfg = SteadyConfig(stipples=80)
    d = design_steady_job(BUNNY, cfg, np.random.default_rng(0))
    out = tmp_path / "out"
    s = write_steady(d, cfg, out, 2.5)
    assert s["stray"] == 0
    canon = run_rs274(out / "hologram.gcode")
    feeds = [args for name, args in canon if name == "STRAIGHT_FEED"]
    nums = np.array([[float(v) for v in re.split(r",\s*", a)[:3]] for a in feeds])
    tips = tool_tips(d, cfg.tool)
    # every feed move ends on a tool-tip vertex of a cut, and all of them are cut
    assert len(nums) == len(tips)
    np.testing.assert_allclose(nums, tips, atol=2e-4)
    # no deeper than the depth asked (a sloping scoop is raised by its dip)
    assert tips[:, 2].min() >= -cfg.tool.depth - 1e-9
    assert np.all(tips[d.offsets[:-1], 2] > -1e-3)
    again, cfg2 = load_steady_folder(out)
    from specholo.jobs.steady.design import light_steps, summarise

    rep = summarise(verify_steady(again, cfg2.tool, light_steps(cfg2.setup, 2.5)))
    assert rep == pytest.approx(s)


def test_cli_writes_a_verified_folder(tmp_path: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    out = tmp_path / "steady"
    # --light-range: the older name of --light-sweep, still taken
    assert main(["steady", str(BUNNY), "--out", str(out), "--stipples", "60",
                 "--light-range", "3"]) == 0
    ver = json.loads((out / "verify.json").read_text())
    assert len(ver["elevations"]) == 7 and ver["summary"]["stray"] == 0
    settings = json.loads((out / "hologram.json").read_text())["settings"]
    assert settings["light_sweep"] == pytest.approx(3.0)
    assert ver["summary"]["worst_drift_p95_mm"] < 0.5
    # the preview: three panels of the left eye's glints as the light moves
    from PIL import Image

    with Image.open(out / "preview.png") as im:
        assert im.format == "PNG" and im.size[0] > 2 * im.size[1]
    assert main(["verify", str(out)]) == 0
    assert "drift" in capsys.readouterr().out
    # the picture commands draw scoops too (tests/test_pictures.py checks what they draw)
    assert main(["render", str(out), "--width", "32", "--height", "32"]) == 0
    assert (out / "render.png").is_file()
    # and --at is a light elevation: one in the plate's plane is refused in one line
    assert main(["render", str(out), "--at", "0", "--width", "32", "--height", "32"]) != 0
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "light elevation" in err[0]


@pytest.mark.parametrize("args, message", [
    (["--light-sweep", "30"], "light sweep"),
    (["--light-elevation", "0"], "light elevation"),
    (["--depth", "0.001"], "cut deeper"),
    (["--step", "0"], "step"),
])
def test_cli_bad_input(tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str],
                       message: str) -> None:
    out = tmp_path / "steady"
    rc = main(["steady", str(BUNNY), "--out", str(out), "--stipples", "30", *args])
    err = capsys.readouterr().err.strip()
    assert rc != 0 and message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_a_pose_is_kept_and_read_back(tmp_path: Path) -> None:
    """--up z then a quarter turn about x brings a y-up model back as it was: the
    same scoops; the pose is recorded and read back with the folder."""
    from specholo.scene.pose import Pose

    plain = design_steady_job(BUNNY, SteadyConfig(stipples=40), np.random.default_rng(0))
    cfg = SteadyConfig(stipples=40, pose=Pose("z", (90.0, 0.0, 0.0)))
    turned = design_steady_job(BUNNY, cfg, np.random.default_rng(0))
    np.testing.assert_allclose(turned.centres, plain.centres, atol=1e-9)
    write_steady(turned, cfg, tmp_path / "out", 5.0)
    _, again = load_steady_folder(tmp_path / "out")
    assert again.pose == cfg.pose
    # moved on the plate: every scoop moves with it
    moved = design_steady_job(BUNNY, SteadyConfig(stipples=40, pose=Pose(offset=(5.0, -2.0))),
                              np.random.default_rng(0))
    assert moved.points.shape == plain.points.shape
    np.testing.assert_allclose(moved.points - plain.points - [5.0, -2.0, 0.0], 0.0, atol=1e-9)


def _program_floor(path: Path, feed: float, plunge: float, rapid: float = 3000.0
                   ) -> tuple[float, float]:
    """Seconds a program's moves take at their full rates with no acceleration
    (a floor of any estimate): all of them, and the feed moves along the cuts."""
    pos, total, cutting = np.zeros(3), 0.0, 0.0
    for line in path.read_text().splitlines():
        if line.startswith("(") or not line.strip():
            continue
        words = dict(re.findall(r"([A-Z])(-?[\d.]+)", line))
        new = pos.copy()
        for i, k in enumerate("XYZ"):
            if k in words:
                new[i] = float(words[k])
        moved = float(np.linalg.norm(new - pos))
        if words.get("G") == "0":
            total += 60.0 * moved / rapid
        elif words.get("G") == "1":
            along = "X" in words or "Y" in words
            seconds = 60.0 * moved / (feed if along else plunge)
            total += seconds
            cutting += seconds if along else 0.0
        pos = new
    return total, cutting


def test_summary_says_what_became_of_every_stipple_asked_for_and_how_long_it_cuts(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The summary accounts for every stipple asked for (cut, hidden, no scoop),
    names the plate, the tool and its depth, and the machining time at the feed,
    which is the program's own: no less than its moves at full speed."""
    from specholo.fabrication.programs.timing import describe_machining

    out = tmp_path / "steady"
    # a high, wide light: some visible stipples find no scoop that keeps the other
    # eye's glint off it over the range
    assert main(["steady", str(BUNNY), "--out", str(out), "--stipples", "60",
                 "--light-elevation", "70", "--light-sweep", "15", "--step", "5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    meta = json.loads((out / "hologram.json").read_text())
    kept, dropped, st = meta["stipples"], meta["stipples_dropped"], meta["stippling"]
    assert dropped > 0 and st["hidden_both_eyes"] > 0 and st["asked"] == st["placed"] == 60
    # every stipple asked for is cut or has its reason
    assert kept + dropped + st["hidden_both_eyes"] + st["hidden_one_eye"] == 60
    assert lines[0].startswith(f"{kept} of the 60 stipples asked for got scoops "
                               f"({2 * kept}, one for each eye)")
    left = next(ln for ln in lines if ln.startswith("not cut:"))
    assert left.startswith(f"not cut: {60 - kept} of the 60: ")
    assert f"{st['hidden_both_eyes']} hidden from both eyes" in left
    assert f"{dropped} with no scoop" in left and "--light-sweep" in left
    assert (f"{st['hidden_one_eye']} hidden from one eye" in left) == (st["hidden_one_eye"] > 0)
    (x0, y0), (x1, y1) = meta["plate_mm"]
    assert any(ln.startswith(f"plate: {x1 - x0:.0f} x {y1 - y0:.0f} mm, 3 mm thick (fitted "
                             "to the cuts") for ln in lines)
    assert any(ln.startswith("tool: ball end, radius 0.05 mm, 0.02 mm deep at most, scoops "
                             "0.080 mm wide") for ln in lines)
    machining = describe_machining(meta["machining"], 300.0)
    assert machining.startswith("machining: about ") and " at 300 mm/min" in machining
    assert machining in lines
    # the estimate is of the program written: its moves at full rates are a floor
    # that acceleration adds to, by a fraction of a second a move at most
    floor, cutting = _program_floor(out / "hologram.gcode", 300.0, 100.0)
    estimate = 3600.0 * meta["machining"]["estimated_hours"]
    moves = sum(meta["safety_check"]["moves"][k] for k in ("G0", "G1"))
    assert floor <= estimate <= floor + 0.5 * moves
    assert cutting <= 3600.0 * meta["machining"]["cutting_hours"] <= 1.2 * cutting
    assert meta["machining"]["hops"] == 0  # the program retracts after every cut


def test_the_lights_angles_have_their_own_names_and_old_folders_read(tmp_path: Path) -> None:
    """The steady setup's light angles are ``light_elevation`` and ``light_sweep``
    (a viewer's ``elevation`` and ``half_range`` are the eyes'); a folder that
    saved them under the old names reads back the same."""
    import json

    cfg = SteadyConfig(stipples=30, setup=SteadySetup(light_elevation=math.radians(50.0),
                                                      light_sweep=math.radians(6.0)))
    d = design_steady_job(BUNNY, cfg, np.random.default_rng(0))
    write_steady(d, cfg, tmp_path / "out", 5.0)
    meta_path = tmp_path / "out" / "hologram.json"
    meta = old_settings(tmp_path / "out")
    setup = meta["config"]["setup"]
    assert setup["light_elevation_deg"] == pytest.approx(50.0)
    assert setup["light_sweep_deg"] == pytest.approx(6.0)
    setup["elevation_deg"] = setup.pop("light_elevation_deg")
    setup["half_range_deg"] = setup.pop("light_sweep_deg")
    meta_path.write_text(json.dumps(meta))
    _, again = load_steady_folder(tmp_path / "out")
    assert again.setup.light_elevation == pytest.approx(math.radians(50.0))
    assert again.setup.light_sweep == pytest.approx(math.radians(6.0))
