"""Settings at and beyond their physical bounds, Ctrl-C, and reproducible outputs.

- Every design setting has physical bounds (``pipeline.SETTING_BOUNDS``); a value
  beyond them is refused up front with one line naming it, and a combination
  whose walk would not fit in memory is refused with an estimate.
- Random settings, within and beyond the bounds, through the command line: a
  complete design folder, or one line and no folder; never more than a bounded
  time or memory.
- Ctrl-C during a design exits with status 130 and one line, and leaves the
  output folder as it was.
- The same model, settings and seed give the same files byte for byte, whatever
  the hash seed or the number of threads; only ``run.json`` records the run.

``SPECHOLO_RANDOM_DESIGNS=N`` runs N random designs instead of 25;
``SPECHOLO_RANDOM_LOG=FILE`` appends each one's options to FILE before it runs
(the last line names a design that hangs).
"""

from __future__ import annotations

import json
import math
import os
import resource
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from specholo.errors import SpecholoError
from specholo.jobs.flat.folder import SETTING_BOUNDS, DesignConfig, design
from specholo.scene import loading
from specholo.toolpaths import striped
from specholo_cli.cli import main

ROOT = Path(__file__).resolve().parents[1]
BUNNY = ROOT / "examples" / "bunny.obj"


def _run(argv: list[object], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ---------------------------------------------------------------- bounds


def _beyond(name: str) -> list[float]:
    lo, hi, _ = SETTING_BOUNDS[name]
    values = [hi * 10 if hi > 0 else hi + 1, hi + abs(hi) * 1e-3 + 1e-9]
    if lo > 0:
        values.append(lo / 10)
    elif lo < 0:
        values.append(lo * 10)
    return values


@pytest.mark.parametrize(("name", "value"), [(n, v) for n in SETTING_BOUNDS for v in _beyond(n)])
def test_a_setting_beyond_its_bounds_is_refused_naming_it(name: str, value: float) -> None:
    values: dict[str, object] = {name: value}
    if name in ("tool_radius", "tool_angle"):
        values["tool"] = "drag"
    if name == "tip_flat":
        values["tool"] = "vbit"
    if name == "spot":
        values["tool"] = "laser"
    if name == "spacing":
        values["stipples"] = None
    if name == "ipd":
        values["view_distance"] = 1e6  # refused by its bounds, not by the distance
    if name == "view_distance" and value < 10:
        values["ipd"] = 0.5
    if name == "depth":
        values["stock_thickness"] = 1000.0
        values["tool"] = "ball"
        values["tool_radius"] = 25.0
    with pytest.raises(SpecholoError) as info:
        DesignConfig.from_dict(values)
    msg = str(info.value)
    assert "\n" not in msg
    option = name.replace("_", "-")
    assert option in msg or option.replace("-", " ") in msg, msg


def test_the_bounds_themselves_are_valid() -> None:
    """Each bound, on its own, is an acceptable setting."""
    for name, (lo, hi, _) in SETTING_BOUNDS.items():
        for value in (lo, hi):
            values: dict[str, object] = {name: value}
            if name in ("tool_radius", "tool_angle"):
                values["tool"] = "drag"
            if name == "tip_flat":
                values["tool"] = "vbit"
            if name == "spot":
                values["tool"] = "laser"
            if name == "view_distance" and value < 100:
                values["ipd"] = 1.0
            if name == "view_range" and value > 80:
                values["view_distance"] = 1e6
            if name == "ipd":
                values["view_distance"] = 1e4
            if name == "depth":
                values.update(tool="ball", tool_radius=25.0, stock_thickness=1000.0)
                values["depth"] = min(value, 25.0)
            if name == "stock_thickness" and value < 0.1:
                values.update(depth=value / 2)
            if name == "safe_z":
                values["depth"] = 0.01
            if name == "hop":  # a hop stays below the safe height
                values["safe_z"] = max(1.0, 2 * value)
            DesignConfig.from_dict(values)


@pytest.mark.parametrize(("options", "words"), [
    (["--tool-radius", "1e6"], "tool-radius 1e+06 mm is out of range"),
    (["--tool-radius", "1e-9"], "tool-radius 1e-09 mm is out of range"),
    (["--eye-height", "1e300"], "eye-height 1e+300 is out of range"),
    (["--eye-height", "1e6"], "eye-height 1e+06 mm is out of range"),
    (["--view-distance", "1e13"], "view-distance 10000000000000.0 is out of range"),
    (["--band", "1e-9"], "band 1e-09 mm is out of range"),
    (["--tool", "laser", "--spot", "10"], "spot 10 mm is out of range"),
    (["--tool", "laser", "--depth", "1e-6", "--size", "1"], "depth 1e-06 mm is out of range"),
    (["--tool", "laser", "--spot", "1", "--depth", "0.0002"], "too flat to show a glint"),
])
def test_settings_that_used_to_blow_up_are_refused_at_once(tmp_path: Path, capsys,
                                                           options: list[str],
                                                           words: str) -> None:
    t0 = time.perf_counter()
    code, _, err = _run(["design", BUNNY, "--out", tmp_path / "o", "--stipples", "200",
                         *options], capsys)
    assert time.perf_counter() - t0 < 5
    assert code == 1 and err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "o").exists()


