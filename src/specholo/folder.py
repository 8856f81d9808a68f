"""What kind of design a folder holds, and its ``verify.json``: shared by the jobs
that write their own folders (turning plates, compositions, steady images)."""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any


def design_kind(folder: str | os.PathLike[str]) -> str | None:
    """The ``design`` named in a folder's ``hologram.json``, or None if unreadable
    (the design's own loader then says why)."""
    from specholo.errors import SpecholoError
    from specholo.readback import read_json

    try:
        meta = read_json(Path(folder) / "hologram.json")
    except SpecholoError:
        return None
    kind = meta.get("design") if isinstance(meta, dict) else None
    return kind if isinstance(kind, str) else None


def write_verify_json(folder: str | os.PathLike[str], step_deg: float,
                      summary: dict[str, Any], key: str, rows: list[dict[str, Any]]) -> None:
    """Write ``verify.json`` atomically: the step, the summary and one row per position."""
    from specholo.fabrication.atomic import atomic_open

    with atomic_open(Path(folder) / "verify.json") as fh:
        json.dump({"step_deg": step_deg, "summary": summary, key: rows}, fh, indent=1)
