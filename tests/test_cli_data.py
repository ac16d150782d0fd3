from __future__ import annotations

import json

from click.testing import CliRunner

from odmd_bench.cli.main import cli


def test_generate_writes_and_then_reuses(tmp_path) -> None:
    runner = CliRunner()
    r = runner.invoke(cli, ["generate", "--split", "val", "--out", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "written" in r.stdout and str(tmp_path / "odmd-v1" / "val.h5") in r.stdout
    r = runner.invoke(cli, ["generate", "--split", "val", "--data-dir", str(tmp_path)])
    assert r.exit_code == 0 and "reused" in r.stdout


def test_info_shows_sets(tmp_path) -> None:
    runner = CliRunner()
    runner.invoke(cli, ["generate", "--split", "val", "--out", str(tmp_path)])
    r = runner.invoke(cli, ["info", str(tmp_path / "odmd-v1" / "val.h5")])
    assert r.exit_code == 0
    assert "set robot: 2400 examples x 10 observations" in r.stdout
    r = runner.invoke(cli, ["info", "--json", str(tmp_path / "odmd-v1" / "val.h5")])
    assert set(json.loads(r.stdout)["sets"]) == {"normal", "camera", "object", "robot"}


def test_info_of_a_non_hdf5_file_exits_2(tmp_path) -> None:
    p = tmp_path / "x.h5"
    p.write_text("hello")
    r = CliRunner().invoke(cli, ["info", str(p)])
    assert r.exit_code == 2 and "not a readable HDF5 file" in r.stderr
    assert "Traceback" not in r.output


def test_import_refusal_exits_2(tmp_path) -> None:
    (tmp_path / "test_normal.pk").write_bytes(b"junk")
    r = CliRunner().invoke(cli, ["import", str(tmp_path), "--data-dir", str(tmp_path / "d")])
    assert r.exit_code == 2 and "unknown file" in r.stderr


def test_import_of_the_release(original_release, tmp_path) -> None:
    r = CliRunner().invoke(cli, ["import", str(original_release), "--data-dir", str(tmp_path)])
    assert r.exit_code == 0, r.output
    assert "odmd-paper test" in r.stdout and "odms-detection val" in r.stdout


def test_unknown_benchmark_is_a_usage_error() -> None:
    r = CliRunner().invoke(cli, ["generate", "--benchmark", "odmd-paper"])
    assert r.exit_code == 2


def test_info_of_another_programs_hdf5_file_says_so(tmp_path) -> None:
    import h5py
    import numpy as np

    p = tmp_path / "theirs.h5"
    with h5py.File(p, "w") as f:
        f["x"] = np.arange(3)
    for args in (["info", str(p)], ["info", "--stats", str(p)]):
        r = CliRunner().invoke(cli, args)
        assert r.exit_code == 2 and "not one odmd-bench writes" in r.stderr and "delete it" not in r.stderr
