"""The shareable report: self-contained, and true to the design's files."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from specholo.preview.report import write_report
from specholo_cli.cli import main

BUNNY = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"


@pytest.fixture(scope="module")
def verified(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("rep") / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "120"]) == 0
    assert main(["verify", str(out)]) == 0
    return out


def test_report_is_self_contained_and_matches_the_files(verified: Path):
    verify = json.loads((verified / "verify.json").read_text())
    info = json.loads((verified / "hologram.json").read_text())
    page = write_report(verified, verify).read_text()
    # One file a user can share: no network, no scripts, pictures inline.
    assert not re.search(r"""(src|href)=["']?(https?:)?//""", page)
    assert "<script" not in page
    assert page.count('src="data:image/png;base64,') >= 2
    # One table row per verified azimuth, with its figures.
    for row in verify["azimuths"]:
        assert f"<td>{row['azimuth']:+.1f}°</td><td>{row['median_error']:.3f}</td>" in page
    assert f"{info['stats']['groove_length_mm'] / 1000:.2f} m" in page
    assert f"{info['stats']['paths']:,}" in page
    # the machining time is the design's own estimate, as hologram.json holds it
    from specholo.fabrication.programs.timing import plain_duration

    hours = info["machining"]["estimated_hours"]
    assert f"<th>machining</th><td>about {plain_duration(3600 * hours)} at" in page
    assert f"{info['stats']['hidden_stipples']:,} stipples (no groove)" in page
    mean = info["expected"]["as_cut_stereo_visibility"]["mean"]
    assert f"about {mean:.0%} of the stipples" in page
    steps = page.split("<h2>What to do next</h2>")[1].split("</ol>")[0]
    assert "specholo verify" not in steps  # verified already


def test_report_before_verification_says_so(tmp_path: Path):
    out = tmp_path / "holo"
    assert main(["design", str(BUNNY), "--out", str(out), "--stipples", "30"]) == 0
    page = write_report(out, None).read_text()
    assert "Not verified yet" in page
    steps = page.split("<h2>What to do next</h2>")[1].split("</ol>")[0]
    assert "specholo verify" in steps and "hologram.gcode" in steps
    # a plate whose glints mostly do not survive the cutting: the report says what to do
    info = json.loads((out / "hologram.json").read_text())
    lowest = info["expected"]["as_cut_stereo_visibility"]["lowest"]
    assert ("--visibility 0.6" in steps) == (lowest < 0.6)
    info["expected"]["as_cut_stereo_visibility"]["lowest"] = 0.3
    (out / "hologram.json").write_text(json.dumps(info))
    assert "Only about 30% of the stipples survive" in write_report(out, None).read_text()


def test_report_command(verified: Path, capsys):
    assert main(["report", str(verified)]) == 0
    assert "report ->" in capsys.readouterr().out
    assert (verified / "report.html").stat().st_size > 10_000
    assert main(["report", str(verified / "nowhere")]) != 0
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1
