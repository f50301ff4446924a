"""mkdocs hook: the CLI reference is generated from the parser at build time
(``tipgeo.cli.build_parser()``), so it is never stale.

- ``docs/reference/cli.md``: the marker ``<!-- cli-reference -->`` becomes one
  section per command (and per sub-command), each with its description,
  usage and a table of its arguments;
- ``docs/reference/vocabulary.md``: ``<!-- cli-vocabulary -->`` becomes the
  table of shared flags (``tipgeo.cli.common.VOCABULARY``) with the commands
  that take each, ``<!-- cli-renamed -->`` the table of renamed flags
  (``tipgeo.cli.common.DEPRECATED``, filled as the parser is built).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

MARKER = "<!-- cli-reference -->"
PAGE = "reference/cli.md"
VOCABULARY_PAGE = "reference/vocabulary.md"
VOCABULARY_MARKER = "<!-- cli-vocabulary -->"
RENAMED_MARKER = "<!-- cli-renamed -->"


def on_config(config, **kwargs):
    # document the code beside mkdocs.yml, not whatever tipgeo is installed
    root = str(Path(config["config_file_path"]).resolve().parent)
    if root not in sys.path:
        sys.path.insert(0, root)
    return config


def _escape(text: str) -> str:
    """Help text as Markdown table-cell text: no table breaks, no links,
    no emphasis, no HTML."""
    text = " ".join(text.split())
    for a, b in (("\\", "\\\\"), ("|", "\\|"), ("<", "&lt;"), (">", "&gt;"), ("*", "\\*"),
                 ("[", "\\["), ("]", "\\]"), ("_", "\\_"), ("`", "\\`")):
        text = text.replace(a, b)
    return text


def _help(parser: argparse.ArgumentParser, action: argparse.Action) -> str:
    if not action.help or action.help == argparse.SUPPRESS:
        return ""
    try:
        return parser._get_formatter()._expand_help(action)
    except (KeyError, TypeError, ValueError):
        return action.help


def _usage(parser: argparse.ArgumentParser) -> str:
    """The usage lines without ``usage: `` and its hanging indent."""
    lines = parser.format_usage().rstrip().splitlines()
    prefix = "usage: "
    out = [lines[0][len(prefix):] if lines[0].startswith(prefix) else lines[0]]
    out += [x[len(prefix):] if x.startswith(" " * len(prefix)) else x for x in lines[1:]]
    return "\n".join(out)


def _names(action: argparse.Action) -> str:
    if action.option_strings:
        names = ", ".join(f"`{o}`" for o in action.option_strings)
    else:
        names = f"`{action.metavar or action.dest}`"
    return names


def _value(action: argparse.Action) -> str:
    if action.nargs == 0:
        return ""
    if action.choices is not None and not isinstance(action, argparse._SubParsersAction):
        return " \\| ".join(f"`{c}`" for c in action.choices)
    if not action.option_strings:  # a positional: its name says it; say how many
        return {"+": "one or more", "*": "any number", "?": "optional"}.get(action.nargs, "")
    metavar = action.metavar or (action.dest.upper() if action.option_strings else action.dest)
    if isinstance(metavar, tuple):
        metavar = " ".join(metavar)
    suffix = {"+": " …", "*": " …", "?": " (optional)"}.get(action.nargs, "")
    if isinstance(action.nargs, int) and action.nargs > 1 and not isinstance(action.metavar,
                                                                            tuple):
        metavar = " ".join([metavar] * action.nargs)
    return f"`{metavar}`{suffix}"


def _details(action: argparse.Action) -> list[str]:
    out = []
    if action.required and action.option_strings:
        out.append("required")
    if isinstance(action, argparse._AppendAction) and "repeatable" not in (action.help or ""):
        out.append("repeatable")
    return out


def _section(parser: argparse.ArgumentParser, path: list[str], summary: str | None,
             level: int) -> list[str]:
    title = " ".join(path)
    lines = [f"{'#' * level} `{title}`", ""]
    if summary:
        lines += [_escape(summary[:1].upper() + summary[1:]) + ".", ""]
    if parser.description and parser.description != summary:
        lines += [_escape(parser.description), ""]
    lines += ["```text", _usage(parser), "```", ""]
    rows = []
    subparsers = []
    for action in parser._actions:
        if isinstance(action, argparse._HelpAction):
            continue
        if isinstance(action, argparse._SubParsersAction):
            subparsers.append(action)
            continue
        if action.help == argparse.SUPPRESS:
            continue
        help_text = _escape(_help(parser, action))
        details = _details(action)
        if details:
            help_text = (help_text + " " if help_text else "") + f"({', '.join(details)})"
        rows.append(f"| {_names(action)} | {_value(action)} | {help_text} |")
    if rows:
        lines += ["| argument | value | meaning |", "|---|---|---|", *rows, ""]
    for action in subparsers:
        helps = {a.dest: a.help for a in action._choices_actions}
        for name, sub in action.choices.items():
            lines += _section(sub, [*path, name], helps.get(name), min(level + 1, 6))
    return lines


def cli_reference() -> str:
    """The Markdown of every command, in the parser's order."""
    from tipgeo.cli import build_parser

    parser = build_parser()
    lines = []
    top = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    options = [a for a in parser._actions
               if a.option_strings and not isinstance(a, argparse._HelpAction)]
    if options:
        lines += ["## `tipgeo`", "", "```text", _usage(parser), "```", "",
                  "| argument | value | meaning |", "|---|---|---|"]
        lines += [f"| {_names(a)} | {_value(a)} | {_escape(_help(parser, a))} |"
                  for a in options]
        lines.append("")
    for action in top:
        helps = {a.dest: a.help for a in action._choices_actions}
        for name, sub in action.choices.items():
            lines += _section(sub, ["tipgeo", name], helps.get(name), 2)
    return "\n".join(lines)


