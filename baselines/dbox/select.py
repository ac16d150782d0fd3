"""Choosing the shipped DBox weights among several training runs, on val only.

Each ``train-dbox`` run keeps its best checkpoint on val All (``dbox_<config>.pt``) and,
per validation set, its best checkpoint on that set (``dbox_<config>.<set>.pt``).
When several runs of one configuration were made (seeds, schedules), :func:`select_runs`
applies the same rule across them: the overall checkpoint is the run whose best val
All is lowest, and each per-set checkpoint is the run whose best val score on that set
is lowest. Ties go to the run given first. Test sets are never read.

Every candidate is hash-checked against its record before it is compared or copied,
its val scores can be measured again (:func:`verify_scores`; ``select-dbox`` always
does), and the chosen files are copied byte for byte (so their recorded ``weights_sha256``
still holds). The record written beside each chosen file is the run's own, with a
``selected_from`` list: every candidate run, its training command and the val score it
was compared on. An earlier selection's output folder may be a candidate (new runs
added to those already chosen among): its runs are listed in its place.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from odmd_bench_baselines.dbox.weights import CONFIGS, per_set_path, verify_weights

from odmd_bench import DataError, Examples, StorageError, UsageError, atomic_write

#: What a set's name may be (it becomes part of a file name).
_SET_NAME = re.compile(r"[a-z0-9_-]{1,40}")
#: How far a val score measured again may be from its record, in percentage points:
#: the CPU kernels of two machines differ in the last bits of float32.
SCORE_TOLERANCE = 2e-3
#: Record fields that must agree between candidate runs of one configuration.
_SAME = ("config", "val_benchmark", "val_sets", "generator_version", "batch_size")


@dataclass(frozen=True)
class Candidate:
    """One run's checkpoint for one criterion (``all`` or a set name)."""

    run: Path
    weights: Path
    record: dict[str, Any]
    score: float


@dataclass(frozen=True)
class Selection:
    """What :func:`select_runs` chose: criterion (``all`` or a set) -> chosen candidate."""

    config: str
    chosen: dict[str, Candidate]
    candidates: dict[str, list[Candidate]]


