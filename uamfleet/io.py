"""Atomic file writes: a crash never leaves a half-written result, checkpoint or figure behind; and what an
``OSError`` of a path says, as one line naming the path (:func:`os_error_message`, :class:`PathError`)."""

from __future__ import annotations

import csv
import errno
import io
import os
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any


def write_bytes_atomic(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to a temp file in the target folder, fsync it, then rename it over ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, 0o666 & ~_umask())  # mkstemp makes 0600; give the file the permissions open() would
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def write_text_atomic(path: str | os.PathLike[str], text: str) -> Path:
    return write_bytes_atomic(path, text.encode("utf-8"))


def write_csv_atomic(path: str | os.PathLike[str], rows: Iterable[Mapping[str, Any]], columns: Sequence[str]) -> Path:
    """``rows`` as a CSV with the header ``columns`` (``\\n`` line ends), written atomically."""
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=list(columns), lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return write_text_atomic(path, buffer.getvalue())


def replace_section(path: str | os.PathLike[str], name: str, body: str) -> Path:
    """Replace the text between ``<!-- name:begin -->`` and ``<!-- name:end -->`` in a Markdown file (appending
    the marked section when it is missing), keeping everything else, atomically."""
    path = Path(path)
    begin, end = f"<!-- {name}:begin -->", f"<!-- {name}:end -->"
    text = path.read_text(encoding="utf-8") if path.exists() else ""
    block = f"{begin}\n{body.rstrip()}\n{end}"
    if begin in text and end in text:
        head, rest = text.split(begin, 1)
        _, tail = rest.split(end, 1)
        text = head + block + tail
    else:
        text = (text.rstrip() + "\n\n" if text.strip() else "") + block + "\n"
    return write_text_atomic(path, text)


def has_section(path: str | os.PathLike[str], name: str) -> bool:
    """Whether the Markdown file ``path`` exists and holds the marked section ``name``."""
    path = Path(path)
    return path.is_file() and f"<!-- {name}:begin -->" in path.read_text(encoding="utf-8")


def partial_path(path: str | os.PathLike[str]) -> Path:
    """Where a long run keeps its partial results: ``<stem>.partial<suffix>`` beside ``path``, never over it."""
    path = Path(path)
    return path.with_name(f"{path.stem}.partial{path.suffix}")


SHOWN_PATH_CHARS = 160
"""A longer path is shown by its two ends (a 5,000-character path would otherwise be the whole message)."""


def shown_path(path: str | bytes | os.PathLike[str] | None) -> str:
    """``path`` as a message shows it: whole up to :data:`SHOWN_PATH_CHARS` characters, else its two ends and its
    length."""
    text = os.fsdecode(path) if path is not None else "?"
    if len(text) <= SHOWN_PATH_CHARS:
        return text
    half = SHOWN_PATH_CHARS // 2
    return f"{text[:half]}...{text[-half:]} ({len(text):,} characters)"


_FIXES = {
    errno.EACCES: "choose a folder you may write to (or read from)",
    errno.EPERM: "choose a folder you may write to (or read from)",
    errno.EROFS: "it is on a read-only file system; choose a writable folder",
    errno.ENAMETOOLONG: "shorten the path (its name or one of its folders is longer than the system allows)",
    errno.ENOTDIR: "a part of the path is a file, not a folder; choose another path",
    errno.EISDIR: "it is a folder; give a file name",
    errno.ENOSPC: "the disk is full; free space or write elsewhere",
    errno.ELOOP: "it is a loop of symbolic links; give the real path",
}


def os_error_message(err: OSError, with_path: bool = True) -> str:
    """One line for an OSError: ``<reason>: '<path>'[; <fix>]`` (``'<path>' -> '<other>'`` for a rename; without
    the paths when the caller names them, ``with_path=False``), the path shortened when long (:func:`shown_path`),
    never ``[Errno N]``; the message itself for one of the package's own (a :class:`PathError`, or a
    FileNotFoundError raised with a message)."""
    if isinstance(err, PathError) or err.strerror is None:
        return " ".join(str(err).split())
    fix = _FIXES.get(err.errno or 0)
    if not with_path:
        return err.strerror + (f"; {fix}" if fix else "")
    where = "" if err.filename is None else f": '{shown_path(err.filename)}'"
    if err.filename2 is not None:
        where += f" -> '{shown_path(err.filename2)}'"
    return f"{err.strerror}{where}" + (f"; {fix}" if fix else "")


class PathError(OSError):
    """An OSError whose message is one line naming the path and the fix (its errno and filename kept)."""

    def __init__(self, message: str, cause: OSError | None = None, path: str | os.PathLike[str] | None = None) -> None:
        code = cause.errno if cause is not None else None
        name = path if path is not None else (cause.filename if cause is not None else None)
        super().__init__(code, message, name)
        self.message = " ".join(message.split())

    def __str__(self) -> str:
        return self.message

    def __reduce__(self) -> tuple[type[PathError], tuple[str, None, Any]]:  # picklable (a torchrun rank's error)
        return (PathError, (self.message, None, self.filename))


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask
