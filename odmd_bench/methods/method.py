"""A loaded method (:class:`Method`): its options' values, and a run whose result is checked."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from odmd_bench.data.examples import Examples
from odmd_bench.errors import DepthRangeError, MethodError, OdmdError, UsageError
from odmd_bench.inputs.bounds import MAX_ABS_DEPTH, depth_problems
from odmd_bench.inputs.problems import SHOWN
from odmd_bench.methods.failures import missing_import, raised
from odmd_bench.methods.options import MethodOption, takes


@dataclass(frozen=True)
class Method:
    """A loaded method.

    Attributes:
        name: its registered name.
        target: where its entry point points (``module`` or ``module:attr``).
        source: the distribution that registers it, with its version.
        predict: ``predict(examples, **options) -> depths``.
        predict_report: ``predict_report(examples, **options) -> (depths, counts)``.
        options: the options its module declares (``OPTIONS``), in their order.
        spread: ``predict_spread(examples, **options) -> (N,)``, or None.
    """

    name: str
    target: str
    source: str
    predict: Callable[..., Any]
    predict_report: Callable[..., Any]
    options: tuple[MethodOption, ...] = ()
    spread: Callable[..., Any] | None = None

    def option(self, name: str) -> MethodOption | None:
        """The declared option ``name`` (a keyword, ``weights_sha256``), or ``None``."""
        return next((o for o in self.options if o.name == name), None)

    def values(
        self, given: Mapping[str, object], spell: Callable[[str], str] | None = None
    ) -> dict[str, Any]:
        """``given`` checked against the declared options and converted to their types.

        What an entry records (its ``options``) or a command line gives is text or a
        YAML scalar; this is what :meth:`run` is then given.

        Args:
            given: option name (keyword) -> value.
            spell: how an option is named in a message (default: its ``--flag``).

        Returns:
            The values by name, in the order of the declaration.

        Raises:
            UsageError: every option that is not declared, and every value that is not
                of its type or not one of its choices (named), at once.

        Example:
            >>> from odmd_bench.methods import load
            >>> load("robust").values({"mode": "scale"})
            {'mode': 'scale'}
        """
        name_of = spell or (lambda k: "--" + k.replace("_", "-"))
        problems = []
        declared = ", ".join(o.flag for o in self.options) or "none"
        for k in given:
            if self.option(k) is None:
                problems.append(
                    f"{name_of(k)}: method {self.name!r} declares no such option (it declares: {declared})"
                )
        out = {}
        for o in self.options:
            if o.name in given:
                try:
                    out[o.name] = o.convert(given[o.name])
                except ValueError as e:
                    problems.append(f"{name_of(o.name)}: {e}")
        if len(problems) == 1:
            raise UsageError(problems[0])
        if problems:
            raise UsageError(f"options that method {self.name!r} cannot take", problems)
        return out

    def accepts(self, keyword: str) -> bool:
        """Whether ``predict`` and ``predict_report`` both take ``keyword`` by name."""
        return all(takes(f, keyword) for f in (self.predict, self.predict_report))

    def run(self, examples: Examples, **options: Any) -> tuple[np.ndarray, dict[str, int | str]]:
        """Depths and the method's report for ``examples``, checked.

        The method sees ``examples.without_truth()``: the boxes, detections, camera and
        metadata, never the true depths or the generator's extras.

        Args:
            examples: the examples to estimate.
            **options: keywords for ``predict_report``; each must be accepted.

        Returns:
            ``(depths, report)``: (N,) float64 finite depths, and the report: integers
            (fallback counts; ``n``, where given, the number of examples) and strings
            (what the method says of its run, e.g. which weights it loaded).

        Raises:
            UsageError: an option the method does not take, or an optional module it
                needs is not installed (the message names the extra).
            MethodError: a plug-in (a method of another distribution) raised, or broke
                its promise of one finite depth per example and a report of counts.
            RuntimeError: the same from one of odmd-bench's own methods (a bug of
                odmd-bench).
            DepthRangeError: depths that are not finite or beyond
                :data:`~odmd_bench.inputs.bounds.MAX_ABS_DEPTH`: what the method was given
                (the examples' numbers, its options or weights) makes them; the message
                names the examples and the options.
        """
        refused = [k for k in options if not self.accepts(k)]
        if refused:
            raise UsageError(f"method {self.name!r} takes no option {', '.join(map(repr, refused))}")
        bug = f"method {self.name!r} ({self.target}, from {self.source})"
        broken = RuntimeError if self.is_own else MethodError
        try:
            depths, counts = self.predict_report(examples.without_truth(), **options)
        except ModuleNotFoundError as e:
            raise missing_import(e, self.name) from None
        except (OdmdError, MemoryError):
            raise
        except Exception as e:
            if self.is_own:
                raise
            raise MethodError(f"{bug} failed: {raised(e)}; a bug of that method, not of odmd-bench") from e
        try:
            depths = np.asarray(depths, dtype=np.float64)
            report = {str(k): v if isinstance(v, str) else int(v) for k, v in dict(counts).items()}
        except (TypeError, ValueError) as e:
            raise broken(f"{bug} returned what is not depths and a report of counts: {raised(e)}") from None
        if depths.shape != (len(examples),):
            raise broken(f"{bug} returned shape {depths.shape} for {len(examples)} examples")
        if not self.is_own and not np.isfinite(depths).all():
            raise broken(f"{bug} returned {int((~np.isfinite(depths)).sum())} non-finite depths")
        out = depth_problems(depths)
        if out.any():
            where = np.flatnonzero(out)
            given = ", ".join(f"{k}={v}" for k, v in options.items()) or "none"
            raise DepthRangeError(
                f"method {self.name!r} gives depths that are not finite or beyond {MAX_ABS_DEPTH:.0e} m "
                f"for {where.size} of {len(examples)} examples",
                [
                    ", ".join(f"example {i}: {float(depths[i])!r}" for i in where[:SHOWN].tolist())
                    + (", ..." if where.size > SHOWN else ""),
                    f"what it was given makes them: the boxes and camera motion of those named, or its "
                    f"options ({given})",
                ],
                where=where.tolist(),
            )
        return depths, report

    @property
    def is_own(self) -> bool:
        """Whether odmd-bench's own distribution registers the method (its bugs are ours)."""
        return self.source.split(" ", 1)[0] == "odmd-bench"
