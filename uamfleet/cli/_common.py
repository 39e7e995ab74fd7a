"""What every command line shares: parsing with tyro, one-line errors with exit status 2, choices, "–" for
undefined figures."""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal, TypeVar

import tyro

from uamfleet.baselines import planner_configs
from uamfleet.io import PathError, has_section, os_error_message, shown_path
from uamfleet.config import FEASIBILITY_RULES, EnvConfig
from uamfleet.policies import available, make, make_flown, parse
from uamfleet.policies.learned import for_world
from uamfleet.policies.registry import BASE, PolicyNameError
from uamfleet.env.protocol import observer_of
from uamfleet.presets import SCENARIOS
from uamfleet.instances import FAMILIES, SPLITS, is_map_name, map_family, map_provenance
from uamfleet.radio.packaged import RADIO_MAPS, load_radio_map
from uamfleet.rl.distributed import RankZeroError
from uamfleet.rl.networks import VARIANTS

T = TypeVar("T")

# The known sets as Literal types built from the package's tuples, so tyro lists them as {a,b,...} choices and
# rejects a typo with a usage message (exit 2). mypy sees plain strings.
if TYPE_CHECKING:
    Scenario = str
    Variant = str
    Feasibility = str
    Family = str
    Split = str
else:
    Scenario = Literal[SCENARIOS]
    Variant = Literal[VARIANTS]
    Feasibility = Literal[FEASIBILITY_RULES]
    Family = Literal[tuple(FAMILIES)]
    Split = Literal[tuple(SPLITS)]


def _policy_help() -> str:
    """``--policy``'s help: the grammar and the registered names by kind (:func:`uamfleet.policies.available`)."""
    kinds = {kind: ", ".join(name for name, (k, _) in available().items() if k == kind) for kind in ("planner",
             "dispatcher", "learned", "search")}  # fmt: skip
    return (
        "a policy of uamfleet.policies, NAME[:OPTION=VALUE,...] or SEARCH[:OPTIONS](BASE): a planner (one taxi; "
        f"random: any fleet) {kinds['planner']}; a fleet dispatcher {kinds['dispatcher']}; a learned policy "
        f"{kinds['learned']} (source=<shipped name or checkpoint file>, e.g. learned:source=berlin_stops); a search "
        f"over a learned base {kinds['search']} (e.g. argmax(learned), guided:top_k=4(learned)); or a recorded "
        "name (batch_assignment+wait=1+release, learned:berlin_stops)"
    )


Policy = Annotated[str, tyro.conf.arg(metavar="NAME", help=_policy_help())]
"""``--policy``: a name of :mod:`uamfleet.policies` in its grammar (:func:`uamfleet.policies.parse`), checked by
:func:`policy_call`."""

SCENARIO_DEFAULT = tyro.conf.arg(help_behavior_hint="(default: the scenario's)")
"""``Annotated[float | None, SCENARIO_DEFAULT]``: an option whose unset value means the scenario's own."""

UNDEFINED = "–"
"""How a figure that is undefined for an episode prints (no ride finished: ATT NaN; no step flown: min SINR -inf)."""


def fmt(value: float | None, spec: str = ".1f", unit: str = "") -> str:
    """``value`` formatted with ``spec`` and a unit, or "–" when it is None, NaN or infinite."""
    if value is None or not math.isfinite(value):
        return UNDEFINED
    return f"{value:{spec}}{unit}"


class UsageError(ValueError):
    """A command-line value that makes no sense (printed as one line, exit status 2)."""


