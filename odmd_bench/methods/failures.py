"""How a method's failure is worded: where a plug-in raised, and a module that is not installed."""

from __future__ import annotations

import traceback

from odmd_bench.errors import UsageError
from odmd_bench.extras import is_installed, missing_module_error


def raised(e: BaseException) -> str:
    """``Type: message (raised at file:line, in function)``, the last frame of the trace."""
    frames = traceback.extract_tb(e.__traceback__)
    where = f" (raised at {frames[-1].filename}:{frames[-1].lineno}, in {frames[-1].name})" if frames else ""
    text = " ".join(str(e).split())
    return f"{type(e).__name__}: {text[:300]}{where}"


def missing_import(error: ModuleNotFoundError, name: str, target: str = "") -> Exception:
    """The error to raise for a failed import of method ``name``'s module.

    A module that is not installed becomes a usage error naming what provides it; a module
    that is installed but failed to import is a bug, returned as it is to be re-raised.
    """
    missing = error.name or ""
    if target and (target + ".").startswith(missing + "."):
        return UsageError(f"method {name!r} is not available: its module {target} is not installed")
    if missing and not is_installed(missing):
        return missing_module_error(error, f"method {name!r}")
    return error
