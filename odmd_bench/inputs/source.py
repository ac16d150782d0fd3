"""Reading a predictions file's bytes, capped: a path, bytes, a binary file or stdin, gzip or not.

A predictions file is refused when it (or its gzip-decompressed content) is larger than
:data:`MAX_PREDICTIONS_BYTES`, 64 MiB: more than 100 times the largest file a benchmark
needs (``odmd-v1`` test, 12,000 rows with a ``benchmark`` column, is 0.52 MB), so no real
file comes near it, while ``/dev/zero``, a runaway file or a gzip bomb is refused after
reading at most the cap plus one byte. gzip is recognised by its magic bytes, whatever
the name, so ``.csv.gz`` files and compressed stdin are read alike. A cap bounds what is
read, never what is allocated: a read asks for at most a chunk (:data:`CHUNK_BYTES`) or
the regular file's size, so any legal cap works on a small file (Python's ``read(n)``
allocates ``n`` bytes before it reads one).

The sequences reader (:func:`odmd_bench.predict.sequences.read_sequences`) reads its files
here too, under its own title and cap (:data:`MAX_SEQUENCES_BYTES`), and the importer
caps an original release file (:data:`MAX_ORIGINAL_BYTES`). Those two may legitimately be
larger: the environment variable ``ODMD_BENCH_MAX_INPUT_MIB`` (:data:`LIMIT_ENV`) sets
both caps, in MiB (:func:`input_limit`). A predictions file's size is fixed by its
benchmark, so its cap is not.
"""

from __future__ import annotations

import gzip
import io
import os
import stat
import sys
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO, TypeAlias

from odmd_bench.errors import UsageError, ValidationError

#: The largest predictions file read, before or after gzip decompression (bytes).
MAX_PREDICTIONS_BYTES = 64 * 2**20
#: The largest sequences file ``predict`` reads by default, before or after gzip (bytes):
#: about 3 million observations.
MAX_SEQUENCES_BYTES = 256 * 2**20
#: The largest original release file ``import`` reads by default (bytes; the release's
#: largest is 2.6 MB).
MAX_ORIGINAL_BYTES = 64 * 2**20
#: The environment variable that sets the caps of the sequences and original files, in MiB.
LIMIT_ENV = "ODMD_BENCH_MAX_INPUT_MIB"
#: The most one read asks for beyond a regular file's size (bytes).
CHUNK_BYTES = 2**20


def input_limit(default: int) -> int:
    """The cap in bytes: :data:`LIMIT_ENV` (MiB) where it is set, else ``default``.

    Raises:
        UsageError: the variable is set but not a number > 0.
    """
    value = os.environ.get(LIMIT_ENV, "").strip()
    if not value:
        return default
    try:
        mib = float(value)
    except ValueError:
        mib = float("nan")
    if not (0 < mib <= 2**30):  # NaN too
        raise UsageError(f"{LIMIT_ENV} must be a size in MiB, a number > 0 (up to 2**30), got {value!r}")
    return int(mib * 2**20)


def cap_advice(what: str) -> str:
    """The cap on ``what`` (e.g. "a sequences file") and how to read a larger one, for messages."""
    return f"the cap on {what}; set {LIMIT_ENV}=SIZE (in MiB) to read a larger one"


#: What :func:`read_source` (and so :func:`~odmd_bench.evaluation.parse.parse_predictions`) reads.
Source: TypeAlias = bytes | bytearray | memoryview | str | os.PathLike[str] | BinaryIO

_GZIP_MAGIC = b"\x1f\x8b"


_PREDICTIONS_ADVICE = (
    "the cap on a predictions file (the largest benchmark needs about 0.5 MB); is it the right file?"
)


def _too_large(what: str, limit: int, advice: str = _PREDICTIONS_ADVICE) -> str:
    return f"{what} is larger than {limit / 2**20:g} MiB, {advice}"


def read_at_most(read: Callable[[int], object], limit: int | None, size_hint: int = 0) -> bytes | None:
    """What ``read`` gives, up to ``limit + 1`` bytes (all of it where ``limit`` is None), chunk by chunk.

    Args:
        read: a binary file's ``read``.
        limit: the cap in bytes; one byte more is read, so that the caller can tell a file
            over the cap.
        size_hint: the size expected (a regular file's ``st_size``): the first read asks
            for that plus one byte, or :data:`CHUNK_BYTES` if larger, so that a regular
            file is read in one go; no read asks for more than is left below the cap.

    Returns:
        The bytes read, or None where ``read`` gave something other than bytes (a text
        stream's ``str``), for the caller to refuse.
    """
    if limit is None:
        whole = read(-1)
        return whole if isinstance(whole, bytes) else None
    parts: list[bytes] = []
    got = 0
    ask = max(CHUNK_BYTES, size_hint + 1)
    while got <= limit:
        part = read(min(ask, limit + 1 - got))
        if not isinstance(part, bytes):
            return None
        if not part:
            break
        parts.append(part)
        got += len(part)
        ask = CHUNK_BYTES
    return parts[0] if len(parts) == 1 else b"".join(parts)


