"""What a machine would do that the safety check must see: an arc's extra
turns, an air path of many short hops, and lines no controller reads."""

from __future__ import annotations

import math
import time
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from test_check import PLATE, START, caught, hop_limits, run
from test_gcode import needs_rs274, run_rs274

import specholo.fabrication.check as check
from specholo.errors import SpecholoError
from specholo.fabrication import _check_kernel
from specholo.fabrication.check import MAX_LINE, CheckReport, Stock, check_limits
from specholo_cli.cli import main

# ---------------------------------------------------------------------------
# G2/G3 with P: LinuxCNC runs P - 1 whole circles before the arc's end


#: A plate whose lower edge the arc below keeps clear of while it turns once
#: (clockwise over the top from (0, 0) to (10, 0) round (5, 0), radius 5) but
#: crosses at Y = -5 when it turns a whole circle more.
LOW_EDGE = Stock(-20.0, -3.0, 20.0, 10.0, 3.0)
TWICE = (6, "cut leaves the stock: X 0.00000..10.00000, Y -5.00000..5.00000 outside "
            "X -20..20, Y -3..10")


@pytest.mark.parametrize(("turns", "found"), [
    ("", []), (" P1", []), (" P2", [TWICE]), (" P3", [TWICE]),
    # LinuxCNC reads a P within 0.001 of a whole number as that number
    (" P2.0005", [TWICE]), (" P0.9995", []),
    (" P1.5", [(6, "arc with P1.5: not a whole number of turns")]),
    (" P0", [(6, "arc with P0: fewer than one turn")]),
    (" P-2", [(6, "arc with P-2: fewer than one turn")]),
])
def test_an_arc_with_turns_is_checked_over_its_whole_circle(tmp_path: Path, turns: str,
                                                            found: list) -> None:
    for arc in (f"G2 X10 Y0 I5 J0{turns} F200", f"G2 X10 Y0 R5{turns} F200"):
        assert caught(run(tmp_path, START + arc + "\n", LOW_EDGE)) == found, arc


def test_turns_are_an_arcs_only(tmp_path: Path) -> None:
    # the arc's mode carries over to a line without G2, its P to no other line
    wide = Stock(-20.0, -3.0, 40.0, 10.0, 3.0)
    body = "G2 X10 Y0 I5 J0 F200\nX20 Y0 I5 J0 P2\nX30 Y0 I5 J0\n"
    assert caught(run(tmp_path, START + body, wide)) == [
        (7, "cut leaves the stock: X 10.00000..20.00000, Y -5.00000..5.00000 outside "
            "X -20..40, Y -3..10")]
    # a P no word reads: LinuxCNC refuses the line, its effect is not modelled
    for body, what in [("G1 X1 P2 F200\n", "P word in a G1 move"),
                       ("G0 Z1 P2\n", "P word in a G0 move"),
                       ("M3 S12000 P2\n", "P word with no dwell or arc to read it"),
                       ("G4 P1 G2 X10 Y0 I5 J0 F200\n", "G4 and G2 on one line: both read P")]:
        assert caught(run(tmp_path, START + body, LOW_EDGE)) == [(6, what)], body
    # a dwell's P is its time
    assert run(tmp_path, START + "G4 P0.5\n", LOW_EDGE).ok


def test_an_arc_hops_the_length_of_its_turns(tmp_path: Path) -> None:
    """A hop round half a circle of radius 0.5 (1.57 mm) is within 3 mm; a whole
    circle more (4.71 mm) is not."""
    go = ("G21 G90\nM3 S12000\nG0 Z1\nG0 X0 Y0\nG1 Z-0.08 F100\nG1 X0.5 F300\nG0 Z0.03\n"
          "G2 X1.5 Y0 I0.5 J0{} F300\nG1 Z-0.08 F100\nG0 Z1\nM2\n")
    path = tmp_path / "p.ngc"
    path.write_text(go.format(""))
    assert check_limits(path, hop_limits()).ok
    path.write_text(go.format(" P2"))
    assert caught(check_limits(path, hop_limits())) == [(8, (
        f"feed move of {3 * math.pi * 0.5:.5f} mm in X/Y between the surface and the safe "
        "height 1: longer than the longest hop 3 mm"))]


