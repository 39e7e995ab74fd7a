"""Input probe of issue 39: every case the issue names, tried as a new user would against a given checkout, each
answer classified good or bad by the rules of README.md (fixed before the first run).

    python reports/2026-12-03-input-probe/probe.py --checkout /work/wt/before --out before.csv

Each case runs in its own subprocess (several for the race and torchrun cases) with a timeout, in a fresh temp
folder, with ``PYTHONPATH=<checkout>`` so that the interpreter imports that checkout's uamfleet (checked before the
first case). Scene cases run under the Sionna RT interpreter (``--rt-python``); without one they are recorded as
``skipped``. Everything a case creates stays inside its temp folder, removed afterwards.
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import textwrap
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

PYTHON = "/work/main/.venv/bin/python"
TORCHRUN = "/work/main/.venv/bin/torchrun"
RT_PYTHON = str(Path.home() / ".cache/uamfleet-rt/venv/bin/python")
COLUMNS = ("class", "case", "command", "exit_code", "seconds", "verdict", "reason", "first_line_of_stderr")
MEMORY_GIB = 8  # address-space limit of every case: a case that asks for tens of GiB fails instead of swapping
# the smallest training the CLI accepts: one iteration of one env, no evaluation on the way
TINY_TRAIN = (
    "--scenario berlin_p4 --total-timesteps 64 --num-envs 1 --num-steps 64 --num-minibatches 1 --update-epochs 1 "
    "--eval-every 0 --checkpoint-every 1"
).split()
TINY_IMITATE = (
    "--init berlin_stops --thresholds -3 --envs-per-threshold 1 --rounds 1 --steps-per-round 2 --expert-beam 1 "
    "--epochs 1 --eval-instances 1 --max-wall-s 30"
).split()
TINY_QUICKSTART = "--total-timesteps 2048 --minutes 0.2 --no-generalist".split()  # one iteration of 32 envs x 64
TINY_RENDER = "--scenario berlin_p4 --policy random".split()
TINY_BENCHMARK = "--count 1 --methods straight --jobs 1".split()
TINY_FLEET_BENCHMARK = "--settings 1x6 --count 1 --dispatchers insertion --jobs 1".split()


# ---------------------------------------------------------------------------------------------------------------
# running


@dataclass
class Proc:
    argv: list[str]
    code: int | None  # None: killed at the timeout
    seconds: float
    stdout: str
    stderr: str

    @property
    def timed_out(self) -> bool:
        return self.code is None


@dataclass
class Row:
    cls: str
    case: str
    command: str = ""
    exit_code: str = ""
    seconds: float = 0.0
    verdict: str = "bad"
    reason: str = ""
    first_line: str = ""

    def csv_row(self) -> dict[str, str]:
        return {
            "class": self.cls, "case": self.case, "command": self.command, "exit_code": self.exit_code,
            "seconds": f"{self.seconds:.1f}", "verdict": self.verdict, "reason": self.reason,
            "first_line_of_stderr": self.first_line,
        }  # fmt: skip


@dataclass
class Ctx:
    checkout: Path
    tmp: Path  # this case's own fresh folder (the cwd of its commands)
    rt_python: str | None
    shared: Path  # the probe's own temp folder: a home (caches) shared by its cases, removed at the end

    def env(self) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if not k.startswith(("UAMFLEET_", "PYTHON", "XDG_"))}
        env.update(PYTHONPATH=str(self.checkout), OMP_WAIT_POLICY="PASSIVE", OMP_NUM_THREADS="1")
        # every cache (distance tables, Dr.Jit kernels, matplotlib) lands in the probe's temp home, never the user's
        env.update(MPLBACKEND="Agg", HOME=str(self.shared / "home"), UAMFLEET_CACHE=str(self.shared / "cache"))
        return env


def _limits() -> None:
    os.setsid()  # its own process group: a timeout kills the case and its children
    limit = MEMORY_GIB * 2**30
    resource.setrlimit(resource.RLIMIT_AS, (limit, limit))


def spawn(ctx: Ctx, argv: Sequence[str], timeout: float = 120.0) -> subprocess.Popen[str]:
    return subprocess.Popen(
        list(argv), cwd=ctx.tmp, env=ctx.env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        preexec_fn=_limits, errors="replace",
    )  # fmt: skip


def finish(proc: subprocess.Popen[str], argv: Sequence[str], started: float, timeout: float) -> Proc:
    try:
        out, err = proc.communicate(timeout=max(0.1, started + timeout - time.monotonic()))
        code: int | None = proc.returncode
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        code = None
    return Proc(list(argv), code, time.monotonic() - started, out, err)


def run(ctx: Ctx, argv: Sequence[str], timeout: float = 120.0) -> Proc:
    started = time.monotonic()
    return finish(spawn(ctx, argv, timeout), argv, started, timeout)


def cli(ctx: Ctx, module: str, args: Sequence[str], timeout: float = 120.0, python: str = PYTHON) -> Proc:
    return run(ctx, [python, "-m", f"uamfleet.cli.{module}", *args], timeout)


def api(ctx: Ctx, body: str, timeout: float = 120.0, prelude: str = "") -> Proc:
    """Run ``body`` (Python that calls the API once) and print PROBE_RESULT {...}: what it raised, or accepted."""
    script = textwrap.dedent(
        """
        import json, sys
        {prelude}
        def _probe():
        {body}
        try:
            _value = _probe()
            _out = {{"accepted": True, "value": _value if isinstance(_value, dict) else repr(_value)[:200]}}
        except BaseException as _err:  # noqa: BLE001 - the probe classifies whatever comes out
            _out = {{"accepted": False, "raised": type(_err).__name__, "message": str(_err),
                    "valueerror": isinstance(_err, ValueError), "oserror": isinstance(_err, OSError),
                    "importerror": isinstance(_err, ImportError)}}
        print("PROBE_RESULT " + json.dumps(_out))
        """
    ).format(prelude=textwrap.dedent(prelude), body=textwrap.indent(textwrap.dedent(body).strip(), "    "))
    (ctx.tmp / "case.py").write_text(script)
    return run(ctx, [PYTHON, "case.py"], timeout)


# ---------------------------------------------------------------------------------------------------------------
# judging (README.md, "Verdict rules")


def first_line(text: str) -> str:
    for line in text.splitlines():
        if line.strip():
            return line.strip()[:300]
    return ""


def error_lines(text: str) -> list[str]:
    """The lines that report an error (``prog: error: ...``); torchrun's own ChildFailedError line is not one."""
    return [
        line
        for line in text.splitlines()
        if "error:" in line.lower() and "traceback" not in line.lower() and "ChildFailedError" not in line
    ]


