"""Machine profiles: their table, the physics of the time estimate on each, and
``specholo design --machine``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from specholo.errors import SpecholoError
from specholo.fabrication.programs.machines import KINDS, MACHINES, MachineProfile, machine_profile
from specholo.fabrication.programs.timing import estimate_time
from specholo.jobs.flat.settings import DesignConfig
from specholo.jobs.ridged.settings import RidgedConfig
from specholo.setup import Machining
from specholo.toolpaths.grooves import Grooves
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
ROUTER = machine_profile("grbl-router")
GALVO = machine_profile("galvo-fiber")
PLOTTER = machine_profile("pen-plotter")
#: The router's default feeds: 1000 mm/min cutting, 300 mm/min plunging.
FEEDS = Machining(feed=1000.0, plunge=300.0, safe_z=1.0, spindle=0.0)


def groove(vertices, bulges=None, stipple=0) -> Grooves:
    v = np.asarray(vertices, dtype=float)
    b = np.zeros(len(v)) if bulges is None else np.asarray(bulges, dtype=float)
    return Grooves(v, b, np.array([0, len(v)]), np.array([stipple]))


def parts(est) -> float:
    """Every part of an estimate added up."""
    return (est.cutting_s + est.rapid_s + est.plunge_s + est.dwell_s + est.hop_s + est.lift_s
            + est.delay_s)


def test_every_profile_is_sourced_and_registered_by_name():
    assert list(MACHINES) == ["grbl-router", "linuxcnc-mill", "pen-plotter", "co2-laser",
                              "galvo-fiber"]
    for name, p in MACHINES.items():
        assert p.name == name and p.kind in KINDS and len(p.source) > 40 and p.title
        assert p.feed <= p.xy_rate
    # the figures the issue names
    assert (ROUTER.xy_accel, ROUTER.z_accel, ROUTER.junction_deviation) == (400.0, 50.0, 0.01)
    assert GALVO.xy_accel is None and GALVO.laser and not GALVO.has_z
    assert PLOTTER.pen_raise > 0 and PLOTTER.pen_lower > 0 and PLOTTER.z_rate is None


def test_unknown_machine_is_refused_naming_the_profiles():
    with pytest.raises(SpecholoError, match="unknown machine 'shapeoko': one of grbl-router, "
                                            "linuxcnc-mill, pen-plotter, co2-laser, galvo-fiber"):
        machine_profile("shapeoko")
    with pytest.raises(SpecholoError, match="z_rate must be a positive number"):
        MachineProfile("bad", "router", "a router", "nowhere", xy_rate=1000.0, feed=100.0,
                       xy_accel=100.0, z_accel=10.0, plunge=10.0)


def test_a_long_straight_cut_accelerates_cruises_and_brakes():
    # 100 mm at F = 1000 mm/min with a = 400 mm/s^2: L / F + F / a
    f, a = 1000.0 / 60.0, ROUTER.xy_accel
    est = estimate_time(groove([[0.0, 0.0], [100.0, 0.0]]), 0.02, FEEDS, machine=ROUTER)
    assert est.cutting_s == pytest.approx(100.0 / f + f / a)
    # 0.1 mm never reaches F (sqrt(a L) = 6.3 mm/s): accelerate half way, brake
    est = estimate_time(groove([[0.0, 0.0], [0.1, 0.0]]), 0.02, FEEDS, machine=ROUTER)
    assert est.cutting_s == pytest.approx(2.0 * math.sqrt(0.1 / a))


def test_a_right_angle_slows_to_the_junction_speed():
    f, a, delta = 1000.0 / 60.0, ROUTER.xy_accel, ROUTER.junction_deviation
    c = math.cos(math.pi / 4)  # half of the 90 degree turn
    v = math.sqrt(a * delta * c / (1.0 - c))
    # each leg: reach F over F^2 / 2a, cruise, brake to v over (F^2 - v^2) / 2a
    leg = f / a + (10.0 - f * f / (2 * a) - (f * f - v * v) / (2 * a)) / f + (f - v) / a
    est = estimate_time(groove([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]]), 0.02, FEEDS,
                        machine=ROUTER)
    assert est.cutting_s == pytest.approx(2.0 * leg)


def test_z_moves_run_at_the_z_acceleration():
    # two grooves 1 mm apart: one hop, lifting 0.03 mm above a 0.02 mm groove
    g = Grooves.concatenate([groove([[0.0, 0.0], [10.0, 0.0]], stipple=1),
                             groove([[11.0, 0.0], [21.0, 0.0]], stipple=2)])
    est = estimate_time(g, 0.02, FEEDS, machine=ROUTER)
    za, z_max = ROUTER.z_accel, ROUTER.z_rate / 60.0
    assert est.hops == 1 and math.sqrt(za * 1.02) < z_max  # no lift reaches the Z rate
    # the lift of 0.05 mm at 50 mm/s^2 and the last retract of 1.02 mm, from rest to rest
    assert est.rapid_s == pytest.approx(2 * math.sqrt(0.05 / za) + 2 * math.sqrt(1.02 / za))
    # plunges at 300 mm/min = 5 mm/s: from the safe height it cruises, from the hop it cannot
    assert est.plunge_s == pytest.approx(1.02 / 5.0 + 5.0 / za + 2 * math.sqrt(0.05 / za))
    # the hop is an X/Y move at the feed and the X/Y acceleration
    f, a = 1000.0 / 60.0, ROUTER.xy_accel
    assert est.hop_s == pytest.approx(1.0 / f + f / a)
    assert est.total_s == pytest.approx(parts(est))
    # the Z acceleration is what sets a lift's time: the same on a mill's 508 mm/s^2 is faster
    mill = estimate_time(g, 0.02, FEEDS, machine=machine_profile("linuxcnc-mill"))
    assert mill.plunge_s < est.plunge_s


def test_a_feed_above_the_machine_runs_at_its_rate():
    fast = Machining(feed=20_000.0, plunge=300.0, safe_z=1.0, spindle=0.0)
    capped = estimate_time(groove([[0.0, 0.0], [100.0, 0.0]]), 0.02, fast, machine=ROUTER)
    at_rate = estimate_time(groove([[0.0, 0.0], [100.0, 0.0]]), 0.02,
                            Machining(feed=5000.0, plunge=300.0, spindle=0.0), machine=ROUTER)
    assert capped.cutting_s == pytest.approx(at_rate.cutting_s)


def test_a_galvo_stroke_is_its_delays_and_its_length_over_the_mark_speed():
    mark, jump = GALVO.feed / 60.0, GALVO.xy_rate / 60.0
    laser = Machining(feed=GALVO.feed, plunge=100.0, spindle=0.0)
    # a stroke with one right-angle corner, 50 mm from the origin
    est = estimate_time(groove([[30.0, 40.0], [40.0, 40.0], [40.0, 50.0]]), 0.04, laser,
                        machine=GALVO, dot_time=0.0)
    delays = GALVO.laser_on_delay + GALVO.laser_off_delay + GALVO.polygon_delay
    assert est.cutting_s == pytest.approx(20.0 / mark)
    assert est.rapid_s == pytest.approx(50.0 / jump)
    assert est.delay_s == pytest.approx(delays + GALVO.jump_delay)
    assert est.plunge_s == 0.0 and est.hops == 0
    assert est.total_s == pytest.approx(parts(est))
    # no inertia: an arc is its length over the mark speed, with no corner
    half = estimate_time(groove([[0.0, 0.0], [2.0, 0.0]], [1.0, 0.0]), 0.04, laser,
                         machine=GALVO)
    assert half.cutting_s == pytest.approx(math.pi / mark)
    assert half.delay_s == pytest.approx(GALVO.laser_on_delay + GALVO.laser_off_delay
                                         + GALVO.jump_delay)


def test_a_plotter_lifts_its_pen_once_a_stroke():
    g = Grooves.concatenate([groove([[0.0, 0.0], [10.0, 0.0]], stipple=1),
                             groove([[11.0, 0.0], [21.0, 0.0]], stipple=2),
                             groove([[25.0, 0.0]], stipple=3)])  # a dot: down and up
    pen = Machining(feed=PLOTTER.feed, plunge=100.0, spindle=0.0)
    est = estimate_time(g, 0.01, pen, machine=PLOTTER)
    assert est.lift_s == pytest.approx(3 * (PLOTTER.pen_raise + PLOTTER.pen_lower))
    assert est.hops == 0 and est.hop_s == 0.0 and est.plunge_s == 0.0
    # pen-up travel at the plotter's X/Y rate and acceleration: 1 mm and 4 mm, from rest to rest
    a = PLOTTER.xy_accel
    assert est.rapid_s == pytest.approx(2 * math.sqrt(1.0 / a) + 2 * math.sqrt(4.0 / a))
    assert est.total_s == pytest.approx(parts(est))


def test_the_default_estimate_is_the_same_without_a_machine():
    g = groove([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    est = estimate_time(g, 0.02, FEEDS)
    assert est.lift_s == est.delay_s == 0.0
    assert est.total_s == pytest.approx(est.cutting_s + est.rapid_s + est.plunge_s
                                        + est.dwell_s + est.hop_s)


def test_design_settings_take_the_machines_feeds_and_refuse_its_excess():
    config = DesignConfig.from_dict({"machine": "grbl-router"})
    assert (config.feed, config.plunge, config.profile) == (1000.0, 300.0, ROUTER)
    assert DesignConfig.from_dict({"machine": "grbl-router", "feed": 450}).feed == 450
    galvo = DesignConfig.from_dict({"machine": "galvo-fiber"})
    assert (galvo.tool, galvo.dialect, galvo.feed) == ("laser", "marlin", GALVO.feed)
    assert DesignConfig.from_dict({"machine": "linuxcnc-mill"}).dialect == "linuxcnc"
    assert DesignConfig().machine is None and DesignConfig().profile is None
    for values, message in [
        ({"machine": "grbl-router", "feed": 6000},
         "feed 6000 mm/min is above the grbl-router's X/Y maximum rate 5000 mm/min"),
        ({"machine": "grbl-router", "plunge": 6000},
         "plunge 6000 mm/min is above the grbl-router's Z maximum rate 5000 mm/min"),
        ({"machine": "pen-plotter", "tool": "ball"}, "carries --tool drag or scriber, not ball"),
        ({"machine": "co2-laser", "tool": "drag"}, "carries --tool laser, not drag"),
        ({"machine": "nope"}, "unknown machine 'nope': one of grbl-router"),
    ]:
        with pytest.raises(SpecholoError, match=message.replace("'", ".")):
            DesignConfig.from_dict(values)
    with pytest.raises(SpecholoError, match="--machine times a grooved design"):
        RidgedConfig.from_dict({"machine": "grbl-router"})


def test_unknown_machine_on_the_command_line_is_one_line(tmp_path, capsys):
    code = main(["design", str(BUNNY), "--out", str(tmp_path / "o"), "--stipples", "5",
                 "--machine", "shapeoko"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and "grbl-router" in err[0] and "galvo-fiber" in err[0]
    assert not (tmp_path / "o").exists()
    code = main(["design", str(BUNNY), "--out", str(tmp_path / "o"), "--stipples", "5",
                 "--machine", "grbl-router", "--feed", "9000"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and "maximum rate 5000 mm/min" in err[0]


@pytest.fixture(scope="module")
def on_router(tmp_path_factory) -> tuple[Path, str]:
    """A 60-stipple bunny designed for the GRBL router, and its summary."""
    out = tmp_path_factory.mktemp("machine") / "router"
    return out, _design(out, "--machine", "grbl-router")


def _design(out: Path, *options: str) -> str:
    from contextlib import redirect_stdout
    from io import StringIO

    printed = StringIO()
    with redirect_stdout(printed):
        assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "60",
                     *options]) == 0
    return printed.getvalue()


def test_a_design_names_its_machine_and_its_source(on_router):
    out, summary = on_router
    info = json.loads((out / "hologram.json").read_text())
    mach = info["machining"]
    assert mach["machine"]["name"] == "grbl-router"
    assert mach["machine"]["source"] == ROUTER.source
    assert info["settings"]["machine"] == "grbl-router" and info["settings"]["feed"] == 1000.0
    line = next(ln for ln in summary.splitlines() if ln.startswith("machining"))
    assert line.startswith("machining on grbl-router (Shapeoko-class GRBL): about ")
    assert " at 1000 mm/min" in line and "(Brand's paper reports about 4 a second)" in line
    assert "F1000" in (out / "hologram.gcode").read_text()


def test_the_program_takes_longer_on_the_router_than_on_the_galvo(on_router):
    out, _ = on_router
    info = json.loads((out / "hologram.json").read_text())
    grooves = Grooves.load(out / "grooves.npz")
    depth = info["tool"]["depth_mm"]
    estimates = {}
    for name, profile in MACHINES.items():
        config = DesignConfig.from_dict({"machine": name})
        est = estimate_time(grooves, depth, config.setup().machining, machine=profile)
        assert est.total_s == pytest.approx(parts(est), rel=1e-12), name
        estimates[name] = est
    assert estimates["grbl-router"].total_s > estimates["galvo-fiber"].total_s