def test_no_fast_reader_takes_a_line_with_turns() -> None:
    """Neither the plain-move pattern nor the compiled reader reads a P word:
    the line goes to the reader that knows what P does."""
    for line in ("G2 X10 Y0 I5 J0 P2 F200", "G2 X10 Y0 I5 J0 F200 P2", "G3 X1 Y0 P2",
                 "G02 X10 Y0 I5 J0 P2"):
        assert check._PLAIN_MOVE.fullmatch(line) is None
        buf = np.frombuffer(line.encode(), dtype=np.uint8)
        state = np.array([0.0, 0.0, -0.05, 200.0, 1.0, 2.0])
        out = np.empty((1, _check_kernel.ROW))
        taken, row = _check_kernel.plain_lines(buf, np.array([0]), np.array([len(buf)]), 0,
                                               1, 1.0, state, out, 0)
        assert (taken, row) == (0, 0), line
    # the control: the same arc without P is taken
    line = b"G2 X10 Y0 I5 J0 F200"
    buf = np.frombuffer(line, dtype=np.uint8)
    state = np.array([0.0, 0.0, -0.05, 200.0, 1.0, 2.0])
    out = np.empty((1, _check_kernel.ROW))
    assert _check_kernel.plain_lines(buf, np.array([0]), np.array([len(buf)]), 0, 1, 1.0,
                                     state, out, 0) == (1, 1)
    assert out[0, check._TURNS] == 0.0


@needs_rs274
def test_linuxcnc_reads_p_as_turns(tmp_path: Path) -> None:
    """rs274 runs the arc flagged above twice round (its turn count -2, clockwise)."""
    path = tmp_path / "p.ngc"
    path.write_text(START + "G2 X10 Y0 I5 J0 P2 F200\nG0 Z1\nM2\n")
    arcs = [args.split(", ") for name, args in run_rs274(path) if name == "ARC_FEED"]
    assert len(arcs) == 1 and int(arcs[0][4]) == -2
    assert caught(run(tmp_path, path.read_text(), LOW_EDGE)) == [TWICE]


# ---------------------------------------------------------------------------
# an air path: the hops between two cuts, summed


#: A cut, then up to the hop height at (0.5, 0): 7 lines.
CUT = "G21 G90\nM3 S12000\nG0 Z1\nG0 X0 Y0\nG1 Z-0.08 F100\nG1 X0.5 F300\nG0 Z0.03\n"


def _hops(y0: float, n: int, step: float = 0.6) -> str:
    """n hops of ``step`` mm up Y from Y = y0, at the hop height."""
    return "".join(f"G1 Y{y0 + step * (k + 1):.1f} F300\n" for k in range(n))


