"""Every input read is capped: predict's sequences (path, stdin, gzip) and import's pickles."""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest
from click.testing import CliRunner

from odmd_bench import ImportRefused
from odmd_bench.cli.main import cli
from odmd_bench.data.importer import read_original
from odmd_bench.inputs.source import LIMIT_ENV, MAX_ORIGINAL_BYTES, MAX_SEQUENCES_BYTES, input_limit

HEADER = b"sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z\n"


def _predict(source: str, stdin: bytes | None = None) -> tuple[int, str]:
    args = ["predict", source, "--method", "box-ls", "--image-size", "640", "480", "-o", "-"]
    r = CliRunner().invoke(cli, args, input=stdin)
    return r.exit_code, r.stderr


def test_the_caps_and_their_setting(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(LIMIT_ENV, raising=False)
    assert input_limit(MAX_SEQUENCES_BYTES) == 256 * 2**20 and input_limit(MAX_ORIGINAL_BYTES) == 64 * 2**20
    monkeypatch.setenv(LIMIT_ENV, "0.5")
    assert input_limit(MAX_SEQUENCES_BYTES) == 2**19


@pytest.mark.parametrize("value", ["0", "-1", "nan", "big", "1e300"])
def test_a_bad_setting_is_a_usage_error(monkeypatch: pytest.MonkeyPatch, tmp_path: Path, value: str) -> None:
    monkeypatch.setenv(LIMIT_ENV, value)
    (tmp_path / "s.csv").write_bytes(HEADER)
    code, err = _predict(str(tmp_path / "s.csv"))
    assert code == 2 and f"{LIMIT_ENV} must be a size in MiB" in err and "Traceback" not in err


def test_predict_caps_a_device_stdin_and_a_gzip_bomb(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(LIMIT_ENV, "0.0625")  # 64 KiB: the same code path as the 256 MiB default
    said = f"is larger than 0.0625 MiB, the cap on a sequences file; set {LIMIT_ENV}=SIZE (in MiB)"
    code, err = _predict("/dev/zero")
    assert code == 2 and "the input is larger than" not in err and said in err and "Traceback" not in err
    code, err = _predict("-", stdin=HEADER + b"a,0,1,1,2,2,0,0,0\n" * 5000)
    assert code == 2 and f"the input {said}" in err
    bomb = tmp_path / "bomb.csv.gz"
    bomb.write_bytes(gzip.compress(HEADER + b"\n" * 200_000))  # 200 KB in under 10 KB
    assert bomb.stat().st_size < 10_000
    code, err = _predict(str(bomb))
    assert code == 2 and f"the decompressed file {said}" in err
    monkeypatch.setenv(LIMIT_ENV, "1")  # raised: the same file is read (and refused for its content)
    code, err = _predict(str(bomb))
    assert code == 2 and said.replace("0.0625", "1") not in err and "no rows" in err


def test_import_caps_a_pickle(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(LIMIT_ENV, "0.0625")
    big = tmp_path / "test_normal.pk"
    big.write_bytes(b"\x80\x04" + b"\0" * 70_000)
    said = f"larger than 0.0625 MiB, the cap on an original release file; set {LIMIT_ENV}"
    r = CliRunner().invoke(cli, ["import", str(big), "--data-dir", str(tmp_path / "data")])
    assert r.exit_code == 2 and "Traceback" not in r.stderr and said in r.stderr
    with pytest.raises(ImportRefused, match=said):  # the command refuses a device before reading it
        read_original("/dev/zero")


def test_reported_yaml_is_read_to_its_cap(tmp_path: Path) -> None:
    from odmd_bench import ValidationError
    from odmd_bench.documents import MAX_DOCUMENT_BYTES
    from odmd_bench.leaderboard import read_reported

    (tmp_path / "reported.yaml").write_bytes(b"#" * (100 * MAX_DOCUMENT_BYTES))
    with pytest.raises(ValidationError, match=f"at most {MAX_DOCUMENT_BYTES} are read"):
        read_reported(tmp_path)
