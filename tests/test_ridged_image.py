"""A full-parallax (ridged) plate of the defaults shows an image: each plate
cell sends one ray, so a head sees about (plate area) / (one stipple's patch)
stipples; the defaults keep that budget large, the regions wide enough for
both eyes, and the summary and verify state it."""

from __future__ import annotations

import contextlib
import io
import json
import re
from pathlib import Path

import pytest

from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


def _run(argv: list[str]) -> tuple[int, str]:
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        code = main([str(a) for a in argv])
    return code, buf.getvalue()


@pytest.fixture(scope="module")
def ridged(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, str]:
    out = tmp_path_factory.mktemp("ridged") / "plate"
    code, summary = _run(["design", BUNNY, "--out", out, "--method", "ridged",
                          "--formats", "png"])
    assert code == 0
    code, verified = _run(["verify", out])
    assert code == 0
    return out, summary, verified


def test_the_default_plate_shows_a_head_an_image(ridged: tuple[Path, str, str]):
    out, _, _ = ridged
    summary = json.loads((out / "verify.json").read_text())["summary"]
    # Dozens of stipples glint for both eyes of every head, not one or two.
    assert summary["mean_glinting_per_head"] >= 40
    assert summary["heads_with_glints"] == summary["heads"]
    assert summary["worst_p95_error"] < 0.1


def test_regions_hold_both_eyes(ridged: tuple[Path, str, str]):
    out, _, _ = ridged
    budget = json.loads((out / "hologram.json").read_text())["ridged"]["stereo_budget"]
    # A region narrower than the two eyes' sightlines lie apart never holds both.
    assert budget["region_width_mm"] >= 1.5 * budget["eye_spacing_on_plate_mm"]
    assert budget["stipples_per_head_both_eyes"] >= 0.6 * budget["stipples_per_eye"]


def test_the_summary_and_verify_state_the_budget(ridged: tuple[Path, str, str]):
    out, summary, verified = ridged
    budget = json.loads((out / "hologram.json").read_text())["ridged"]["stereo_budget"]
    per_head = f"{budget['stipples_per_head_both_eyes']:.0f}"
    assert re.search(rf"per head: .* about {per_head} of the 2000 stipples", summary)
    glinting = json.loads((out / "verify.json").read_text())["summary"][
        "mean_glinting_per_head"]
    assert f"per head: {glinting:.0f} stipples glint for both eyes, of the {per_head}" \
        in verified
