"""The columns of the sequences format (``docs/own-data.md``), known below its reader.

The sequences reader (:mod:`odmd_bench.predict.sequence_rows`) reads them; the
predictions reader (:mod:`odmd_bench.evaluation.columns`) names a sequences file given
in its place by them.
"""

#: Columns every sequences file must have, in the order files are written.
SEQUENCE_COLUMNS: tuple[str, ...] = (
    "sequence",
    "observation",
    "x1",
    "y1",
    "x2",
    "y2",
    "cam_x",
    "cam_y",
    "cam_z",
)
#: The camera's orientation, a unit quaternion x, y, z, w (Hamilton, as TUM trajectories):
#: all four or none.
ORIENTATION_COLUMNS: tuple[str, ...] = ("cam_qx", "cam_qy", "cam_qz", "cam_qw")
#: Columns read when present; any other column is ignored.
OPTIONAL_SEQUENCE_COLUMNS: tuple[str, ...] = ("depth", *ORIENTATION_COLUMNS)
