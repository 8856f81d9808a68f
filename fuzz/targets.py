"""Fuzz targets shared by the atheris harnesses in this folder and by tests/test_fuzz.py.

Every ``check_*`` function feeds one input to specholo and returns normally when
specholo either accepted it with a sane result or refused it with a
:class:`~specholo.errors.SpecholoError` whose message is one non-empty line.
Anything else propagates and is a crash: another exception, a multi-line or
empty message, a result that breaks the documented invariants, or a warning or
log record that would reach the user's terminal.

This module does not import atheris, so the regression test can replay saved
inputs without it.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import logging
import math
import os
import re
import tempfile
import traceback
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from specholo.errors import SpecholoError

#: Model extensions picked by the first byte of a load_model fuzz input.
MODEL_EXTS = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf", ".xyz", ".csv")


class FuzzFailure(AssertionError):
    """specholo mishandled an input (not an expected SpecholoError)."""


class _Records(logging.Handler):
    """Keeps every WARNING+ record: with no logging set up, Python prints those on stderr."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.records: list[logging.LogRecord] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)


@contextlib.contextmanager
def quiet_check(what: str) -> Iterator[None]:
    """Fail if the block warns or logs at WARNING or above (it would print on stderr)."""
    handler = _Records()
    root = logging.getLogger()
    root.addHandler(handler)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
    finally:
        root.removeHandler(handler)
    if caught:
        w = caught[0]
        raise FuzzFailure(f"{what}: a warning would reach stderr: {w.category.__name__}: "
                          f"{w.message} ({Path(w.filename).name}:{w.lineno})")
    if handler.records:
        r = handler.records[0]
        raise FuzzFailure(f"{what}: a log record would reach stderr: {r.name}: {r.getMessage()}")


def check_message(exc: SpecholoError, what: str, must_name: str | None = None) -> None:
    """A SpecholoError must carry one short non-empty line (naming the file if given)."""
    msg = str(exc)
    if not msg.strip() or "\n" in msg or "\r" in msg:
        raise FuzzFailure(f"{what}: message is not one line: {msg!r}") from exc
    if "Traceback" in msg:
        raise FuzzFailure(f"{what}: message holds a traceback: {msg!r}") from exc
    if must_name is not None and must_name not in msg:
        raise FuzzFailure(f"{what}: message does not name {must_name!r}: {msg!r}") from exc


# ---------------------------------------------------------------- load_model


def model_case(data: bytes) -> tuple[str, bytes]:
    """Split a fuzz input into a model extension (first byte) and the file's bytes."""
    if not data:
        return ".obj", b""
    return MODEL_EXTS[data[0] % len(MODEL_EXTS)], data[1:]


def check_model(model: Any, what: str) -> None:
    """The invariants of a loaded model (see specholo.scene.loading.Model)."""
    pts = model.points
    if not (isinstance(pts, np.ndarray) and pts.dtype == np.float64 and pts.ndim == 2
            and pts.shape[1] == 3 and len(pts) > 0):
        raise FuzzFailure(f"{what}: bad points array {getattr(pts, 'shape', None)}")
    if not np.isfinite(pts).all():
        raise FuzzFailure(f"{what}: non-finite points accepted")
    if model.mesh is None:
        return
    faces = np.asarray(model.mesh.faces)
    if faces.ndim != 2 or faces.shape[1] != 3 or len(faces) == 0:
        raise FuzzFailure(f"{what}: bad faces array {faces.shape}")
    if faces.min() < 0 or faces.max() >= len(pts):
        raise FuzzFailure(f"{what}: face index out of range")
    if not np.array_equal(np.asarray(model.mesh.vertices), pts):
        raise FuzzFailure(f"{what}: points differ from the mesh vertices")
    with np.errstate(all="ignore"):
        scale = float(np.max(np.abs(pts)))
        tri = pts[faces] / scale
        area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not (area > 0).all():
        raise FuzzFailure(f"{what}: zero-area face kept")


def check_model_file(path: str | os.PathLike[str], stipples: int = 8) -> None:
    """Load a model file; if it loads, place it and put a few stipples on it."""
    from specholo.scene.loading import load_model
    from specholo.scene.placement import place
    from specholo.scene.stippling import stipple

    name = Path(path).name
    with quiet_check(f"load {name}"):
        try:
            model = load_model(path)
        except SpecholoError as exc:
            check_message(exc, f"load {name}", must_name=name)
            return
        check_model(model, f"load {name}")
        try:
            placed = place(model, 60.0, -40.0)
        except SpecholoError as exc:
            check_message(exc, f"place {name}")
            return
        if not np.isfinite(placed.points).all():
            raise FuzzFailure(f"place {name}: non-finite placed points")
        extent = float(np.max(np.ptp(placed.points, axis=0)))
        if not math.isclose(extent, 60.0, rel_tol=1e-6):
            raise FuzzFailure(f"place {name}: placed size {extent} instead of 60")
        try:
            st = stipple(placed, np.random.default_rng(0), count=stipples)
        except SpecholoError as exc:
            check_message(exc, f"stipple {name}")
            return
        if not (0 < len(st.points) <= stipples and np.isfinite(st.points).all()):
            raise FuzzFailure(f"stipple {name}: {len(st.points)} stipples or non-finite")
        if placed.mesh is not None and (st.normals is None or not np.isfinite(st.normals).all()):
            raise FuzzFailure(f"stipple {name}: bad normals")


