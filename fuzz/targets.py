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

    from specholo.jobs.flat.folder import DesignConfig

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
    from specholo.jobs.flat.folder import DesignConfig
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
    from specholo.fabrication.programs.gcode_reader import read_gcode

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


# ---------------------------------------------------------------- design folders


def compiled_modules() -> list[str]:
    """The modules of specholo with compiled (numba) kernels, for atheris to leave
    alone: numba compiles a kernel from its bytecode, which instrumented bytecode
    breaks (it calls into atheris)."""
    import importlib.util

    spec = importlib.util.find_spec("specholo")
    assert spec is not None and spec.origin is not None
    root = Path(spec.origin).parent
    found = re.compile(r"^\s*(import numba|from numba)", re.MULTILINE)
    return sorted(".".join(p.relative_to(root.parent).with_suffix("").parts)
                  for p in root.rglob("*.py")
                  if found.search(p.read_text(encoding="utf-8", errors="replace")))


#: The files of a design folder that the folder fuzz target mutates.
FOLDER_FILES = ("hologram.json", "grooves.npz", "stipples.npz", "model.ply")
#: Commands run on a mutated folder: each must work or refuse in one line.
FOLDER_COMMANDS = (("verify", "--step", "5"), ("render", "--width", "24", "--height", "24"),
                   ("report",), ("stereo", "--width", "16", "--height", "16"),
                   ("verify", "--from-gcode", "--step", "5"))

_TET = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n"
        "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")
_BASE: Path | None = None


def base_folder() -> Path:
    """A tiny design folder (8 stipples on a tetrahedron), made once per process."""
    global _BASE
    if _BASE is None:
        from specholo.jobs.flat.folder import DesignConfig, design, write_design

        model = scratch("tet.obj")
        model.write_text(_TET)
        d = design(model, DesignConfig(stipples=8, view_range=20.0, seed=1))
        write_design(d, scratch("base"), ("gcode",))
        _BASE = scratch("base")
    return _BASE


_HOSTILE_NUMBERS = (math.nan, math.inf, -math.inf, -1, -100, 0, 10**12, -1e12, 2**62, 1e300,
                    -0.0, 1, 3)
_HOSTILE_DTYPES = ("float32", "float16", "int8", "uint64", "int32", "bool", ">f8", ">i8",
                   "complex128", "object", "U3")
_HOSTILE_JSON: tuple[Any, ...] = (None, -1, 0, 1e308, -1e308, "x", "", [], {}, True, math.nan,
                                  math.inf, 10**30, [1, 2], {"a": 1}, 0.5)


def _mutate_array(a: np.ndarray, b: _Bytes) -> np.ndarray | None:
    """One hostile change to an array (None: drop it from the file)."""
    op = b.byte() % 9
    flat = a.reshape(-1).copy()
    if op == 0 and flat.size:  # one hostile element
        v = b.pick(_HOSTILE_NUMBERS)
        i = b.byte() % flat.size
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            flat = flat.astype(float) if isinstance(v, float) and flat.dtype.kind in "iub" \
                else flat
            flat[i] = v if flat.dtype.kind == "f" or not isinstance(v, float) or math.isfinite(v) \
                else 0
        return flat.reshape(a.shape)
    if op == 1 and a.dtype.kind in "iuf":  # everything shifted
        return a + b.pick((-100, -1, 1, 10**6))
    if op == 2 and a.ndim:  # cut short
        return a[:b.byte() % (len(a) + 1)]
    if op == 3:  # another dtype
        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return a.astype(b.pick(_HOSTILE_DTYPES))
    if op == 4:  # another shape
        return b.pick((a.T, a.reshape(-1), a[..., None], np.asfortranarray(a)))
    if op == 5:
        return None
    if op == 6:
        return np.zeros((0,) * max(a.ndim, 1), dtype=a.dtype)
    if op == 7:
        return np.array(b.pick(_HOSTILE_NUMBERS))
    return a[::-1].copy() if a.ndim else a  # reversed: offsets that decrease


