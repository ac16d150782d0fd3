"""odmd-bench: the ODMD benchmark (Griffin and Corso, CVPR 2021) as a package.

Importing the package loads numpy and h5py only; torch is needed by DBox alone.

>>> import odmd_bench
>>> batch = odmd_bench.generate(8, preset="odmd", perturbation="both", rng=0)
>>> batch.boxes.shape
(8, 10, 4)
"""

from odmd_bench.data.config import PRESETS, CameraConfig, GeneratorConfig
from odmd_bench.data.examples import Examples, fill_missing, nearest_detected_index
from odmd_bench.data.generator import GENERATOR_VERSION, generate, stream
from odmd_bench.data.store import ensure_generated, load, load_split
from odmd_bench.errors import (
    ConfigError,
    DataError,
    ImportRefused,
    OdmdError,
    UsageError,
    ValidationError,
)

__version__ = "0.1.0"

__all__ = [
    "GENERATOR_VERSION",
    "PRESETS",
    "CameraConfig",
    "ConfigError",
    "DataError",
    "Examples",
    "GeneratorConfig",
    "ImportRefused",
    "OdmdError",
    "UsageError",
    "ValidationError",
    "__version__",
    "ensure_generated",
    "fill_missing",
    "generate",
    "load",
    "load_split",
    "nearest_detected_index",
    "stream",
]