def _commands(parser: argparse.ArgumentParser, path: str = ""):
    """(command path, its parser) for every command and sub-command."""
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                full = f"{path} {name}".strip()
                yield full, sub
                yield from _commands(sub, full)


def vocabulary_table() -> str:
    """The shared flags, their one meaning, and the commands that take each."""
    from tipgeo.cli import build_parser
    from tipgeo.cli.common import VOCABULARY

    commands = list(_commands(build_parser()))
    rows = ["| flag | meaning | commands |", "|---|---|---|"]
    for flag, meaning in VOCABULARY.items():
        names = flag.split("/")
        having = [c for c, p in commands
                  if any(o in names for a in p._actions if a.help != argparse.SUPPRESS
                         for o in a.option_strings)]
        where = "every command" if len(having) == len(commands) else ", ".join(
            f"`{c}`" for c in having)
        shown = ", ".join(f"`{n}`" for n in names)
        rows.append(f"| {shown} | {_escape(meaning)} | {where} |")
    return "\n".join(rows)


def renamed_table() -> str:
    """Every renamed flag: command, old spelling, new spelling."""
    from tipgeo.cli import build_parser
    from tipgeo.cli.common import DEPRECATED

    build_parser()  # fills DEPRECATED
    seen = []
    for row in DEPRECATED:
        if row not in seen:
            seen.append(row)
    rows = ["| command | old | new |", "|---|---|---|"]
    rows += [f"| `{c}` | `{old}` | `{new}` |" for c, old, new in seen]
    return "\n".join(rows)


def on_page_markdown(markdown: str, page, config, files, **kwargs):
    if page.file.src_uri == PAGE:
        if MARKER not in markdown:
            raise ValueError(f"{PAGE} lost its marker {MARKER}")
        return markdown.replace(MARKER, cli_reference())
    if page.file.src_uri == VOCABULARY_PAGE:
        for marker in (VOCABULARY_MARKER, RENAMED_MARKER):
            if marker not in markdown:
                raise ValueError(f"{VOCABULARY_PAGE} lost its marker {marker}")
        return (markdown.replace(VOCABULARY_MARKER, vocabulary_table())
                .replace(RENAMED_MARKER, renamed_table()))
    return markdown