def _read_path(path: Path, title: str, kind: str, limit: int | None, advice: str) -> bytes:
    try:
        with path.open("rb") as fh:
            info = os.fstat(fh.fileno())
            if limit is not None and stat.S_ISREG(info.st_mode) and info.st_size > limit:
                raise ValidationError(title, [_too_large("the file", limit, advice)])
            hint = info.st_size if stat.S_ISREG(info.st_mode) else 0
            return read_at_most(fh.read, limit, hint) or b""  # bytes: the file is opened "rb"
    except FileNotFoundError:
        raise ValidationError(title, [f"no such file: {path}"]) from None
    except IsADirectoryError:
        raise ValidationError(title, [f"{path} is a folder, not a {kind} CSV file"]) from None
    except OSError as e:
        raise ValidationError(title, [f"the file cannot be read ({e.strerror or e})"]) from None


def _read_stream(stream: BinaryIO, name: str, title: str, kind: str, limit: int | None) -> bytes:
    try:
        data = read_at_most(stream.read, limit)
    except OSError as e:
        raise ValidationError(title, [f"the input cannot be read ({e.strerror or e})"]) from None
    if data is None:
        raise UsageError(f"{name}: {kind} must be read from a binary file (open it with 'rb')")
    return data


def _gunzip(data: bytes, title: str, limit: int | None, advice: str) -> bytes:
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as fh:
            plain = read_at_most(fh.read, limit) or b""  # bytes: GzipFile reads bytes
    except (OSError, EOFError, zlib.error) as e:
        raise ValidationError(title, [f"not a readable gzip file ({e})"]) from None
    if limit is not None and len(plain) > limit:
        raise ValidationError(title, [_too_large("the decompressed file", limit, advice)])
    return plain


def stdin_bytes() -> BinaryIO:
    """Standard input as bytes, for ``-``; a :class:`UsageError` when it is closed (``<&-``)."""
    stream = getattr(sys.stdin, "buffer", None)
    if stream is None:
        raise UsageError("standard input is closed: there is nothing to read for '-'; name a file")
    return stream


def read_source(
    source: Source,
    *,
    name: str | None = None,
    limit: int | None = MAX_PREDICTIONS_BYTES,
    title: str = "{name} cannot be scored",
    kind: str = "predictions",
    advice: str = _PREDICTIONS_ADVICE,
) -> tuple[bytes, str]:
    """The CSV bytes of ``source`` and the name to report it by.

    Args:
        source: a path (``str`` or path-like), the file's bytes, or a binary file object
            (e.g. ``sys.stdin.buffer``); gzip-compressed content is decompressed.
        name: how messages and provenance name it (default: the path, the file object's
            ``name``, or ``"<bytes>"``).
        limit: the cap in bytes, before and after decompression; None: no cap.
        title: the title of every error, ``{name}`` standing for the name.
        kind: what the file holds, in messages (``"a folder, not a KIND CSV file"``).
        advice: what a message over the cap says after the cap (what the cap is, and how
            to read a larger file where one can).

    Returns:
        ``(data, name)``.

    Raises:
        ValidationError: no such file, a folder, unreadable, over the cap, or broken gzip.
        UsageError: ``source`` is none of the accepted types.
    """
    if isinstance(source, (bytes, bytearray, memoryview)):
        label = name or "<bytes>"
        data = bytes(source)
        what = "the input"
    elif isinstance(source, (str, os.PathLike)):
        label = name or str(Path(source))
        data = _read_path(Path(source), title.format(name=label), kind, limit, advice)
        what = "the file"
    elif hasattr(source, "read"):
        label = name or str(getattr(source, "name", "<file>"))
        data = _read_stream(source, label, title.format(name=label), kind, limit)
        what = "the input"
    else:
        raise UsageError(
            f"cannot read {kind} from a {type(source).__name__}; give a path, bytes or a binary file"
        )
    if data[:2] == _GZIP_MAGIC:
        data = _gunzip(data, title.format(name=label), limit, advice)
    elif limit is not None and len(data) > limit:
        raise ValidationError(title.format(name=label), [_too_large(what, limit, advice)])
    return data, label