def test_a_walk_too_large_for_memory_is_refused_with_an_estimate(monkeypatch) -> None:
    room = loading.available_memory()
    if room is None:
        pytest.skip("memory available unknown")
    monkeypatch.setattr(striped, "BYTES_PER_SAMPLE", room)  # any walk is too large
    with pytest.raises(SpecholoError) as info:
        design(BUNNY, DesignConfig(stipples=20, band=0.001), check_overlaps=False)
    msg = str(info.value)
    assert msg.startswith("the striped design would need ~") and "available" in msg
    assert "band 0.001 mm" in msg and "\n" not in msg
    monkeypatch.undo()
    monkeypatch.setattr(striped, "MAX_SAMPLES", 1000)  # or too much work
    with pytest.raises(SpecholoError, match="^the striped design would need ~"):
        design(BUNNY, DesignConfig(stipples=20), check_overlaps=False)


def test_a_walk_that_does_not_settle_is_refused(monkeypatch) -> None:
    """Runs whose sample bound keeps overflowing end in one line, not in a loop
    that takes all the memory."""
    monkeypatch.setattr(striped, "MAX_GROWTH", 1)
    monkeypatch.setattr(striped, "MIN_BOUND", 1)
    monkeypatch.setattr(striped.kernel, "start_offsets", _tiny_caps(striped.kernel.start_offsets))
    with pytest.raises(SpecholoError, match=r"^the striped walk for the stipple at .* does not "
                                            r"settle"):
        # the walk of one family per stipple (the placement's own plan is
        # bounded the same way, see test_avoid)
        design(BUNNY, DesignConfig(stipples=5, placement="phase"), check_overlaps=False)


def _tiny_caps(fn):  # type: ignore[no-untyped-def]
    def wrapped(*args):  # type: ignore[no-untyped-def]
        u0, valid, cap = fn(*args)
        return u0, valid, np.full_like(cap, 2)
    return wrapped


@pytest.mark.parametrize("options", [
    {"tool_radius": 25.0},  # the walk never settled: minutes, then out of memory
    {"tool": "ball", "tool_radius": 25.0, "depth": 2.0},
    {"tool_radius": 0.001},  # the overlap grid took 10^10 cells
    {"eye_height": 1e5},
    {"center_z": -10_000.0},
    {"tool": "laser", "spot": 0.005},  # a groove finer than the overlap slack: 1/0
])
def test_settings_at_their_bounds_design_quickly(options: dict[str, object]) -> None:
    t0 = time.perf_counter()
    d = design(BUNNY, DesignConfig(stipples=8, **options))  # type: ignore[arg-type]
    assert time.perf_counter() - t0 < 30
    assert d.grooves.n_paths > 0


