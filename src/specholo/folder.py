"""What kind of design a folder holds, its ``verify.json`` and the rest every job
that writes its own folder shares (turning plates, compositions, steady images):
JSON without NaN, the blank's header line, and the bounds of their settings."""

from __future__ import annotations

import json
import math
import os
from pathlib import Path
from typing import Any

#: The version of the header every kind's ``hologram.json`` opens with
#: (:func:`hologram_header`).
HOLOGRAM_SCHEMA = "specholo-hologram/1"


def hologram_header(kind: str) -> dict[str, str]:
    """What every kind's ``hologram.json`` (a coupon's ``coupon.json``) records
    first: the folder's kind, as its ``run.json`` names it, and the schema."""
    return {"kind": kind, "schema": HOLOGRAM_SCHEMA}


def design_kind(folder: str | os.PathLike[str]) -> str | None:
    """The ``design`` named in a folder's ``hologram.json`` (the kind a folder
    written before the header recorded there), or None if unreadable (the
    design's own loader then says why)."""
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


def config_arguments(saved: Any, setup_type: Any, angles: tuple[str, ...],
                     whole: tuple[str, ...]) -> dict[str, Any]:
    """The keyword arguments of a job's config from what a folder written before
    :func:`shared_settings` recorded (``config``: the config's fields, the
    setup's angles as ``<name>_deg``): the setup rebuilt with its angles back in
    radians, the tool, the machining and the pose (the default pose in folders
    written before poses).
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


#: The machining settings every kind records under the design command's names
#: (:class:`~specholo.setup.Machining`'s fields, in mm/min, mm and rpm).
MACHINING_SETTINGS = ("feed", "plunge", "safe_z", "spindle", "hop", "hop_max")


def shared_settings(config: Any) -> dict[str, Any]:
    """The settings a turning plate and a steady image (``SpinConfig``,
    ``SteadyConfig``) share, as ``hologram.json`` records them: by the command's
    option names (underscores for dashes) and in its units (mm, degrees), as a
    flat design's ``settings`` are. Each kind adds its own (:func:`split_settings`
    reads them back)."""
    from dataclasses import asdict

    pose = config.pose
    return {"size": config.size, "center_z": config.center_z, "stipples": config.stipples,
            "seed": config.seed, "up": pose.up,
            **dict(zip(("rotate_x", "rotate_y", "rotate_z"), pose.rotate_deg, strict=True)),
            **dict(zip(("offset_x", "offset_y"), pose.offset, strict=True)),
            "tool_radius": config.tool.radius, "depth": config.tool.depth,
            "plate_width": config.plate_width, "plate_height": config.plate_height,
            "fit": config.fit, "stock_thickness": config.stock_thickness,
            "dialect": config.dialect, "units": config.units, **asdict(config.machining)}


def from_settings(saved: Any, options: Any, own: tuple[str, ...]) -> tuple[Any, Any,
                                                                          dict[str, Any]]:
    """A turning plate's or a steady image's config from what
    :func:`shared_settings` and the kind's own settings recorded: (the config
    its ``options`` (``from_options``) builds, the machining, and the setup's
    settings named in ``own`` that the command does not take, for the caller to
    put in). A missing setting takes its default; an unknown one, a null where
    the command takes a value, or text where it takes a number is refused in one
    line naming it. Call it inside :func:`specholo.readback.settings_from`,
    which names the file."""
    import inspect

    from specholo.errors import SpecholoError
    from specholo.readback import table
    from specholo.scene.pose import POSE_OPTIONS, Pose
    from specholo.setup import Machining

    given = dict(table(saved, "settings"))
    pose = Pose.from_options(**{k: given.pop(k) for k in POSE_OPTIONS if k in given})
    machining = Machining(**{k: given.pop(k) for k in MACHINING_SETTINGS if k in given})
    extra = {k: given.pop(k) for k in own if k in given}
    takes = inspect.signature(options).parameters
    for key, value in given.items():
        if key not in takes or key == "pose":
            raise SpecholoError(f"unknown setting {key!r}")
        default = takes[key].default
        if value is None and default is not None:
            raise SpecholoError(f"{key} must be given, got null")
        if isinstance(default, int | float) and not isinstance(default, bool) and \
                (isinstance(value, bool) or not isinstance(value, int | float)):
            raise SpecholoError(f"{key} must be a number, got {str(value)[:40]!r}")
    return options(pose=pose, **given), machining, extra


#: Seeds a design takes: the whole numbers numpy's generator is seeded with
#: (a negative one it refuses), as a composition's.
SEED_RANGE = (0, 2**32)
#: Why a verification row's figures are null.
NOTHING_SEEN = "no stipple glints for both eyes here: nothing to measure"


def json_ready(values: dict[str, Any]) -> dict[str, Any]:
    """``values`` with None for each NaN: JSON has no NaN (``json.dump`` writes a
    bare ``NaN`` that strict readers refuse)."""
    return {k: None if isinstance(v, float) and math.isnan(v) else v
            for k, v in values.items()}


def row_json(row: dict[str, Any]) -> dict[str, Any]:
    """A verification row for ``verify.json``: a figure with nothing to measure
    (no stipple glints for both eyes there) is null, and a note says why."""
    out = json_ready(row)
    if out != row:
        out["note"] = NOTHING_SEEN
    return out


def stock_line(config: Any) -> str:
    """The header's words for the blank's thickness (``SpinConfig``, ``SteadyConfig``)."""
    return f"{config.stock_thickness:g} mm thick plate: no cut may reach its back"


def check_job_bounds(config: Any) -> None:
    """Refuse a turning plate's or a steady image's setting (``SpinConfig``,
    ``SteadyConfig``) beyond its physical range, in one line naming its option:
    the model's size and depth, the eyes' spacing, the tool's radius, the plate
    and its thickness, as a flat design's (``setup.SETTING_BOUNDS``), and the seed. Beyond them
    the placement overflows or the optics divide by nothing; a groove depth of
    the tool's radius or less is the tool's own check, and the blank must be
    thicker than the cut."""
    from specholo.errors import SpecholoError
    from specholo.setup import SETTING_BOUNDS
    from specholo.toolpaths.spinning import within

    values = {"size": config.size, "center_z": config.center_z, "ipd": config.setup.ipd,
              "tool_radius": config.tool.radius, "plate_width": config.plate_width,
              "plate_height": config.plate_height, "stock_thickness": config.stock_thickness}
    for name, value in values.items():
        if value is not None:
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise SpecholoError(f"{name.replace('_', '-')} must be a number, got {value!r}")
            within(name, value, *SETTING_BOUNDS[name])
    lo, hi = SEED_RANGE
    if isinstance(config.seed, bool) or not isinstance(config.seed, int) \
            or not lo <= config.seed <= hi:
        raise SpecholoError(f"seed {config.seed} is out of range: it must be a whole number in "
                            f"[{lo}, {hi}]")
    if not config.tool.depth < config.stock_thickness:
        raise SpecholoError(f"a {config.tool.depth:g} mm deep cut would go through the "
                            f"{config.stock_thickness:g} mm plate: give a larger --stock-thickness")