_TMP: Path | None = None


def scratch(name: str) -> Path:
    """A path in a per-process scratch folder (reused between inputs)."""
    global _TMP
    if _TMP is None:
        _TMP = Path(tempfile.mkdtemp(prefix="specholo-fuzz-"))
    return _TMP / name


def check_model_bytes(data: bytes) -> None:
    """The load_model fuzz target: first byte picks the format, the rest is the file."""
    ext, body = model_case(data)
    path = scratch("model" + ext)
    path.write_bytes(body)
    check_model_file(path)


# ---------------------------------------------------------------- TOML configs


class _Bytes:
    """Draws small choices from a byte string (zeros once it runs out)."""

    def __init__(self, data: bytes) -> None:
        self.data = data
        self.pos = 0

    def byte(self) -> int:
        b = self.data[self.pos] if self.pos < len(self.data) else 0
        self.pos += 1
        return b

    def pick(self, options: tuple[Any, ...] | list[Any]) -> Any:
        return options[self.byte() % len(options)]

    def text(self, limit: int = 12) -> str:
        n = self.byte() % (limit + 1)
        raw = bytes(self.byte() for _ in range(n))
        return raw.decode("utf-8", errors="replace")


def _fields() -> list[str]:
    from dataclasses import fields

    from specholo.pipeline import DesignConfig

    return [f.name for f in fields(DesignConfig)]


_NUMBERS = ("0", "-0.0", "1", "-1", "2", "0.5", "1e-300", "1e300", "-1e300", "nan", "inf",
            "-inf", "+inf", "45", "90", "180", "600", "12000", "10", "1e9", "1_000_000_000_000",
            "9223372036854775807", "-9223372036854775808", "3.0", "1e18")
_STRINGS = ('"striped"', '"hyperbola"', '"arc"', '"ball"', '"vbit"', '"drag"', '"scriber"',
            '"laser"', '"60"', '"nan"', '""', '"many"')


def _value(b: _Bytes, depth: int = 0) -> str:
    kind = b.byte() % 10
    if kind <= 3:
        return str(b.pick(_NUMBERS))
    if kind == 4:
        return str(b.pick(_STRINGS))
    if kind == 5:
        return str(b.pick(("true", "false")))
    if kind == 6 and depth < 2:
        return "[" + ", ".join(_value(b, depth + 1) for _ in range(b.byte() % 3)) + "]"
    if kind == 7 and depth < 2:
        return "{" + ", ".join(f"{b.pick(_fields())} = {_value(b, depth + 1)}"
                               for _ in range(b.byte() % 3)) + "}"
    if kind == 8:
        return str(b.pick(("1979-05-27T07:32:00Z", "1979-05-27", "07:32:00")))
    return json.dumps(b.text(), ensure_ascii=False)


def config_text(data: bytes) -> bytes:
    """A TOML file from a fuzz input: raw bytes (first byte even) or key = value lines."""
    if not data or data[0] % 2 == 0:
        return data[1:]
    b = _Bytes(data[1:])
    names = _fields()
    lines = []
    for _ in range(1 + b.byte() % 6):
        name = b.pick(names)
        key = b.pick((name, name.replace("_", "-"), name.upper(), b.text(6) or "x"))
        lines.append(f"{json.dumps(key, ensure_ascii=False)} = {_value(b)}")
    return ("\n".join(lines) + "\n").encode("utf-8")


def check_config_file(path: str | os.PathLike[str]) -> None:
    """Read a TOML config as the CLI does; a config that is accepted must be usable."""
    from specholo.pipeline import DesignConfig
    from specholo_cli.cli import _read_config

    name = Path(path).name
    with quiet_check(f"config {name}"):
        try:
            values = _read_config(Path(path))
            config = DesignConfig.from_dict(values)
        except SpecholoError as exc:
            check_message(exc, f"config {name}")
            return
        # An accepted config holds settings of the right types, so the physical
        # setup and tool are built without surprises and the stipple count can
        # be checked against memory before any work.
        config.setup()
        np.random.default_rng(config.seed)  # design() seeds its stippling so
        depth = config.depth_mm if hasattr(config, "depth_mm") else config.depth
        config.cutter().section(float(depth))
        for field in ("size", "center_z", "band"):
            if not math.isfinite(float(getattr(config, field))):
                raise FuzzFailure(f"config {name}: {field} is not finite")
        if config.stipples is not None:
            from specholo.scene.stippling import check_memory

            try:
                check_memory(int(config.stipples))
            except SpecholoError as exc:
                check_message(exc, f"config {name} memory")


