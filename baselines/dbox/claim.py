"""A training run's claim on its ``--out`` folder: one run per folder, even when two start together.

Two ``train-dbox`` runs started at the same moment into one empty folder both passed the
"already holds a run" check and wrote over each other's files. A run now claims its
folder before it trains, in two steps:

- it holds a lock (:class:`filelock.FileLock` on ``.claim.lock``, ``flock`` on POSIX) for
  as long as it trains; the kernel releases it when the run ends or is killed, so a lock
  is never left behind. A second run, new or resumed, that finds it held is refused;
- a new run creates ``claim.json`` (who: process id, host, start time, command)
  exclusively (``O_CREAT | O_EXCL``: of two runs exactly one succeeds). The claim stays
  with the run's files, so a later new run into the folder is refused too, naming the
  run that holds it; ``--resume`` continues that run (and records itself as resumed).

Under torchrun only process 0 claims (it alone writes under ``--out``).
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path

from odmd_bench import StorageError, UsageError, atomic_write

#: The claim's record of the run that holds the folder.
CLAIM_FILE = "claim.json"
#: The lock held while a run trains.
LOCK_FILE = ".claim.lock"


def _who(command: str | None) -> dict[str, object]:
    return {
        "pid": os.getpid(),
        "host": socket.gethostname(),
        "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
        "command": command if command is not None else " ".join(sys.argv),
    }


#: How long a run refused for a held lock waits for the holder's claim to be written (s).
CLAIM_WAIT_S = 5.0


def describe(out: Path, wait_s: float = 0.0) -> str:
    """The run named by ``out``'s claim, in words ("process 123 on host h, started ..., command ...").

    Waits up to ``wait_s`` seconds for a claim being written (a run that has just taken
    the lock writes it once it has checked the folder).
    """
    deadline = time.monotonic() + wait_s
    while True:
        try:
            who = json.loads((out / CLAIM_FILE).read_text(encoding="utf-8"))
            words = f"process {who['pid']} on {who['host']}, started {who['started']} ({who['command']})"
            break
        except (OSError, ValueError, TypeError, KeyError):
            if time.monotonic() >= deadline:
                return "a run whose claim is not written yet or cannot be read"
            time.sleep(0.05)
    if "resumed" in who:
        words += f", resumed {who['resumed']}"
    return words


@contextlib.contextmanager
def claimed(
    out: Path, *, resume: bool, check: Callable[[], None], command: str | None = None
) -> Iterator[None]:
    """Hold ``out`` for one training run while the body runs (the folder is created).

    Args:
        out: the run's folder.
        resume: the run continues the one that claimed ``out`` (its claim is updated
            rather than created).
        check: called once the lock is held, before the claim is written: raises where
            the folder cannot take this run (it holds another run's files).
        command: the command line recorded in the claim (default: ``sys.argv``).

    Raises:
        UsageError: another run holds the folder (it trains now, or a new run is asked
            for in a folder an earlier run claimed); the message names that run.
        StorageError: the folder or the claim cannot be written.
    """
    from filelock import FileLock, Timeout  # here: most commands never lock

    try:
        out.mkdir(parents=True, exist_ok=True)
        lock = FileLock(out / LOCK_FILE)
        lock.acquire(timeout=0)
    except Timeout:
        raise UsageError(
            f"{out} is in use by another train-dbox run: {describe(out, CLAIM_WAIT_S)}; wait for it to end or "
            "choose another --out"
        ) from None
    except OSError as e:
        raise StorageError(
            f"cannot create the run folder {out}: {e.strerror or type(e).__name__}; give --out a folder "
            "you can write"
        ) from None
    try:
        check()
        path = out / CLAIM_FILE
        if resume:
            who = _who(command)
            with contextlib.suppress(OSError, ValueError):
                first = json.loads(path.read_text(encoding="utf-8"))
                if isinstance(first, dict) and "started" in first:
                    who = {**first, "resumed": who["started"], "pid": who["pid"], "host": who["host"]}
            with atomic_write(path, "w") as fh:
                fh.write(json.dumps(who, indent=1) + "\n")
        else:
            try:
                fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
            except FileExistsError:
                raise UsageError(
                    f"{out} is claimed by an earlier train-dbox run ({describe(out)}), which is not "
                    f"running now and left no training state to resume; choose another --out, or "
                    f"delete {path} to start over in this folder"
                ) from None
            except OSError as e:
                raise StorageError(f"cannot write {path}: {e.strerror or type(e).__name__}") from None
            with os.fdopen(fd, "w", encoding="utf-8") as fh:
                fh.write(json.dumps(_who(command), indent=1) + "\n")
        yield
    finally:
        lock.release()