def output_path(path: Path, flag: str) -> Path:
    """An output file's path, relative to the current folder, checked before any work: its folder must exist, or be
    one new folder inside an existing one (created here: a typo such as ``/nonexistent/sub/x.html`` fails instead
    of making a tree), and be writable; the path must not be a folder, a FIFO or another non-file, nor too long
    (the system's refusal, named). Each refusal is one line naming ``flag`` and the path."""
    shown = shown_path(path)
    parent = path.parent
    try:
        if parent.exists() and not parent.is_dir():
            raise UsageError(f"{flag} {shown}: {shown_path(parent)} is a file, not a folder; write into a folder.")
        if not parent.is_dir():
            if not parent.parent.is_dir():
                raise UsageError(
                    f"{flag} {shown}: neither its folder {shown_path(parent)} nor that folder's parent exists; "
                    "create the folders first or write to an existing one."
                )
            parent.mkdir()
        if path.is_dir():
            raise UsageError(f"{flag} {shown} is a folder; give a file name.")
        if path.exists() and not path.is_file():
            raise UsageError(f"{flag} {shown} is not a regular file (a FIFO, socket or device); give a file name.")
    except OSError as err:  # a path the system refuses to look at (too long, a loop of links, no permission)
        raise PathError(f"{flag} {shown}: {os_error_message(err, with_path=False)}", err) from None
    if not os.access(parent, os.W_OK | os.X_OK):
        raise PathError(
            f"{flag} {shown}: its folder {shown_path(parent)} is not writable (permission or a read-only file "
            "system); write elsewhere.",
            path=path,
        )
    return path


def output_paths(paths: dict[str, Path | None]) -> None:
    """:func:`output_path` of each output file, by its flag (None: not written)."""
    for flag, path in paths.items():
        if path is not None:
            output_path(path, flag)


def check_outputs(
    overwrite: bool, files: Sequence[Path | None] = (), md: Path | None = None, section: str | None = None
) -> None:
    """Refuse, before any work, to replace an existing output (a file of ``files``, or the marked ``section`` of
    the Markdown file ``md``) unless ``--overwrite`` was given: committed results are never replaced silently."""
    held = [str(path) for path in files if path is not None and path.exists()]
    if md is not None and section is not None and has_section(md, section):
        held.append(f"the {section!r} section of {md}")
    if held and not overwrite:
        verb = "hold" if len(held) > 1 else "holds"
        raise UsageError(
            f"{' and '.join(held)} already {verb} results; pass --overwrite to replace them, or write elsewhere "
            "(--out-csv / --out-md / --section / --out). Nothing was written."
        )


def earlier_rows(read: Callable[[Path], list[T]], path: Path) -> list[T]:
    """The rows ``read`` finds in ``--from-csv path``; a UsageError when there are none (nothing to render)."""
    rows = read(path)
    if not rows:
        raise UsageError(f"--from-csv {path} holds no rows: nothing to render.")
    return rows


def policy_call(text: str, flag: str = "--policy") -> tuple[str, dict[str, Any]]:
    """``(name, options)`` of the policy ``text`` names (:func:`uamfleet.policies.parse`); a UsageError naming
    ``flag``, the value and the registered policies when its name is unknown, or the parser's reason otherwise."""
    try:
        return parse(text)
    except PolicyNameError as err:
        head = re.split(r"[:+@(]", text, maxsplit=1)[0] if isinstance(text, str) else text
        if head not in available():
            names = ", ".join(repr(name) for name in available())
            raise UsageError(
                f"unknown {flag} {text!r}; choose one of {names} (options after ':', e.g. replan:beam=64; a search "
                "over a base in parentheses, e.g. argmax(learned:source=berlin_stops))."
            ) from None
        raise UsageError(f"{flag} {text!r}: {err}") from None


def _fit_to_world(call: tuple[str, dict[str, Any]], cfg: EnvConfig) -> tuple[str, dict[str, Any]]:
    """``call`` with each learned policy in it (a search's base too) sized to ``cfg``'s world
    (:func:`uamfleet.policies.learned.for_world`: ``passenger_slots="world"`` read as its requests)."""
    name, options = call[0], dict(call[1])
    if name == "learned":
        options = for_world(options, cfg.num_taxis, cfg.num_requests_max)
    if isinstance(options.get(BASE), tuple):
        options[BASE] = _fit_to_world(options[BASE], cfg)
    return name, options


