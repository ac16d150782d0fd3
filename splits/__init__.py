"""The pinned set manifests and the imported robot sets (installed as ``odmd_bench.splits``)."""
