"""A maker's first run: the README's command on a fresh install, and after.

Usage: python benchmarks/first_run.py [--repeat 3] [--cold 1] [--no-cold]

Times, each command in a fresh process as a maker runs it:

- the README's ``specholo design`` (2,000 stipples) and ``specholo verify``
  with an empty numba cache (every kernel compiled for this machine: a fresh
  install) and with the cache that run filled (every run after);
- the same design with ``--stipples 100``, cache filled;
- ``specholo --help`` and ``import specholo_cli.cli`` (what every command pays).

Each cold run gets its own empty ``NUMBA_CACHE_DIR`` and ``SPECHOLO_CACHE_DIR``
(the models read before) in a temporary folder, so neither the project's own
kernels nor the user's models are read or touched; the warm runs use the
caches the cold runs filled. Prints the median of
the repeats (min-max beside it) and how many kernels the cold runs compiled
(counted as the index files numba wrote into the empty cache: the design's
own and its second process's, which compiles the later kernels beside it).
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODEL = ROOT / "examples" / "bunny.obj"
BIN = Path(sys.executable).parent
SPECHOLO = str(BIN / "specholo")
README = ["--size", "60", "--center-z", "-40", "--light-elevation", "45",
          "--view-distance", "600", "--view-range", "45"]


def timed(cmd: list[str], cache: Path | None) -> tuple[float, int]:
    """Seconds for ``cmd`` to end, and how many kernels ``cache`` holds after it."""
    env = dict(os.environ)
    # As on a maker's machine, Python keeps the modules' bytecode (an
    # environment that turns that off compiles every module on every run).
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
        env["SPECHOLO_CACHE_DIR"] = str(cache / "specholo")
    t0 = time.perf_counter()
    run = subprocess.run(cmd, env=env, cwd=ROOT, capture_output=True, text=True)
    seconds = time.perf_counter() - t0
    if run.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{run.stderr}")
    return seconds, _kernels(cache)


def _kernels(cache: Path | None) -> int:
    """Kernels numba has cached in ``cache``: one index file each."""
    return 0 if cache is None else sum(1 for _ in cache.rglob("*.nbi"))


def readme(out: Path, stipples: int) -> list[list[str]]:
    design = [SPECHOLO, "design", str(MODEL), "--out", str(out), *README,
              "--stipples", str(stipples)]
    return [design, [SPECHOLO, "verify", str(out)]]


def row(name: str, times: list[float], note: str = "") -> str:
    spread = f"{min(times):.2f}-{max(times):.2f}" if len(times) > 1 else ""
    return f"{name:<44} {statistics.median(times):>8.2f} {spread:>13}  {note}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=3, help="warm repeats [3]")
    ap.add_argument("--cold", type=int, default=1, help="cold repeats [1]")
    ap.add_argument("--no-cold", action="store_true", help="skip the cold runs")
    args = ap.parse_args()
    rows: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        tmpdir = Path(tmp)
        cache = tmpdir / "cache-warm"
        if not args.no_cold:
            cold: dict[str, list[float]] = {"design": [], "verify": [], "both": []}
            kernels: dict[str, int] = {}
            for i in range(args.cold):
                cache = tmpdir / f"cache-{i}"
                cache.mkdir()
                (d, nd), (v, nv) = (timed(c, cache) for c in readme(tmpdir / f"cold{i}", 2000))
                nv -= nd  # (the cache's count after verify includes the design's)
                cold["design"].append(d)
                cold["verify"].append(v)
                cold["both"].append(d + v)
                kernels = {"design": nd, "verify": nv}
            rows += [row("README design, cold cache", cold["design"],
                         f"{kernels['design']} kernels compiled"),
                     row("README verify, after the cold design", cold["verify"],
                         f"{kernels['verify']} more"),
                     row("README design + verify, cold", cold["both"])]
        else:
            cache.mkdir()
            for c in readme(tmpdir / "fill", 2000):
                timed(c, cache)
        warm: dict[str, list[float]] = {"design": [], "verify": [], "both": [], "100": []}
        for i in range(args.repeat):
            d, v = (timed(c, cache)[0] for c in readme(tmpdir / f"warm{i}", 2000))
            warm["design"].append(d)
            warm["verify"].append(v)
            warm["both"].append(d + v)
            warm["100"].append(timed(readme(tmpdir / f"small{i}", 100)[0], cache)[0])
        rows += [row("README design, warm", warm["design"]),
                 row("README verify, warm", warm["verify"]),
                 row("README design + verify, warm", warm["both"]),
                 row("100-stipple design, warm", warm["100"])]
        helps = [timed([SPECHOLO, "--help"], cache)[0] for _ in range(args.repeat)]
        imports = [timed([sys.executable, "-c", "import specholo_cli.cli"], cache)[0]
                   for _ in range(args.repeat)]
        rows += [row("specholo --help", helps), row("python -c 'import specholo_cli.cli'",
                                                    imports)]
    print(f"{os.cpu_count()} cores, numba threads {os.environ.get('NUMBA_NUM_THREADS', 'all')}")
    print(f"{'run':<44} {'median s':>8} {'min-max s':>13}")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
