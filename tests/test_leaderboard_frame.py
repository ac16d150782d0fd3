"""The committed leaderboard as data.

The reported table against the paper's LaTeX, and ``odmd_bench.leaderboard.frame``
(pandas, imported lazily).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from conftest import boards_data

from odmd_bench import leaderboard as lb
from odmd_bench.cli.main import cli
from odmd_bench.errors import UsageError, ValidationError

REPO = Path(__file__).resolve().parents[1]
PAPER = REPO.parent / "shared" / "paper" / "depth-from-camera-motion-and-object-detection.tex"


def _latex_table(label: str) -> dict[str, list[str]]:
    """``{row name: [values...]}`` of the paper's table ``label``, as printed."""
    if not PAPER.is_file():
        pytest.skip(f"the paper's LaTeX source is not at {PAPER}")
    tex = PAPER.read_text(encoding="utf-8")
    body = tex[: tex.index(rf"\label{{{label}}}")]
    body = body[body.rindex(r"\begin{tabular}") :]
    rows = {}
    for line in body.splitlines():
        cells = [c.strip() for c in line.split(r"\\")[0].split("&")]
        values = [re.sub(r"\\bf\s*", "", c) for c in cells[-5:]]
        if len(cells) >= 6 and all(re.fullmatch(r"\d+\.\d", v) for v in values):
            name = re.sub(r"\\rowcolor\{rowgray\}|\\cite\{\w+\}|~?\\eqref\{[\w:]+\}", "", cells[0]).strip()
            rows[name] = [*cells[1:-5], *values]
    return rows


def _reported(benchmark: str) -> list[lb.ReportedResult]:
    return [r for r in lb.read_reported(REPO / "leaderboard") if r.benchmark == benchmark]


NAMES = {  # the LaTeX of each method name -> the name in reported.yaml
    r"DBox$_{p}$": "DBox_p",
    r"DBox$_{\text{Abs}}$": "DBox_Abs",
    r"DBox$_p^{1\textrm{M}}$": "DBox_p^1M",
    r"DBox$_p^{100\textrm{K}}$": "DBox_p^100K",
    r"DBox$_{\text{NS}}$": "DBox_NS",
    r"Box$_\text{LS}$": "Box_LS",
    r"DBox$_{p}^z$": "DBox_p^z",
    r"ODN$_{\ell r}$": "ODN_lr",
    r"ODN$_{\ell p}$": "ODN_lp",
    r"ODN$_\ell$": "ODN_l",
    r"DBox$_{\text{NS}}^z$": "DBox_NS^z",
    r"DBox$_{\text{Abs}}^z$": "DBox_Abs^z",
    "VOS-DE": "VOS-DE",
}


@pytest.mark.parametrize(
    ("label", "bench", "source"),
    [("tab:odmd", "odmd-paper", "CVPR 2021, Table 1"), ("tab:odms", "odms-detection", "CVPR 2021, Table 2")],
)
def test_reported_rows_are_the_papers_tables(label: str, bench: str, source: str) -> None:
    table = _latex_table(label)
    rows = _reported(bench)
    assert [r.method for r in rows] == [NAMES[n] for n in table]
    for (latex, cells), r in zip(table.items(), rows, strict=True):
        assert [*r.sets.values(), r.all] == cells[-5:], latex
        assert r.source == source
        if bench == "odms-detection":  # Table 2 names each method's vision input
            assert r.input == cells[0].lower()


def test_reported_inputs_default_to_detection_and_are_checked(tmp_path: Path) -> None:
    item = {
        "method": "X",
        "benchmark": "odmd-paper",
        "split": "test",
        "sets": {"normal": "1", "camera": "2", "object": "3", "robot": "4"},
        "all": "2.5",
        "training_data": "none",
        "source": "somewhere",
    }
    (tmp_path / lb.REPORTED).write_text(yaml.safe_dump([item]))
    assert lb.read_reported(tmp_path)[0].input == "detection"
    (tmp_path / lb.REPORTED).write_text(yaml.safe_dump([item | {"input": "lidar"}]))
    with pytest.raises(ValidationError, match="input must be one of detection, segmentation"):
        lb.read_reported(tmp_path)


def test_reported_yaml_refuses_aliases(tmp_path: Path) -> None:
    (tmp_path / lb.REPORTED).write_text("- &a {method: X}\n- *a\n")
    with pytest.raises(ValidationError, match=r"YAML anchors \(&name\) are not allowed"):
        lb.read_reported(tmp_path)


def test_frame_of_the_committed_leaderboard(
    paper_data_dir: Path, v1_data_dir: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The board built from the committed entries (the views are not committed)."""
    pytest.importorskip("pandas")
    data = boards_data(tmp_path / "data", paper_data_dir, v1_data_dir)
    built = lb.build(REPO / "leaderboard", data, n_resamples=200)
    df = lb.frame(built, reported=True)
    entries = df[~df["reported"]]
    assert set(entries["benchmark"]) <= {b.benchmark for b in lb.BOARDS}
    box = entries[(entries["benchmark"] == "odmd-paper") & (entries["method"] == "box-ls")]
    assert [round(float(box[s].iloc[0]), 2) for s in ("normal", "camera", "object", "robot")] == [
        0.0,
        4.47,
        21.6,
        21.23,
    ]
    odms = df[df["reported"] & (df["benchmark"] == "odms-detection")]
    assert set(odms.loc[odms["input"] == "segmentation", "name"]) == {"ODN_lr", "ODN_lp", "ODN_l", "VOS-DE"}
    assert odms["camera"].isna().all() and not odms["driving"].isna().any()
    assert odms["position"].isna().all()
    assert len(lb.frame(built)) == len(entries)
    # frame(folder) reads what `leaderboard build` wrote there
    lb.write(tmp_path / "views", built, plot=False)
    assert lb.frame(tmp_path / "views", reported=True).equals(df)


def test_frame_without_a_json_file_says_what_to_run(tmp_path: Path) -> None:
    pytest.importorskip("pandas")
    with pytest.raises(UsageError, match="run `odmd-bench leaderboard build`"):
        lb.frame(tmp_path)


def test_frame_outside_a_checkout_names_its_argument_not_a_cli_option(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.chdir(tmp_path)  # no leaderboard/ here or above
    with pytest.raises(UsageError) as e:
        lb.frame()
    assert "--root" not in str(e.value)
    assert str(e.value).endswith(
        "run from the repository or give the folder: frame('path/to/odmd-bench/leaderboard')"
    )
    done = CliRunner().invoke(cli, ["leaderboard", "check"])  # the command line names its option
    assert done.exit_code == 2 and "run from the repository or pass --root" in done.stderr


def test_importing_the_leaderboard_does_not_import_pandas() -> None:
    code = "import sys, odmd_bench.leaderboard; print('pandas' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
