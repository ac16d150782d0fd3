"""What the per-set before/after scripts share: their arguments and the sets they time.

``croissant_before_after.py`` and ``read_before_after.py`` take an earlier commit and
``--original``, and time it against this checkout on the same data folder: odmd-v1 val
and test generated, and with ``--original`` the original release imported (odmd-paper,
odms-detection).
"""

from __future__ import annotations

import argparse
import platform
import subprocess
import tempfile
from pathlib import Path


def arguments(description: str) -> argparse.Namespace:
    """``rev`` (default ``HEAD~1``) and ``--original``."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("rev", nargs="?", default="HEAD~1")
    parser.add_argument("--original", help="the original release's folder (odmd-paper, odms-detection)")
    return parser.parse_args()


def data_folder(prefix: str, original: str | None) -> tuple[Path, Path]:
    """A new temporary folder and, inside it, a data folder with the sets to time."""
    from odmd_bench.data.importer import import_release
    from odmd_bench.data.store import ensure_generated

    work = Path(tempfile.mkdtemp(prefix=prefix))
    data = work / "data"
    ensure_generated("odmd-v1", ("val", "test"), data)
    if original:
        import_release(original, data)
    return work, data


def cpu_model() -> str:
    """The processor's model name, for the first line of a report."""
    cpu = subprocess.run(["grep", "-m1", "model name", "/proc/cpuinfo"], capture_output=True, text=True)
    return cpu.stdout.strip() or platform.processor()