def last_line(text: str) -> str:
    lines = [line.strip() for line in text.splitlines() if line.strip(" =-")]  # not torchrun's rules
    return lines[-1][:200] if lines else ""


def _names(message: str, must: Sequence[Sequence[str]]) -> str | None:
    """None when ``message`` holds one of each group of ``must`` (case-insensitive), else what it lacks."""
    low = message.lower()
    for group in must:
        if not any(word.lower() in low for word in group):
            return f"message names none of {list(group)}"
    return None


def judge_cli(
    row: Row,
    p: Proc,
    must: Sequence[Sequence[str]] = (),
    forbid: Sequence[str] = (),
    outside: Sequence[Path] = (),
    marker: Path | None = None,
    leak: Sequence[str] = (),
    expect_ok: bool = False,
) -> Row:
    """A refusal: exit 2, no traceback, one ``error:`` line naming ``must``, none of ``forbid`` (misleading
    words), no raw [Errno ...]; nothing at ``outside``, no ``marker``, none of ``leak`` in the output."""
    row.command = " ".join(_short(a) for a in p.argv)
    row.exit_code = "timeout" if p.timed_out else str(p.code)
    row.seconds = p.seconds
    row.first_line = first_line(p.stderr)
    errors = error_lines(p.stderr)
    message = " ".join(errors)
    both = p.stdout + p.stderr
    problems: list[str] = []
    if marker is not None and marker.exists():
        problems.append("the plugin's constructor ran (marker file created)")
    written = [str(path) for path in outside if path.exists()]
    if written:
        problems.append(f"wrote outside: {', '.join(_short(w) for w in written)}")
    leaked = [word for word in leak if word in both]
    if leaked:
        problems.append(f"output holds the content of a file outside ({leaked[0]!r})")
    if p.timed_out:
        problems.append(f"hang: killed after {p.seconds:.0f} s")
    elif expect_ok:
        if p.code != 0:
            problems.append(f"a valid input failed (exit {p.code}): {last_line(p.stderr)}")
    elif "Traceback" in p.stderr:
        problems.append(f"traceback: {last_line(p.stderr)}")
    elif p.code == 0:
        problems.append("accepted silently (exit 0)")
    elif p.code != 2:
        problems.append(f"exit {p.code}: {last_line(p.stderr)}")
    elif len(errors) != 1:
        problems.append(f"{len(errors)} error lines")
    if not problems and not expect_ok:
        if "[errno" in message.lower():
            problems.append(f"raw OS error: {message[:160]}")
        elif (lack := _names(message, must)) is not None:
            problems.append(f"{lack}: {message[:160]}")
        elif bad := [w for w in forbid if w.lower() in message.lower()]:
            problems.append(f"misleading ({bad[0]!r}): {message[:160]}")
    row.verdict = "bad" if problems else "good"
    row.reason = "; ".join(problems) if problems else ("ran as it should" if expect_ok else "refused in one line")
    return row


def result_of(p: Proc) -> dict | None:
    for line in p.stdout.splitlines():
        if line.startswith("PROBE_RESULT "):
            return json.loads(line[len("PROBE_RESULT ") :])
    return None


def judge_api(
    row: Row,
    p: Proc,
    must: Sequence[Sequence[str]] = (),
    forbid: Sequence[str] = (),
    kinds: Sequence[str] = ("valueerror",),
    outside: Sequence[Path] = (),
) -> Row:
    """A refusal: an exception of ``kinds`` (ValueError, its subclasses ConfigError ...; FileNotFoundError /
    FileExistsError for files: 'oserror'; ImportError for engines) with a one-line message naming ``must``."""
    row.command = row.command or " ".join(_short(a) for a in p.argv)
    row.exit_code = "timeout" if p.timed_out else str(p.code)
    row.seconds = p.seconds
    got = result_of(p)
    problems: list[str] = []
    written = [str(path) for path in outside if path.exists()]
    if written:
        problems.append(f"wrote outside: {', '.join(_short(w) for w in written)}")
    if p.timed_out:
        problems.append(f"hang: killed after {p.seconds:.0f} s")
        row.first_line = first_line(p.stderr)
    elif got is None:
        problems.append(f"crashed (exit {p.code}): {last_line(p.stderr)}")
        row.first_line = first_line(p.stderr)
    elif got["accepted"]:
        problems.append("accepted silently")
        row.first_line = first_line(p.stderr)
    else:
        message = got["message"]
        row.first_line = f"{got['raised']}: {first_line(message)}"[:300]
        if not any(got.get(kind) for kind in kinds):
            problems.append(f"{got['raised']}, not a documented input error: {first_line(message)[:160]}")
        elif len(message.strip().splitlines()) != 1:
            problems.append(f"{len(message.strip().splitlines())}-line message")
        elif "[errno" in message.lower():
            problems.append(f"raw OS error: {message[:160]}")
        elif (lack := _names(message, must)) is not None:
            problems.append(f"{lack}: {message[:160]}")
        elif bad := [w for w in forbid if w.lower() in message.lower()]:
            problems.append(f"misleading ({bad[0]!r}): {message[:160]}")
    row.verdict = "bad" if problems else "good"
    row.reason = "; ".join(problems) if problems else "refused in one line"
    return row


def _short(text: str) -> str:
    """A long argument (a 5,000-character path) shortened for the CSV."""
    return text if len(text) <= 120 else f"{text[:40]}...({len(text)} chars)...{text[-30:]}"


# ---------------------------------------------------------------------------------------------------------------
# cases

CASES: list[tuple[str, str, Callable[[Ctx, Row], Row]]] = []


def case(cls: str, name: str) -> Callable[[Callable[[Ctx, Row], Row]], Callable[[Ctx, Row], Row]]:
    def register(fn: Callable[[Ctx, Row], Row]) -> Callable[[Ctx, Row], Row]:
        CASES.append((cls, name, fn))
        return fn

    return register


# --- scene ------------------------------------------------------------------------------------------------------

