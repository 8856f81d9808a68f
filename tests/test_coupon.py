"""The test coupon (``specholo coupon``): a card of rungs at a ladder of depths
(rigid holder) or preloads (spring holder), cut in at most 15 minutes.

- Its program parses in LinuxCNC's rs274, passes ``specholo check`` with no
  options, and every cut of a rung runs at its depth or preload (read from
  the program's text, and from rs274's canonical moves); a groove edited to
  another depth is refused.
- Its machining estimate on grbl-router is at most 15 minutes, and lies
  between the whole program timed at its shallowest and its deepest rung.
- Its glints show from where its sheet says: for every stipple, simulated
  eyes (``find_glints`` on the grooves read back from the program) at random
  azimuths inside the sheet's range find its glint within 0.05 mm of the
  sheet's place for that azimuth, and eyes beyond its dark azimuths find none;
  the sheet's places are the sightline through the stipple's point
  (horizontally exact, vertically within the stripes' band).
- Settings it cannot honour are refused in one line, nothing written.
"""

from __future__ import annotations

import json
import math
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from test_gcode import needs_rs274, run_rs274

from specholo_cli.cli import main

#: The coupon's own claim: a glint within this of its sheet's place, mm.
ON_THE_SHEET = 0.05


@pytest.fixture(scope="module", params=["spring", "rigid"])
def card(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A default coupon on the GRBL router, in a spring or a rigid holder."""
    out = tmp_path_factory.mktemp("coupon") / request.param
    assert main(["coupon", "--out", str(out), "--machine", "grbl-router",
                 "--holder", request.param]) == 0
    return out


def info_of(folder: Path) -> dict:
    return json.loads((folder / "coupon.json").read_text())


def rung_of_stipples(info: dict) -> dict[int, dict]:
    """Stipple and label-dot id -> its rung's record."""
    out = {}
    n = info["settings"]["stipples"]
    rungs = info["rungs"]
    for rung in rungs:
        for s in rung["stipples"]:
            out[s["id"]] = rung
    first = len(rungs) * n
    for rung in rungs:
        for _ in rung["label_dots_mm"]:
            out[first] = rung
            first += 1
    return out


def setting(rung: dict) -> float:
    return rung["preload_mm"] if "preload_mm" in rung else rung["depth_mm"]


# ---------------------------------------------------------------- the program


def program_cuts(path: Path) -> list[tuple[int, float, float, float]]:
    """Every feed move in X/Y below the surface, read from the program's text:
    (stipple id, x, y, z) at its end."""
    word = re.compile(r"([XYZ])(-?\d+\.?\d*)")
    x = y = z = math.nan
    stipple = -1
    cuts = []
    for line in path.read_text().splitlines():
        m = re.fullmatch(r"\(stipple (\d+)\)", line.strip())
        if m:
            stipple = int(m.group(1))
            continue
        if line.startswith("("):
            continue
        words = dict(word.findall(line))
        nx, ny = float(words.get("X", x)), float(words.get("Y", y))
        nz = float(words.get("Z", z))
        if re.match(r"G[123]\b", line) and (nx, ny) != (x, y) and nz < 0:
            cuts.append((stipple, nx, ny, nz))
        x, y, z = nx, ny, nz
    return cuts


def test_each_rungs_cuts_run_at_its_setting(card: Path) -> None:
    info = info_of(card)
    of = rung_of_stipples(info)
    cuts = program_cuts(card / "hologram.gcode")
    assert len(cuts) > 500
    pitch = info["rungs"][1]["x_mm"] - info["rungs"][0]["x_mm"]
    (_, y0), (_, y1) = info["card"]["plate_mm"]
    seen = set()
    for stipple, x, y, z in cuts:
        rung = of[stipple]
        # the Z is the rung's depth (rigid) or preload (spring), and nowhere else
        assert z == pytest.approx(-setting(rung), abs=1e-9), (stipple, z)
        assert rung["cut_z_mm"] == pytest.approx(-setting(rung))
        assert abs(x - rung["x_mm"]) < 0.5 * pitch and y0 + 5 < y < y1 - 5  # in its column
        seen.add(rung["rung"])
    assert seen == {r["rung"] for r in info["rungs"]}
    assert len({setting(r) for r in info["rungs"]}) == len(info["rungs"]) == 5


@needs_rs274
def test_rs274_reads_the_program_and_cuts_each_rung_at_its_z(card: Path) -> None:
    info = info_of(card)
    of = rung_of_stipples(info)
    stipple, at, moved = -1, None, 0
    for name, args in run_rs274(card / "hologram.gcode"):
        if name == "COMMENT" and args.startswith('"stipple '):
            stipple = int(args.strip('"').split()[1])
            continue
        if name not in ("STRAIGHT_FEED", "ARC_FEED", "STRAIGHT_TRAVERSE"):
            continue
        v = [float(a) for a in args.split(",")]
        x, y, z = (v[0], v[1], v[2]) if name != "ARC_FEED" else (v[0], v[1], v[5])
        if name != "STRAIGHT_TRAVERSE" and at is not None and z < 0 \
                and (abs(x - at[0]) > 1e-4 or abs(y - at[1]) > 1e-4):
            assert z == pytest.approx(-setting(of[stipple]), abs=1e-4)
            moved += 1
        at = (x, y, z)
    assert moved > 500


def test_the_check_passes_it_with_no_options_and_refuses_another_depth(
        card: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    program = card / "hologram.gcode"
    assert main(["check", str(program)]) == 0
    assert "0 violation(s) (against the limits in its header)" in capsys.readouterr().out
    # a rung's groove plunged between two rungs' settings: a cut at no rung's Z
    info = info_of(card)
    a, b = (setting(r) for r in info["rungs"][:2])
    text = program.read_text()
    z = f"G1 Z-{a:.5f} F"
    assert z in text
    edited = tmp_path / "edited.gcode"
    edited.write_text(text.replace(z, f"G1 Z-{0.5 * (a + b):.5f} F", 1))
    with pytest.raises(SystemExit) as ended:  # check ends with status 1 on a violation
        main(["check", str(edited)])
    assert ended.value.code == 1
    out = capsys.readouterr().out
    assert "not at the groove depth" in out or "a scratch" in out


def test_an_inch_linuxcnc_card_cuts_each_rung_at_its_z(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "inch"
    assert main(["coupon", "--out", str(out), "--dialect", "linuxcnc", "--units", "inch",
                 "--holder", "rigid", "--depths", "0.008,0.012", "--stipples", "3"]) == 0
    program = out / "hologram.gcode"
    assert main(["check", str(program)]) == 0
    assert "0 violation(s)" in capsys.readouterr().out
    of = rung_of_stipples(info_of(out))
    cuts = program_cuts(program)
    assert cuts and {round(-z * 25.4, 4) for _, _, _, z in cuts} == {0.008, 0.012}
    for stipple, _, _, z in cuts:
        assert -z * 25.4 == pytest.approx(setting(of[stipple]), abs=2e-5)  # 6 decimals in inch
    if Path("/usr/bin/rs274").exists():
        assert any(name == "ARC_FEED" for name, _ in run_rs274(program))


def test_the_card_is_small_and_named_in_its_header(card: Path) -> None:
    info = info_of(card)
    (x0, y0), (x1, y1) = info["card"]["plate_mm"]
    assert x1 - x0 <= 60 and y1 - y0 <= 40
    head = (card / "hologram.gcode").read_text().split("G21")[0]
    assert f"(plate: {x1 - x0:g} x {y1 - y0:g} mm" in head
    for rung in info["rungs"]:
        assert f"(rung {rung['rung']}: " in head
        assert len(rung["label_dots_mm"]) == rung["rung"]  # rung 3: three dots


# ---------------------------------------------------------------- time


def test_it_takes_at_most_15_minutes_on_the_router(card: Path) -> None:
    from specholo.fabrication.programs.timing import estimate_time
    from specholo.jobs.flat.coupon import CouponConfig
    from specholo.toolpaths.grooves import Grooves

    info = info_of(card)
    m = info["machining"]
    assert m["machine"]["name"] == "grbl-router"
    minutes = 60.0 * m["estimated_hours"]
    assert 0 < minutes <= 15.0
    # each rung timed at its own Z: between the card timed all at the shallowest
    # and all at the deepest
    config = CouponConfig.from_saved(info["settings"])
    grooves = Grooves.load(card / "grooves.npz")
    times = []
    for r in (0, config.rungs - 1):
        rc = config.rung_config(r)
        holder = rc.holder_setup()
        assert holder is not None
        depth, machining = holder.program(rc.depth_mm, rc.setup().machining)
        times.append(estimate_time(grooves, depth, machining, machine=rc.profile).total_s)
    assert times[0] <= 60.0 * minutes + 1e-6 <= times[1] + 1e-6
    parts = sum(m[k] for k in ("cutting_hours", "rapid_hours", "plunge_hours", "hop_hours",
                               "dwell_hours", "lift_hours", "delay_hours"))
    assert parts == pytest.approx(m["estimated_hours"])


def test_a_card_over_15_minutes_is_refused_in_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "slow"
    assert main(["coupon", "--out", str(out), "--machine", "grbl-router", "--plunge", "1"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "would take about" in err and "more than 15" in err
    assert not out.exists()


def test_the_summary_gives_the_estimate(tmp_path: Path,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "small"
    assert main(["coupon", "--out", str(out), "--rungs", "2", "--stipples", "3",
                 "--machine", "linuxcnc-mill"]) == 0
    printed = capsys.readouterr().out
    assert "machining on linuxcnc-mill" in printed and "about " in printed
    assert "G21" in (out / "hologram.gcode").read_text()


# ---------------------------------------------------------------- the glints


def sheet_places(track: np.ndarray, azimuth: float, step: float) -> list[np.ndarray]:
    """The sheet's places for an azimuth (coupon.json's position_rule): on each
    stroke whose rows reach within a step, linearly between its two rows about
    it (or beyond its last two)."""
    out = []
    for stroke in np.unique(track[:, 3]):
        rows = track[track[:, 3] == stroke]
        if not rows[0, 0] - step - 1e-9 <= azimuth <= rows[-1, 0] + step + 1e-9:
            continue
        if len(rows) == 1:
            out.append(rows[0, 1:3])
            continue
        i = min(max(int(np.searchsorted(rows[:, 0], azimuth)) - 1, 0), len(rows) - 2)
        t = (azimuth - rows[i, 0]) / (rows[i + 1, 0] - rows[i, 0])
        out.append(rows[i, 1:3] + t * (rows[i + 1, 1:3] - rows[i, 1:3]))
    return out


def handing_over(track: np.ndarray, azimuth: float, step: float) -> bool:
    """Whether two strokes meet within two steps of the azimuth."""
    near = track[np.abs(track[:, 0] - azimuth) <= 2 * step + 1e-9]
    return len(np.unique(near[:, 3])) > 1


def test_the_glints_show_from_where_the_sheet_says(card: Path) -> None:
    from specholo.fabrication.programs.gcode_reader import read_gcode
    from specholo.jobs.flat.coupon import CouponConfig
    from specholo.simulation.glints import Engraved, find_glints

    info = info_of(card)
    config = CouponConfig.from_saved(info["settings"])
    step = info["track_step_deg"]
    assert info["on_the_sheet_mm"] == ON_THE_SHEET
    grooves = read_gcode(card / "hologram.gcode")  # the program that is cut
    of = rung_of_stipples(info)
    rung_of_path = np.array([of[int(s)]["rung"] for s in grooves.stipple])
    rng = np.random.default_rng(7)
    found = gaps = stray = 0
    for rung in info["rungs"]:
        setup = config.rung_config(rung["rung"] - 1).setup()
        eng = Engraved.from_grooves(grooves.take(np.flatnonzero(rung_of_path == rung["rung"])),
                                    setup.tool)

        def glints(azimuth: float, sid: int, setup=setup, eng=eng) -> np.ndarray:
            eye = setup.viewer.eye(np.radians([azimuth]))[0]
            g = find_glints(eng, eye, setup.light)
            return g.point[g.stipple == sid][:, :2]

        for s in rung["stipples"]:
            track = np.asarray(s["track"], dtype=float)
            lo, hi = s["shows_deg"]
            wlo, whi = s["window_deg"]
            # the sheet's range is its window, but for a step at either end
            assert wlo < lo <= wlo + 2 * step and whi - 2 * step <= hi < whi
            for azimuth in rng.uniform(lo, hi, 12):
                mine = glints(float(azimuth), s["id"])
                places = sheet_places(track, float(azimuth), step)
                assert places, (s["id"], azimuth)
                if not len(mine):
                    # an eye a few hundredths of a degree from a hand-over
                    # between two strokes may find neither's end
                    assert handing_over(track, float(azimuth), step), (s["id"], azimuth)
                    gaps += 1
                    continue
                gap = min(float(np.linalg.norm(p - q)) for p in mine for q in places)
                assert gap <= ON_THE_SHEET, (rung["rung"], s["letter"], azimuth, gap)
                found += 1
            dlo, dhi = s["dark_beyond_deg"]
            assert dlo <= wlo - 0.5 and dhi >= whi + 0.5
            edge = config.design.view_range + 5.0
            for azimuth in [dlo - 0.01, dlo - 1.0, dlo - 7.0, dhi + 0.01, dhi + 1.0, dhi + 7.0]:
                if -edge <= azimuth <= edge:
                    stray += len(glints(azimuth, s["id"]))
    assert stray == 0
    assert found >= 0.98 * (found + gaps) and found > 250


def test_the_sheet_places_glints_on_the_sightline(card: Path) -> None:
    """Each track row lies where the eye's sightline through the stipple's
    point crosses the card: exactly across, within the stripes' band up and
    down (the striped design's promise)."""
    from specholo.jobs.flat.coupon import CouponConfig

    info = info_of(card)
    config = CouponConfig.from_saved(info["settings"])
    viewer = config.design.setup().viewer
    assert info["viewing"]["eye_distance_mm"] == pytest.approx(viewer.eye_radius)
    band = info["tool"]["band_mm"]
    for rung in info["rungs"]:
        for s in rung["stipples"]:
            track = np.asarray(s["track"], dtype=float)
            p = np.asarray(s["point_mm"])
            eye = viewer.eye(np.radians(track[:, 0]))
            t = -p[2] / (eye[:, 2] - p[2])
            cross = p[:2] + t[:, None] * (eye[:, :2] - p[:2])
            assert np.abs(track[:, 1] - cross[:, 0]).max() < 0.01
            assert np.abs(track[:, 2] - cross[:, 1]).max() < band + 0.01
            # in the middle of its window the glint crosses its rung's centre line
            assert s["glint_at_middle_mm"][0] == pytest.approx(rung["x_mm"], abs=0.01)


def test_verify_reads_the_folder_as_a_coupon(card: Path, tmp_path: Path,
                                             capsys: pytest.CaptureFixture[str]) -> None:
    from specholo.jobs import job_of
    from specholo.jobs.base import quiet

    folder = tmp_path / "card"
    shutil.copytree(card, folder)
    job = job_of(folder)
    assert job.kind == "coupon"
    assert main(["verify", str(folder), "--from-gcode"]) == 0
    assert "every glint shows where and from where the sheet says" in capsys.readouterr().out
    record = json.loads((folder / "verify.json").read_text())
    assert record["kind"] == "coupon" and record["summary"]["glints_as_the_sheet_says"]
    # the sheet drawn again from the folder's files is the same file
    files = job.preview(folder, quiet)
    again = tmp_path / "again"
    again.mkdir()
    files["sheet.pdf"](again)
    assert (again / "sheet.pdf").read_bytes() == (folder / "sheet.pdf").read_bytes()
    assert (folder / "sheet.pdf").read_bytes().startswith(b"%PDF")
    assert main(["report", str(folder)]) == 1  # its report is its sheet
    assert "sheet.pdf" in capsys.readouterr().err
    assert main(["verify", str(folder), "--cut"]) == 1
    assert "are for flat-plate designs" in capsys.readouterr().err


def test_a_rigid_card_is_probed_as_a_design_is(card: Path, tmp_path: Path) -> None:
    folder = tmp_path / "card"
    shutil.copytree(card, folder)
    code = main(["probe", str(folder)])
    if info_of(folder)["settings"]["holder"] == "spring":
        assert code == 1  # a spring holder's tip follows the card
    else:
        assert code == 0 and (folder / "probe.gcode").is_file()


# ---------------------------------------------------------------- refusals


@pytest.mark.parametrize(("args", "words"), [
    (["--tool", "laser"], "a laser has none"),
    (["--machine", "pen-plotter"], "has none"),
    (["--holder", "rigid", "--preloads", "0.1,0.2"], "ladder is of depths"),
    (["--holder", "rigid", "--depths", "0.002,0.011"], "too shallow"),
    (["--preloads", "0.2,0.2"], "must differ"),
    (["--preloads", "0.2,2.5"], "out of range"),
    (["--rungs", "10"], "rungs must be a whole number in [2, 9]"),
    (["--stipples", "6"], "stipples must be a whole number in [3, 5]"),
    (["--window", "30"], "does not fit"),
    (["--behind", "100"], "behind must be in"),
    (["--preloads", "0.1,x"], "separated by commas"),
])
def test_bad_settings_are_refused_in_one_line(args: list[str], words: str, tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "bad"
    assert main(["coupon", "--out", str(out), *args]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("error: ") and words in err, err
    assert not out.exists()