def flight(
    scenario: str, text: str, seed: int = 0, overrides: dict[str, Any] | None = None, flag: str = "--policy"
) -> tuple[EnvConfig, EnvConfig, Any]:
    """(the config it flies, the config it is scored against, the policy) of the policy ``text`` names on
    ``scenario`` with config ``overrides``. A planner or dispatcher is built by
    :func:`~uamfleet.policies.make_flown` for one flight (a planner under its own rules,
    :func:`~uamfleet.baselines.planner_configs`); a learned policy or a search over one flies the scenario's world as
    it is, observed by its spec, and says in one line when it cannot read that world (``ObserverSpec.reads``)."""
    call = policy_call(text, flag)
    flown, scored = planner_configs(scenario, text, **(overrides or {}))
    if available()[call[0]][0] in ("planner", "dispatcher"):
        return flown, scored, make_flown(text, seed, scored.num_taxis)
    try:
        name, options = _fit_to_world(call, scored)
        policy = make(name, **options)
        spec = observer_of(policy)
        refusal = spec.reads(scored.world) if spec is not None else None
        if refusal is not None:  # e.g. more requests than the policy reads, another fleet size, no hover action
            raise ValueError(refusal)
    except PolicyNameError as err:
        raise UsageError(f"{flag} {text!r}: {err}") from None
    except ValueError as err:
        raise UsageError(f"{flag} {text!r} cannot fly {scored.scenario}: {' '.join(str(err).split())}") from None
    return scored, scored, policy


MapName = Annotated[
    str | None,
    tyro.conf.arg(
        metavar="FILE|NAME",
        help=f"fly this radio map: a packaged map ({', '.join(RADIO_MAPS)}) or the path of a map file (.npz of "
        "uamfleet-radio-map, or WinProp ASCII .txt); its instances are its family's (uamfleet.instances.map_family: "
        "Berlin's rules scaled to the map), its provenance is printed above the results",
        help_behavior_hint="(default: the command's own map)",
    ),
]
"""``--map``: a packaged map's name or a map file's path (checked by :func:`check_map`)."""


def check_map(value: str, flag: str = "--map") -> str:
    """``value`` when it names a map whose instance family can be derived (:func:`uamfleet.instances.map_family`):
    a packaged map or a readable map file; else a UsageError naming ``flag``, the value and the fix."""
    if not isinstance(value, str) or not value or not (value in RADIO_MAPS or is_map_name(value)):
        raise UsageError(
            f"{flag} {value!r}: no packaged map of that name and no such map file; give one of "
            f"{', '.join(RADIO_MAPS)} or the path of a map file (a .npz written by uamfleet-radio-map, or a WinProp "
            "ASCII .txt)."
        )
    try:
        map_family(value)
    except (ValueError, OSError) as err:  # a file that is no map, or a map too small to draw on
        raise UsageError(f"{flag} {value}: {' '.join(str(err).split())}") from None
    return value


FIXED_SCENARIOS: tuple[str, ...] = ("berlin_p4", "detroit_p5", "detroit3gpp_p5")
"""The paper's fixed instances: their stops lie on their own maps, so they fly no other map."""


def on_map(map_: str | None, scenario: str, overrides: dict[str, Any]) -> tuple[str, dict[str, Any]]:
    """(scenario, config overrides) of a command that flies ``scenario`` on the map ``--map map_``: the scenario's
    world on that map (``radio``) at the strictest threshold of the map's family
    (:func:`uamfleet.instances.map_family`) unless ``overrides`` set one; the default fixed scenario
    ``berlin_p4`` becomes ``berlin_instances`` (one taxi, random demand), another fixed scenario is refused in one line.
    Without a map, both as given."""
    if map_ is None:
        return scenario, overrides
    check_map(map_)
    if scenario == "berlin_p4":
        scenario = "berlin_instances"
    elif scenario in FIXED_SCENARIOS:
        raise UsageError(
            f"--scenario {scenario} with --map {map_}: a fixed scenario's stops lie on its own map; give a scenario "
            "of random demand (e.g. --scenario berlin_random or berlin_instances) with --map."
        )
    threshold = {"sinr_min_db": map_family(map_).thresholds_db[-1]}
    return scenario, {**threshold, **overrides, "radio": load_radio_map(map_)}


def with_provenance(body: str, map_: str | None) -> str:
    """A results section ``body`` with the provenance line of the map it was flown on
    (:func:`uamfleet.instances.map_provenance`) above its first table; ``body`` as it is without a map."""
    if map_ is None:
        return body
    line = f"Map: {map_provenance(map_)}."
    lines = body.split("\n")
    first = next((i for i, text in enumerate(lines) if text.startswith("|")), len(lines))
    return "\n".join([*lines[:first], line, "", *lines[first:]])


