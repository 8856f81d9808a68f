"""What the README and the docs tell a new user holds: every command line they
show uses options the command has, with values it accepts; every timing the
README states gives its conditions; and the README names what the skipped
tests need."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import click
import pytest

import specholo_cli.cli  # noqa: F401 - registers every command on the group
from specholo_cli.app import cli

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]


def _command_lines() -> list[tuple[str, list[str]]]:
    """Every `specholo COMMAND ...` a page shows in a code block or inline code."""
    found = []
    for page in PAGES:
        text = page.read_text(encoding="utf-8")
        blocks = re.findall(r"```(?:sh|bash|console)?\n(.*?)```", text, re.S)
        spans = [s for s in re.findall(r"`([^`\n]+)`", text) if s.startswith("specholo ")]
        for chunk in [*blocks, *spans]:
            chunk = chunk.replace("\\\n", " ")
            for line in chunk.splitlines():
                for part in re.split(r"&&|;|\|\|", line.split("#")[0]):
                    part = part.strip()
                    if part.startswith("specholo "):
                        try:
                            words = shlex.split(part)
                        except ValueError:
                            continue
                        found.append((page.name, words[1:]))
    return found


COMMAND_LINES = _command_lines()


def test_the_pages_show_commands():
    assert len(COMMAND_LINES) > 40


@pytest.mark.parametrize("page, words", COMMAND_LINES,
                         ids=[f"{p}:{' '.join(w)[:50]}" for p, w in COMMAND_LINES])
def test_every_command_shown_has_its_options_and_accepted_values(page: str, words: list[str]):
    """Each --option is one the command has, and a --step given to verify is one
    it accepts (docs/studio.md once suggested `verify --step 15`)."""
    if not words or words[0] not in cli.commands:
        pytest.skip(f"not a command line: {' '.join(words)[:40]}")
    command = cli.commands[words[0]]
    names = {opt for p in command.params if isinstance(p, click.Option)
             for opt in (*p.opts, *p.secondary_opts)}
    names.add("--help")
    for word in words[1:]:
        option = word.split("=")[0]
        if option.startswith("--") and option.isascii() and option[2:3].isalpha():
            assert option in names, f"{page}: `specholo {words[0]}` has no {option}"
    if words[0] == "verify" and "--step" in words:
        value = words[words.index("--step") + 1]
        if re.fullmatch(r"[\d.]+", value):
            assert 0.01 <= float(value) <= 5.0, f"{page}: verify refuses --step {value}"


def test_every_timing_in_the_readme_gives_its_conditions():
    """A seconds or minutes figure sits in a paragraph that names the machine and
    its load, and the day it was measured or the page that holds the figures."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    for para in text.split("\n\n"):
        if para.lstrip().startswith("```"):
            continue
        if re.search(r"\b\d+(\.\d+)?\s*(s|seconds|min|minutes)\b", para):
            assert "2-core" in para, para
            assert re.search(r"nothing else|idle|busy|load", para), para
            assert re.search(r"20\d\d-\d\d-\d\d|benchmarks\.md|that machine", para), para


def test_the_readme_names_what_skipped_tests_need():
    """The programs whose absence skips tests (pytest's skip reasons in the
    suite) are each named in the README, with how CI installs them."""
    reasons = " ".join(p.read_text(encoding="utf-8") for p in (ROOT / "tests").glob("*.py")
                       if p.name != Path(__file__).name)
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for need in ("rs274", "Chromium", "de_DE"):
        assert need.lower() in reasons.lower()
        assert need in readme, f"the README does not say tests need {need}"
    assert "bash .ci/run" in readme