MATERIAL = """  <bsdf type="itu-radio-material" id="concrete">
    <string name="type" value="concrete"/>
    <float name="thickness" value="0.2"/>
  </bsdf>
"""
# the ground is a flat cube: Sionna's loader leaves a "rectangle" out of the scene's bounding box
GROUND = """  <shape type="cube" id="ground">
    <transform name="to_world"><scale x="{half}" y="{half}" z="0.05"/><translate x="0" y="0" z="-0.05"/></transform>
    <ref id="concrete" name="bsdf"/>
  </shape>
"""
BUILDING = """  <shape type="cube" id="building">
    <transform name="to_world"><scale x="10" y="10" z="15"/><translate x="20" y="20" z="15"/></transform>
    <ref id="concrete" name="bsdf"/>
  </shape>
"""
CANARY = "PROBE-CANARY-7f3a"  # the first line of a file outside the scene folder: must never reach the output
RT_ARGS = "--samples-per-tx 10000 --gbs-m 0 0 25".split()


def scene_xml(extra: str = "", doctype: str = "", half: float = 100.0) -> str:
    ground = GROUND.format(half=half)
    return f'<?xml version="1.0"?>\n{doctype}<scene version="2.1.0">\n{MATERIAL}{ground}{BUILDING}{extra}</scene>\n'


def evil_plugin(ctx: Ctx, folder: Path) -> Path:
    """``folder``/evil.so whose constructor writes ``ctx.tmp``/MARKER; the marker's path."""
    marker = ctx.tmp / "MARKER"
    folder.mkdir(parents=True, exist_ok=True)
    source = ctx.tmp / "evil.c"
    source.write_text(
        "#include <stdio.h>\n__attribute__((constructor)) static void probe_marker(void) {\n"
        f'  FILE *f = fopen("{marker}", "w"); if (f) {{ fputs("ran\\n", f); fclose(f); }}\n}}\n'
    )
    subprocess.run(["gcc", "-shared", "-fPIC", "-o", str(folder / "evil.so"), str(source)], check=True)
    return marker


def outside_canary(ctx: Ctx, name: str = "secret.ply") -> Path:
    outside = ctx.tmp / "outside"
    outside.mkdir(exist_ok=True)
    path = outside / name
    path.write_text(f"{CANARY} first line of a file outside the scene folder\n")
    return path


def scene_case(ctx: Ctx, row: Row, xml: str, args: Sequence[str] = (), timeout: float = 120.0, **judge) -> Row:
    if ctx.rt_python is None:
        row.verdict, row.reason = "skipped", "no Sionna RT interpreter (--rt-python)"
        return row
    city = ctx.tmp / "city"
    city.mkdir(exist_ok=True)
    (city / "scene.xml").write_text(xml)
    p = cli(ctx, "radio_map", ["--scene", "city/scene.xml", "--out", "out.npz", *RT_ARGS, *args], timeout,
            python=ctx.rt_python)  # fmt: skip
    return judge_cli(row, p, **judge)


@case("scene", "control: a valid small scene is ray-traced")
def scene_control(ctx: Ctx, row: Row) -> Row:
    row = scene_case(ctx, row, scene_xml(), expect_ok=True)
    if row.verdict == "good" and not (ctx.tmp / "out.npz").exists():
        row.verdict, row.reason = "bad", "exit 0 but no out.npz"
    return row


@case("scene", 'plugin path climb: <shape type="../meshes/evil"/> beside plugins/ and meshes/evil.so')
def scene_plugin_climb(ctx: Ctx, row: Row) -> Row:
    marker = evil_plugin(ctx, ctx.tmp / "city" / "meshes")
    (ctx.tmp / "city" / "plugins").mkdir()
    xml = scene_xml('  <shape type="../meshes/evil" id="evil"/>\n')
    return scene_case(ctx, row, xml, marker=marker, must=[["evil", "type", "plugin"]])


@case("scene", "absolute plugin path climb (../ x 24 + /abs/evil, no plugins/ folder)")
def scene_plugin_abs_climb(ctx: Ctx, row: Row) -> Row:
    marker = evil_plugin(ctx, ctx.tmp / "city" / "meshes")
    climb = "../" * 24 + str(ctx.tmp / "city" / "meshes" / "evil").lstrip("/")
    return scene_case(ctx, row, scene_xml(f'  <shape type="{climb}" id="evil"/>\n'), marker=marker,
                      must=[["evil", "type", "plugin"]])  # fmt: skip


@case("scene", 'absolute plugin path <shape type="/abs/evil"/>')
def scene_plugin_abs(ctx: Ctx, row: Row) -> Row:
    marker = evil_plugin(ctx, ctx.tmp / "city" / "meshes")
    xml = scene_xml(f'  <shape type="{ctx.tmp / "city" / "meshes" / "evil"}" id="evil"/>\n')
    return scene_case(ctx, row, xml, marker=marker, must=[["evil", "type", "plugin"]])


@case("scene", '<include filename="/etc/passwd"/>')
def scene_include_passwd(ctx: Ctx, row: Row) -> Row:
    xml = scene_xml('  <include filename="/etc/passwd"/>\n')
    return scene_case(ctx, row, xml, leak=["root:x:", "root:"], must=[["include", "passwd"]])


@case("scene", "PLY outside the scene folder (filename ../outside/secret.ply)")
def scene_ply_outside(ctx: Ctx, row: Row) -> Row:
    outside_canary(ctx)
    xml = scene_xml(
        '  <shape type="ply" id="stolen">\n    <string name="filename" value="../outside/secret.ply"/>\n'
        '    <ref id="concrete" name="bsdf"/>\n  </shape>\n'
    )
    return scene_case(ctx, row, xml, leak=[CANARY], must=[["secret.ply", "outside", "filename"]])


@case("scene", "PLY filename ../../../../../../../../etc/passwd")
def scene_ply_passwd(ctx: Ctx, row: Row) -> Row:
    xml = scene_xml(
        '  <shape type="ply" id="stolen">\n    <string name="filename" value="../../../../../../../../etc/passwd"/>\n'
        '    <ref id="concrete" name="bsdf"/>\n  </shape>\n'
    )
    return scene_case(ctx, row, xml, leak=["root:x:", "root:"], must=[["passwd", "filename", "outside"]])