def check_jobs(jobs: int, flag: str = "--jobs") -> int:
    """``jobs`` worker processes, checked: at least 1, at most 4 per CPU core (more only thrash)."""
    most = 4 * (os.cpu_count() or 1)
    if isinstance(jobs, bool) or not isinstance(jobs, int) or not 1 <= jobs <= most:
        raise UsageError(f"{flag} {jobs}: give 1 ... {most} worker processes (4 per CPU core at most), e.g. {flag} 2.")
    return jobs


def _deferring_checks(args_type: Callable[..., T]) -> Callable[..., T]:
    """A subclass of a dataclass whose ``__post_init__`` keeps its ValueError for :func:`run` to report as one
    line (tyro would wrap it in a box of its own)."""
    if not (dataclasses.is_dataclass(args_type) and hasattr(args_type, "__post_init__")):
        return args_type

    @functools.wraps(args_type, updated=())
    class Checked(args_type):  # type: ignore[misc,valid-type]
        def __post_init__(self) -> None:
            try:
                super().__post_init__()
            except (ValueError, OSError) as err:
                object.__setattr__(self, "_cli_error", err)  # also for a frozen dataclass

    return dataclasses.dataclass(frozen=args_type.__dataclass_params__.frozen)(Checked)  # type: ignore[attr-defined]


_RULE = set("─━-=+╭╮╰╯│| ")


def _box_message(text: str) -> str:
    """The message of tyro's error box as one line. rich draws it framed (title bar, message, rule, "For full
    helptext ...") or plain (title, rule, message, rule, ...): the message is the text after the first rule
    (a title bar counts as one) up to the next."""
    blocks: list[list[str]] = [[]]
    for line in text.splitlines():
        inner = line.strip().strip("│|").strip()
        if inner and (set(inner) <= _RULE or (inner[0] in _RULE and inner[-1] in _RULE)):  # a rule or title bar
            blocks.append([])
        elif inner:
            blocks[-1].append(inner)
    words = blocks[1] if len(blocks) > 2 else [line for block in blocks for line in block]
    return " ".join(" ".join(words).split())


def _parse(args_type: Callable[..., T], argv: Sequence[str] | None, prog: str, description: str) -> T:
    """tyro's parse, its usage errors (unknown choice or option, unparsable number) turned into one line and
    exit status 2 like every other error (tyro draws them as a box)."""
    captured = io.StringIO()
    try:
        with contextlib.redirect_stderr(captured):
            args = tyro.cli(args_type, args=argv, prog=prog, description=description)
    except SystemExit as done:
        if done.code in (0, None):
            raise
        message = _box_message(captured.getvalue()) or " ".join(captured.getvalue().split())
        print(f"{prog}: error: {message} (see {prog} --help)", file=sys.stderr)
        raise SystemExit(2) from None
    sys.stderr.write(captured.getvalue())
    return args


def run(
    main: Callable[[T], Any], args_type: Callable[..., T], argv: Sequence[str] | None, prog: str, doc: str | None
) -> int:
    """Parse ``argv`` into ``args_type`` and call ``main``; the exit status. Bad input (any ``ValueError``, the
    type of every documented input error of the package, an existing run) and a path or device that cannot be used
    (any ``OSError``: a missing, unwritable or too long path, a folder given for a file) print ``prog: error:
    <message>`` on stderr, one line naming the path, and return 2; so do tyro's parse errors (as a SystemExit).
    Under torchrun a rank other than 0 whose rank 0 failed (:class:`~uamfleet.rl.distributed.RankZeroError`)
    returns 2 silently: rank 0 prints the error. ``UAMFLEET_TRACEBACK=1`` re-raises instead, for debugging."""
    description = (doc or "").strip()
    try:
        args = _parse(_deferring_checks(args_type), argv, prog, description)
        if (error := getattr(args, "_cli_error", None)) is not None:
            raise error
        status = main(args)
    except RankZeroError:
        if os.environ.get("UAMFLEET_TRACEBACK"):
            raise
        return 2
    except (ValueError, OSError) as err:
        if os.environ.get("UAMFLEET_TRACEBACK"):
            raise
        message = os_error_message(err) if isinstance(err, OSError) else " ".join(str(err).split())  # one line
        print(f"{prog}: error: {message}", file=sys.stderr)
        return 2
    return status if isinstance(status, int) else 0
