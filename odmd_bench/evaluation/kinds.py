"""Kinds of problem with a depth, shared by the CSV rows and the array entry point.

The bound is :data:`odmd_bench.inputs.bounds.MAX_ABS_DEPTH`, shared by every command.
"""

from odmd_bench.inputs.bounds import MAX_ABS_DEPTH

__all__ = ["MAX_ABS_DEPTH", "NONFINITE", "OUT_OF_RANGE", "TOO_LARGE"]

NONFINITE = "depth is NaN or infinite"
TOO_LARGE = "depth is too large to be a finite float64"
OUT_OF_RANGE = f"depth is out of range (|depth| > {MAX_ABS_DEPTH:.0e} m, where errors can overflow)"
