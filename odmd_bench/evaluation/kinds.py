"""Kinds of problem with a depth, shared by the CSV rows and the array entry point."""

NONFINITE = "depth is NaN or infinite"
TOO_LARGE = "depth is too large to be a finite float64"
#: Estimates beyond this magnitude (metres) are refused: no scene is that deep, and the
#: squares summed for the standard deviation of their errors could overflow float64.
MAX_ABS_DEPTH = 1e12
OUT_OF_RANGE = f"depth is out of range (|depth| > {MAX_ABS_DEPTH:.0e} m, where errors can overflow)"
