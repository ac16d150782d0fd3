"""The leaderboard folder: finding it, discovering and reading entries, the outputs' names.

The folder (``leaderboard/`` in the repository) holds::

    entries/<method>/<benchmark>-<split>/entry.yaml   metadata (or entry.json)
    entries/<method>/<benchmark>-<split>/predictions.csv.gz   the predictions (or .csv)
    entries/<method>/<benchmark>-<split>/<source>/   a plug-in's plain .py files (optional)
    reported.yaml      results reported in papers without predictions (never ranked)
    audits/            recorded fresh-seed audits

and, not committed (``build`` writes them, by default into ``build/``, which git ignores)::

    LEADERBOARD.md     the tables
    leaderboard.json   every number, with full provenance
    leaderboard.png    the plot (needs matplotlib); it records the SHA-256 of the
                       leaderboard.json it was drawn from

What an entry is, is decided in one place, :func:`read_entry` (also exported as
``validate_entry``), which ``add``, ``build``, ``check`` and the site all call: every
file in an entry folder is a regular file with one link (no symbolic link, no hard
link, no pipe or device: refused, naming it, before anything in it is read, so that no
other file's content is ever shown), the metadata follows
:mod:`~odmd_bench.leaderboard.rules`, and the predictions are read as the evaluator
reads any file (:func:`read_predictions_bytes`, then
:func:`~odmd_bench.evaluation.parse.parse_predictions`: gzip once, the same cap).
The rules between the entries of a board (a name or predictions another entry has) are
:func:`~odmd_bench.leaderboard.board.board_problems`, which ``add`` and ``build`` share.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat as stat_lib
import struct
from pathlib import Path

from odmd_bench.documents import MAX_DOCUMENT_BYTES, DocumentError, load_document
from odmd_bench.errors import UsageError, ValidationError
from odmd_bench.inputs.source import MAX_PREDICTIONS_BYTES
from odmd_bench.leaderboard.entry import ENTRY_FILES, Entry, validate_meta

#: The entries, relative to the leaderboard folder.
ENTRIES = "entries"
#: Where ``build`` writes the views by default, relative to the leaderboard folder (ignored by git).
BUILD = "build"
#: The views ``build`` writes (never committed: derived from the entries).
MARKDOWN = "LEADERBOARD.md"
JSON_FILE = "leaderboard.json"
PLOT = "leaderboard.png"
#: The PNG text key under which the plot records the SHA-256 of the JSON it was drawn from.
PLOT_SOURCE_KEY = "odmd-bench leaderboard.json sha256"
#: Largest plot file whose record is read (the committed one is about 0.5 MB).
MAX_PLOT_BYTES = 64 * 1024 * 1024


def find_root(start: str | os.PathLike[str] | None = None, *, otherwise: str = "pass --root") -> Path:
    """The ``leaderboard`` folder in ``start`` (default: the current folder) or a parent.

    Args:
        start: where to look first.
        otherwise: what the error tells the caller to do instead (the command line's
            option by default; Python callers name their own argument).

    Raises:
        UsageError: When there is none.
    """
    here = Path(start if start is not None else Path.cwd()).resolve()
    for folder in (here, *here.parents):
        if (folder / "leaderboard" / ENTRIES).is_dir():
            return folder / "leaderboard"
        if folder.name == "leaderboard" and (folder / ENTRIES).is_dir():
            return folder
    raise UsageError(
        f"no leaderboard folder (one holding {ENTRIES}/) in {here} or its parents; "
        f"run from the repository or {otherwise}"
    )


def discover(root: str | os.PathLike[str]) -> list[Path]:
    """Entry folders ``root/entries/<method>/<benchmark>-<split>/``, sorted.

    Symbolic links at either level are listed too, so that :func:`read_entry` refuses them.
    """
    base = Path(root) / ENTRIES
    if not base.is_dir():
        raise UsageError(f"{root} has no {ENTRIES}/ folder; is it a leaderboard folder?")
    found = []
    for method in base.iterdir():
        if method.is_symlink():
            found.append(method)
        elif method.is_dir():
            found += [p for p in method.iterdir() if p.is_symlink() or p.is_dir()]
    return sorted(found)


def symlinks(folder: Path) -> list[str]:
    """Every symbolic link at or under ``folder`` (and its parent), relative to the parent's parent."""
    top = folder.parent.parent
    if folder.parent.is_symlink() or folder.is_symlink():
        return [str((folder.parent if folder.parent.is_symlink() else folder).relative_to(top))]
    out, stack = [], [folder]
    while stack:
        with os.scandir(stack.pop()) as items:
            for item in items:
                if item.is_symlink():
                    out.append(str(Path(item.path).relative_to(top)))
                elif item.is_dir(follow_symlinks=False):
                    stack.append(Path(item.path))
    return sorted(out)


