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


#: The version of ``verify.json``'s shared keys (:func:`write_verify_json`).
VERIFY_SCHEMA = "specholo-verify/1"

#: Where each kind's summary gives the figures every kind has (older
#: ``verify.json`` files hold only the summary): (worst p95 error, lowest visibility).
_FIGURE_KEYS = (("worst_p95_error", "worst_p95_mm"), ("min_visibility", "lowest_visibility"))


def verify_figures(summary: dict[str, Any], positions: int) -> dict[str, Any]:
    """The figures every kind's verification gives, under one name each: the
    worst 95th-percentile error of the apparent point (mm), the lowest share of
    stipples shown to both eyes, and the number of positions simulated."""
    worst, lowest = (next((summary[k] for k in keys if k in summary), None)
                     for keys in _FIGURE_KEYS)
    return {"worst_p95_mm": worst, "lowest_visibility": lowest, "positions": positions}


def write_verify_json(folder: str | os.PathLike[str], kind: str, step_deg: float,
                      summary: dict[str, Any], key: str, rows: list[dict[str, Any]],
                      extra: dict[str, Any] | None = None, name: str = "verify.json") -> None:
    """Write a verification atomically, in the one schema every kind shares:
    ``schema``, ``kind``, ``step_deg``, ``figures`` (:func:`verify_figures`) and
    ``summary`` (the kind's own figures), then one row per position under ``key``
    (``azimuths``, ``views``, ``positions``, ``angles``, ``elevations``: what the
    kind moves) and the kind's ``extra`` keys (what it verified).
    """
    from specholo.fabrication.atomic import atomic_open

    record = {"schema": VERIFY_SCHEMA, "kind": kind, "step_deg": step_deg,
              "figures": verify_figures(summary, len(rows)), "summary": summary,
              "rows": key, **(extra or {}), key: rows}
    with atomic_open(Path(folder) / name) as fh:
        json.dump(record, fh, indent=1, sort_keys=False)


def read_verify_figures(path: str | os.PathLike[str]) -> dict[str, Any]:
    """The shared figures of a ``verify.json`` of any kind, written now or before
    the shared schema (those are worked out from the kind's own summary).

    Raises:
        SpecholoError: the file is unreadable or holds no summary.
    """
    from specholo.errors import SpecholoError
    from specholo.readback import read_json

    record = read_json(Path(path))
    if not isinstance(record, dict) or not isinstance(record.get("summary"), dict):
        raise SpecholoError(f"{path}: not a verification (no summary)")
    if isinstance(record.get("figures"), dict):
        return dict(record["figures"])
    rows = next((v for k in ("azimuths", "views", "positions", "angles", "elevations")
                 if isinstance(v := record.get(k), list)), [])
    return verify_figures(record["summary"], len(rows))


def saved_config(config: Any, angles: tuple[str, ...]) -> dict[str, Any]:
    """A job's config as its ``hologram.json`` records it: a table of tables, the
    setup's ``angles`` (radians inside) saved in degrees as ``<name>_deg``."""
    import math
    from dataclasses import asdict

    saved = asdict(config)
    for name in angles:
        saved["setup"][f"{name}_deg"] = math.degrees(saved["setup"].pop(name))
    return saved


def config_arguments(saved: Any, setup_type: Any, angles: tuple[str, ...],
                     whole: tuple[str, ...]) -> dict[str, Any]:
    """The keyword arguments of a job's config from what :func:`saved_config`
    recorded: the setup rebuilt with its angles back in radians, the tool, the
    machining and the pose (the default pose in folders written before poses).
    Call it inside :func:`specholo.readback.settings_from`, which names the file
    in the one-line error a bad value gives.

    Args:
        saved: the ``config`` table of ``hologram.json``.
        setup_type: the setup's class (it checks its own values).
        angles: the setup's angles saved in degrees.
        whole: keys of the config or its setup that must be whole numbers (they
            size arrays).
    """
    import math

    from specholo.readback import number, table
    from specholo.readback import whole as whole_number
    from specholo.scene.pose import Pose
    from specholo.setup import Machining, Tool

    c = dict(table(saved, "config"))
    st = dict(table(c.pop("setup"), "config.setup"))
    c["pose"] = Pose.from_saved(c.pop("pose", None))
    for name in angles:
        st[name] = math.radians(number(st.pop(f"{name}_deg"), f"{name}_deg"))
    for values in (c, st):
        for key in whole:
            if key in values:
                whole_number(values[key], key)
    c["setup"] = setup_type(**st)
    c["tool"] = Tool(**table(c.pop("tool"), "tool"))
    c["machining"] = Machining(**table(c.pop("machining"), "machining"))
    return c
