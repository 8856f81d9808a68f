"""The job registry: each kind of folder is told apart by its files and owned by
one job, and the options a kind has no use for are refused in one line."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from specholo.errors import SpecholoError
from specholo.jobs import JOBS, VerifyOptions, job_of
from specholo.jobs.base import PICTURE_COMMANDS, quiet, refuse_cut_options
from specholo_cli.cli import main


def folder_of(tmp_path: Path, design: str | None) -> Path:
    folder = tmp_path / (design or "none")
    folder.mkdir()
    if design is not None:
        (folder / "hologram.json").write_text(json.dumps({"design": design}))
    return folder


@pytest.mark.parametrize("design, kind", [
    ("spin", "spin"), ("steady", "steady"), ("composition", "composition"),
    # as folders written before the kinds took their commands' names say it
    ("spinning", "spin"), ("conforming", "composition"),
    ("ridged", "ridged"), ("striped", "flat"), ("arc", "flat")])
def test_each_folder_has_one_owner(tmp_path, design, kind):
    """A folder written before run.json named its kind is told by its files."""
    folder = folder_of(tmp_path, design)
    owners = [job.kind for job in JOBS[:-1] if job.holds(folder)]
    assert len(owners) <= 1
    assert job_of(folder).kind == kind


@pytest.mark.parametrize("kind", [job.kind for job in JOBS])
def test_a_folder_is_its_run_records_kind(tmp_path, kind):
    """A folder's run.json names its kind: the registry takes that, whatever
    other files lie there, and nothing else."""
    folder = folder_of(tmp_path, "striped")  # a flat plate's hologram.json
    (folder / "coupon.json").write_text("{}")  # and a coupon's file
    (folder / "run.json").write_text(json.dumps({"kind": kind}))
    assert job_of(folder).kind == kind


def test_a_folder_of_no_kind_is_refused(tmp_path):
    """No catch-all: a folder holding no design is refused in one line."""
    with pytest.raises(SpecholoError, match="not a design folder") as err:
        job_of(folder_of(tmp_path, None))
    assert "\n" not in str(err.value)


def test_a_ridged_folder_without_settings_is_told_by_its_plate(tmp_path):
    folder = folder_of(tmp_path, None)
    (folder / "plate.npz").write_bytes(b"")
    assert job_of(folder).kind == "ridged"


@pytest.mark.parametrize("job", JOBS[:-1], ids=lambda j: j.kind)
@pytest.mark.parametrize("options", [VerifyOptions(cut=True), VerifyOptions(from_gcode=True)])
def test_cut_options_are_the_flat_plates(tmp_path, job, options):
    with pytest.raises(SpecholoError, match="are for flat-plate designs") as err:
        refuse_cut_options(job, options)
    assert "\n" not in str(err.value) and job.title in str(err.value)
    if job.kind == "coupon" and options.from_gcode:
        return  # a coupon's glints are checked on its program too (tests/test_coupon.py)
    # the job refuses them before reading anything: an empty folder is enough
    with pytest.raises(SpecholoError, match="are for flat-plate designs"):
        job.verify(folder_of(tmp_path, None), options, quiet)


def test_a_flat_folder_missing_its_files_says_so(tmp_path):
    with pytest.raises(SpecholoError):
        job_of(folder_of(tmp_path, None)).verify(tmp_path / "none", VerifyOptions(), quiet)


@pytest.mark.parametrize("design", ["spin", "steady", "composition", "ridged"])
@pytest.mark.parametrize("command", sorted(PICTURE_COMMANDS))
def test_every_picture_command_serves_a_kind_or_says_why(tmp_path, capsys, design, command):
    folder = folder_of(tmp_path, design)
    job = job_of(folder)
    code = main([command, str(folder)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code != 0 and len(err) == 1 and err[0].startswith("error: ")
    if command not in job.pictures:
        # refused before anything is read, naming the pictures the kind has
        assert job.title in err[0] and job.own_pictures in err[0]


class DotsJob:
    """A sixth kind, as a new module would add it: one dimple per model vertex,
    written through the stage, verified by reading its program back."""

    kind = "dots"
    title = "a dot design"
    verified_on = "its dots"
    pictures: frozenset[str] = frozenset()
    own_pictures = "none"
    design_step: tuple[float, float, float] | None = (10.0, 1.0, 45.0)
    preview_frames: int | None = None
    files = frozenset({"hologram.json", "hologram.gcode", "run.json", "dots.txt"})
    overcut = 0.0

    def configure(self, values, inputs):  # type: ignore[no-untyped-def]
        depth = float(values.get("depth", 0.01))
        if not 0 < depth < 0.1:
            raise SpecholoError(f"depth must be in (0, 0.1) mm, got {depth}")
        return depth

    def check_options(self, config, options):  # type: ignore[no-untyped-def]
        from specholo.jobs.base import refuse_formats

        refuse_formats(self, options)

    def design(self, inputs, config, status):  # type: ignore[no-untyped-def]
        from specholo.jobs.base import Designed

        status("reading the model...")
        return Designed((inputs[0].read_text().split(), config), ["one dot per word"])

    def write(self, designed, out, inputs, options, status):  # type: ignore[no-untyped-def]
        from specholo.fabrication.check import Limits, Stock
        from specholo.jobs.base import Summary
        from specholo.staging import stage_design

        words, depth = designed.design
        limits = Limits(Stock(-50.0, -50.0, 50.0, 50.0, 3.0), depth, 1.0, (100.0, 100.0),
                        (0.0, 0.0), tool="drag")
        with stage_design(out, inputs, kind=self.kind) as stage:
            program = ["G21", "G90", "G0 Z1"]
            for i, _ in enumerate(words):
                program += [f"G0 X{i:.1f} Y0", f"G1 Z{-depth - self.overcut:.3f} F100", "G0 Z1"]
            (stage.path / "hologram.gcode").write_text("\n".join(program) + "\n")
            report = stage.check("hologram.gcode", limits)
            (stage.path / "hologram.json").write_text(json.dumps(
                {"design": "dots", "step_deg": options.step_deg}))
            (stage.path / "dots.txt").write_text("\n".join(words))
        return Summary([*designed.notes, f"{len(words)} dots, {report.moves['G1']} plunges"],
                       [])

    def holds(self, folder):  # type: ignore[no-untyped-def]
        from specholo.folder import design_kind

        return design_kind(folder) == "dots"

    def load(self, folder):  # type: ignore[no-untyped-def]
        return json.loads((folder / "hologram.json").read_text())

    def preview(self, folder, status):  # type: ignore[no-untyped-def]
        return {}

    def verify(self, folder, options, status):  # type: ignore[no-untyped-def]
        raise SpecholoError("not verified")


def test_a_sixth_kind_is_one_class_and_a_line_in_the_registry(tmp_path, monkeypatch):
    import specholo.folders as folders
    import specholo.jobs as jobs
    from specholo.jobs.base import WriteOptions, run

    # the registry's line: the kind, and its files made specholo's
    monkeypatch.setattr(folders, "_REGISTERED", set(folders._REGISTERED))
    monkeypatch.setattr(jobs, "JOBS", (DotsJob(), *JOBS))
    folders.register_outputs(DotsJob.files)
    model = tmp_path / "model.txt"
    model.write_text("a b c")
    out = tmp_path / "holo"
    seen: list[str] = []
    summary = run(DotsJob(), [model], {"depth": 0.02}, out, status=seen.append)
    assert summary.lines == ["one dot per word", "3 dots, 3 plunges"]
    assert seen == ["reading the model..."]
    assert jobs.job_of(out).kind == "dots"
    assert json.loads((out / "hologram.json").read_text())["step_deg"] == 10.0  # its default
    # bad settings and steps are refused before anything is designed or written
    for values, options, why in (({"depth": 0.5}, None, "depth must be"),
                                 ({}, WriteOptions(step_deg=90.0), "step must be in"),
                                 ({}, WriteOptions(formats=("svg",)), "writes its own files")):
        with pytest.raises(SpecholoError, match=why):
            run(DotsJob(), [model], values, tmp_path / "never", options, seen.append)
    assert not (tmp_path / "never").exists() and len(seen) == 1  # never designed
    # a dot deeper than its limits: refused, the folder as it was
    before = (out / "hologram.gcode").read_bytes()
    monkeypatch.setattr(DotsJob, "overcut", 0.01)
    with pytest.raises(SpecholoError, match="failed its safety check"):
        run(DotsJob(), [model], {"depth": 0.02}, out)
    assert (out / "hologram.gcode").read_bytes() == before
    # another kind's design over the folder leaves none of the new kind's files
    (out / "notes.txt").write_text("mine")
    bunny = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
    assert main(["design", str(bunny), "--out", str(out), "--stipples", "8"]) == 0
    names = {p.name for p in out.iterdir()}
    assert "dots.txt" not in names and "notes.txt" in names and jobs.job_of(out).kind == "flat"
