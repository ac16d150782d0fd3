"""Click commands, one module per area; :mod:`odmd_bench.cli` adds them to the group.

Each module lists its commands in ``COMMANDS`` and imports heavy modules (torch,
matplotlib) inside the command functions only.
"""