def _mutate_npz(path: Path, b: _Bytes) -> None:
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    for _ in range(1 + b.byte() % 3):
        if not arrays:
            break
        key = b.pick(sorted(arrays))
        new = _mutate_array(arrays[key], b)
        if new is None:
            del arrays[key]
        else:
            arrays[key] = new
    np.savez(path, **arrays)  # object arrays are pickled: the reader must refuse them


def _mutate_json(path: Path, b: _Bytes) -> None:
    info = json.loads(path.read_text())
    for _ in range(1 + b.byte() % 3):
        node = info
        # Walk down a few levels of tables and lists, then replace or drop what is there.
        for _ in range(b.byte() % 4):
            keys = list(node) if isinstance(node, dict) else list(range(len(node))) \
                if isinstance(node, list) else []
            child = node[b.pick(keys)] if keys else None
            if not isinstance(child, dict | list) or not child:
                break
            node = child
        if isinstance(node, dict) and node:
            key = b.pick(sorted(node))
            if b.byte() % 5 == 0:
                del node[key]
            else:
                node[key] = b.pick(_HOSTILE_JSON)
        elif isinstance(node, list) and node:
            node[b.byte() % len(node)] = b.pick(_HOSTILE_JSON)
    path.write_text(json.dumps(info))


def mutate_folder(data: bytes, folder: Path) -> str:
    """Apply a fuzz input to the design folder ``folder`` (a copy of :func:`base_folder`).

    The first byte picks the file, the second how: the rest of the input as the
    whole file (raw), a hostile change to its arrays or settings, or byte edits
    (truncation, overwrites) of the real file.

    Returns:
        What was done, for messages.
    """
    b = _Bytes(data)
    name = FOLDER_FILES[b.byte() % len(FOLDER_FILES)]
    mode = b.byte() % 3
    path = folder / name
    if mode == 0:
        path.write_bytes(data[2:])
        return f"{name} raw"
    if mode == 1 and name.endswith(".npz"):
        _mutate_npz(path, b)
        return f"{name} arrays"
    if mode == 1 and name.endswith(".json"):
        _mutate_json(path, b)
        return f"{name} settings"
    raw = bytearray(path.read_bytes())
    for _ in range(1 + b.byte() % 4):
        if not raw:
            break
        at = (b.byte() << 8 | b.byte()) % len(raw)
        op = b.byte() % 3
        if op == 0:
            del raw[at:]
        elif op == 1:
            raw[at] = b.byte()
        else:
            raw[at:at] = bytes(b.byte() for _ in range(1 + b.byte() % 8))
    path.write_bytes(bytes(raw))
    return f"{name} bytes"


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    """Run a ``specholo`` command in this process: exit code, stdout, stderr."""
    import io

    from specholo_cli.cli import main

    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = main([str(a) for a in argv])
    return code, out.getvalue(), err.getvalue()


def check_cli_result(code: int, err: str, what: str) -> None:
    """A command either worked (0) or refused in one line (1, "error: ...")."""
    lines = err.strip().splitlines()
    if code == 0:
        return
    if code != 1 or len(lines) != 1 or not lines[0].startswith("error: ") \
            or "internal error" in err or "Traceback" in err:
        raise FuzzFailure(f"{what}: exit {code}, stderr {err.strip()[:300]!r}")


def check_folder(folder: Path, what: str, commands: tuple[tuple[str, ...], ...] = FOLDER_COMMANDS
                 ) -> None:
    """Run the commands that read design folders on ``folder``."""
    for command in commands:
        name, *options = command
        label = f"{what}: {' '.join(command)}"
        with quiet_check(label):
            code, _, err = run_cli([name, str(folder), *options])
        check_cli_result(code, err, label)


def check_folder_bytes(data: bytes,
                       commands: tuple[tuple[str, ...], ...] = FOLDER_COMMANDS) -> None:
    """The folder fuzz target: a tiny design folder, one file mutated, then read back
    by verify, render, report and stereo (``commands``)."""
    import shutil

    base = base_folder()
    folder = scratch("folder")
    shutil.rmtree(folder, ignore_errors=True)
    shutil.copytree(base, folder)
    what = mutate_folder(data, folder)
    check_folder(folder, what, commands)


