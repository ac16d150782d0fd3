"""KITTI tracking as an ODMD benchmark: strict readers, the window rules, the sets and their import.

``odmd-bench import kitti-tracking`` reads KITTI tracking labels, a pose file per sequence
and the intrinsics (:mod:`~odmd_bench.kitti.readers`), cuts each static object's track
into windows by fixed, versioned rules (:mod:`~odmd_bench.kitti.windows`) and makes them
examples the way ``odmd-bench predict`` makes a turning camera's (:mod:`~odmd_bench.kitti.sets`).
The sets this gives from ``../shared/kitti-tracking`` are pinned in
``splits/kitti-tracking.json`` and shipped in ``splits/kitti-tracking/`` (docs/kitti.md).

This part sits above :mod:`odmd_bench.predict` (layer 5, docs/development.md): it reuses
predict's orientation functions; only the command line imports it.
"""
