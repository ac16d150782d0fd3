"""Strict readers of the KITTI tracking files: labels, camera poses and intrinsics.

Three small text formats (docs/kitti.md#formats):

- a KITTI tracking label file (``label_02/NNNN.txt``): one object per line, 17
  space-separated fields ``frame track_id type truncated occluded alpha x1 y1 x2 y2 h w l
  X Y Z rotation_y``;
- a pose file in the KITTI odometry format (``poses/NNNN.txt``, what ORB-SLAM3 and most
  odometry tools write): one frame per line, the 3x4 camera-to-world matrix ``[R | t]``
  row by row;
- the intrinsics: ORB-SLAM3's camera file (``calib/NNNN.yaml``: ``Camera.fx``, ``fy``,
  ``cx``, ``cy``, ``width``, ``height``) or KITTI's own ``calib/NNNN.txt`` (the projection
  matrix ``P2`` of camera 2).

Every reader is strict: each line is checked (field count, decimal numbers only, no
``nan`` or ``inf``, whole numbers where the format has them, known object types, a
rotation that is a rotation) and every problem of a file is reported at once, located by
file and line, as one :class:`~odmd_bench.errors.ImportRefused` (exit status 2).

Written by hand: pandas' and numpy's text readers take ``nan``, ``inf`` and ``1_0`` as
numbers and stop at the first bad line without its reason; these formats are short lines
of a fixed number of fields, so a located check per line is a few lines of Python and
reads the 21 sequences (65,000 label lines) in well under a second.

Its rooms: :mod:`~odmd_bench.kitti.readers.labels`, :mod:`~odmd_bench.kitti.readers.poses`
and :mod:`~odmd_bench.kitti.readers.camera`, one format each, over
:mod:`~odmd_bench.kitti.readers.text` (a file's text, a located number, the refusal).
Their public names are imported from here.
"""

from odmd_bench.kitti.readers.camera import Camera, read_camera
from odmd_bench.kitti.readers.labels import TYPES, Labels, read_labels
from odmd_bench.kitti.readers.poses import ROTATION_TOLERANCE, read_poses, rotation_problem
from odmd_bench.kitti.readers.text import MAX_FILE_BYTES

__all__ = [
    "MAX_FILE_BYTES",
    "ROTATION_TOLERANCE",
    "TYPES",
    "Camera",
    "Labels",
    "read_camera",
    "read_labels",
    "read_poses",
    "rotation_problem",
]
