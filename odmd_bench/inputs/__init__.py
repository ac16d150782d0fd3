"""Strict input reading, shared by data, evaluation and predict.

:mod:`~odmd_bench.inputs.source` reads a file's bytes (a path, bytes, a binary file or
stdin; gzip or not; capped); :mod:`~odmd_bench.inputs.records` decodes them and yields
CSV records located by line (and the number pattern every reader takes);
:mod:`~odmd_bench.inputs.table` reads a large clean file's columns at once (pandas' C
parser, numbers correctly rounded); :mod:`~odmd_bench.inputs.problems` collects what is wrong,
by kind, counted and located, into one error. Nothing here knows a benchmark or a
format's meaning beyond the column names of :mod:`~odmd_bench.inputs.formats`.
"""
