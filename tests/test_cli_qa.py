"""A new user's reading of the command line (issue 25/26/29 acceptance): the commands and
options that README.md and the documentation pages show are the ones ``are-stats`` has, and
the help says what the commands do now (a tracks table for ``fit``, the one assembly's
motion for ``generate --behaviours``)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import typer
from typer.testing import CliRunner

from are_stats.cli import app

ROOT = Path(__file__).resolve().parents[1]
#: The pages a user reads the commands from.
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs" / "src").glob("*.md"))]

runner = CliRunner()


def shown_commands(text: str) -> list[tuple[str, list[str], str]]:
    """``(command, options, line)`` of every ``are-stats COMMAND ...`` the markdown ``text``
    shows: in code blocks (a line continued by a backslash, or an indented line of options
    under it, joined to it) and inline code spans; options given before the command (such as
    ``--max-memory 16G``) are skipped."""
    text = re.sub(r"\\\n\s*", " ", text)  # shell continuations
    text = re.sub(r"\n {4,}(?=[\[-])", " ", text)  # a synopsis' indented option lines
    found = []
    for line in text.splitlines():
        for m in re.finditer(
            r"are-stats((?:\s+--[\w-]+(?:\s+\S+)?)*)\s+([a-z]+)\b([^`\n#]*)", line
        ):
            options = re.findall(r"(?<![\w-])(--[a-z][\w-]*)", m.group(3))
            found.append((m.group(2), options, " ".join(line.split())))
    return found


def unknown_options(text: str) -> list[str]:
    """The commands and options ``text`` shows that ``are-stats`` does not have, one line
    each (``fit --no-such-option: are-stats fit ...``)."""
    root = typer.main.get_command(app)
    top = {o for p in root.params for o in p.opts}
    wrong = []
    for name, options, line in shown_commands(text):
        cmd = root.commands.get(name)
        if cmd is None:
            wrong.append(f"{name} (no such command): {line}")
            continue
        known = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)} | {"--help"} | top
        wrong += [f"{name} {o}: {line}" for o in options if o not in known]
    return wrong


def test_the_checker_finds_a_wrong_option_and_a_wrong_command():
    """The check below can fail: a made-up option, a made-up command and an option on the
    indented line of a synopsis are found; the right ones pass."""
    text = (
        "```bash\nare-stats generate fits/a.nc --scenarios 2 --horizon 60 --seed 1 \\\n"
        "    --out s/ --behaviors\n```\n"
        "Run `are-stats simulate fits/a.nc` or\n"
        "`are-stats --max-memory 16G fit log.csv --out a.nc`.\n"
        "```\nare-stats augment BAG --fit FIT --map MAP --out OUT.mcap --seed S\n"
        "    [--pose-topic TOPIC] [--camera-topic TOPIC]\n```\n"
    )
    assert unknown_options(text) == [
        "generate --behaviors: are-stats generate fits/a.nc --scenarios 2 --horizon 60 "
        "--seed 1 --out s/ --behaviors",
        "simulate (no such command): Run `are-stats simulate fits/a.nc` or",
        "augment --camera-topic: are-stats augment BAG --fit FIT --map MAP --out OUT.mcap "
        "--seed S [--pose-topic TOPIC] [--camera-topic TOPIC]",
    ]


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.name)
def test_documented_commands_and_options_exist(page):
    """Every ``are-stats COMMAND --option`` README.md and the docs pages show is a command
    and an option of that command (or of ``are-stats`` itself): a renamed or removed option
    fails here instead of in a user's shell. The inputs page quotes an error message that
    says "raise it with are-stats --max-memory SIZE or ...": not a command line."""
    text = page.read_text(encoding="utf-8").replace("are-stats --max-memory SIZE or", "")
    assert unknown_options(text) == []


def test_the_pages_show_every_command():
    """Each command of ``are-stats`` is shown at least once on README.md or the docs pages
    (``version`` is ``--version``)."""
    root = typer.main.get_command(app)
    shown = {name for page in PAGES for name, _, _ in shown_commands(page.read_text("utf-8"))}
    assert set(root.commands) - {"version"} <= shown, set(root.commands) - shown


def _help(*command: str) -> str:
    res = runner.invoke(app, [*command, "--help"], env={"COLUMNS": "200"})
    assert res.exit_code == 0, res.output
    return " ".join(res.output.split())


def test_fit_help_says_it_reads_a_tracks_table():
    """``fit`` reads a life-cycle log or a tracks table (told apart by the columns): its help
    names both, not a life-cycle log alone."""
    text = _help("fit")
    assert "a life-cycle log (id, t_arrive, t_leave, ...)" in text
    assert "a tracks table (id, t, x, y [, label])" in text


def test_generate_help_says_how_behaviours_move_and_what_is_written():
    """``generate --behaviours`` moves the artefacts by the one assembly (the fit's learned
    behaviour, else the catalogue's MDP, then the social force) and writes tracks.parquet."""
    text = _help("generate")
    assert "the fit's behaviour when it learned one from a tracks table" in text
    assert "else the catalogue's MDP behaviours, then the social force; needs --map." in text
    assert "(artefacts.parquet, manifest.yaml; tracks.parquet with --behaviours)" in text
    assert "Add MDP trajectories" not in text