def _read_record(weights: Path) -> dict[str, Any]:
    record = weights.with_suffix(".json")
    try:
        data = json.loads(record.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise DataError(f"cannot read the training record {record}: {type(e).__name__}: {e}") from None
    if not isinstance(data, dict):
        raise DataError(f"the training record {record} is not a JSON object")
    return data


def _score(record: dict[str, Any], key: str, where: Path) -> float:
    scores = record.get("val_mean_percent_error")
    value = scores.get(key) if isinstance(scores, dict) else None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise DataError(f"{where.with_suffix('.json')} has no finite val_mean_percent_error[{key!r}]")
    return float(value)


def select_runs(runs: Sequence[str | Path], config: str) -> Selection:
    """Choose the overall and per-set checkpoints of ``config`` among ``runs`` by val.

    Args:
        runs: ``train-dbox`` output folders of the same configuration (at least one).
        config: the configuration (``p``, ``p-z``, ...).

    Returns:
        :class:`Selection`.

    Raises:
        UsageError: no runs, a run given twice, or an unknown configuration.
        DataError: a run without the configuration's checkpoints or records, a
            checkpoint that fails its hash check, or runs that differ in
            configuration, validation sets or generator version (every problem named).
    """
    if config not in CONFIGS:
        raise UsageError(f"unknown DBox configuration {config!r}; expected one of {', '.join(CONFIGS)}")
    folders = [Path(r) for r in runs]
    if not folders:
        raise UsageError("give at least one training run folder")
    resolved = [f.resolve() for f in folders]
    if len(set(resolved)) != len(resolved):
        raise UsageError("a run folder is given twice")
    problems: list[str] = []
    overall: list[Candidate] = []
    for run in folders:
        weights = run / f"dbox_{config}.pt"
        if not weights.is_file():
            problems.append(f"{run}: no {weights.name} (not a finished train-dbox run of {config})")
            continue
        try:
            verify_weights(weights, require_record=True)
            record = _read_record(weights)
            overall.append(Candidate(run, weights, record, _score(record, "all", weights)))
        except DataError as e:
            problems.append(str(e))
            continue
        done, planned = record.get("steps_done"), record.get("steps")
        if record.get("selected_from") is None and done != planned:
            problems.append(
                f"{run}: the run stopped at step {done} of {planned} (killed?); finish it with "
                "train-dbox --resume, or leave it out"
            )
    if problems:
        raise DataError(f"cannot select DBox {config} weights", problems)
    first = overall[0].record
    for cand in overall[1:]:
        for key in _SAME:
            if cand.record.get(key) != first.get(key):
                problems.append(
                    f"{cand.run}: {key} {cand.record.get(key)!r} differs from {overall[0].run}'s "
                    f"{first.get(key)!r}"
                )
    val_sets = first.get("val_sets")
    if not isinstance(val_sets, list) or not all(
        isinstance(s, str) and _SET_NAME.fullmatch(s) for s in val_sets
    ):
        problems.append(f"{overall[0].weights.with_suffix('.json')} has no list of val_sets (set names)")
        val_sets = []
    if problems:
        raise DataError(f"cannot select DBox {config} weights: the runs are not comparable", problems)
    candidates: dict[str, list[Candidate]] = {"all": overall}
    for name in val_sets:
        found = []
        for cand in overall:
            weights = per_set_path(cand.weights, name)
            try:
                verify_weights(weights, require_record=True)
                record = _read_record(weights)
                found.append(Candidate(cand.run, weights, record, _score(record, name, weights)))
            except DataError as e:
                problems.append(str(e))
        candidates[name] = found
    if problems:
        raise DataError(f"cannot select DBox {config} weights", problems)
    chosen = {key: min(cands, key=lambda c: c.score) for key, cands in candidates.items()}
    return Selection(config, chosen, candidates)


def verify_scores(selection: Selection, val_sets: Mapping[str, Examples]) -> int:
    """Measure every candidate's val score again; refuse records that state another.

    The choice rests on the scores in the runs' records; they are compared only once
    each checkpoint, on ``val_sets`` (the runs' val split), gives what its record says
    (within :data:`SCORE_TOLERANCE`).

    Returns:
        The number of checkpoints measured.

    Raises:
        DataError: ``val_sets`` are not the runs' val sets, or a record states a score
            its checkpoint does not give (every one named).
    """
    import torch
    from odmd_bench_baselines.dbox.loading import load_model
    from odmd_bench_baselines.dbox.recipe import validation_scores

    expected = selection.candidates["all"][0].record.get("val_sets")
    if list(val_sets) != expected:
        raise DataError(f"the val sets given are {list(val_sets)}, the runs were validated on {expected}")
    measured: dict[Path, dict[str, float]] = {}
    problems = []
    for key, cands in selection.candidates.items():
        for cand in cands:
            if cand.weights not in measured:
                model, formulation = load_model(cand.weights)
                measured[cand.weights] = validation_scores(model, val_sets, formulation, torch.device("cpu"))
            got = measured[cand.weights][key]
            if not abs(got - cand.score) <= SCORE_TOLERANCE:
                problems.append(
                    f"{cand.weights.with_suffix('.json')}: val {key} {cand.score:.4f} recorded, "
                    f"{got:.4f} measured"
                )
    if problems:
        raise DataError(
            f"cannot select DBox {selection.config} weights: records state val scores their weights do not give",
            problems,
        )
    return len(measured)


def _listed(cand: Candidate, key: str) -> list[dict[str, Any]]:
    """How ``cand`` is listed in ``selected_from``: its run, or an earlier selection's runs.

    A candidate folder may itself be the output of ``select-dbox`` (the shipped weights,
    say, when new runs are added to the ones already chosen among). Its file is then the
    best of the runs in its own ``selected_from``, which are listed in its place, each
    with the folder it was reached through (``via``) and that selection's command, so
    that the record still names every training run and its val score.
    """
    earlier = cand.record.get("selected_from")
    if (
        isinstance(earlier, list)
        and earlier
        and all(isinstance(e, dict) and e.get("on") == key for e in earlier)
    ):
        via = {"via": str(cand.run), "via_select_command": cand.record.get("select_command")}
        return [{**e, **via} for e in earlier]
    return [{"run": str(cand.run), "command": cand.record.get("command"), "val": cand.score, "on": key}]


def write_selection(selection: Selection, out: str | Path, command: str | None = None) -> list[Path]:
    """Copy the chosen checkpoints into ``out`` with their records; return the files written.

    The checkpoints are copied byte for byte after a second hash check; each record is
    the chosen run's, plus ``selected_from`` (every candidate, its command and score)
    and ``select_command``. Every file is written atomically.
    """
    out = Path(out)
    runs = {c.run.resolve() for cands in selection.candidates.values() for c in cands}
    if out.resolve() in runs:
        raise UsageError(f"--out {out} is one of the candidate runs; choose another folder")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise StorageError(f"cannot create the folder {out}: {e.strerror or e}") from None
    written = []
    for key, cand in selection.chosen.items():
        data, _ = verify_weights(cand.weights, require_record=True)
        name = f"dbox_{selection.config}.pt" if key == "all" else f"dbox_{selection.config}.{key}.pt"
        target = out / name
        record = dict(cand.record)
        record["selected_from"] = [entry for c in selection.candidates[key] for entry in _listed(c, key)]
        record["select_command"] = command
        with atomic_write(target) as fh:
            fh.write(data)
        with atomic_write(target.with_suffix(".json"), "w") as fh:
            fh.write(json.dumps(record, indent=2) + "\n")
        written += [target, target.with_suffix(".json")]
    return written


__all__ = ["Candidate", "Selection", "select_runs", "write_selection"]