def entry_file_problems(folder: Path) -> list[str]:
    """Everything at or under an entry folder that is not a folder or a regular file with one link.

    Symbolic links (the entry and method folders included), hard links (a second name for
    a file elsewhere: reading it would show that file) and pipes, sockets or devices;
    paths relative to the ``entries`` folder.
    """
    top = folder.parent.parent
    links = symlinks(folder)
    if links:
        return [f"{p} is a symbolic link; an entry holds plain files (links are not followed)" for p in links]
    out, stack = [], [folder]
    while stack:
        with os.scandir(stack.pop()) as items:
            for item in items:
                st = item.stat(follow_symlinks=False)
                where = Path(item.path).relative_to(top)
                if stat_lib.S_ISDIR(st.st_mode):
                    stack.append(Path(item.path))
                elif not stat_lib.S_ISREG(st.st_mode):
                    out.append(
                        f"{where} is not a regular file (a pipe, socket or device); an entry holds plain files"
                    )
                elif st.st_nlink != 1:
                    out.append(
                        f"{where} has {st.st_nlink} hard links; an entry holds files of its own "
                        "(a hard link is another file's content under a second name): copy it instead"
                    )
    return sorted(out)


def read_capped(path: Path, limit: int) -> bytes:
    """At most ``limit + 1`` bytes of ``path``: a regular file with one link, never through a symbolic link.

    Raises:
        OSError: it cannot be opened, or is not a regular file with one link (checked on
            the open file, so that nothing swapped in after :func:`entry_file_problems`
            is read).
    """
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0))
    with os.fdopen(fd, "rb") as fh:
        st = os.fstat(fd)
        if not stat_lib.S_ISREG(st.st_mode) or st.st_nlink != 1:
            raise OSError(errno.EPERM, "not a regular file with one link")
        return fh.read(limit + 1)


def _metadata(folder: Path) -> tuple[Path | None, object, list[str]]:
    """(file, parsed document) of an entry's metadata, or the problem."""
    found = [folder / n for n in ENTRY_FILES if (folder / n).is_file()]
    if not found:
        return None, None, [f"no metadata file: expected one of {', '.join(ENTRY_FILES)}"]
    if len(found) > 1:
        return None, None, [f"two metadata files ({', '.join(p.name for p in found)}); keep one"]
    path = found[0]
    try:
        data = load_document(read_capped(path, MAX_DOCUMENT_BYTES), path.suffix.lstrip("."))
    except (OSError, DocumentError) as e:
        return None, None, [f"{path.name} cannot be read: {e.strerror if isinstance(e, OSError) else e}"]
    if not isinstance(data, dict):
        return None, None, [f"{path.name} must hold a mapping of fields"]
    if not all(isinstance(k, str) for k in data):
        return None, None, [f"{path.name}: every field name must be text"]
    return path, data, []


def read_entry(folder: str | os.PathLike[str], repo_root: str | os.PathLike[str] | None = None) -> Entry:
    """Read and check an entry: its files and its metadata (not its predictions' content).

    The one validator of what an entry is (see the module docstring); its predictions are
    scored by :func:`~odmd_bench.leaderboard.board.score_entry`.

    Args:
        folder: the entry folder ``<root>/entries/<method>/<benchmark>-<split>``.
        repo_root: where repository paths in ``code`` are resolved (default: the folder
            holding the leaderboard folder).

    Raises:
        ValidationError: Naming every missing, unknown or malformed field at once, or
            every file in the entry that is not a regular file with one link.
    """
    folder = Path(folder)
    key = f"{folder.parent.name}/{folder.name}"
    odd = entry_file_problems(folder)
    if odd:
        rule = (
            "symbolic links are not allowed" if "symbolic link" in odd[0] else "only plain files are allowed"
        )
        raise ValidationError(f"entry {key}: {rule}", odd)
    path, data, problems = _metadata(folder)
    if path is None or not isinstance(data, dict):
        raise ValidationError(f"entry {key}: metadata cannot be used", problems)
    repo = Path(repo_root) if repo_root is not None else folder.parents[2].parent
    meta, problems = validate_meta(data, method_folder=folder.parent.name, folder=folder.name, repo=repo)
    name = data.get("predictions")
    named = isinstance(name, str) and not any(
        p.startswith(("predictions ", "field 'predictions'")) for p in problems
    )
    if named and not (folder / str(name)).is_file():
        problems.append(f"predictions file {name} is not in the entry folder")
    if meta is not None and not problems and meta.plugin is not None and "source" in meta.plugin:
        problems += plugin_source_problems(folder, meta.plugin["source"], meta.plugin["module"])
    if meta is None or problems:
        raise ValidationError(f"entry {key}: metadata is incomplete or wrong", problems)
    return Entry(folder=folder, key=key, meta=meta, predictions=folder / meta.predictions)