def check_folder_input(path: str | os.PathLike[str]) -> None:
    """Replay a saved folder fuzz input (kept as the input itself: it edits the
    tiny design folder of :func:`base_folder`)."""
    check_folder_bytes(Path(path).read_bytes())


# ---------------------------------------------------------------- compositions

_COMP_NUMBERS = ("0", "1", "2", "5", "-1", "0.5", "30", "45", "60", "90", "180", "1e9", "-1e9",
                 "nan", "inf", "-inf", "1e400", "99999999999999999999", "3.0", "1.5", "0.001")
_COMP_KEYS: dict[str, tuple[str, ...]] = {
    "": ("mode", "stipples", "seed", "band", "step"),
    "host": ("kind", "radius", "height", "width", "file"),
    "light": ("elevation", "distance", "stop"),
    "viewer": ("distance", "range", "height", "ipd"),
    "tool": ("radius", "depth"),
    "machining": ("feed", "plunge", "safe_z", "spindle", "axes"),
    "scene": ("model", "frames", "size", "center_z", "from", "to", "turn", "shift", "yaw",
              "stipples"),
}
_COMP_STRINGS = ('"walk"', '"light"', '"plane"', '"cylinder"', '"sphere"', '"heightfield"',
                 '"mesh"', '"panels"', '"tet.obj"', '"hf.npz"', '"missing.obj"', '"tet*.obj"',
                 '"/etc/passwd"', '"../tet.obj"', '""', '"**"', '"fifo.obj"')
#: A composition that designs in about a second, the generator's starting point.
SMALL_COMPOSITION = ('stipples = 4\nstep = 2\n[viewer]\nrange = 10\n'
                     '[[scene]]\nmodel = "tet.obj"\nsize = 20\ncenter_z = -20\n')


def composition_base() -> Path:
    """The folder compositions are read in: tet.obj, a height field hf.npz, a FIFO."""
    base = scratch("comp")
    if not (base / "hf.npz").exists():
        base.mkdir(exist_ok=True)
        (base / "tet.obj").write_text(_TET)
        (base / "tet_1.obj").write_text(_TET)
        x = np.linspace(-60, 60, 9)
        np.savez(base / "hf.npz", x=x, y=x, z=np.outer(np.sin(x / 30), np.cos(x / 40)))
        with contextlib.suppress(OSError, AttributeError):
            os.mkfifo(base / "fifo.obj")  # read, it must be refused, never waited on
    return base


#: Values a composition may well hold, per key: half the generated lines take one,
#: so that most compositions get past parsing into the design.
_COMP_SANE: dict[str, tuple[str, ...]] = {
    "mode": ('"walk"', '"light"'), "stipples": ("1", "2", "3"), "seed": ("0", "7"),
    "band": ("0.2", "1"), "step": ("1", "2"),
    "kind": ('"plane"', '"cylinder"', '"sphere"', '"heightfield"', '"mesh"', '"panels"'),
    "radius": ("30", "60", "0.05"), "height": ("0", "60"), "width": ("100", "40"),
    "file": ('"hf.npz"', '"tet.obj"'), "elevation": ("30", "45", "60"),
    "distance": ("500", "600"), "stop": ("50", "70"), "range": ("5", "10", "20"),
    "ipd": ("64",), "depth": ("0.02", "0.04"), "feed": ("300",), "plunge": ("100",),
    "safe_z": ("1",), "spindle": ("0", "12000"), "axes": ("3", "4"),
    "model": ('"tet.obj"', '"tet_1.obj"'), "frames": ('"tet*.obj"',), "size": ("20", "30"),
    "center_z": ("-20", "0", "10"), "from": ("-5", "0"), "to": ("5", "50"),
    "turn": ("0", "0.5"), "shift": ("[1, 0, 0]", "[0, 0, 0.1]"), "yaw": ("0", "30"),
}


