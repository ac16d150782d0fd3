"""The faults of issue 45's battery, each pinned: caps, claims, the site's folder, float options, exits."""

from __future__ import annotations

import gzip
import io
from pathlib import Path

import pytest
from click.testing import CliRunner

from odmd_bench import ValidationError
from odmd_bench.cli.main import cli
from odmd_bench.inputs.source import CHUNK_BYTES, LIMIT_ENV, read_source

HEADER = b"sequence,observation,x1,y1,x2,y2,cam_x,cam_y,cam_z\n"
ONE_ROW = HEADER + b"a,0,1,1,2,2,0,0,0\n"  # refused for its content: one observation


# --- a cap bounds what is read, never what is allocated ---------------------------------

#: The largest legal cap (2**30 MiB, 1 PiB): no machine can allocate it.
LARGEST_CAP = str(2**30)


@pytest.mark.parametrize("how", ["path", "stdin", "gzip"])
def test_the_largest_legal_cap_reads_a_small_sequences_file(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path, how: str
) -> None:
    monkeypatch.setenv(LIMIT_ENV, LARGEST_CAP)
    path = tmp_path / "s.csv"
    path.write_bytes(gzip.compress(ONE_ROW) if how == "gzip" else ONE_ROW)
    source, stdin = ("-", ONE_ROW) if how == "stdin" else (str(path), None)
    args = ["predict", source, "--method", "box-ls", "--image-size", "640", "480", "-o", "-"]
    r = CliRunner().invoke(cli, args, input=stdin)
    assert r.exit_code == 2, r.output
    assert "internal error" not in r.stderr and "sequence with one observation" in r.stderr


def test_the_largest_legal_cap_reads_a_small_original_file(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv(LIMIT_ENV, LARGEST_CAP)
    (tmp_path / "test_normal.pk").write_bytes(b"\x80\x04N.")
    r = CliRunner().invoke(
        cli, ["import", str(tmp_path / "test_normal.pk"), "--data-dir", str(tmp_path / "d")]
    )
    assert r.exit_code == 2 and "internal error" not in r.stderr and "unknown file" in r.stderr


class _Spy(io.RawIOBase):
    """A binary stream of ``size`` bytes that gives at most ``most`` per read and records what is asked."""

    def __init__(self, size: int, most: int) -> None:
        self.left, self.most, self.asked = size, most, []

    def readable(self) -> bool:
        return True

    def read(self, n: int = -1) -> bytes:
        self.asked.append(n)
        got = min(self.left, self.most, n if n >= 0 else self.left)
        self.left -= got
        return b"x" * got


def test_no_read_asks_for_more_than_a_chunk_or_what_is_left_below_the_cap() -> None:
    spy = _Spy(3 * CHUNK_BYTES + 5, most=CHUNK_BYTES // 3)  # short reads, as a pipe gives
    data, _ = read_source(spy, limit=2**50)
    assert len(data) == 3 * CHUNK_BYTES + 5 and max(spy.asked) == CHUNK_BYTES and min(spy.asked) > 0
    spy = _Spy(10 * CHUNK_BYTES, most=CHUNK_BYTES)
    with pytest.raises(ValidationError, match="larger than"):
        read_source(spy, limit=CHUNK_BYTES + 10)
    assert spy.asked == [CHUNK_BYTES, 11]  # the cap plus one byte, and no more


def test_a_regular_file_is_read_whole_in_one_read(tmp_path: Path) -> None:
    path = tmp_path / "big.csv"
    path.write_bytes(b"y" * (2 * CHUNK_BYTES + 3))
    data, _ = read_source(path, limit=2**50)
    assert data == path.read_bytes()
    data, _ = read_source(path, limit=2 * CHUNK_BYTES + 3)  # exactly at the cap: read
    assert len(data) == 2 * CHUNK_BYTES + 3
    with pytest.raises(ValidationError, match="larger than"):
        read_source(path, limit=2 * CHUNK_BYTES + 2)