@case("scene", "billion laughs (nested entities)")
def scene_billion_laughs(ctx: Ctx, row: Row) -> Row:
    entities = '<!ENTITY lol0 "lololololololololololololololololol">\n' + "".join(
        f'<!ENTITY lol{k} "{f"&lol{k - 1};" * 10}">\n' for k in range(1, 10)
    )
    xml = scene_xml('  <shape type="rectangle" id="laughs"><string name="lol" value="&lol9;"/></shape>\n',
                    doctype=f"<!DOCTYPE scene [\n{entities}]>\n")  # fmt: skip
    return scene_case(ctx, row, xml, must=[["entit", "doctype", "dtd"]])


@case("scene", "XXE: <!ENTITY xxe SYSTEM 'file:///.../secret.txt'>")
def scene_xxe(ctx: Ctx, row: Row) -> Row:
    secret = outside_canary(ctx, "secret.txt")
    doctype = f'<!DOCTYPE scene [\n<!ENTITY xxe SYSTEM "file://{secret}">\n]>\n'
    xml = scene_xml('  <shape type="rectangle" id="&xxe;"><ref id="concrete" name="bsdf"/></shape>\n', doctype)
    return scene_case(ctx, row, xml, leak=[CANARY], must=[["entit", "doctype", "dtd", "external"]])


@case("scene", "a 2e7 m ground plane (default --cell-m 10)")
def scene_huge_plane(ctx: Ctx, row: Row) -> Row:
    return scene_case(ctx, row, scene_xml(half=1e7), timeout=150,
                      must=[["GiB", "GB", "bytes", "cells", "limit", "extent", "UAMFLEET_MAX"]])  # fmt: skip


@case("scene", "--cell-m 0.001 on a valid 200 m scene")
def scene_tiny_cell(ctx: Ctx, row: Row) -> Row:
    return scene_case(ctx, row, scene_xml(), ["--cell-m", "0.001"], timeout=150, must=[["cell"]])


# --- run folder -------------------------------------------------------------------------------------------------


@case("run folder", "two trainings of one --run-name started together (2 trials)")
def race(ctx: Ctx, row: Row) -> Row:
    verdicts: list[str] = []
    codes: list[str] = []
    started = time.monotonic()
    for trial in range(2):
        argv = [PYTHON, "-m", "uamfleet.cli.train", *TINY_TRAIN, "--run-name", f"same{trial}"]
        t0 = time.monotonic()
        procs = [spawn(ctx, argv) for _ in range(2)]
        done = [finish(proc, argv, t0, 180) for proc in procs]
        codes.append("+".join("timeout" if d.timed_out else str(d.code) for d in done))
        ok = [d for d in done if d.code == 0]
        refused = [d for d in done if d.code == 2 and len(error_lines(d.stderr)) == 1 and "Traceback" not in d.stderr]
        if len(ok) == 2:
            verdicts.append(f"trial {trial + 1}: both exited 0 into runs/same{trial}")
        elif len(ok) == 1 and len(refused) == 1 and f"same{trial}" in error_lines(refused[0].stderr)[0]:
            row.first_line = row.first_line or first_line(refused[0].stderr)
        else:
            verdicts.append(f"trial {trial + 1}: exits {codes[-1]}: {last_line(done[0].stderr + done[1].stderr)}")
        if not row.first_line:
            row.first_line = first_line(done[0].stderr) or first_line(done[1].stderr)
    row.command = "python " + " ".join(argv[1:]).replace("same1", "same<trial>") + "  (x2 at once, 2 trials)"
    row.exit_code, row.seconds = " ".join(codes), time.monotonic() - started
    row.verdict = "bad" if verdicts else "good"
    row.reason = "; ".join(verdicts) if verdicts else "one ran, the other refused in one line naming the folder"
    return row


def _run_name_case(
    ctx: Ctx, row: Row, module: str, tiny: Sequence[str], name: str, target: Path, timeout: float = 120
) -> Row:
    p = cli(ctx, module, [*tiny, "--run-name", name], timeout)
    return judge_cli(row, p, outside=[target], must=[[name, target.name]])


@case("run folder", "imitate --run-name /abs/path")
def imitate_abs(ctx: Ctx, row: Row) -> Row:
    target = ctx.tmp / "elsewhere" / "abs_run"
    (ctx.tmp / "elsewhere").mkdir()
    return _run_name_case(ctx, row, "imitate", TINY_IMITATE, str(target), target)


@case("run folder", "imitate --run-name ../x")
def imitate_dotdot(ctx: Ctx, row: Row) -> Row:
    return _run_name_case(ctx, row, "imitate", TINY_IMITATE, "../x", ctx.tmp / "x")


@case("run folder", "train --run-name /abs/path")
def train_abs(ctx: Ctx, row: Row) -> Row:
    target = ctx.tmp / "elsewhere" / "abs_run"
    (ctx.tmp / "elsewhere").mkdir()
    return _run_name_case(ctx, row, "train", TINY_TRAIN, str(target), target)


@case("run folder", "train --run-name ../x")
def train_dotdot(ctx: Ctx, row: Row) -> Row:
    return _run_name_case(ctx, row, "train", TINY_TRAIN, "../x", ctx.tmp / "x")


@case("run folder", "quickstart --run-name /abs/path")
def quickstart_abs(ctx: Ctx, row: Row) -> Row:
    target = ctx.tmp / "elsewhere" / "abs_run"
    (ctx.tmp / "elsewhere").mkdir()
    return _run_name_case(ctx, row, "quickstart", TINY_QUICKSTART, str(target), target, timeout=150)


@case("run folder", "quickstart --run-name ../x")
def quickstart_dotdot(ctx: Ctx, row: Row) -> Row:
    return _run_name_case(ctx, row, "quickstart", TINY_QUICKSTART, "../x", ctx.tmp / "x", timeout=150)


# --- shield -----------------------------------------------------------------------------------------------------

SHIELD = """
import numpy as np
import uamfleet
from uamfleet.baselines import make_policy
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import fly
one = uamfleet.VectorEnv(uamfleet.make_config("berlin_fleet", num_taxis=1), num_envs=1, autoreset=False)
one.reset(seed={seed})
start = tuple(float(v) for v in one.state.pos_m[0, 0])  # a feasible start of this map
cfg = uamfleet.make_config("berlin_fleet", num_taxis={taxis}, min_separation_m={sep}, starts_m=(start,) * {taxis})
traj = fly(cfg, make_policy("{policy}", num_taxis={taxis}), seed=0)
m = episode_metrics(traj, cfg.radio, threshold_db=cfg.sinr_min_db)
flags = np.asarray(traj.stacked("separation_violation"))
flags = flags.reshape(len(flags), -1)
clear = np.flatnonzero(~flags.any(1))
first = int(clear[0]) if clear.size else len(flags)
return dict(pr_pct=float(m.pr_pct), violations=int(m.separation_violations), steps=len(flags),
            first_clear=first, after_clear=int(flags[first:].sum()), step_m=cfg.step_m)
"""


