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
    ("spinning", "spinning"), ("steady", "steady"), ("conforming", "composed"),
    ("ridged", "ridged"), ("striped", "flat"), ("arc", "flat"), (None, "flat")])
def test_each_folder_has_one_owner(tmp_path, design, kind):
    folder = folder_of(tmp_path, design)
    owners = [job.kind for job in JOBS[:-1] if job.holds(folder)]
    assert len(owners) <= 1
    assert job_of(folder).kind == kind


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
    # the job refuses them before reading anything: an empty folder is enough
    with pytest.raises(SpecholoError, match="are for flat-plate designs"):
        job.verify(folder_of(tmp_path, None), options, quiet)


def test_a_flat_folder_missing_its_files_says_so(tmp_path):
    with pytest.raises(SpecholoError):
        job_of(folder_of(tmp_path, None)).verify(tmp_path / "none", VerifyOptions(), quiet)


@pytest.mark.parametrize("design", ["spinning", "steady", "conforming", "ridged"])
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