def test_vbit_gcode_cuts_to_the_groove_depth(tmp_path: Path, capsys) -> None:
    """The G-code of a V-bit cut the small round model's depth (0.3 um), not the
    groove's; with a wide tip flat that was deeper than the groove and the safety
    check refused the design."""
    for flat in ("0", "2"):
        out = tmp_path / f"v{flat}"
        code, _, err = _run(["design", BUNNY, "--out", out, "--stipples", "20", "--tool", "vbit",
                             "--depth", "0.05", "--tip-flat", flat], capsys)
        assert code == 0, err
        text = (out / "hologram.gcode").read_text()
        assert "G1 Z-0.05000 F" in text
        assert not [ln for ln in text.splitlines() if ln.startswith("G1 Z-")
                    and ln.split()[1] != "Z-0.05000"]


# ---------------------------------------------------------------- random settings, CLI


def _value(name: str) -> st.SearchStrategy[float]:
    lo, hi, _ = SETTING_BOUNDS[name]
    inside = (st.floats(math.log10(lo), math.log10(hi)).map(lambda e: float(f"{10 ** e:.4g}"))
              if lo > 0 else st.floats(lo, hi).map(lambda v: float(f"{v:.4g}")))
    below = st.just(lo / 100 if lo > 0 else (lo - 1 if lo == 0 else lo * 100))
    return st.one_of(inside, inside, inside, st.sampled_from([lo, hi]),
                     st.just(hi * 100 if hi > 0 else hi + 1), below)


#: Settings the property test draws (others keep their defaults).
VARIED = ["size", "center_z", "light_distance", "view_distance", "view_range", "eye_height",
          "ipd", "band", "tool_radius", "tip_flat", "depth", "plate_width", "feed", "safe_z"]


@st.composite
def design_settings(draw: st.DrawFn) -> dict[str, object]:
    names = draw(st.lists(st.sampled_from(VARIED), min_size=1, max_size=4, unique=True))
    values: dict[str, object] = {n: draw(_value(n)) for n in names}
    values["light_elevation"] = draw(st.one_of(
        st.just(45.0), st.floats(0.001, 179.999).map(lambda v: float(f"{v:.4g}")),
        st.sampled_from([0.0, 90.0, 180.0, 1e-6])))
    values["tool"] = draw(st.sampled_from(["drag", "ball", "vbit", "laser"]))
    values["method"] = draw(st.sampled_from(["striped", "striped", "hyperbola", "arc"]))
    return values


#: What one random design may take: seconds, and address space over the start.
TIME_LIMIT = 60.0
MEMORY_LIMIT = 4 << 30


def _address_space() -> int:
    with open("/proc/self/status", encoding="ascii") as fh:
        for line in fh:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise AssertionError("no VmSize")


#: How many random designs the property test ran (for the README's figures).
RANDOM_DESIGNS = {"run": 0, "designed": 0, "refused": 0}
REFUSALS: list[str] = []


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="needs /proc")
@settings(max_examples=int(os.environ.get("SPECHOLO_RANDOM_DESIGNS", "25")), deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])
@given(values=design_settings())
@example(values={"tool_radius": 1e6, "tool": "drag", "method": "striped",
                 "light_elevation": 45.0})
@example(values={"eye_height": 1e5, "tool": "drag", "method": "striped",
                 "light_elevation": 45.0})
@example(values={"light_elevation": 90.0, "light_distance": 300.0, "tool": "drag",
                 "method": "striped"})
@example(values={"view_range": 89.0, "view_distance": 1e7, "tool": "drag",
                 "method": "striped", "light_elevation": 1e-6})