def shield_case(ctx: Ctx, row: Row, taxis: int, sep: float, policy: str, seed: int, timeout: float = 180) -> Row:
    p = api(ctx, SHIELD.format(taxis=taxis, sep=sep, policy=policy, seed=seed), timeout)
    got = result_of(p)
    if got is not None and got["accepted"]:
        flown = got["value"]
        row.command = (
            f"fly(make_config('berlin_fleet', num_taxis={taxis}, min_separation_m={sep}, "
            f"starts_m=(start,)*{taxis}), {policy})"
        )
        row.exit_code, row.seconds = str(p.code), p.seconds
        row.first_line = (
            f"PR {flown['pr_pct']:.0f} %, {flown['violations']} violations ({flown['after_clear']} after the first "
            f"separation at step {flown['first_clear']} of {flown['steps']})"
        )
        good = flown["pr_pct"] >= 100.0 and flown["after_clear"] == 0 and flown["first_clear"] < flown["steps"]
        row.verdict = "good" if good else "bad"
        row.reason = (
            "everyone delivered, no violation after the first separation"
            if good
            else ("silent deadlock: " if flown["pr_pct"] < 100 else "violations after separation: ") + row.first_line
        )
        return row
    row.command = f"make_config('berlin_fleet', num_taxis={taxis}, min_separation_m={sep}, coincident starts)"
    return judge_api(row, p, must=[["min_separation", "separation"]])


@case("shield", "min_separation_m 150 > step_m 100, 4 taxis start on one point (greedy)")
def shield_deadlock(ctx: Ctx, row: Row) -> Row:
    return shield_case(ctx, row, 4, 150.0, "greedy", 0)


@case("shield", "8 taxis start on one point, min_separation_m 50 (greedy)")
def shield_eight_greedy(ctx: Ctx, row: Row) -> Row:
    return shield_case(ctx, row, 8, 50.0, "greedy", 0)


@case("shield", "8 taxis start on one point, min_separation_m 50 (batch_assignment, another start)")
def shield_eight_batch(ctx: Ctx, row: Row) -> Row:
    return shield_case(ctx, row, 8, 50.0, "batch_assignment", 1)


@case("shield", "8 taxis start on one point, min_separation_m 50 (greedy, the start of seed 2)")
def shield_eight_greedy_2(ctx: Ctx, row: Row) -> Row:
    return shield_case(ctx, row, 8, 50.0, "greedy", 2)


# --- map size ---------------------------------------------------------------------------------------------------

NPZ = """
import io, zipfile, numpy as np
from uamfleet.radio.raytrace import NPZ_FORMAT
def member(z, name, array):
    buf = io.BytesIO(); np.save(buf, array); z.writestr(name + ".npy", buf.getvalue())
with zipfile.ZipFile("{path}", "w", zipfile.ZIP_DEFLATED) as z:
    member(z, "format", np.array(NPZ_FORMAT))
    {sinr}
    member(z, "resolution_m", np.array(10.0)); member(z, "origin_m", np.array([0.0, 0.0]))
    member(z, "side_m", np.array({side})); member(z, "name", np.array("crafted"))
    member(z, "is_estimate", np.array(False)); member(z, "altitude_m", np.array(100.0))
    member(z, "bs_values", np.array([[50.0, 50.0, 25.0, 46.0, 2000.0, 1.0]])); member(z, "bs_name", np.array(["GBS 0"]))
    member(z, "source", np.array("crafted by the input probe"))
"""
# a .npy header that declares 60,000 x 60,000 float64 cells (26.8 GiB) followed by 3.6 MB of data
HUGE_SINR = (
    'buf = io.BytesIO(); np.lib.format.write_array_header_1_0(buf, {"descr": "<f8", "fortran_order": False, '
    '"shape": (60000, 60000)}); z.writestr("sinr_db.npy", buf.getvalue() + bytes(3_600_000))'
)
SMALL_SINR = 'member(z, "sinr_db", np.zeros((10, 10)))'


def npz_case(ctx: Ctx, row: Row, sinr: str, side: float) -> Row:
    path = ctx.tmp / "crafted.npz"
    writer = run(ctx, [PYTHON, "-c", textwrap.dedent(NPZ.format(path=path, sinr=sinr, side=side))])
    if writer.code != 0:
        row.verdict, row.reason = "skipped", f"could not write the crafted map: {last_line(writer.stderr)}"
        return row
    p = api(ctx, f"return uamfleet.vector_env('berlin_random', radio={str(path)!r})", prelude="import uamfleet")
    row.command = "uamfleet.vector_env('berlin_random', radio='crafted.npz')"
    return judge_api(row, p, must=[["crafted.npz"], ["GiB", "GB", "bytes", "cells", "limit", "UAMFLEET_MAX"]])


@case("map size", ".npz whose sinr_db declares 60,000 x 60,000 cells (26.8 GiB) in 3.6 MB")
def npz_huge(ctx: Ctx, row: Row) -> Row:
    return npz_case(ctx, row, HUGE_SINR, 600000.0)


@case("map size", ".npz with side_m=1e7 (a 10 x 10 raster)")
def npz_side(ctx: Ctx, row: Row) -> Row:
    return npz_case(ctx, row, SMALL_SINR, 1e7)


# --- API options ------------------------------------------------------------------------------------------------

GUIDED = "import uamfleet\nfrom uamfleet.rl.guided import AnticipatingGuidedSearch, GuidedSearchPolicy"


def option_case(ctx: Ctx, row: Row, call: str, name: str, prelude: str = GUIDED, timeout: float = 60) -> Row:
    """``call`` refused with a message naming the option (``name``: words separated by "|", any of them)."""
    row.command = call
    p = api(ctx, f"return {call}", timeout, prelude)
    return judge_api(row, p, must=[name.split("|")])