def _air_program() -> tuple[str, list[tuple[int, str]]]:
    """A program of air paths of many short hops, and what must be flagged."""
    def said(n: int, mm: float) -> str:
        return (f"{n} hops in a row, {mm:.5f} mm in X/Y in all between the surface and the "
                "safe height 1 (no cut or rise to it between): longer than the longest hop "
                "3 mm")

    plunge, rise, lower = "G1 Z-0.08 F100\n", "G0 Z1\n", "G1 Z0.03 F100\n"
    lines: list[str] = []
    found: list[tuple[int, str]] = []

    def add(text: str) -> None:
        lines.extend(text.splitlines())

    add(CUT)
    # a 24 mm drag at the hop height in 0.6 mm steps: past 3 mm at the sixth
    add(_hops(0.0, 40))
    found.append((7 + 6, said(6, 3.6)))
    # five steps (3 mm) between two cuts pass, and again after a cut
    add(plunge + "G0 Z0.03\n" + _hops(24.0, 5) + plunge + "G0 Z0.03\n" + _hops(27.0, 5))
    # a rise to the safe height ends a path as a cut does (5 steps, then 4)
    add(rise + "G0 X0 Y0\n" + lower + _hops(0.0, 5) + rise + lower + _hops(3.0, 4)
        + plunge + "G0 Z0.03\n")
    # a hop alone longer is flagged as one move, not again as a path
    add("G1 Y8.8 F300\n" + _hops(8.8, 10))
    found.append((len(lines) - 10, "feed move of 3.40000 mm in X/Y between the surface and the "
                                   "safe height 1: longer than the longest hop 3 mm"))
    # a path that passes the bound in its last step, then a new one that does
    add(plunge + "G0 Z0.03\n" + _hops(14.8, 4, 0.8))
    found.append((len(lines), said(4, 3.2)))
    add(rise + "G0 X0 Y0\n" + lower + _hops(0.0, 7, 0.5))
    found.append((len(lines), said(7, 3.5)))
    add(plunge + rise + "M2\n")
    return "\n".join(lines) + "\n", found


def test_many_short_hops_are_one_air_path(tmp_path: Path) -> None:
    program, found = _air_program()
    path = tmp_path / "air.ngc"
    path.write_text(program)
    assert caught(check_limits(path, hop_limits())) == found
    # the limit reached and not passed: nothing to say
    path.write_text(CUT + _hops(0.0, 5) + "G1 Z-0.08 F100\nG0 Z1\nM2\n")
    assert check_limits(path, hop_limits()).ok
    # a job that does not bound hops says nothing of them
    path.write_text(program)
    assert check_limits(path, hop_limits(hop_max=None, groove_depth=None)).ok


@pytest.mark.parametrize("block", [1, 2, 3, 5, 7, 16])
@pytest.mark.parametrize("threads", [True, False])
def test_an_air_path_is_summed_across_blocks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                             block: int, threads: bool) -> None:
    """Blocks of a few moves (each split between two threads, or not) cut every
    air path somewhere: the same paths are flagged at the same moves."""
    program, found = _air_program()
    path = tmp_path / "air.ngc"
    path.write_text(program)
    monkeypatch.setattr(check, "_BLOCK_LINES", block)
    monkeypatch.setattr(check, "_READ_BYTES", 64)  # lines straddle the reads, too
    monkeypatch.setattr(check, "_SPLIT_ROWS", 1)
    if not threads:
        monkeypatch.setattr(check, "concurrent_kernels_safe", lambda: False)
    assert caught(check_limits(path, hop_limits())) == found


# ---------------------------------------------------------------------------
# lines longer than a controller reads, and files that are not text


@pytest.mark.parametrize("ending", ["\n", "\r\n", "\r"])
def test_a_line_too_long_is_flagged_in_bounded_memory(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch,
                                                      ending: str) -> None:
    """40 MB on one line: read a block at a time (1 MB here, so that the bound
    shows against a file of a size a test can write), flagged once by its
    number and quoted short; the lines after it are checked as before. A
    carriage return alone ends lines in text mode, read by the other reader."""
    monkeypatch.setattr(check, "_READ_BYTES", 1 << 20)
    size = 40 << 20
    path = _long_line(tmp_path / "long.ngc", ending, size)
    # The same file checked first: every kernel and module it reaches is
    # compiled or loaded before the memory is counted, whatever ran before in
    # this process (on a fresh clone a first check of a 2 MB line still left
    # 50 MB of first loads to the 40 MB one).
    _report_of(path)
    tracemalloc.start()
    try:
        start = time.perf_counter()
        report = _report_of(path)
        seconds = time.perf_counter() - start
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < size / 8, f"{peak / 1e6:.1f} MB for a {size / 1e6:.0f} MB line"
    assert seconds < 30
    too_long = f"line longer than {MAX_LINE} characters (LinuxCNC reads no more): not read"
    leaves = "cut leaves the stock: X {}..99.00000"
    expected = [(6, too_long), (7, leaves.format("0.00000")), (8, leaves.format("2.00000")),
                (9, too_long)]
    assert [(line, what[:len(w)]) for (line, what), (_, w) in
            zip(caught(report), expected, strict=True)] == expected
    assert report.lines == 9
    assert all(len(v.text) <= 60 for v in report.violations)
    assert report.violations[0].text.startswith("G1 X1 F100 (aaa")
    assert len(report.summary()) < 1000


