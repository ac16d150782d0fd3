"""odmd-bench: the ODMD benchmark (Griffin and Corso, CVPR 2021) as a package.

Importing the package loads numpy and h5py only; torch is needed by DBox alone.

>>> import odmd_bench
>>> batch = odmd_bench.generate(8, preset="odmd", perturbation="both", rng=0)
>>> batch.boxes.shape
(8, 10, 4)
"""

# First: a Ctrl-C while the command line imports ends it quietly (see the module).
from odmd_bench import _interrupt as _interrupt
from odmd_bench._version import __version__
from odmd_bench.data.config import PRESETS, CameraConfig, GeneratorConfig
from odmd_bench.data.describe import describe
from odmd_bench.data.examples import Examples, fill_missing, nearest_detected_index
from odmd_bench.data.generator import GENERATOR_VERSION, generate, stream
from odmd_bench.data.hashing import file_sha256
from odmd_bench.data.manifests import known_originals
from odmd_bench.data.registry import BENCHMARKS, Benchmark, get_benchmark
from odmd_bench.data.scale import implied_depth
from odmd_bench.data.store import ensure_generated, load, load_split
from odmd_bench.errors import (
    ConfigError,
    DataError,
    DepthRangeError,
    ImportRefused,
    MethodError,
    MissingDataError,
    OdmdError,
    StorageError,
    UsageError,
    ValidationError,
)
from odmd_bench.evaluation.arrays import score_depths as score
from odmd_bench.evaluation.metrics import absolute_error, all_sets_mean, percent_error
from odmd_bench.evaluation.parse import ParsedPredictions, parse_predictions
from odmd_bench.evaluation.predictions import write_predictions
from odmd_bench.evaluation.result import EvaluationResult
from odmd_bench.evaluation.scoring import evaluate
from odmd_bench.inputs.bounds import MAX_ABS_DEPTH, MAX_ABS_WEIGHT
from odmd_bench.outputs import atomic_path, atomic_write
from odmd_bench.predict import predict_sequences
from odmd_bench.predict.orientation import carry_boxes
from odmd_bench.predict.sequences import read_sequences

__all__ = [
    "BENCHMARKS",
    "GENERATOR_VERSION",
    "MAX_ABS_DEPTH",
    "MAX_ABS_WEIGHT",
    "PRESETS",
    "Benchmark",
    "CameraConfig",
    "ConfigError",
    "DataError",
    "DepthRangeError",
    "EvaluationResult",
    "Examples",
    "GeneratorConfig",
    "ImportRefused",
    "MethodError",
    "MissingDataError",
    "OdmdError",
    "StorageError",
    "ParsedPredictions",
    "UsageError",
    "ValidationError",
    "__version__",
    "absolute_error",
    "atomic_path",
    "atomic_write",
    "all_sets_mean",
    "carry_boxes",
    "describe",
    "ensure_generated",
    "evaluate",
    "file_sha256",
    "fill_missing",
    "generate",
    "get_benchmark",
    "implied_depth",
    "known_originals",
    "load",
    "load_split",
    "nearest_detected_index",
    "parse_predictions",
    "percent_error",
    "predict_sequences",
    "read_sequences",
    "score",
    "stream",
    "write_predictions",
]