def check_config_bytes(data: bytes) -> None:
    """The config fuzz target."""
    path = scratch("config.toml")
    path.write_bytes(config_text(data))
    check_config_file(path)


# ---------------------------------------------------------------- G-code reader


def check_gcode_file(path: str | os.PathLike[str]) -> None:
    """Read a G-code program back into grooves; accepted grooves must be well formed."""
    from specholo.fabrication.gcode import read_gcode

    name = Path(path).name
    with quiet_check(f"gcode {name}"):
        try:
            g = read_gcode(path)
        except SpecholoError as exc:
            check_message(exc, f"gcode {name}")
            return
        v, bulges, offsets = g.vertices, g.bulges, g.offsets
        if v.ndim != 2 or v.shape[1] != 2 or len(bulges) != len(v):
            raise FuzzFailure(f"gcode {name}: bad groove arrays")
        if offsets[0] != 0 or offsets[-1] != len(v) or (np.diff(offsets) <= 0).any():
            raise FuzzFailure(f"gcode {name}: bad path offsets {offsets[:5]}")
        if len(g.stipple) != len(offsets) - 1:
            raise FuzzFailure(f"gcode {name}: stipple ids do not match paths")
        if not (np.isfinite(v).all() and np.isfinite(bulges).all()):
            raise FuzzFailure(f"gcode {name}: non-finite groove vertices or bulges accepted")


_GCODE_NUMBERS = ("0", "1", "-1", "0.5", "-0.1", "10.00000", "1e3", ".5", "5.", "+2",
                  "99999999999999999999999", "-99999999999999999999999", "9" * 320,
                  "0." + "0" * 330 + "1", "1" * 19, "3.14159")
_GCODE_WORDS = ("G0", "G1", "G2", "G3", "G17", "G20", "G21", "G80", "G90", "G91", "G4", "M2",
                "M3", "M5", "M30", "X", "Y", "Z", "I", "J", "F", "S", "P", "R", "T", "N")


def gcode_text(data: bytes) -> bytes:
    """A G-code program from a fuzz input: raw bytes (first byte even) or generated lines."""
    if not data or data[0] % 2 == 0:
        return data[1:]
    b = _Bytes(data[1:])
    lines = []
    for _ in range(1 + b.byte() % 12):
        kind = b.byte() % 8
        if kind == 0:
            lines.append(f"(stipple {b.pick(_GCODE_NUMBERS)})")
        elif kind == 1:
            lines.append(b.pick(("%", "; comment", "(comment)", "", "M2", "G0 Z1", "G1 Z-0.1")))
        elif kind == 2:
            lines.append(b.text(16))
        else:
            words = []
            for _ in range(1 + b.byte() % 4):
                word = str(b.pick(_GCODE_WORDS))
                words.append(word if word[1:] else word + str(b.pick(_GCODE_NUMBERS)))
            lines.append(" ".join(words))
    return ("\n".join(lines) + "\n").encode("utf-8", errors="surrogatepass")


def check_gcode_bytes(data: bytes) -> None:
    """The G-code reader fuzz target: the first byte picks raw or generated text."""
    path = scratch("program.gcode")
    path.write_bytes(gcode_text(data))
    check_gcode_file(path)


# ---------------------------------------------------------------- collecting crashes

_SEEN: dict[str, int] = {}


def signature(exc: BaseException) -> str:
    """Exception type and the innermost frame of the project or trimesh, for de-duplication."""
    frames = traceback.extract_tb(exc.__traceback__)
    inner = [f for f in frames if "specholo" in f.filename or "trimesh" in f.filename] or frames
    where = f"{Path(inner[-1].filename).name}:{inner[-1].lineno}" if inner else "?"
    if isinstance(exc, FuzzFailure):  # the failed check, without the file's numbers
        return "FuzzFailure " + re.sub(r"[\d.]+", "#", str(exc))[:100]
    return f"{type(exc).__name__} at {where}"


def run_case(check: Callable[[bytes], None], data: bytes) -> None:
    """Run one fuzz case; with $SPECHOLO_FUZZ_COLLECT set, save crashes there and go on.

    libFuzzer stops at the first crash; collecting keeps fuzzing and keeps a few
    inputs per distinct crash (type and place) instead.
    """
    folder = os.environ.get("SPECHOLO_FUZZ_COLLECT")
    if not folder:
        check(data)
        return
    try:
        check(data)
    except Exception as exc:  # noqa: BLE001 - every crash is recorded
        sig = signature(exc)
        seen = _SEEN.get(sig, 0)
        _SEEN[sig] = seen + 1
        if seen < 3:
            tag = hashlib.sha1(sig.encode()).hexdigest()[:8]
            name = f"crash-{tag}-{hashlib.sha1(data).hexdigest()[:12]}"
            out = Path(folder)
            out.mkdir(parents=True, exist_ok=True)
            (out / name).write_bytes(data)
            with open(out / "signatures.txt", "a", encoding="utf-8") as fh:
                fh.write(f"{name}\t{sig}\t{' '.join(str(exc).split())[:300]}\n")
