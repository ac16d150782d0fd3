"""The benchmark's baseline methods, installed as ``odmd_bench_baselines``.

One module per method, each with ``predict`` and ``predict_report``, registered under
the entry-point group ``odmd_bench.methods`` in ``pyproject.toml``, which is how
``odmd-bench baseline NAME`` finds them (:mod:`odmd_bench.methods`). They use only the
public API of ``odmd_bench``, as a third-party method would.
"""
