"""The docs and the tool say the same thing (issue 32, part 1), read from the docs' own text.

* every ``tli ...`` command line and every ``--option VALUE`` the docs show is one the CLI
  accepts (a value the parser refuses is a docs bug: ``tli gate --rerun 0`` was one);
* what the docs say about the gate's re-run seed is what ``tli gate --help`` says;
* the looping bound on cuts is stated once, the same way in the docs, the oracle's docstring
  and its message;
* ``EpisodeResult`` documents every field, and the mode sequence has one name
  (``run.json``'s ``mode_sequence`` is ``EpisodeResult.mode_sequence``);
* every field of the task file's ``[demonstrator]`` is described in the schema and in the
  task-file how-to.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import json
import re
import shlex
from collections.abc import Iterator
from pathlib import Path

import pytest

from tli_verify.cli import build_parser

REPO = Path(__file__).resolve().parents[2]
DOCS = [REPO / "README.md", *sorted(p for p in (REPO / "docs").rglob("*.md")
                                   if "_build" not in p.parts)]

# placeholders of a synopsis (not a command line to run as is)
_PLACEHOLDER = re.compile(r"\[|\.\.\.|…|<|\{|\||\b[A-Z][A-Z0-9_.]*\b")
# errors that only say a mention is not a whole command (arguments left out), not that a
# value is refused
_INCOMPLETE = ("are required", "expected one argument", "expected at least one argument")


def _command_lines() -> list[tuple[str, str]]:
    out = []
    for f in DOCS:
        text = f.read_text(encoding="utf-8")
        rel = str(f.relative_to(REPO))
        for m in re.finditer(r"`(tli [^`\n]+)`", text):
            out.append((rel, m.group(1)))
        for block in re.findall(r"```(?:console|sh|bash|shell)\n(.*?)```", text, re.S):
            for line in re.sub(r"\\\n\s*", " ", block).splitlines():  # continuations
                line = line.strip()
                if line.startswith("$ tli "):
                    out.append((rel, line[2:]))
    return out


def _option_snippets() -> list[tuple[str, str, bool]]:
    """Inline code that is an option with a concrete value (``--rerun 0``), and whether the
    text around it presents it as bad input."""
    out = []
    for f in DOCS:
        text = f.read_text(encoding="utf-8")
        rel = str(f.relative_to(REPO))
        for m in re.finditer(r"`(--[a-z][a-z0-9-]*[ =][^`\n]+)`", text):
            around = text[max(0, m.start() - 60):m.start()].rsplit("\n", 1)[-1].lower()
            bad = any(w in around for w in ("bad input", "refus", "exits 2", "exit 2"))
            out.append((rel, m.group(1), bad))
    return out


def _parse(argv: list[str]) -> str | None:
    """The parser's error line for ``argv`` (None: accepted)."""
    err = io.StringIO()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            build_parser().parse_args(argv)
    except SystemExit as exc:
        if exc.code:
            lines = err.getvalue().strip().splitlines()
            return lines[-1] if lines else "refused"
    return None


