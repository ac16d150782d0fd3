"""One ``odmd-bench train-dbox`` process for tests/test_dbox_distributed.py (torchrun starts it).

Usage: ``python tests/dbox_worker.py TRAIN-DBOX-ARGS...``, alone or under
``python -m torch.distributed.run``. It runs the real command line with two changes
for the tests: the validation sets are two tiny generated sets (no data folder), and
environment variables inject faults and watch writes:

- ``DBOX_TEST_FAIL=RANK:STEP:HOW``: process RANK, after step STEP, kills itself
  (``kill``: SIGKILL), raises an error (``raise``) or hangs (``hang``: sleeps a minute).
- ``DBOX_TEST_WRITES=FOLDER``: every write, rename, removal or folder creation this process
  makes under ``--out`` is listed in ``FOLDER/writes.RANK.json`` at exit.
"""

from __future__ import annotations

import atexit
import json
import os
import signal
import sys
import time
from pathlib import Path
from typing import Any


def _tiny_val() -> dict[str, Any]:
    import odmd_bench

    return {
        "normal": odmd_bench.generate(64, "odmd", "normal", 100),
        "camera": odmd_bench.generate(64, "odmd", "camera", 101),
    }


def _watch_writes(out: Path, folder: Path, rank: str) -> None:
    seen: list[str] = []
    root = str(out.resolve())

    def under_out(path: Any) -> bool:
        try:
            return str(Path(os.fsdecode(path)).resolve()).startswith(root)
        except (TypeError, ValueError, OSError):
            return False

    def hook(event: str, args: tuple[Any, ...]) -> None:
        if event == "open" and args and isinstance(args[0], str | bytes | os.PathLike):
            mode = args[1] if len(args) > 1 and isinstance(args[1], str) else "r"
            flags = args[2] if len(args) > 2 and isinstance(args[2], int) else 0
            writes = any(c in mode for c in "wax+") or flags & (os.O_WRONLY | os.O_RDWR | os.O_CREAT)
            if writes and under_out(args[0]):
                seen.append(f"open {args[0]} {mode}")
        elif event in ("os.rename", "os.remove", "os.mkdir", "os.rmdir", "os.truncate", "os.link") and any(
            under_out(a) for a in args[:2] if isinstance(a, str | bytes | os.PathLike)
        ):
            seen.append(f"{event} {args[:2]}")

    sys.addaudithook(hook)
    atexit.register(lambda: (folder / f"writes.{rank}.json").write_text(json.dumps(seen)))


def main() -> None:
    import odmd_bench_baselines.dbox.train as train_module

    from odmd_bench.cli.main import main as cli_main

    argv = sys.argv[1:]
    rank = os.environ.get("RANK", "0")
    watch = os.environ.get("DBOX_TEST_WRITES")
    if watch:
        _watch_writes(Path(argv[argv.index("--out") + 1]), Path(watch), rank)
    train_module.odmd_bench.load_split = lambda *a, **k: _tiny_val()  # type: ignore[assignment]
    fail = os.environ.get("DBOX_TEST_FAIL")
    if fail:
        who, at, how = fail.split(":")
        real = train_module.train

        def on_step(step: int, loss: float) -> None:
            if rank == who and step == int(at):
                if how == "kill":
                    os.kill(os.getpid(), signal.SIGKILL)
                elif how == "hang":
                    time.sleep(60)
                else:
                    raise RuntimeError(f"injected failure in process {rank} after step {step}")

        train_module.train = lambda *a, **k: real(*a, **k, on_step=on_step)  # type: ignore[assignment]
    sys.argv = ["odmd-bench", *argv]
    cli_main()


if __name__ == "__main__":
    main()