def test_random_settings_design_completely_or_are_refused_in_one_line(
        tmp_path: Path, capsys, values: dict[str, object]) -> None:
    out = tmp_path / "out"
    shutil.rmtree(out, ignore_errors=True)
    argv: list[object] = ["design", BUNNY, "--out", out, "--stipples", "8",
                          "--formats", "gcode,svg,dxf"]
    for name, value in values.items():
        argv += [f"--{name.replace('_', '-')}", value]
    if os.environ.get("SPECHOLO_RANDOM_LOG"):
        with open(os.environ["SPECHOLO_RANDOM_LOG"], "a", encoding="utf-8") as fh:
            fh.write(" ".join(map(str, argv[5:])) + "\n")
    soft, hard = resource.getrlimit(resource.RLIMIT_AS)
    resource.setrlimit(resource.RLIMIT_AS, (_address_space() + MEMORY_LIMIT, hard))
    t0 = time.perf_counter()
    try:
        code, _, err = _run(argv, capsys)
    finally:
        resource.setrlimit(resource.RLIMIT_AS, (soft, hard))
    assert time.perf_counter() - t0 < TIME_LIMIT, argv
    RANDOM_DESIGNS["run"] += 1
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")], argv
    if code == 0:
        RANDOM_DESIGNS["designed"] += 1
        info = json.loads((out / "hologram.json").read_text())
        files = {p.name for p in out.iterdir()}
        assert {"hologram.gcode", "hologram.svg", "hologram.dxf", "hologram.json", "run.json",
                "grooves.npz", "stipples.npz", "preview.png", "model.ply"} <= files, argv
        assert len(info["stipples"]) <= 8
        assert info["machining"]["safety_check"]["violations"] == 0
        return
    RANDOM_DESIGNS["refused"] += 1
    REFUSALS.append(err.strip() + "  <- " + " ".join(map(str, argv[5:])))
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), (argv, err)
    assert "internal error" not in err and "out of memory" not in err, (argv, err)
    assert "safety check" not in err, (argv, err)  # a design must fit its own plate
    assert not out.exists(), argv


# ---------------------------------------------------------------- Ctrl-C


def _exe() -> list[str]:
    """The ``specholo`` command as installed (its entry point), else the same
    function run by this Python."""
    script = Path(sys.executable).parent / "specholo"
    if script.exists():
        return [str(script)]
    return [sys.executable, "-c", "import sys; from specholo_cli.cli import main; "
            "sys.exit(main())"]


def _default_sigint() -> None:
    """In the child: Ctrl-C as at a terminal, even when these tests run in a
    background job (whose children inherit SIGINT ignored, and Python then leaves
    it ignored)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def _interrupt(argv: list[str], after: float) -> subprocess.CompletedProcess[str]:
    proc = subprocess.Popen([*_exe(), *argv], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=ROOT, preexec_fn=_default_sigint)
    time.sleep(after)
    assert proc.poll() is None, "finished before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    out, err = proc.communicate(timeout=60)
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir())}


def test_ctrl_c_during_a_design_leaves_no_output(tmp_path: Path) -> None:
    out = tmp_path / "new" / "holo"
    r = _interrupt(["design", str(BUNNY), "--out", str(out), "--stipples", "4000"], 1.5)
    assert r.returncode == 130, r.stderr
    assert r.stderr == "error: interrupted; no file was left half-written\n"
    assert not out.exists() and not (tmp_path / "new").exists()
    assert list(tmp_path.iterdir()) == []


def test_ctrl_c_while_writing_removes_the_staged_files(tmp_path: Path) -> None:
    """Interrupted while its files are being staged beside the output folder."""
    out = tmp_path / "new" / "holo"
    proc = subprocess.Popen([*_exe(), "design", str(BUNNY), "--out", str(out), "--stipples",
                             "3000", "--formats", "gcode,svg,dxf", "--placement", "phase"],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            preexec_fn=_default_sigint)
    t0 = time.perf_counter()
    while not (out.parent.is_dir() and any(out.parent.iterdir())):
        assert proc.poll() is None and time.perf_counter() - t0 < 120
        time.sleep(0.02)
    staged = next(out.parent.iterdir())
    assert staged.name.startswith(".holo.")
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err == "error: interrupted; no file was left half-written\n"
    assert not staged.exists() and not out.exists() and not out.parent.exists()


def test_ctrl_c_during_a_design_keeps_the_older_one(tmp_path: Path, capsys) -> None:
    out = tmp_path / "holo"
    code, _, err = _run(["design", BUNNY, "--out", out, "--stipples", "10"], capsys)
    assert code == 0, err
    before = _snapshot(out)
    # Once while designing, once while the new files are staged beside it.
    r = _interrupt(["design", str(BUNNY), "--out", str(out), "--stipples", "4000",
                    "--formats", "gcode,svg,dxf"], 1.5)
    assert r.returncode == 130 and r.stderr.count("\n") == 1, r.stderr
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["holo"]
    proc = subprocess.Popen([*_exe(), "design", str(BUNNY), "--out", str(out), "--stipples",
                             "3000", "--formats", "gcode,svg,dxf", "--placement", "phase"],
                            stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, cwd=ROOT,
                            preexec_fn=_default_sigint)
    t0 = time.perf_counter()
    while len(list(tmp_path.iterdir())) < 2:
        assert proc.poll() is None and time.perf_counter() - t0 < 120
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and err.count("\n") == 1, err
    assert _snapshot(out) == before
    assert [p.name for p in tmp_path.iterdir()] == ["holo"]


# ---------------------------------------------------------------- determinism

_SCRIPT = """
import sys
from specholo_cli.cli import main
model, out = sys.argv[1], sys.argv[2]
assert main(["design", model, "--out", out + "/s", "--stipples", "60",
             "--formats", "gcode,svg,dxf"]) == 0