def _commands(parser: argparse.ArgumentParser, prefix: tuple[str, ...] = ()
              ) -> Iterator[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    yield prefix, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _commands(sub, (*prefix, name))


COMMAND_LINES = [c for c in _command_lines()
                 if not _PLACEHOLDER.search(c[1].split("#")[0])]
OPTION_SNIPPETS = [c for c in _option_snippets() if not _PLACEHOLDER.search(c[1])]


def test_the_docs_show_command_lines() -> None:
    assert len(COMMAND_LINES) > 100 and len(OPTION_SNIPPETS) > 10


@pytest.mark.parametrize(("where", "line"), COMMAND_LINES)
def test_every_command_line_the_docs_show_parses(where: str, line: str) -> None:
    argv = shlex.split(line.split(" #")[0])[1:]
    error = _parse(argv)
    assert error is None or any(s in error for s in _INCOMPLETE), (
        f"{where}: `{line}`: the CLI refuses it: {error}")


@pytest.mark.parametrize(("where", "snippet", "bad"), OPTION_SNIPPETS)
def test_every_option_value_the_docs_show_is_accepted(where: str, snippet: str, bad: bool
                                                      ) -> None:
    """``--opt VALUE`` is accepted by at least one command that has ``--opt`` (refused by
    every one where the docs present it as bad input)."""
    words = shlex.split(snippet.replace("=", " ", 1))
    option = words[0]
    owners = [prefix for prefix, p in _commands(build_parser())
              if option in p._option_string_actions]
    if not owners:
        pytest.skip(f"{option} is not a tli option")
    errors = [_parse([*prefix, *words]) for prefix in owners]
    accepted = any(e is None or any(s in e for s in _INCOMPLETE) for e in errors)
    if bad:
        assert not accepted, f"{where}: `{snippet}` is shown as bad input; the CLI takes it"
    else:
        assert accepted, (f"{where}: `{snippet}`: refused by every command that has "
                          f"{option}: {errors[0]}")


def test_the_rerun_seed_is_described_the_same_way(capsys: pytest.CaptureFixture[str]) -> None:
    """The gate re-runs on a seed it derives, not the evidence's: the help, the docs and the
    gate's docstring say so, and none of them says it uses the evidence's seed."""
    from tli_verify.deploy import gate

    with pytest.raises(SystemExit):
        build_parser().parse_args(["gate", "--help"])
    help_text = " ".join(capsys.readouterr().out.split())
    docs = " ".join((REPO / "docs" / "howto" / "ci-gate.md").read_text().split())
    doc = " ".join((gate.__doc__ or "").split())
    for text in (help_text, docs, doc):
        assert "derive" in text
        assert not re.search(r"with (the|its) evidence's seed", text), text[:200]


def test_the_looping_bound_is_stated_one_way() -> None:
    """The cut bound after the last perturbation is 3 per mode of the task, counted in total
    over all modes (3 x modes): the oracle, its message and the docs say exactly that."""
    from tli_verify.verify import oracle

    closed_loop = " ".join((REPO / "docs" / "explanation" / "closed-loop.md").read_text()
                           .split())
    stated = "3 x the number of modes, in total over all modes"
    assert stated in closed_loop
    assert stated in " ".join((oracle.__doc__ or "").split())
    assert "at most 3 cuts per mode" not in closed_loop


def test_the_looping_message_says_how_the_bound_counts() -> None:
    from tli_verify.verify.oracle import cut_bound_message

    text = cut_bound_message(learned=16, last_push=100, bound=15, modes=5)
    assert "bound 15 = 3 x 5 modes, in total over all modes" in text


def test_episode_result_documents_every_field() -> None:
    import tli_verify as tli
    from tli_verify.runtime.loop import EpisodeResult

    assert "EpisodeResult" in tli.__all__ and tli.EpisodeResult is EpisodeResult
    doc = EpisodeResult.__doc__ or ""
    names = [f.name for f in dataclasses.fields(EpisodeResult)] + ["mode_sequence"]
    for name in names:
        assert re.search(rf"^\s+{name} : \S", doc, re.M), f"{name} undocumented"
        entry = doc.split(f"{name} :", 1)[1].split("\n", 2)
        assert len(entry) > 2 and entry[1].strip(), f"{name}: only a type, no meaning"


def test_the_mode_sequence_has_one_name(tmp_path: Path) -> None:
    """``run.json``'s ``mode_sequence`` is the object's ``mode_sequence``."""
    import tli_verify as tli
    from tli_verify.cli import main

    out = tmp_path / "run"
    assert main(["run", "--spec", str(REPO / "specs" / "scoop.toml"), "--start=-5,4.5",
                 "--out", str(out)]) == 0
    record = json.loads((out / "run.json").read_text())
    policy = tli.make_policy(REPO / "specs" / "scoop.toml", REPO / "models" /
                             "scoop.model.json", REPO / "certificates" / "scoop.cert.json")
    episode = tli.run(policy, start=[-5.0, 4.5])
    assert record["mode_sequence"] == episode.mode_sequence
    assert set(episode.mode_sequence) <= set(episode.modes)


def test_the_demonstrator_fields_are_documented() -> None:
    schema = json.loads((REPO / "tli_verify" / "schemas" / "task.schema.json").read_text())
    demo = schema["properties"]["demonstrator"]
    fields = {**demo["properties"], **demo["properties"]["scripts"]["items"]["properties"]}
    howto = (REPO / "docs" / "howto" / "own-task.md").read_text()
    assert len(fields) >= 9
    for name, node in fields.items():
        assert len(node.get("description", "")) > 20, f"schema: {name} has no description"
        assert re.search(rf"`{name}`[^|\n]*:", howto) or re.search(
            rf"^\| `{name}` \|", howto, re.M), f"own-task.md: {name} not explained"