def plugin_source_problems(folder: Path, source: str, module: str) -> list[str]:
    """What is wrong with a plug-in's source folder ``folder/source`` (empty: nothing).

    It holds plain ``.py`` files only (UTF-8 text; at most :data:`~odmd_bench.leaderboard.rules.MAX_PLUGIN_FILES`
    of them, each at most ``MAX_PLUGIN_FILE_BYTES``, ``MAX_PLUGIN_BYTES`` in all; no
    ``__pycache__``), and the file of ``module`` (``a/b.py`` or ``a/b/__init__.py``).
    Links and special files are refused before, by :func:`entry_file_problems`.
    """
    from odmd_bench.leaderboard.rules import MAX_PLUGIN_BYTES, MAX_PLUGIN_FILE_BYTES, MAX_PLUGIN_FILES

    top = folder / source
    where = f"plugin source {source}/"
    if not top.is_dir():
        return [f"{where} is not a folder in the entry folder"]
    files = sorted(p for p in top.rglob("*") if p.is_file())
    problems = []
    if len(files) > MAX_PLUGIN_FILES:
        problems.append(f"{where} holds {len(files)} files; at most {MAX_PLUGIN_FILES} are allowed")
    total = 0
    for path in files[: MAX_PLUGIN_FILES + 1]:
        rel = path.relative_to(top).as_posix()
        if path.suffix != ".py" or "__pycache__" in path.parts:
            problems.append(f"{where}{rel} is not a .py file; a plug-in's source is plain Python files only")
            continue
        try:
            data = read_capped(path, MAX_PLUGIN_FILE_BYTES)
        except OSError as e:
            problems.append(f"{where}{rel} cannot be read ({e.strerror or e})")
            continue
        total += len(data)
        if len(data) > MAX_PLUGIN_FILE_BYTES:
            problems.append(f"{where}{rel} is larger than {MAX_PLUGIN_FILE_BYTES // 1024} KiB")
        else:
            try:
                data.decode("utf-8")
            except UnicodeDecodeError:
                problems.append(f"{where}{rel} is not UTF-8 text")
    if total > MAX_PLUGIN_BYTES:
        problems.append(f"{where} holds more than {MAX_PLUGIN_BYTES // 1024} KiB")
    parts = module.split(".")
    candidates = (top.joinpath(*parts[:-1], parts[-1] + ".py"), top.joinpath(*parts, "__init__.py"))
    if not any(c.is_file() for c in candidates):
        problems.append(
            f"{where} has no module {module} ({'/'.join(parts)}.py or {'/'.join(parts)}/__init__.py)"
        )
    return problems


def build_folder(root: str | os.PathLike[str]) -> Path:
    """Where ``build`` writes the views by default: ``ROOT/build`` (ignored by git)."""
    return Path(root) / BUILD


#: The one validator of what an entry is (its files and metadata): ``add``, ``build``,
#: ``check`` and the site call it; the entry's predictions are then scored by
#: :func:`~odmd_bench.leaderboard.board.score_entry`.
validate_entry = read_entry


def read_predictions_bytes(path: Path) -> bytes:
    """The predictions file's bytes as stored (gzip or not), for the evaluator to read.

    Read without following a link, from a regular file with one link (:func:`read_capped`),
    and capped at :data:`MAX_PREDICTIONS_BYTES`; decompression is the evaluator's
    (:func:`~odmd_bench.evaluation.parse.parse_predictions`), exactly once, as for
    ``evaluate``: a file gzipped twice is refused by both.

    Raises:
        ValidationError: When it cannot be read, is a link, or is larger than
            :data:`MAX_PREDICTIONS_BYTES`.
    """
    title = f"{path} cannot be scored"
    try:
        raw = read_capped(path, MAX_PREDICTIONS_BYTES)
    except OSError as e:
        if path.is_symlink():  # O_NOFOLLOW's "too many levels of symbolic links"
            raise ValidationError(
                title, ["the file is a symbolic link, which is not followed; give the file itself"]
            ) from None
        raise ValidationError(title, [f"the file cannot be read ({e.strerror or e})"]) from None
    if len(raw) > MAX_PREDICTIONS_BYTES:
        raise ValidationError(title, [f"the file is larger than {MAX_PREDICTIONS_BYTES / 2**20:g} MiB"])
    return raw


def board_digest(json_text: str) -> str:
    """The SHA-256 of a ``leaderboard.json`` text: what a plot records it was drawn from."""
    return hashlib.sha256(json_text.encode("utf-8")).hexdigest()


def plot_source(path: str | os.PathLike[str]) -> str | None:
    """The ``leaderboard.json`` SHA-256 a ``leaderboard.png`` records, or None.

    Reads the PNG's chunks up to the image data (no matplotlib needed): None for a file
    that is not a PNG, is damaged before its data, or records nothing.

    Raises:
        OSError: the file cannot be read.
    """
    with open(path, "rb") as f:
        if f.read(8) != b"\x89PNG\r\n\x1a\n":
            return None
        read = 8
        while read < MAX_PLOT_BYTES:
            head = f.read(8)
            if len(head) < 8:
                return None
            length, kind = struct.unpack(">I4s", head)
            if kind in (b"IDAT", b"IEND") or length > MAX_PLOT_BYTES:
                return None
            data = f.read(length)
            f.read(4)  # CRC
            read += 12 + length
            if kind == b"tEXt" and len(data) == length:
                key, _, value = data.partition(b"\0")
                if key == PLOT_SOURCE_KEY.encode("latin-1"):
                    return value.decode("latin-1")
    return None