def _register_options() -> None:
    hedge = "AnticipatingGuidedSearch(uamfleet.pretrained('berlin'), 'berlin', {})"
    guided = "GuidedSearchPolicy(uamfleet.pretrained('berlin'), {})"
    fleet = "uamfleet.pretrained('berlin_fleet').for_fleet({})"
    options = [
        (hedge, "futures=10**6", "futures"),
        (hedge, "futures=2.5", "futures"),
        (hedge, "futures=True", "futures"),
        (hedge, "first_headings=float('nan')", "first_headings"),
        (hedge, "first_headings=2.5", "first_headings"),
        (hedge, "commit=float('inf')", "commit"),
        (hedge, "commit=1.5", "commit"),
        (hedge, "tail=float('nan')", "tail"),
        (hedge, "tail=float('inf')", "tail"),
        (hedge, "top_k=2.5", "top_k"),
        (hedge, "wait='no'", "wait"),
        (guided, "top_k=True", "top_k"),
        (guided, "horizon=2.5", "horizon"),
        (guided, "horizon=float('nan')", "horizon"),
        (guided, "samples=10**7", "samples"),
        (fleet, "1024", "num_taxis|1024"),  # positional: the value names it
        (fleet, "4, passenger_slots=0", "passenger_slots"),
        (fleet, "4, passenger_slots=2.5", "passenger_slots"),
        (fleet, "4, passenger_slots=10**9", "passenger_slots"),
        (fleet, "4, passenger_window=0", "passenger_window"),
        (fleet, "4, passenger_window=True", "passenger_window"),
        (fleet, "4, passenger_window=float('nan')", "passenger_window"),
    ]
    for template, given, name in options:
        call = template.format(given)
        CASES.append(("API options", call, lambda ctx, row, call=call, name=name: option_case(ctx, row, call, name)))
    policy = "from uamfleet.baselines import make_policy, BatchAssignmentPolicy, InsertionPolicy"
    dispatch = [
        ("make_policy('batch_assignment+wait=1+wait=2', num_taxis=2)", "wait"),
        ("make_policy('batch_assignment+release+release', num_taxis=2)", "release"),
        ("make_policy('batch_assignment+price=1000+price=5', num_taxis=2)", "price"),
        ("make_policy('batch_assignment+price=1000+guard=600+guard=5', num_taxis=2)", "guard"),
        ("make_policy('insertion+release', num_taxis=2)", "release"),
        ("make_policy('greedy+wait=1', num_taxis=2)", "wait"),
        ("BatchAssignmentPolicy(wait_weight=float('nan'))", "wait_weight"),
        ("InsertionPolicy(wait_weight=-1.0)", "wait_weight"),
        ("BatchAssignmentPolicy(unassigned_price_s=True)", "unassigned_price_s"),
        ("BatchAssignmentPolicy(unassigned_price_s=10.0, unassigned_guard_s='600')", "unassigned_guard_s"),
        ("BatchAssignmentPolicy(period=2.5)", "period"),
    ]
    for call, name in dispatch:
        CASES.append(("API options", call,
                      lambda ctx, row, call=call, name=name: option_case(ctx, row, call, name, policy)))  # fmt: skip


_register_options()


# --- paths and devices ------------------------------------------------------------------------------------------


def bad_output(ctx: Ctx, kind: str, filename: str) -> tuple[Path, list[str]]:
    """An output path of ``kind``: unwritable (a folder made immutable with chattr +i: root writes anywhere
    else), parent is a file, too long (a 300-character name), a folder, a FIFO. The path and the words its message
    must name."""
    if kind == "unwritable":
        folder = ctx.tmp / "readonly"
        folder.mkdir()
        if subprocess.run(["chattr", "+i", str(folder)], capture_output=True).returncode != 0:
            folder = Path("/sys")  # writable by no one, root included
        return folder / filename, [["readonly", "/sys"]]
    if kind == "parent is a file":
        (ctx.tmp / "afile").write_text("a file\n")
        return ctx.tmp / "afile" / filename, [["afile"]]
    if kind == "too long":
        stem, suffix = os.path.splitext(filename)
        return ctx.tmp / (stem + "x" * 300 + suffix), [["xxxxxxxx"]]
    if kind == "a folder":
        (ctx.tmp / filename).mkdir()
        return ctx.tmp / filename, [[filename]]
    if kind == "a FIFO":
        os.mkfifo(ctx.tmp / filename)
        return ctx.tmp / filename, [[filename]]
    raise AssertionError(kind)


OUTPUT_KINDS = ("unwritable", "parent is a file", "too long", "a folder", "a FIFO")


def _register_paths() -> None:
    for kind in OUTPUT_KINDS:

        def render(ctx: Ctx, row: Row, kind: str = kind) -> Row:
            out, must = bad_output(ctx, kind, "render.html")
            return judge_cli(row, cli(ctx, "render", [*TINY_RENDER, "--out", str(out)]), must=must)

        def benchmark(ctx: Ctx, row: Row, kind: str = kind) -> Row:
            out, must = bad_output(ctx, kind, "bench.csv")
            args = [*TINY_BENCHMARK, "--out-csv", str(out), "--out-md", str(ctx.tmp / "bench.md")]
            return judge_cli(row, cli(ctx, "benchmark", args), must=must)

        CASES.append(("paths and devices", f"render --out: {kind}", render))
        CASES.append(("paths and devices", f"benchmark --out-csv: {kind}", benchmark))
    for kind in ("unwritable", "too long"):

        def fleet_benchmark(ctx: Ctx, row: Row, kind: str = kind) -> Row:
            out, must = bad_output(ctx, kind, "fleet.csv")
            args = [*TINY_FLEET_BENCHMARK, "--out-csv", str(out), "--out-md", str(ctx.tmp / "fleet.md")]
            return judge_cli(row, cli(ctx, "fleet_benchmark", args), must=must)

        def radio_map(ctx: Ctx, row: Row, kind: str = kind) -> Row:
            if ctx.rt_python is None:
                row.verdict, row.reason = "skipped", "no Sionna RT interpreter (--rt-python)"
                return row
            out, must = bad_output(ctx, kind, "map.npz")
            (ctx.tmp / "city").mkdir()
            (ctx.tmp / "city" / "scene.xml").write_text(scene_xml())
            args = ["--scene", "city/scene.xml", "--out", str(out), *RT_ARGS]
            return judge_cli(row, cli(ctx, "radio_map", args, python=ctx.rt_python), must=must)

        CASES.append(("paths and devices", f"fleet-benchmark --out-csv: {kind}", fleet_benchmark))
        CASES.append(("paths and devices", f"radio-map --out (a valid scene): {kind}", radio_map))
    for kind in ("unwritable", "parent is a file", "too long", "a FIFO"):

        def train_dir(ctx: Ctx, row: Row, kind: str = kind) -> Row:
            folder, must = bad_output(ctx, kind, "runs")
            return judge_cli(row, cli(ctx, "train", [*TINY_TRAIN, "--run-dir", str(folder), "--run-name", "r"]),
                             must=must)  # fmt: skip

        CASES.append(("paths and devices", f"train --run-dir: {kind}", train_dir))


