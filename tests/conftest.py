"""Shared test options and fixtures."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import strategies as st

from specholo.toolpaths.grooves import Grooves

GOLDEN = Path(__file__).resolve().parent / "golden"

# Models read by the tests are kept in a cache of the test run's own, not the
# user's (subprocesses inherit it), removed when the run ends: every run made one.
if "SPECHOLO_CACHE_DIR" not in os.environ:
    _CACHE = tempfile.mkdtemp(prefix="specholo-test-cache-")
    os.environ["SPECHOLO_CACHE_DIR"] = _CACHE
    atexit.register(shutil.rmtree, _CACHE, ignore_errors=True)


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption(
        "--regen-golden", action="store_true", default=False,
        help="rewrite the golden files under tests/golden/ from the current code",
    )


@pytest.fixture
def golden(request: pytest.FixtureRequest) -> Callable[[Path, str], None]:
    """Compare a produced file with ``tests/golden/<name>`` (or rewrite it with --regen-golden)."""
    regen = request.config.getoption("--regen-golden")

    def check(produced: Path, name: str) -> None:
        expected = GOLDEN / name
        if regen:
            GOLDEN.mkdir(exist_ok=True)
            shutil.copyfile(produced, expected)
            return
        assert expected.exists(), f"missing golden file {expected}; run pytest --regen-golden"
        assert produced.read_bytes() == expected.read_bytes(), (
            f"{produced.name} differs from golden {name}; if the change is intended, "
            "run pytest --regen-golden and review the diff"
        )

    return check


@pytest.fixture
def groove_example() -> Grooves:
    """Three grooves of two stipples: arcs both ways, a straight segment, a dot,
    a semicircle and an arc over 180 degrees."""
    vertices = np.array([
        [0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [20.0, 5.0],  # stipple 4: CCW, CW, straight
        [-5.0, -5.0],                                        # stipple 4: dot
        [1.0, 1.0], [2.0, 1.5], [4.0, 1.5],                  # stipple 9: 270 deg CCW, half CW
    ])
    bulges = np.array([0.5, -0.3, 0.0, 0.0, 0.0, np.tan(np.radians(270) / 4), -1.0, 0.0])
    return Grooves(vertices, bulges, np.array([0, 4, 5, 8]), np.array([4, 4, 9]))


@st.composite
def random_grooves(
    draw: st.DrawFn,
    max_paths: int = 6,
    max_arcs: int = 6,
    max_bulge: float = 1.0,
    chord: tuple[float, float] = (0.5, 10.0),
) -> Grooves:
    """Random grooves: chains of arcs with random bulges, and dots (paths of one vertex).

    Chords lie in ``chord`` (mm); bulges are exactly 0 (straight) or uniform in
    [-max_bulge, max_bulge]; stipple ids are in [-1, 10**6].
    """
    coord = st.floats(-100.0, 100.0, allow_nan=False)
    bulge = st.one_of(st.just(0.0), st.floats(-max_bulge, max_bulge, allow_nan=False))
    verts: list[np.ndarray] = []
    bulges: list[float] = []
    sizes: list[int] = []
    stipple: list[int] = []
    for _ in range(draw(st.integers(0, max_paths))):
        p = np.array([draw(coord), draw(coord)])
        k = draw(st.integers(0, max_arcs))  # 0 arcs: a dot
        verts.append(p)
        for _ in range(k):
            length = draw(st.floats(*chord))
            angle = draw(st.floats(-np.pi, np.pi))
            bulges.append(draw(bulge))
            p = p + length * np.array([np.cos(angle), np.sin(angle)])
            verts.append(p)
        bulges.append(0.0)
        sizes.append(k + 1)
        stipple.append(draw(st.integers(-1, 10**6)))
    if not sizes:
        return Grooves.empty()
    return Grooves(np.array(verts), np.array(bulges),
                   np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64),
                   np.array(stipple, dtype=np.int64))


@pytest.fixture(scope="session")
def grooves_strategy() -> Callable[..., st.SearchStrategy[Grooves]]:
    """The :func:`random_grooves` strategy factory, for ``data.draw`` in tests."""
    return random_grooves


@pytest.fixture(scope="session")
def small_design(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A 150-stipple design of the bundled bunny, shared by the picture tests."""
    from specholo.jobs.flat.folder import DesignConfig, design, write_design

    out = tmp_path_factory.mktemp("small") / "bunny"
    bunny = Path(__file__).resolve().parents[1] / "examples" / "bunny.obj"
    write_design(design(bunny, DesignConfig(stipples=150)), out)
    return out


#: Headless Chromium for the pages' tests (SwiftShader: WebGL without a GPU).
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless=new", "--no-sandbox", "--disable-background-networking",
    "--disable-component-update", "--disable-sync", "--no-first-run",
    "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
]


@pytest.fixture(scope="module")
def browser() -> Any:
    """A headless Chromium (skipped where it is not installed)."""
    if not Path(CHROMIUM).exists():
        pytest.skip("Chromium not installed at /usr/bin/chromium")
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as pw:
        b = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        yield b
        b.close()
