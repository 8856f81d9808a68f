"""Every kind of hologram as a job behind one interface (:class:`~.base.Job`).

:data:`JOBS` is the registry: :func:`job_of` tells a folder's kind by the kind
its ``run.json`` names (an older folder's by its files), and each job verifies
its own folders (:meth:`~.base.Job.verify`), returning what to print and the
files to publish, so the command line only parses and prints. Each kind is a
package here (its design and its job); a new kind is one package and a line in
:data:`JOBS`.
"""

from __future__ import annotations

from pathlib import Path

from specholo.folders import register_outputs
from specholo.jobs.base import Job, Table, Verification, VerifyOptions, publish_verification
from specholo.jobs.composition.job import CompositionJob
from specholo.jobs.flat.coupon_job import CouponJob
from specholo.jobs.flat.job import FlatJob
from specholo.jobs.ridged.job import RidgedJob
from specholo.jobs.spin.job import SpinJob
from specholo.jobs.steady.job import SteadyJob

#: The kinds of folder, by the kind each folder names in its ``run.json``; a
#: folder written before run.json named it is told apart by the files each kind
#: :meth:`~.base.Job.holds`, in this order (a flat plate's last).
JOBS: tuple[Job, ...] = (CouponJob(), SpinJob(), SteadyJob(), CompositionJob(), RidgedJob(),
                         FlatJob())
# Every kind's files are specholo's: a design of any kind replaces them all.
register_outputs(name for job in JOBS for name in job.files)


def folder_kind(folder: Path) -> str | None:
    """The kind a folder's ``run.json`` names, or None where it names none (no
    run.json: a folder written before it, or not a design)."""
    from specholo.errors import SpecholoError
    from specholo.readback import read_json

    try:
        run = read_json(Path(folder) / "run.json")
    except SpecholoError:
        return None
    kind = run.get("kind") if isinstance(run, dict) else None
    return kind if isinstance(kind, str) else None


def job_of(folder: Path) -> Job:
    """The job whose kind of design ``folder`` holds: the kind its ``run.json``
    names; for an older folder, the first kind whose files it holds.

    Raises:
        SpecholoError: the folder holds no design of any kind.
    """
    from specholo.errors import SpecholoError

    kind = folder_kind(folder)
    for job in JOBS:
        if job.kind == kind:
            return job
    for job in JOBS:
        if job.holds(folder):
            return job
    raise SpecholoError(f"{folder} holds no hologram.json: not a design folder")


__all__ = ["JOBS", "Job", "Table", "Verification", "VerifyOptions", "folder_kind",
           "job_of",
           "publish_verification"]
