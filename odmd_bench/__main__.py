"""``python -m odmd_bench``: the ``odmd-bench`` command line."""

from odmd_bench.cli.main import main

if __name__ == "__main__":
    main()
