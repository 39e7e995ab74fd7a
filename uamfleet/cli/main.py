"""The ``uamfleet`` command: ``uamfleet <command> [options]`` runs one of the package's command lines.

    uamfleet --help                      # the commands, one line each
    uamfleet train --scenario berlin_p4  # = uamfleet-train --scenario berlin_p4
    uamfleet bench --help                # a command's own options
    uamfleet --version

Each command hands the rest of the command line to its module's ``cli(argv, prog)``, so its options, ``--help``,
one-line errors and exit status 2 are those of the ``uamfleet-<name>`` script of the same module. Only the module
of the command that runs is imported: ``uamfleet --help`` reads the modules' docstrings from their files.
"""

from __future__ import annotations

import ast
import difflib
import re
import sys
from collections.abc import Sequence
from importlib import import_module
from pathlib import Path

COMMANDS: dict[str, str] = {
    "train": "train",
    "imitate": "imitate",
    "expert-iteration": "expert_iteration",
    "fleet-imitate": "fleet_imitate",
    "fleet-finetune": "fleet_finetune",
    "quickstart": "quickstart",
    "rollout": "rollout",
    "render": "render",
    "bench": "benchmark",
    "fleet-bench": "fleet_benchmark",
    "paper-table": "paper_table",
    "msha-table": "msha_table",
    "radio-map": "radio_map",
    "docs-tables": "docs_tables",
    "demand": "demand",
}
"""Each command of ``uamfleet <command>`` and its module in :mod:`uamfleet.cli`, in the order ``--help`` lists them."""

ALIASES: dict[str, str] = {"benchmark": "bench", "fleet-benchmark": "fleet-bench"}
"""The names of the ``uamfleet-<name>`` scripts that differ from their command's, accepted as that command."""

SUMMARY_WIDTH = 80
"""The longest one-line summary ``--help`` prints for a command."""

_HERE = Path(__file__).resolve().parent


def module_of(command: str) -> str:
    """The dotted module that runs ``command`` (a name of :data:`COMMANDS` or :data:`ALIASES`)."""
    return f"uamfleet.cli.{COMMANDS[ALIASES.get(command, command)]}"


def summary(doc: str | None, width: int = SUMMARY_WIDTH) -> str:
    """One line from a module docstring: the first sentence of its first paragraph without the asides in
    parentheses and its full stop; if that is longer than ``width``, its longest head that ends before a comma,
    semicolon or colon, fits and names at least four words, else the sentence cut at a word with "…"."""
    paragraph = " ".join((doc or "").strip().split("\n\n", 1)[0].split())
    while (bare := re.sub(r"\s*\([^()]*\)", "", paragraph)) != paragraph:  # innermost asides first
        paragraph = bare
    sentence = re.split(r"(?<=\.)\s", paragraph, maxsplit=1)[0].strip().removesuffix(".")
    if len(sentence) <= width:
        return sentence
    heads = [sentence[: m.start()] for m in re.finditer(r"[,;:] ", sentence[: width + 2])]
    heads = [head for head in heads if len(head.split()) >= 4]
    if heads:
        return heads[-1]
    return sentence[: width - 1].rsplit(" ", 1)[0].rstrip(",;:") + "…"


def command_summary(command: str) -> str:
    """The one-line summary of ``command``, read from its module's file without importing the module."""
    source = (_HERE / f"{COMMANDS[command]}.py").read_text(encoding="utf-8")
    return summary(ast.get_docstring(ast.parse(source)))


def usage(prog: str = "uamfleet") -> str:
    """What ``uamfleet --help`` prints: the commands, one line each, and how to reach their options."""
    pad = max(map(len, COMMANDS)) + 2
    lines = [f"{name:<{pad}}{command_summary(name)}" for name in COMMANDS]
    renamed = " and ".join(ALIASES.values())
    scripts = " and ".join(f"uamfleet-{name}" for name in ALIASES)
    return "\n".join([
        f"usage: {prog} <command> [options]",
        "",
        "Communication-aware ride-sharing route planning for Urban Air Mobility fleets.",
        "",
        "commands:",
        *(f"  {line}" for line in lines),
        "",
        "options:",
        "  -h, --help     show this listing and exit",
        "  -V, --version  show the package's version and exit",
        "",
        f"'{prog} <command> --help' lists a command's options. Each command is also a script, uamfleet-<command>;",
        f"{renamed} are {scripts} (their names work here too).",
    ])  # fmt: skip


def version() -> str:
    """The package's version."""
    from uamfleet import __version__

    return __version__


def unknown(word: str, prog: str) -> str:
    """The one-line error for a command that is not one, with the closest name when one is close."""
    message = f"{prog}: error: unknown command {word!r}; the commands are: {', '.join(COMMANDS)}."
    if close := difflib.get_close_matches(word, [*COMMANDS, *ALIASES], n=1):
        message += f" Did you mean {ALIASES.get(close[0], close[0])!r}?"
    return message


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet") -> int:
    """The ``uamfleet`` command (``python -m uamfleet``): the exit status of the command it runs; 0 after
    ``--help`` or ``--version``; 2 with one line on stderr for an unknown command or option, and with the listing
    when no command is given."""
    args = list(sys.argv[1:] if argv is None else argv)
    if not args:
        print(usage(prog), file=sys.stderr)
        return 2
    first, rest = args[0], args[1:]
    if first in ("-h", "--help"):
        print(usage(prog))
        return 0
    if first in ("-V", "--version"):
        print(f"uamfleet {version()}")
        return 0
    if first.startswith("-"):
        print(
            f"{prog}: error: unknown option {first!r}; give a command first ({prog} --help lists them), "
            f"then its options.",
            file=sys.stderr,
        )
        return 2
    if first not in COMMANDS and first not in ALIASES:
        print(unknown(first, prog), file=sys.stderr)
        return 2
    command = import_module(module_of(first)).cli
    return int(command(rest, prog=f"{prog} {first}"))


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.main"))