def test_the_longest_line_a_controller_reads(tmp_path: Path) -> None:
    """A comment line of MAX_LINE characters is read; one more is not."""
    for extra, found in ((0, []), (1, [(6, "line longer than")])):
        line = "G0 Z1 (" + "a" * (MAX_LINE - 8 + extra) + ")"
        assert len(line) == MAX_LINE + extra
        report = run(tmp_path, START + line + "\nM2\n")
        assert [(n, what[:16]) for n, what in caught(report)] == found


@needs_rs274
def test_linuxcnc_reads_no_longer_line(tmp_path: Path) -> None:
    """rs274 reads a line of MAX_LINE characters and refuses one more."""
    path = tmp_path / "p.ngc"
    line = "G0 Z1 (" + "a" * (MAX_LINE - 8) + ")"
    path.write_text(f"G21 G90\n{line}\nM2\n")
    run_rs274(path)
    path.write_text(f"G21 G90\n{line}a\nM2\n")
    with pytest.raises(AssertionError, match="Command too long"):
        run_rs274(path)


@pytest.mark.parametrize(("content", "line"), [
    (b"\0" * (3 << 20), 1),  # zeros, one line of them
    (b"G21\nG0 Z1\n\0\0\0 G1 X1\nM2\n", 3),
    (b"G21\rG0 Z1\r\0\rM2\r", 3),  # read as text
    (b"G21\n" + b"x" * 1000 + b"\0\nM2\n", 2),  # in a line too long
])
@pytest.mark.parametrize("read", [None, 64])
def test_a_binary_file_is_refused_in_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                              monkeypatch: pytest.MonkeyPatch, content: bytes,
                                              line: int, read: int | None) -> None:
    path = tmp_path / "p.ngc"
    path.write_bytes(content)
    said = f"{path} is not a G-code program: line {line} holds a NUL byte (a binary file?)"
    with monkeypatch.context() as m:
        if read is not None:  # a NUL in what a line too long skips, too
            m.setattr(check, "_READ_BYTES", read)
        with pytest.raises(SpecholoError) as info:
            check_limits(path, hop_limits())
    assert str(info.value) == said
    # the command, with limits given or read from the header
    for args in ([], ["--plate-width", "50", "--plate-height", "50", "--max-depth", "0.1"]):
        assert main(["check", str(path), *args]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert err == [f"error: {said}"]


def _long_line(path: Path, ending: str, size: int) -> Path:
    """A program with one line of ``size`` bytes (a whole number of MB) after
    its start, then a line the checks flag, then two lines of about MAX_LINE."""
    with path.open("wb") as fh:
        fh.write((START + "G1 X1 F100 (").replace("\n", ending).encode())
        step = b"a" * (1 << 20)
        for _ in range(size >> 20):
            fh.write(step)
        fh.write((")\nG1 X99 F200\nG1 X2 (" + "b" * (MAX_LINE - 8) + ")\nG1 X3 ("
                  + "c" * (MAX_LINE - 7) + ")").replace("\n", ending).encode())
    return path


def _report_of(path: Path) -> CheckReport:
    return check.check_gcode(path, PLATE, 0.1, 1.0, (10.0, 1000.0), (1000.0, 24000.0))