assert main(["verify", out + "/s"]) == 0
assert main(["render", out + "/s", "--width", "96", "--height", "96"]) == 0
assert main(["design", model, "--out", out + "/a", "--stipples", "30", "--method", "arc",
             "--formats", "gcode,pdf"]) == 0
"""


def test_same_inputs_give_byte_identical_files(tmp_path: Path) -> None:
    runs = []
    for i, threads in enumerate(("1", "2")):
        out = tmp_path / f"run{i}"
        env = {**os.environ, "PYTHONHASHSEED": str(17 + i), "NUMBA_NUM_THREADS": threads}
        r = subprocess.run([sys.executable, "-c", _SCRIPT, str(BUNNY), str(out)], env=env,
                           capture_output=True, text=True, timeout=300, cwd=ROOT)
        assert r.returncode == 0, r.stderr[-2000:]
        runs.append(out)
    for sub, names in (("s", {"hologram.gcode", "hologram.svg", "hologram.dxf",
                              "hologram.json", "grooves.npz", "stipples.npz", "model.ply",
                              "preview.png", "verify.json", "verify.png", "render.png"}),
                       ("a", {"hologram.gcode", "pattern.pdf", "hologram.json"})):
        a, b = _snapshot(runs[0] / sub), _snapshot(runs[1] / sub)
        assert set(a) == set(b) and names <= set(a)
        differ = sorted(n for n in a if a[n] != b[n])
        assert differ == ["run.json"], differ
        run = [json.loads(a["run.json"]), json.loads(b["run.json"])]
        assert run[0]["software"]["specholo"] and "numpy" in run[0]["software"]
        assert {r["platform"]["numba_threads"] for r in run} == {1, 2}
        assert run[0]["command"][:2] == ["specholo", "design"]
        assert run[0]["settings"] == run[1]["settings"]


def test_run_json_records_the_run(tmp_path: Path, capsys) -> None:
    out = tmp_path / "holo"
    argv = ["design", str(BUNNY), "--out", str(out), "--stipples", "12", "--seed", "3"]
    code, _, err = _run(argv, capsys)
    assert code == 0, err
    run = json.loads((out / "run.json").read_text())
    assert run["command"] == ["specholo", *argv]
    assert run["settings"]["seed"] == 3 and run["settings"]["stipples"] == 12
    assert set(run["software"]) >= {"specholo", "python", "numpy", "trimesh", "numba"}
    assert set(run["seconds"]) == {"design", "writing"}
    assert "toolpaths" in run["seconds"]["design"] and "gcode" in run["seconds"]["writing"]
    info = json.loads((out / "hologram.json").read_text())
    assert "seconds" not in info["stats"]  # timings live in run.json only


def test_ordering_paths_far_from_the_origin_ends() -> None:
    """The closed-form hyperbolas with the sun at 90 degrees reach 1e16 mm: the
    2-opt pass undid its own moves forever there (rounding passed for gains)."""
    from specholo.fabrication.programs.order import order_paths
    from specholo.toolpaths.common import make_runs
    from specholo.toolpaths.hyperbola import design_hyperbola

    cfg = DesignConfig(light_elevation=90.0, tool_radius=1.0, center_z=-1.756)
    setup = cfg.setup()
    pts = np.random.default_rng(1).uniform(-30, 30, size=(8, 3))
    r = setup.viewer.design_range
    grooves = design_hyperbola(make_runs(pts, np.arange(8), np.full(8, -r), np.full(8, r)),
                               setup)
    assert np.abs(grooves.vertices).max() > 1e12
    order_paths(design_hyperbola(make_runs(pts, np.arange(8), np.full(8, -0.1),
                                           np.full(8, 0.1)), DesignConfig().setup()))
    t0 = time.perf_counter()  # compiled: the time is the ordering's alone
    ordered, stats = order_paths(grooves)
    assert time.perf_counter() - t0 < 10
    assert ordered.n_paths == grooves.n_paths
    assert stats.travel_after_mm <= stats.travel_before_mm


def test_the_closed_form_with_the_sun_in_the_eyes_plane_drops_its_stipples(tmp_path: Path,
                                                                          capsys) -> None:
    out = tmp_path / "holo"
    t0 = time.perf_counter()
    code, _, err = _run(["design", BUNNY, "--out", out, "--stipples", "8", "--method",
                         "hyperbola", "--light-elevation", "90", "--center-z", "-1.756",
                         "--tool-radius", "1"], capsys)
    assert time.perf_counter() - t0 < 30
    # Every stipple the eyes see is dropped: nothing to cut, so nothing is written.
    lines = err.strip().splitlines()
    assert code == 1 and len(lines) == 1, err
    assert lines[0].startswith("error: no stipple gets a groove") and \
        "could not be designed (4: light in the eyes' plane)" in lines[0], err
    assert not out.exists()


@pytest.fixture(scope="module")
def small_folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("small") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "40"]) == 0
    return out


@pytest.mark.parametrize("argv", [
    ["verify", "{d}", "--step", "0.01"],
    ["render", "{d}", "--width", "5000", "--height", "5000", "--ghost"],
    ["animate", "{d}", "--frames", "3000", "--width", "256", "--height", "256",
     "--out", "{d}/turntable.gif"],
], ids=["verify", "render", "animate"])
def test_ctrl_c_during_verify_render_animate(small_folder: Path, argv: list[str]) -> None:
    before = _snapshot(small_folder)
    t0 = time.perf_counter()
    r = _interrupt([a.format(d=small_folder) for a in argv], 2.5)
    assert time.perf_counter() - t0 < 10  # the work in progress is not waited for
    assert r.returncode == 130, r.stderr
    assert r.stderr == "error: interrupted; no file was left half-written\n"
    assert _snapshot(small_folder) == before  # nothing new, nothing half-written


def test_the_glint_index_grid_stays_small_on_a_huge_plate() -> None:
    """Arcs spread over kilometres (the grooves of a nearly flat laser trough)
    made the 5 mm grid of the glint index outgrow memory."""
    from specholo.simulation.glints import ArcIndex

    rng = np.random.default_rng(0)
    mid = rng.uniform(-1e6, 1e6, size=(1000, 2))
    index = ArcIndex.build(mid, rng.uniform(0, math.pi, 1000), np.zeros(1000),
                           np.ones(1000))
    assert index.cell_size > ArcIndex.CELL
    assert index.ny * (int(index.cells.max()) // index.ny + 1) <= 2 * (4 * 1000 + 1024)
