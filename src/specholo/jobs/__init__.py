"""Every kind of hologram as a job behind one interface (:class:`~.base.Job`).

:data:`JOBS` is the registry: :func:`job_of` tells a folder's kind from its
files, and each job verifies its own folders (:meth:`~.base.Job.verify`),
returning what to print and the files to publish, so the command line only
parses and prints. Each kind is a package here (its design and its job); a new
kind is one package and a line in :data:`JOBS`.
"""

from __future__ import annotations

from pathlib import Path

from specholo.folders import register_outputs
from specholo.jobs.base import Job, Table, Verification, VerifyOptions, publish_verification
from specholo.jobs.composition.job import CompositionJob
from specholo.jobs.coupon.job import CouponJob
from specholo.jobs.flat.job import FlatJob
from specholo.jobs.ridged.job import RidgedJob
from specholo.jobs.spin.job import SpinJob
from specholo.jobs.steady.job import SteadyJob

#: The kinds of folder, in the order they are told apart: the first whose
#: :meth:`~.base.Job.holds` is true owns the folder; a flat design is the rest.
JOBS: tuple[Job, ...] = (CouponJob(), SpinJob(), SteadyJob(), CompositionJob(), RidgedJob(),
                         FlatJob())
# Every kind's files are specholo's: a design of any kind replaces them all.
register_outputs(name for job in JOBS for name in job.files)


def job_of(folder: Path) -> Job:
    """The job whose kind of design ``folder`` holds (the flat design's when no
    other's: its loader then says what is missing)."""
    for job in JOBS:
        if job.holds(folder):
            return job
    return JOBS[-1]


__all__ = ["JOBS", "Job", "Table", "Verification", "VerifyOptions", "job_of",
           "publish_verification"]
