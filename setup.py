"""Package discovery only; everything else is in pyproject.toml.

Every package under ``odmd_bench/`` and ``baselines/`` is found from the folders, so a
new module can never be left out of the wheel (``scripts/check_wheel.sh`` checks it).
"""

from setuptools import find_packages, setup

setup(
    packages=[
        *find_packages(include=["odmd_bench", "odmd_bench.*"]),
        "odmd_bench.splits",
        *(
            "odmd_bench_baselines" + p.removeprefix("baselines")
            for p in find_packages(include=["baselines*"])
        ),
    ]
)