def _comp_value(b: _Bytes, key: str) -> str:
    kind = b.byte() % 8
    if kind < 4:
        return str(b.pick(_COMP_SANE[key]))
    if key == "shift" or kind == 7:
        return "[" + ", ".join(b.pick(_COMP_NUMBERS) for _ in range(b.byte() % 4)) + "]"
    if key in ("mode", "kind", "model", "frames", "file") or kind == 6:
        return str(b.pick(_COMP_STRINGS))
    return str(b.pick(_COMP_NUMBERS))


def composition_text(data: bytes) -> bytes:
    """A composition from a fuzz input: raw TOML (first byte even), or a small
    composition with hostile lines added to its tables (odd)."""
    if not data or data[0] % 2 == 0:
        return data[1:]
    b = _Bytes(data[1:])
    tables: dict[str, list[str]] = {name: [] for name in _COMP_KEYS}
    for _ in range(1 + b.byte() % 5):
        name = b.pick(sorted(_COMP_KEYS))
        key = b.pick(_COMP_KEYS[name])
        tables[name].append(f"{key} = {_comp_value(b, key)}")
    lines = [*tables[""], "stipples = 4", "step = 2"]
    for name in ("host", "light", "viewer", "tool", "machining"):
        body = tables[name] + (["range = 10"] if name == "viewer" else [])
        if body:
            lines += [f"[{name}]", *body]
    scene = tables["scene"]
    if not any(line.startswith(("model ", "frames ")) for line in scene):
        scene.append('model = "tet.obj"')
    lines += ["[[scene]]", *scene, "size = 20", "center_z = -20"]
    # TOML refuses a key given twice: keep each key's first line.
    seen: set[tuple[str, str]] = set()
    table, out = "", []
    for line in lines:
        if line.startswith("["):
            table = line
            seen = {k for k in seen if k[0] != table}
            out.append(line)
            continue
        key = line.split("=")[0].strip()
        if (table, key) not in seen:
            seen.add((table, key))
            out.append(line)
    return ("\n".join(out) + "\n").encode("utf-8")


def _tiny(comp: Any) -> bool:
    """Whether a composition designs in a second or two (else it is only parsed)."""
    return (sum(s.stipples for s in comp.scenes) <= 12 and len(comp.scenes) <= 3
            and comp.motion.step >= math.radians(1.0))


def check_composition_file(path: str | os.PathLike[str]) -> None:
    """Read a composition as `specholo compose` does; a tiny one is designed,
    verified, written and read back (verify's path)."""
    import shutil

    from specholo.jobs.composition.design import (
        design_composition,
        load_composition_folder,
        read_composition,
        verify_composition,
        write_composition,
    )

    name = Path(path).name
    with quiet_check(f"composition {name}"):
        try:
            comp = read_composition(path)
        except SpecholoError as exc:
            check_message(exc, f"composition {name}")
            return
        if not _tiny(comp):
            return
        try:
            d = design_composition(comp)
        except SpecholoError as exc:
            check_message(exc, f"design composition {name}")
            return
        g = d.grooves
        n = sum(len(s.points) for s in d.scenes)
        if not (np.isfinite(g.point).all() and len(g.stipple) and g.stipple.min() >= 0
                and g.stipple.max() < n):
            raise FuzzFailure(f"composition {name}: bad grooves")
        verify_composition(d, math.radians(15.0))
        out = scratch("composed")
        shutil.rmtree(out, ignore_errors=True)
        try:
            write_composition(d, out)
        except SpecholoError as exc:  # the G-code check may refuse what the host cannot cut
            check_message(exc, f"write composition {name}")
            return
        back = load_composition_folder(out)
        if not np.array_equal(back.grooves.point, g.point):
            raise FuzzFailure(f"composition {name}: grooves differ once read back")


def check_composition_bytes(data: bytes) -> None:
    """The composition fuzz target."""
    path = composition_base() / "c.toml"
    path.write_bytes(composition_text(data))
    check_composition_file(path)


def check_composition_input(path: str | os.PathLike[str]) -> None:
    """Replay a saved composition, read in the folder of :func:`composition_base`
    (the files it names: tet.obj, hf.npz, the FIFO)."""
    check_composition_bytes(b"\x00" + Path(path).read_bytes())


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