def _register_loads() -> None:
    def load(ctx: Ctx, row: Row, path: Path, must: list[list[str]], forbid: Sequence[str] = ()) -> Row:
        row.command = f"load_policy({_short(str(path))!r})"
        p = api(ctx, f"return load_policy({str(path)!r})", prelude="from uamfleet.rl.policy import load_policy")
        return judge_api(row, p, must=must, forbid=forbid, kinds=("valueerror", "oserror"))

    def load_folder(ctx: Ctx, row: Row) -> Row:
        (ctx.tmp / "policy.pt").mkdir()
        return load(ctx, row, ctx.tmp / "policy.pt", [["policy.pt"]], forbid=["does not exist", "no such"])

    def load_fifo(ctx: Ctx, row: Row) -> Row:
        os.mkfifo(ctx.tmp / "policy.pt")
        return load(ctx, row, ctx.tmp / "policy.pt", [["policy.pt"]], forbid=["does not exist", "no such"])

    def load_long(ctx: Ctx, row: Row) -> Row:
        path = ctx.tmp / "/".join(["d" * 200] * 25)
        return load(ctx, row, Path(str(path)[:5000]), [["ddddd"]])

    def load_parent_file(ctx: Ctx, row: Row) -> Row:
        (ctx.tmp / "afile").write_text("x\n")
        return load(ctx, row, ctx.tmp / "afile" / "policy.pt", [["afile"]])

    def load_missing(ctx: Ctx, row: Row) -> Row:
        return load(ctx, row, ctx.tmp / "missing.pt", [["missing.pt"]])

    CASES.extend([
        ("paths and devices", "load_policy: a folder", load_folder),
        ("paths and devices", "load_policy: a FIFO", load_fifo),
        ("paths and devices", "load_policy: a 5,000-character path", load_long),
        ("paths and devices", "load_policy: parent is a file", load_parent_file),
        ("paths and devices", "load_policy: a missing file (control)", load_missing),
    ])  # fmt: skip

    def device(ctx: Ctx, row: Row, name: str, must: list[list[str]]) -> Row:
        row.command = f"uamfleet.pretrained(device={name!r})"
        p = api(ctx, f"return uamfleet.pretrained(device={name!r})", prelude="import uamfleet")
        return judge_api(row, p, must=must, forbid=["loads safely", "not a checkpoint"])

    CASES.append(("paths and devices", "pretrained(device='bogus')",
                  lambda ctx, row: device(ctx, row, "bogus", [["bogus"]])))  # fmt: skip
    CASES.append(("paths and devices", "pretrained(device='cuda:7'): a missing CUDA device",
                  lambda ctx, row: device(ctx, row, "cuda:7", [["cuda"]])))  # fmt: skip


_register_paths()
_register_loads()


@case("paths and devices", "train --resume with a corrupt progress.csv")
def resume_corrupt(ctx: Ctx, row: Row) -> Row:
    first = cli(ctx, "train", [*TINY_TRAIN, "--run-name", "r"], 180)
    progress = ctx.tmp / "runs" / "r" / "progress.csv"
    if first.code != 0 or not progress.exists():
        row.verdict, row.reason = "skipped", f"the first training failed (exit {first.code}): {last_line(first.stderr)}"
        return row
    lines = progress.read_text().splitlines()
    header = lines[0].split(",")
    body = lines[1].split(",")
    body[header.index("global_step") if "global_step" in header else 0] = "abc"
    progress.write_text("\n".join([lines[0], ",".join(body), *lines[2:]]) + "\n")
    p = cli(ctx, "train", [*TINY_TRAIN, "--run-name", "r", "--resume", "--total-timesteps", "128"], 180)
    return judge_cli(row, p, must=[["progress.csv"]], forbid=["could not convert"])


@case("paths and devices", "torchrun (2 ranks) train on an existing run name")
def torchrun_existing(ctx: Ctx, row: Row) -> Row:
    held = ctx.tmp / "runs" / "held"
    held.mkdir(parents=True)
    (held / "progress.csv").write_text("global_step\n0\n")
    tiny = [*TINY_TRAIN, "--num-envs", "2", "--total-timesteps", "128"]  # the global env count divides among 2 ranks
    argv = [TORCHRUN, "--standalone", "--nproc_per_node=2", "-m", "uamfleet.cli.train", *tiny, "--run-name", "held"]
    p = run(ctx, argv, 150)
    # torchrun reports any rank's non-zero exit with a traceback of its own (ChildFailedError) and exit status 1,
    # whatever the ranks print: that part is the launcher's. The ranks must print no traceback and one error line.
    launcher = p.stderr.count("ChildFailedError") > 0
    ranks = p.stderr.count("Traceback (most recent call last)") - (1 if launcher else 0)
    errors = error_lines(p.stderr)
    row = judge_cli(row, p, must=[["held"]])
    if p.code not in (None, 0) and ranks == 0 and len(errors) == 1 and "held" in errors[0]:
        if "[errno" not in errors[0].lower():
            row.verdict, row.reason = "good", f"rank 0 refused in one line (torchrun's exit {p.code})"
    elif p.code not in (None, 0) and ranks > 0:
        rank = next((line for line in p.stderr.splitlines() if line.startswith("[rank") and "Error: " in line), "")
        row.reason = f"{ranks} traceback(s) from the ranks: {rank[:160] or last_line(p.stderr)}"
    return row


# --- engines ----------------------------------------------------------------------------------------------------

BLOCK = """
import importlib.abc, sys
class _Block(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in ("ray", "torchrl", "tensordict"):
            raise ModuleNotFoundError(f"No module named {name!r}", name=name)
        return None
sys.meta_path.insert(0, _Block())
"""


@case("engines", "uamfleet.engines.rllib.ppo_config() without ray")
def engine_rllib(ctx: Ctx, row: Row) -> Row:
    row.command = "from uamfleet.engines.rllib import ppo_config; ppo_config('berlin_random')  (ray blocked)"
    p = api(ctx, "from uamfleet.engines.rllib import ppo_config\nreturn ppo_config('berlin_random')", prelude=BLOCK)
    return judge_api(row, p, must=[["pip install", "engines.sh"], ["rllib", "ray"]], kinds=("importerror",))


