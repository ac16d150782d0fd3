"""A method's module imported and made a :class:`~odmd_bench.methods.method.Method`, its ``OPTIONS`` checked.

An entry point's module (:func:`odmd_bench.methods.load`) and a module named directly
(:func:`load_module`: a pinned plug-in's, or an entry's plug-in source) are imported the
same way, with the same errors.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from odmd_bench.errors import UsageError
from odmd_bench.methods.failures import missing_import
from odmd_bench.methods.method import Method
from odmd_bench.methods.options import declaration_problems


def load_module(name: str, module: str, source: str, folder: Path | None = None) -> Method:
    """Method ``name`` from the module ``module`` (not an entry point): a pinned plug-in's, or one kept as source.

    Args:
        name: what messages call it.
        module: the dotted module that has ``predict`` and ``predict_report``.
        source: where it comes from, in words (shown in its errors).
        folder: a folder of plain ``.py`` files to import ``module`` from (an entry's
            plug-in source); it is put first on ``sys.path`` and stays there, so that the
            module's own later imports work. Its top package must not be one already
            imported or installed elsewhere.

    Raises:
        UsageError: the module cannot be imported or lacks the two functions.
    """
    import importlib
    import importlib.util

    top = module.split(".", 1)[0]
    if folder is not None:
        loaded = sys.modules.get(top)
        where = Path(getattr(loaded, "__file__", None) or "") if loaded is not None else None
        found = importlib.util.find_spec(top) if loaded is None else None
        other = where if where is not None else (Path(found.origin) if found and found.origin else None)
        if (loaded is not None or found is not None) and (
            other is None or folder.resolve() not in other.resolve().parents
        ):
            raise UsageError(
                f"method {name!r}: its module {top} is already {'imported' if loaded else 'installed'} from elsewhere ({other})"
            )
        if str(folder) not in sys.path:
            sys.path.insert(0, str(folder))
    return imported(name, module, source, module, lambda: importlib.import_module(module))


def imported(name: str, target: str, source: str, module: str, load: Callable[[], Any]) -> Method:
    """The :class:`Method` that ``load()`` imports (``module``: what a missing import names)."""
    try:
        obj = load()
    except ModuleNotFoundError as e:
        raise missing_import(e, name, module) from None
    except Exception as e:
        raise UsageError(
            f"method {name!r} ({target}, from {source}) cannot be loaded: {type(e).__name__}: {e}"
        ) from None
    missing = [f for f in ("predict", "predict_report") if not callable(getattr(obj, f, None))]
    if missing:
        raise UsageError(
            f"method {name!r} ({target}, from {source}) is not usable: it has no "
            + " and no ".join(f"{f}()" for f in missing)
        )
    return _method(name, target, source, obj)


def _method(name: str, target: str, source: str, obj: Any) -> Method:
    """The :class:`Method` of a loaded module (or object) with both functions, its ``OPTIONS`` checked."""
    declared = getattr(obj, "OPTIONS", ())
    functions = (obj.predict, obj.predict_report)
    problems = declaration_problems(declared, functions)
    if problems:
        raise UsageError(f"method {name!r} ({target}, from {source}) is not usable: its OPTIONS", problems)
    spread = getattr(obj, "predict_spread", None)
    return Method(
        name,
        target,
        source,
        obj.predict,
        obj.predict_report,
        tuple(declared),
        spread if callable(spread) else None,
    )
