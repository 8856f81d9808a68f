"""Folders as older versions of specholo wrote them, made from today's: the
readers must still take them."""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path

#: Each kind's setup angles, which older folders saved in degrees as ``<name>_deg``.
ANGLES = {"spin": ("elevation",), "steady": ("light_elevation", "light_sweep")}


def old_settings(folder: Path) -> dict:
    """Rewrite a turning plate's or a steady image's ``hologram.json`` as folders
    were written before every kind recorded its settings by the command's
    option names: its config's fields under ``config``, the setup's angles in
    degrees. Returns the rewritten record (written back already)."""
    from specholo.jobs import job_of

    meta_path = folder / "hologram.json"
    meta = json.loads(meta_path.read_text())
    kind = meta["kind"]
    loaded = job_of(folder).load(folder)
    config = loaded.config if kind == "spin" else loaded[1]
    saved = asdict(config)
    for name in ANGLES[kind]:
        saved["setup"][f"{name}_deg"] = math.degrees(saved["setup"].pop(name))
    del meta["settings"]
    meta["config"] = saved
    meta_path.write_text(json.dumps(meta))
    return meta