@case("engines", "uamfleet.engines.torchrl.torchrl_env() without torchrl")
def engine_torchrl(ctx: Ctx, row: Row) -> Row:
    row.command = "from uamfleet.engines.torchrl import torchrl_env; torchrl_env('berlin_random')  (torchrl blocked)"
    p = api(ctx, "from uamfleet.engines.torchrl import torchrl_env\nreturn torchrl_env('berlin_random')", prelude=BLOCK)
    return judge_api(row, p, must=[["pip install", "engines.sh"], ["torchrl"]], kinds=("importerror",))


# ---------------------------------------------------------------------------------------------------------------


def imports_checkout(checkout: Path, python: str) -> str | None:
    """The uamfleet file ``python`` imports with PYTHONPATH=checkout from a temp folder, if it is the checkout's."""
    with tempfile.TemporaryDirectory(prefix="probe-import-") as tmp:
        env = dict(os.environ, PYTHONPATH=str(checkout))
        found = subprocess.run([python, "-c", "import uamfleet; print(uamfleet.__file__)"], cwd=tmp, env=env,
                               capture_output=True, text=True, timeout=300)  # fmt: skip
    where = found.stdout.strip()
    return where if where.startswith(str(checkout.resolve())) else None


def cleanup(tmp: Path) -> None:
    for root, dirs, _ in os.walk(tmp):
        for d in dirs:  # a folder the case made immutable
            subprocess.run(["chattr", "-i", os.path.join(root, d)], capture_output=True)
    for root, _, files in os.walk(tmp):
        for f in files:
            path = os.path.join(root, f)
            if stat.S_ISFIFO(os.lstat(path).st_mode):
                os.unlink(path)
    shutil.rmtree(tmp, ignore_errors=True)


def summarize(paths: Sequence[Path]) -> str:
    """A Markdown table of the bad answers by class in each CSV (e.g. before.csv after.csv), for the closing note."""
    tables = [list(csv.DictReader(path.open())) for path in paths]
    classes = list(dict.fromkeys(row["class"] for rows in tables for row in rows))
    head = "| class | cases | " + " | ".join(f"bad in {path.name}" for path in paths) + " |"
    lines = [head, "| --- " * (2 + len(paths)) + "|"]
    for cls in [*classes, "all"]:
        picked = [[r for r in rows if cls in ("all", r["class"])] for rows in tables]
        cells = []
        for rows in picked:
            bad = sum(r["verdict"] == "bad" for r in rows)
            other = sum(r["verdict"] not in ("good", "bad") for r in rows)
            cells.append(f"{bad} of {len(rows)}" + (f" ({other} skipped or errors)" if other else ""))
        lines.append(f"| {cls} | {max(len(rows) for rows in picked)} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--summarize", type=Path, nargs="+", help="print the bad answers by class of these CSVs")
    parser.add_argument("--checkout", type=Path, help="the uamfleet checkout to probe")
    parser.add_argument("--out", type=Path, help="the CSV to write (one row per case)")
    parser.add_argument("--rt-python", default=RT_PYTHON, help="an interpreter with sionna-rt (scene cases)")
    parser.add_argument("--only", default="", help="run only the cases whose class or name holds this text")
    args = parser.parse_args(argv)
    if args.summarize:
        print(summarize(args.summarize))
        return 0
    if args.checkout is None or args.out is None:
        parser.error("give --checkout PATH --out CSV (or --summarize CSV ...)")
    checkout = args.checkout.resolve()
    if imports_checkout(checkout, PYTHON) is None:
        print(f"probe: error: {PYTHON} with PYTHONPATH={checkout} does not import that checkout's uamfleet",
              file=sys.stderr)  # fmt: skip
        return 2
    rt_python: str | None = args.rt_python
    if not (rt_python and Path(rt_python).exists() and imports_checkout(checkout, rt_python)):
        print(f"probe: no Sionna RT interpreter importing {checkout} ({rt_python}): scene cases skipped")
        rt_python = None
    # numba compiles the kernels of a fresh checkout into its cache once: not inside a case's timeout
    warm_env = dict(os.environ, PYTHONPATH=str(checkout), UAMFLEET_CACHE="off")
    warm = subprocess.run([PYTHON, "-m", "uamfleet.warmup"], cwd=tempfile.gettempdir(), env=warm_env,
                          capture_output=True, text=True, timeout=900)  # fmt: skip
    if warm.returncode != 0:
        print(f"probe: warning: python -m uamfleet.warmup failed: {last_line(warm.stderr)}", file=sys.stderr)
    rows: list[Row] = []
    selected = [c for c in CASES if args.only.lower() in f"{c[0]} {c[1]}".lower()]
    started = time.monotonic()
    shared = Path(tempfile.mkdtemp(prefix="probe-shared-"))
    (shared / "home").mkdir()
    for k, (cls, name, fn) in enumerate(selected, 1):
        tmp = Path(tempfile.mkdtemp(prefix="probe-case-"))
        row = Row(cls, name)
        try:
            row = fn(Ctx(checkout, tmp, rt_python, shared), row)
        except Exception as err:  # a broken case is recorded, not fatal
            row.verdict, row.reason = "error", f"probe failed: {type(err).__name__}: {err}"
        finally:
            cleanup(tmp)
        rows.append(row)
        at = time.monotonic() - started
        print(f"[{k}/{len(selected)} {at:5.0f} s] {row.verdict:7} {cls}: {name}: {row.reason[:150]}",
              flush=True)  # fmt: skip
    cleanup(shared)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    partial = args.out.with_name(args.out.name + ".part")
    with partial.open("w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS)
        writer.writeheader()
        writer.writerows(r.csv_row() for r in rows)
    partial.replace(args.out)
    by_class: dict[str, dict[str, int]] = {}
    for r in rows:
        by_class.setdefault(r.cls, {}).setdefault(r.verdict, 0)
        by_class[r.cls][r.verdict] += 1
    for cls, counts in by_class.items():
        print(f"{cls:18} " + ", ".join(f"{v} {n}" for v, n in sorted(counts.items())))
    print(f"wrote {args.out} ({len(rows)} cases, {time.monotonic() - started:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
