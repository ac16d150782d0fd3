"""Reading a predictions file's bytes, capped: a path, bytes, a binary file or stdin, gzip or not.

A predictions file is refused when it (or its gzip-decompressed content) is larger than
:data:`MAX_PREDICTIONS_BYTES`, 64 MiB: more than 100 times the largest file a benchmark
needs (``odmd-v1`` test, 12,000 rows with a ``benchmark`` column, is 0.52 MB), so no real
file comes near it, while ``/dev/zero``, a runaway file or a gzip bomb is refused after
reading at most the cap plus one byte. gzip is recognised by its magic bytes, whatever
the name, so ``.csv.gz`` files and compressed stdin are read alike.

The sequences reader (:func:`odmd_bench.predict.sequences.read_sequences`) reads its files
here too, uncapped and under its own title.
"""

from __future__ import annotations

import gzip
import io
import os
import stat
import sys
import zlib
from pathlib import Path
from typing import BinaryIO, TypeAlias

from odmd_bench.errors import UsageError, ValidationError

#: The largest predictions file read, before or after gzip decompression (bytes).
MAX_PREDICTIONS_BYTES = 64 * 2**20

#: What :func:`read_source` (and so :func:`~odmd_bench.evaluation.parse.parse_predictions`) reads.
Source: TypeAlias = bytes | bytearray | memoryview | str | os.PathLike[str] | BinaryIO

_GZIP_MAGIC = b"\x1f\x8b"


def _too_large(what: str, limit: int) -> str:
    return (
        f"{what} is larger than {limit / 2**20:g} MiB, the cap on a predictions file "
        "(the largest benchmark needs about 0.5 MB); is it the right file?"
    )


def _read_path(path: Path, title: str, kind: str, limit: int | None) -> bytes:
    try:
        with path.open("rb") as fh:
            info = os.fstat(fh.fileno())
            if limit is not None and stat.S_ISREG(info.st_mode) and info.st_size > limit:
                raise ValidationError(title, [_too_large("the file", limit)])
            return fh.read(-1 if limit is None else limit + 1)
    except FileNotFoundError:
        raise ValidationError(title, [f"no such file: {path}"]) from None
    except IsADirectoryError:
        raise ValidationError(title, [f"{path} is a folder, not a {kind} CSV file"]) from None
    except OSError as e:
        raise ValidationError(title, [f"the file cannot be read ({e.strerror or e})"]) from None


def _read_stream(stream: BinaryIO, name: str, title: str, kind: str, limit: int | None) -> bytes:
    try:
        data = stream.read(-1 if limit is None else limit + 1)
    except OSError as e:
        raise ValidationError(title, [f"the input cannot be read ({e.strerror or e})"]) from None
    if not isinstance(data, bytes):
        raise UsageError(f"{name}: {kind} must be read from a binary file (open it with 'rb')")
    return data


def _gunzip(data: bytes, title: str, limit: int | None) -> bytes:
    try:
        with gzip.GzipFile(fileobj=io.BytesIO(data)) as fh:
            plain = fh.read(-1 if limit is None else limit + 1)
    except (OSError, EOFError, zlib.error) as e:
        raise ValidationError(title, [f"not a readable gzip file ({e})"]) from None
    if limit is not None and len(plain) > limit:
        raise ValidationError(title, [_too_large("the decompressed file", limit)])
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
        data = _read_path(Path(source), title.format(name=label), kind, limit)
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
        data = _gunzip(data, title.format(name=label), limit)
    elif limit is not None and len(data) > limit:
        raise ValidationError(title.format(name=label), [_too_large(what, limit)])
    return data, label
