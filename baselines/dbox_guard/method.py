"""The guard's method interface: ``predict``, ``predict_report`` and the chosen parameters."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
from odmd_bench_baselines import box_ls, dbox
from odmd_bench_baselines.dbox_guard.steps import blend, cap, flag_wrong_starts, repair, travel

from odmd_bench import DataError, Examples

#: The counts of the report that are repairs (``odmd_bench.predict.report``): a wrong start
#: repaired, a depth capped.
REPAIRS: tuple[str, ...] = ("wrong_start", "capped")

#: The parameters val chose (written by ``python -m odmd_bench_baselines.dbox_guard.select``).
PARAMETERS_FILE = Path(__file__).with_name("parameters.json")


@dataclass(frozen=True)
class Parameters:
    """One set's guard: wrong-start threshold, Box_LS weight and cap (``None``: off)."""

    tau: float | None = None
    alpha: float = 0.0
    cap: float | None = None

    def as_dict(self) -> dict[str, float | None]:
        """The JSON form: ``{"tau", "alpha", "cap"}``."""
        return {"tau": self.tau, "alpha": self.alpha, "cap": self.cap}


def _number(value: Any, name: str, where: str, optional: bool) -> float | None:
    if value is None and optional:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DataError(
            f"{where}: {name} must be a finite number{' or null' if optional else ''}, got {value!r}"
        )
    return float(value)


def parameters_from(data: Any, where: str) -> Parameters:
    """A :class:`Parameters` from its JSON form ``{"tau", "alpha", "cap"}``, checked."""
    if not isinstance(data, dict) or set(data) != {"tau", "alpha", "cap"}:
        raise DataError(f"{where}: expected an object with the keys tau, alpha and cap")
    alpha = _number(data["alpha"], "alpha", where, optional=False)
    assert alpha is not None
    return Parameters(
        tau=_number(data["tau"], "tau", where, optional=True),
        alpha=alpha,
        cap=_number(data["cap"], "cap", where, optional=True),
    )


def load_parameters(path: Path = PARAMETERS_FILE) -> tuple[dict[str, Parameters], Parameters]:
    """The chosen parameters: per set, and overall (for data of no known set).

    Raises:
        DataError: the file is missing or malformed (the message says how to remake it).
    """
    remake = "remake it with: python -m odmd_bench_baselines.dbox_guard.select"
    try:
        record = json.loads(path.read_text(encoding="utf-8"))
        per_set = record["per_set"]
        overall = record["overall"]
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise DataError(
            f"cannot read the guard's parameters {path}: {type(e).__name__}: {e}; {remake}"
        ) from None
    if not isinstance(per_set, dict):
        raise DataError(f"{path}: per_set must be an object; {remake}")
    chosen = {str(k): parameters_from(v, f"{path}: per_set.{k}") for k, v in per_set.items()}
    return chosen, parameters_from(overall, f"{path}: overall")


def details(
    examples: Examples, params: Parameters, selection: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, int | str]]:
    """The guard with ``params`` over DBox ``p-z`` (``selection``: overall or per-set).

    Returns:
        (depths (N,), repaired (N,) bool: a wrong start was flagged, capped (N,) bool:
        the depth was lowered to the cap, DBox's report).
    """
    flagged = flag_wrong_starts(examples.boxes, examples.detected, params.tau)
    fixed = repair(examples, flagged)
    depth, report = dbox.predict_report(fixed, config="p-z", selection=selection)
    if params.alpha:
        depth = blend(depth, box_ls.predict(fixed), params.alpha)
    capped = cap(depth, travel(examples), params.cap)
    return capped, np.asarray(flagged.any(axis=1)), np.asarray(capped < depth), report


def choose_parameters(examples: Examples) -> tuple[Parameters, str]:
    """The parameters and DBox selection for ``examples``: the set's, else the overall ones.

    Raises:
        DataError: the data are not z-only camera motion (an ODMD benchmark, or x, y
            offsets beyond 10 % of z: the guard assumes forward motion along z), or
            the parameters file is unreadable.
    """
    if len(examples) and dbox.default_config(examples) != "p-z":
        raise DataError(
            "dbox-guard is for z-axis camera motion (ODMS); these data move the camera in x and y "
            "too (or are an ODMD benchmark): run dbox instead"
        )
    per_set, overall = load_parameters()
    name = examples.attrs.get("set")
    if isinstance(name, str) and name in per_set:
        return per_set[name], "per-set"
    return overall, "overall"


def predict_report(examples: Examples) -> tuple[np.ndarray, dict[str, int | str]]:
    """Guarded DBox ``p-z`` depths and what the guard did.

    The examples' set (``examples.attrs["set"]``) picks the per-set checkpoint and
    parameters where val chose some for it; other z-only data run the overall ones.

    Returns:
        (depths (N,), report): ``n``, ``no_detection``, ``wrong_start`` (examples whose
        start was repaired), ``capped`` (depths lowered to ``cap`` times the travel), and
        the DBox weights that ran.

    Raises:
        DataError: as :func:`choose_parameters`.
    """
    params, selection = choose_parameters(examples)
    depth, repaired, capped, report = details(examples, params, selection)
    counts: dict[str, int | str] = {
        "n": len(examples),
        "no_detection": int(report["no_detection"]),
        "wrong_start": int(repaired.sum()),
        "capped": int(capped.sum()),
    }
    for key in ("selection", "weights", "weights_sha256"):
        counts[key] = report[key]
    return depth, counts


def predict(examples: Examples) -> np.ndarray:
    """Guarded DBox ``p-z`` depth estimates (metres, (N,)); see :func:`predict_report`."""
    return predict_report(examples)[0]
