"""DBox: the network's equations, the input formulations, checkpoints, training."""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from collections import OrderedDict
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")

from odmd_bench_baselines import dbox  # noqa: E402
from odmd_bench_baselines.dbox import kernels as model_module  # noqa: E402
from odmd_bench_baselines.dbox import weights as weights_module  # noqa: E402
from odmd_bench_baselines.dbox.formulations import make_inputs, predict_depth  # noqa: E402
from odmd_bench_baselines.dbox.model import DBox, checkpoint_shapes, reference_forward  # noqa: E402
from odmd_bench_baselines.dbox.recipe import learning_rate  # noqa: E402
from odmd_bench_baselines.dbox.train import CONFIGS, train  # noqa: E402

import odmd_bench  # noqa: E402
from odmd_bench.data.examples import Examples  # noqa: E402
from odmd_bench.errors import DataError, UsageError  # noqa: E402

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(autouse=True)
def _one_thread() -> None:
    torch.set_num_threads(1)


def _sigmoid(z: np.ndarray) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-z))


def numpy_dbox(state: dict[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """The paper's equations for one example at a time, gate by gate, in float64."""
    hs = 128
    w, u, b, v = state["W"], state["U"], state["bias"], state["V"]
    out = []
    for ex in x:
        h = np.zeros(hs)
        c = np.zeros(hs)
        for x_t in ex:
            col = [slice(k * hs, (k + 1) * hs) for k in range(4)]  # i, f, c, o
            i = _sigmoid(x_t @ w[:, col[0]] + h @ u[:, col[0]] + b[col[0]] + c @ v[:, col[0]])
            f = _sigmoid(x_t @ w[:, col[1]] + h @ u[:, col[1]] + b[col[1]] + c @ v[:, col[1]])
            g = np.tanh(x_t @ w[:, col[2]] + h @ u[:, col[2]] + b[col[2]] + c @ v[:, col[2]])
            c = f * c + i * g
            # the output gate's peephole sees the NEW cell
            o = _sigmoid(x_t @ w[:, col[3]] + h @ u[:, col[3]] + b[col[3]] + c @ v[:, col[3]])
            h = o * np.tanh(c)
        d = h
        flat = ex.reshape(-1)
        for k in range(6):
            z = state[f"linears.{k}.weight"] @ np.concatenate([d, flat]) + state[f"linears.{k}.bias"]
            d = np.maximum(z, 0.0)
        out.append(float((state["linears.6.weight"] @ d + state["linears.6.bias"])[0]))
    return np.array(out)


def _random_state(seed: int, scale: float = 0.3) -> dict[str, np.ndarray]:
    rng = np.random.default_rng(seed)
    return {k: rng.normal(0.0, scale / np.sqrt(s[-1]), s) for k, s in checkpoint_shapes().items()}


def _model_from(state: dict[str, np.ndarray], dtype: torch.dtype = torch.float64) -> DBox:
    model = DBox().to(dtype)
    model.load_state_dict({k: torch.from_numpy(v).to(dtype) for k, v in state.items()})
    return model


def _examples(n: int, seed: int, perturbation: str = "both") -> Examples:
    return odmd_bench.generate(n, "odmd", perturbation, seed)


# --- the network ----------------------------------------------------------------------


def test_forward_matches_the_equations_step_by_step() -> None:
    state = _random_state(0, scale=1.5)  # large enough that every gate saturates somewhere
    x = np.random.default_rng(1).normal(0.0, 1.0, (3, 10, 7))
    expected = numpy_dbox(state, x)
    model = _model_from(state)
    with torch.no_grad():
        got = model(torch.from_numpy(x)).numpy()
        ref = reference_forward(model, torch.from_numpy(x)).numpy()
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(ref, expected, rtol=1e-10, atol=1e-12)
    assert np.ptp(expected) > 0.1  # a case where a wrong gate would show


def _grads(
    model: DBox, forward: Callable[[torch.Tensor], torch.Tensor], x: torch.Tensor
) -> tuple[torch.Tensor, dict[str, torch.Tensor]]:
    """Output and parameter gradients of sum(output^2)."""
    model.zero_grad()
    out = forward(x)
    out.square().sum().backward()
    return out.detach(), {k: p.grad.clone() for k, p in model.named_parameters() if p.grad is not None}


def _assert_same_grads(got: dict[str, torch.Tensor], want: dict[str, torch.Tensor], rtol: float) -> None:
    assert set(got) == set(want) == {k for k, _ in DBox().named_parameters()}
    for k, g in want.items():
        scale = float(g.abs().max())  # 0 only where nothing reaches the parameter (U with one step)
        assert float((got[k] - g).abs().max()) <= rtol * scale, (k, float((got[k] - g).abs().max()), scale)


@pytest.mark.parametrize("n_obs", [10, 3, 1])
def test_fast_forward_gradients_match_the_reference(n_obs: int) -> None:
    """The hand-written backward pass against autograd through the original's formulation."""
    model = DBox(n_obs=n_obs, generator=torch.Generator().manual_seed(3)).double()
    x = torch.randn(4, n_obs, 7, dtype=torch.float64, generator=torch.Generator().manual_seed(4))
    out, fast = _grads(model, model, x)
    ref_out, ref = _grads(model, lambda x: reference_forward(model, x), x)
    np.testing.assert_allclose(out.numpy(), ref_out.numpy(), rtol=1e-12)
    _assert_same_grads(fast, ref, rtol=1e-10)


def test_float32_path_matches_the_reference() -> None:
    """The float32 CPU path gives the reference's numbers to float32 rounding.

    Checked forward and backward, with and without gradients.
    """
    model = DBox(generator=torch.Generator().manual_seed(5))
    x = torch.from_numpy(make_inputs(_examples(300, 6), "rel").x)
    out, fast = _grads(model, model, x)
    with torch.no_grad():
        inference = model(x)
    ref_out, ref = _grads(model, lambda x: reference_forward(model, x), x)
    assert torch.equal(inference, out)  # the inference path is the same arithmetic
    assert float((out - ref_out).abs().max()) <= 1e-5 * float(ref_out.abs().max())
    _assert_same_grads(fast, ref, rtol=1e-4)


def test_linear_reads_every_operand_layout() -> None:
    """Blocks and transposes are read correctly, the slow-path layout (a transposed block) included."""
    g = torch.Generator().manual_seed(7)
    big_x = torch.randn(40, 30, generator=g)
    big_xt = torch.randn(30, 50, generator=g)
    big_w = torch.randn(50, 30, generator=g)
    xs = {  # each (40, 20)
        "contiguous": big_x[:, :20].contiguous(),
        "block": big_x[:, :20],
        "transposed": big_x[:, :20].contiguous().t().contiguous().t(),
        "transposed block": big_xt[:20, :40].t(),
    }
    ws = {  # each (8, 20)
        "contiguous": big_w[:8, :20].contiguous(),
        "block": big_w[:8, :20],
        "transposed": big_w[:20, :8].contiguous().t(),
        "transposed block": big_w[:20, :8].t(),
    }
    add = torch.randn(40, 8, generator=g)
    for (xn, x), (wn, w) in [(a, b) for a in xs.items() for b in ws.items()]:
        assert x.shape == (40, 20) and w.shape == (8, 20), (xn, wn)
        want = x @ w.t()
        for got in (model_module._linear(x, w), model_module._linear(x, w, add=add) - add):
            assert float((got - want).abs().max()) < 1e-4, (xn, wn)


def test_the_kernel_rule_never_times_anything(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """Every setting a recorded command had runs the same products; no clock is read to decide.

    A choice made by timing two kernels flipped on a busy machine (issue 38: two of six
    runs of one command trained different weights). Since issue 44 dropped the oneDNN
    kernel, ``ODMD_BENCH_ONEDNN`` unset, ``auto``, ``0`` and ``1`` give the same numbers
    bit for bit, and any other value is refused.
    """
    read_by_model: list[str] = []
    clock = time.perf_counter

    def watched() -> float:
        caller = sys._getframe(1).f_globals.get("__name__", "")
        if caller.startswith(("odmd_bench_baselines.dbox.model", "odmd_bench_baselines.dbox.kernels")):
            read_by_model.append(caller)
        return clock()

    monkeypatch.setattr(time, "perf_counter", watched)
    monkeypatch.delenv("ODMD_BENCH_ONEDNN", raising=False)
    train("p", 2, tmp_path / "run", device="cpu", val_sets=_tiny_val(), batch_size=16, progress=None)
    record = json.loads((tmp_path / "run" / "dbox_p.json").read_text())
    assert record["cpu_kernels"] == "plain"
    model = DBox(generator=torch.Generator().manual_seed(5))
    x = torch.from_numpy(make_inputs(_examples(50, 6), "rel").x)
    with torch.no_grad():
        unset = model(x)
    for setting in ("auto", "0", "1"):
        monkeypatch.setenv("ODMD_BENCH_ONEDNN", setting)
        with torch.no_grad():
            assert torch.equal(model(x), unset), setting
        assert model_module.cpu_kernels() == "plain"
    assert read_by_model == []
    monkeypatch.setenv("ODMD_BENCH_ONEDNN", "fast")
    with pytest.raises(UsageError, match="ODMD_BENCH_ONEDNN='fast'"):
        model(x)
    with pytest.raises(UsageError, match="ODMD_BENCH_ONEDNN='fast'"):
        model_module.cpu_kernels()


def test_an_input_that_needs_a_gradient_gets_it() -> None:
    model = DBox(generator=torch.Generator().manual_seed(8)).double()
    x = torch.randn(3, 10, 7, dtype=torch.float64, generator=torch.Generator().manual_seed(9))
    xa = x.clone().requires_grad_()
    model(xa).sum().backward()
    xb = x.clone().requires_grad_()
    reference_forward(model, xb).sum().backward()
    assert xa.grad is not None and xb.grad is not None
    np.testing.assert_allclose(xa.grad.numpy(), xb.grad.numpy(), rtol=1e-12)


def test_parameter_layout_is_the_original_release() -> None:
    shapes = {k: tuple(v.shape) for k, v in DBox().state_dict().items()}
    assert shapes == checkpoint_shapes()
    assert shapes["linears.0.weight"] == (256, 198)
    assert shapes["linears.5.weight"] == (256, 326)
    assert shapes["linears.6.weight"] == (1, 256)
    assert list(shapes)[:4] == ["W", "U", "bias", "V"]


def test_initial_weights_come_from_the_seed() -> None:
    a = DBox(generator=torch.Generator().manual_seed(5)).state_dict()
    b = DBox(generator=torch.Generator().manual_seed(5)).state_dict()
    c = DBox(generator=torch.Generator().manual_seed(6)).state_dict()
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert not torch.equal(a["U"], c["U"])


# --- input formulations ----------------------------------------------------------------


def _hand_example() -> Examples:
    n_obs = 10
    boxes = np.tile(np.array([0.5, 0.4, 0.1, 0.2]), (1, n_obs, 1)) + 0.01 * np.arange(n_obs)[None, :, None]
    camera = np.zeros((1, n_obs, 3))
    camera[0, :, 2] = np.linspace(-0.3, 0.0, n_obs)  # first position 0.3 m behind
    camera[0, :, 0] = np.linspace(0.4, 0.0, n_obs)  # and 0.4 m to the side: L = 0.5
    return Examples(
        boxes=boxes,
        detected=np.ones((1, n_obs), bool),
        camera=camera,
        depth=np.array([0.8]),
    )


def test_f_rel_inputs_are_increments_of_positions_over_the_first_distance() -> None:
    ex = _hand_example()
    inp = make_inputs(ex, "rel")
    assert inp.x.dtype == np.float32 and inp.x.shape == (1, 10, 7)
    np.testing.assert_allclose(inp.scale, [0.5], rtol=1e-6)
    np.testing.assert_allclose(inp.target, [0.8 / 0.5], rtol=1e-6)
    np.testing.assert_allclose(inp.x[0, :, :4], ex.boxes[0], rtol=1e-6)
    np.testing.assert_array_equal(inp.x[0, 0, 4:], [0.0, 0.0, 0.0])
    step = np.array([-0.4 / 9, 0.0, 0.3 / 9]) / 0.5
    np.testing.assert_allclose(inp.x[0, 1:, 4:], np.tile(step, (9, 1)), rtol=1e-5, atol=1e-7)


def test_f_abs_inputs_are_positions_as_they_are() -> None:
    ex = _hand_example()
    inp = make_inputs(ex, "abs")
    np.testing.assert_allclose(inp.x[0, :, 4:], ex.camera[0], rtol=1e-6)
    np.testing.assert_array_equal(inp.scale, [1.0])
    np.testing.assert_allclose(inp.target, [0.8], rtol=1e-6)


def test_missing_detections_are_filled_with_the_shared_rule() -> None:
    ex = _examples(6, 7)
    detected = ex.detected.copy()
    detected[0, 3] = False
    detected[2, [0, 9]] = False
    boxes = ex.boxes.copy()
    boxes[~detected] = 0.0  # as the original files store a missing detection
    holed = Examples(boxes=boxes, detected=detected, camera=ex.camera, depth=ex.depth)
    filled = Examples(
        boxes=odmd_bench.fill_missing(boxes, detected),
        detected=np.ones_like(detected),
        camera=ex.camera,
        depth=ex.depth,
    )
    np.testing.assert_array_equal(make_inputs(holed).x, make_inputs(filled).x)
    assert make_inputs(holed).x[0, 3, 0] == np.float32(boxes[0, 2, 0])


def test_f_rel_refuses_examples_without_camera_motion() -> None:
    ex = _hand_example()
    still = Examples(boxes=ex.boxes, detected=ex.detected, camera=np.zeros_like(ex.camera), depth=ex.depth)
    with pytest.raises(DataError, match="camera motion"):
        make_inputs(still, "rel")
    with pytest.raises(DataError, match="rel, abs"):
        make_inputs(ex, "relative")


@pytest.mark.parametrize("s", [0.01, 0.37, 4.0, 250.0])
def test_f_rel_prediction_scales_with_the_camera_motion(s: float) -> None:
    ex = _examples(64, 8)
    scaled = Examples(boxes=ex.boxes, detected=ex.detected, camera=ex.camera * s, depth=ex.depth)
    model = DBox(generator=torch.Generator().manual_seed(9))
    cpu = torch.device("cpu")
    base = predict_depth(model, ex, "rel", cpu)
    np.testing.assert_allclose(predict_depth(model, scaled, "rel", cpu), s * base, rtol=2e-5)
    # f_Abs has no such property: its output does not follow the scale.
    absolute = predict_depth(model, ex, "abs", cpu)
    assert not np.allclose(predict_depth(model, scaled, "abs", cpu), s * absolute, rtol=1e-3)


# --- checkpoints -----------------------------------------------------------------------


def _save(obj: object, path: Path) -> Path:
    torch.save(obj, path)
    return path


def test_a_checkpoint_in_the_original_layout_loads_and_runs(tmp_path: Path) -> None:
    state = _random_state(10)
    # The original release saved net.state_dict(): an OrderedDict of float32 tensors.
    ckpt = OrderedDict((k, torch.from_numpy(v).float()) for k, v in state.items())
    path = _save(ckpt, tmp_path / "original_layout.pt")
    ex = _examples(50, 11)
    got = dbox.predict(ex, weights=path)
    inp = make_inputs(ex, "rel")
    expected = (
        numpy_dbox({k: v.double().numpy() for k, v in ckpt.items()}, inp.x.astype(np.float64)) * inp.scale
    )
    assert got.shape == (50,) and got.dtype == np.float64
    np.testing.assert_allclose(got, expected, rtol=1e-4)


def test_predict_batches_give_the_same_numbers(tmp_path: Path) -> None:
    path = _save(
        OrderedDict((k, torch.from_numpy(v).float()) for k, v in _random_state(12).items()), tmp_path / "w.pt"
    )
    ex = _examples(33, 13)
    whole = dbox.predict(ex, weights=path)
    np.testing.assert_allclose(dbox.predict(ex, weights=path, chunk=5), whole, rtol=1e-6)
    np.testing.assert_allclose(dbox.predict(ex.subset(slice(10, 20)), weights=path), whole[10:20], rtol=1e-6)


def test_a_corrupt_file_is_a_clear_error(tmp_path: Path) -> None:
    bad = tmp_path / "bad.pt"
    bad.write_bytes(b"\x00not a checkpoint" * 10)
    with pytest.raises(DataError, match="not a loadable DBox checkpoint"):
        dbox.load_model(bad)
    with pytest.raises(DataError, match="not found"):
        dbox.load_model(tmp_path / "missing.pt")


def test_a_file_that_would_run_code_is_refused(tmp_path: Path) -> None:
    path = _save({"W": Path("/etc/passwd")}, tmp_path / "code.pt")  # not a plain tensor
    with pytest.raises(DataError, match="weights_only"):
        dbox.load_model(path)


def test_wrong_keys_and_shapes_are_named(tmp_path: Path) -> None:
    state = {k: torch.zeros(s) for k, s in checkpoint_shapes().items()}
    del state["V"]
    state["W"] = torch.zeros(14, 512)  # an input_obs = 2 network
    state["extra"] = torch.zeros(1)
    with pytest.raises(DataError) as info:
        dbox.load_model(_save(state, tmp_path / "wrong.pt"))
    text = info.value.render()
    assert "missing keys: V" in text
    assert "W: expected shape (7, 512), got (14, 512)" in text
    assert "unexpected keys: extra" in text
    with pytest.raises(DataError, match="not a DBox state dict"):
        dbox.load_model(_save([1, 2, 3], tmp_path / "list.pt"))
    nan = {k: torch.zeros(s) for k, s in checkpoint_shapes().items()}
    nan["U"][0, 0] = float("nan")
    with pytest.raises(DataError, match="U: contains NaN"):
        dbox.load_model(_save(nan, tmp_path / "nan.pt"))


@pytest.mark.parametrize("name", ["p", "p-z"])
def test_shipped_weights_load_and_record_how_they_were_made(name: str) -> None:
    path = dbox.weights_path(name)
    model, formulation = dbox.load_model(path)
    assert formulation == "rel"
    assert all(v.dtype == torch.float32 for v in model.state_dict().values())
    record = json.loads(path.with_suffix(".json").read_text())
    assert record["config"]["name"] == name
    assert record["command"].startswith("odmd-bench train-dbox")
    assert f"--config {name}" in record["command"]
    assert record["best_step"] <= record["steps_done"] == record["steps"]
    assert record["weights_sha256"] == odmd_bench.file_sha256(path)
    assert path.stat().st_size < 5_000_000


def test_shipped_p_weights_are_the_default_and_estimate_depth() -> None:
    ex = _examples(500, 14, "normal")
    pred = dbox.predict(ex)
    err = np.abs(pred - ex.depth) / ex.depth * 100
    assert np.isfinite(pred).all()
    assert err.mean() < 5.0  # Box_LS is exact here; an untrained network is far off


def test_predict_report_counts_examples_without_any_detection(tmp_path: Path) -> None:
    path = _save({k: torch.from_numpy(v).float() for k, v in _random_state(15).items()}, tmp_path / "w.pt")
    ex = _examples(8, 16)
    detected = ex.detected.copy()
    detected[[1, 5]] = False
    holed = Examples(boxes=ex.boxes, detected=detected, camera=ex.camera, depth=ex.depth)
    depths, counts = dbox.predict_report(holed, weights=path)
    assert (counts["n"], counts["no_detection"]) == (8, 2)
    assert counts["weights_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    np.testing.assert_allclose(depths[[0, 2, 3, 4, 6, 7]], dbox.predict(ex, weights=path)[[0, 2, 3, 4, 6, 7]])


# --- training --------------------------------------------------------------------------


def _tiny_val() -> dict[str, Examples]:
    return {"normal": _examples(64, 100, "normal"), "camera": _examples(64, 101, "camera")}


def test_cosine_schedule_goes_from_1e3_to_the_floor() -> None:
    assert learning_rate(0, 1000, "cosine", 0.01) == pytest.approx(1e-3)
    assert learning_rate(999, 1000, "cosine", 0.01) == pytest.approx(1e-5)
    assert learning_rate(500, 1000, "cosine", 0.01) < learning_rate(400, 1000, "cosine", 0.01)
    assert learning_rate(700, 1000, "constant", 0.01) == 1e-3


def test_a_few_hundred_steps_lower_the_loss(tmp_path: Path) -> None:
    result = train(
        "p", 240, tmp_path / "run", seed=0, device="cpu", val_every=120,
        val_sets=_tiny_val(), batch_size=64, progress=None,
    )  # fmt: skip
    losses = np.array(result.losses)
    assert len(losses) == 240
    assert losses[-40:].mean() < 0.6 * losses[:20].mean()
    assert result.best_scores["all"] < 100.0
    record = json.loads((tmp_path / "run" / "dbox_p.json").read_text())
    assert record["best_step"] == result.best_step
    assert record["val_mean_percent_error"]["all"] == pytest.approx(result.best_scores["all"])
    logged = [json.loads(line) for line in (tmp_path / "run" / "log.jsonl").read_text().splitlines()]
    assert [e["step"] for e in logged] == [120, 240]
    dbox.load_model(result.weights)  # the best weights are a loadable original-layout file


def _weights(path: Path) -> dict[str, torch.Tensor]:
    return torch.load(path, weights_only=True)


def test_training_is_deterministic_and_resumes_exactly(tmp_path: Path) -> None:
    opts = {
        "seed": 3,
        "device": "cpu",
        "val_every": 10,
        "val_sets": _tiny_val(),
        "batch_size": 32,
        "progress": None,
    }
    a = train("p", 30, tmp_path / "a", **opts)  # type: ignore[arg-type]
    b = train("p", 30, tmp_path / "b", **opts)  # type: ignore[arg-type]
    assert a.losses == b.losses
    # Interrupted in step 21 (the state file holds step 20), then resumed to 30.
    with pytest.raises(_Interrupt):
        train("p", 30, tmp_path / "c", on_step=_stop_at(21), **opts)  # type: ignore[arg-type]
    c = train("p", 30, tmp_path / "c", resume=True, **opts)  # type: ignore[arg-type]
    assert c.losses == a.losses[20:]
    wa, wc = _weights(a.weights), _weights(c.weights)
    assert all(torch.equal(wa[k], wc[k]) for k in wa)
    other = train("p", 30, tmp_path / "d", **{**opts, "seed": 4})  # type: ignore[arg-type]
    assert other.losses != a.losses


class _Interrupt(Exception):
    pass


def _stop_at(step: int):  # type: ignore[no-untyped-def]
    def on_step(s: int, loss: float) -> None:
        if s == step:
            raise _Interrupt

    return on_step


def test_a_second_cycle_starts_from_given_weights(tmp_path: Path) -> None:
    opts = {"device": "cpu", "val_every": 5, "val_sets": _tiny_val(), "batch_size": 16, "progress": None}
    first = train("p", 5, tmp_path / "one", **opts)  # type: ignore[arg-type]
    seen: list[float] = []
    second = train(
        "p",
        5,
        tmp_path / "two",
        seed=1,
        lr=1e-4,
        init=first.weights,
        on_step=lambda s, v: seen.append(v),
        **opts,
    )  # type: ignore[arg-type]
    fresh = train("p", 5, tmp_path / "three", seed=1, lr=1e-4, **opts)  # type: ignore[arg-type]
    assert second.losses != fresh.losses  # it did not start from the random init
    record = json.loads((tmp_path / "two" / "dbox_p.json").read_text())
    assert record["init"]["sha256"] == odmd_bench.file_sha256(first.weights)
    assert record["lr"] == 1e-4
    with pytest.raises(UsageError, match="--init weights not found"):
        train("p", 5, tmp_path / "four", init=tmp_path / "nope.pt", **opts)  # type: ignore[arg-type]


def test_training_refuses_to_overwrite_or_resume_the_wrong_run(tmp_path: Path) -> None:
    opts = {"device": "cpu", "val_every": 5, "val_sets": _tiny_val(), "batch_size": 16, "progress": None}
    train("p", 5, tmp_path / "run", **opts)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="--resume"):
        train("p", 5, tmp_path / "run", **opts)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="steps: run has 5, asked for 9"):
        train("p", 9, tmp_path / "run", resume=True, **opts)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="nothing to resume"):
        train("p", 5, tmp_path / "none", resume=True, **opts)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="p, ns, abs, p-z"):
        train("q", 5, tmp_path / "x", **opts)  # type: ignore[arg-type]


def test_each_configuration_selects_on_the_benchmark_its_shipped_weights_name() -> None:
    """Training's own val benchmark per configuration is the one prediction assumes."""
    assert {name: cfg.val_benchmark for name, cfg in CONFIGS.items()} == dbox.VAL_BENCHMARK
    for name in dbox.shipped():
        record = json.loads(dbox.weights_path(name).with_suffix(".json").read_text())
        assert record["val_benchmark"] == dbox.VAL_BENCHMARK[name], name
    for record_path in dbox.WEIGHTS_DIR.glob("selected-on-*/dbox_*.json"):
        record = json.loads(record_path.read_text())
        assert record_path.parent.name == f"selected-on-{record['val_benchmark']}", record_path


def test_the_val_benchmark_changes_the_selection_not_the_training(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--val-benchmark: p-z (ODMS-detection val by default) selected on ODMD val instead.

    The same seed trains the same trajectory whichever val split selects; the records say
    which one did, and a run cannot be resumed with another.
    """
    import odmd_bench_baselines.dbox.train as train_module

    asked: list[str] = []

    def load_split(split: str, benchmark: str, *args: object, **kwargs: object) -> dict[str, Examples]:
        asked.append(benchmark)
        return _tiny_val()

    monkeypatch.setattr(train_module.odmd_bench, "load_split", load_split)
    opts = {"device": "cpu", "val_every": 2, "batch_size": 16, "progress": None}
    own = train("p-z", 4, tmp_path / "own", **opts)  # type: ignore[arg-type]
    odmd = train("p-z", 4, tmp_path / "odmd", val_benchmark="odmd-v1", **opts)  # type: ignore[arg-type]
    assert asked == ["odms-detection", "odmd-v1"]
    assert own.losses == odmd.losses
    record = json.loads((tmp_path / "odmd" / "dbox_p-z.json").read_text())
    assert record["val_benchmark"] == record["config"]["val_benchmark"] == "odmd-v1"
    assert record["config"]["preset"] == "odms"  # still trained on z-only motion
    with pytest.raises(UsageError, match="val_benchmark: run has 'odmd-v1', asked for 'odms-detection'"):
        train("p-z", 4, tmp_path / "odmd", resume=True, **opts)  # type: ignore[arg-type]
    with pytest.raises(UsageError, match="unknown benchmark 'odmd-v9'"):
        train("p-z", 4, tmp_path / "x", val_benchmark="odmd-v9", **opts)  # type: ignore[arg-type]


def test_train_dbox_command(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import odmd_bench_baselines.dbox.train as train_module
    from click.testing import CliRunner

    from odmd_bench.cli.main import cli

    monkeypatch.setattr(train_module.odmd_bench, "load_split", lambda *a, **k: _tiny_val())
    out = tmp_path / "run"
    args = [
        "train-dbox",
        "--config",
        "p",
        "--steps",
        "4",
        "--val-every",
        "2",
        "--out",
        str(out),
        "--threads",
        "1",
    ]
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    assert "best step" in result.output and (out / "dbox_p.pt").is_file()
    assert "val All" in result.output  # the progress line
    record = json.loads((out / "dbox_p.json").read_text())
    assert record["command"] == (
        f"odmd-bench train-dbox --config p --steps 4 --seed 0 --val-every 2 --schedule cosine --lr 0.001 "
        f"--threads 1 --device auto --precision fp32 --out {out}"
    )
    again = CliRunner().invoke(cli, args)
    assert again.exit_code == 2 and "--resume" in again.output
    resumed = CliRunner().invoke(cli, [*args, "--resume"])
    assert resumed.exit_code == 0, resumed.output
    other = tmp_path / "other"
    picked = CliRunner().invoke(cli, [*args[:-4], "--out", str(other), "--val-benchmark", "odmd-paper"])
    assert picked.exit_code == 0, picked.output
    record = json.loads((other / "dbox_p.json").read_text())
    assert record["val_benchmark"] == "odmd-paper" and "--val-benchmark odmd-paper" in record["command"]


@pytest.fixture(scope="module")
def shipped_p_on_paper_test(
    paper_data_dir: Path,
    tmp_path_factory: pytest.TempPathFactory,
    dbox_scores: Callable[..., dict[str, float]],
) -> dict[str, float]:
    """The shipped p weights (the default) on the odmd-paper test sets."""
    return dbox_scores(paper_data_dir, tmp_path_factory.mktemp("dbox"), "odmd-paper", "test")


@pytest.fixture(scope="module")
def shipped_ns_on_paper_test(
    paper_data_dir: Path,
    tmp_path_factory: pytest.TempPathFactory,
    dbox_scores: Callable[..., dict[str, float]],
) -> dict[str, float]:
    """The shipped ns weights (``--config ns``) on the odmd-paper test sets."""
    return dbox_scores(paper_data_dir, tmp_path_factory.mktemp("ns"), "odmd-paper", "test", "--config", "ns")


def _odms_means(data_dir: Path, split: str, config: str, selection: str) -> dict[str, float]:
    """Mean percent error per ODMS-detection set of the shipped ``config`` weights, in Python.

    ``selection="per-set"`` runs each set's own checkpoint (``examples.attrs["set"]``).
    """
    return {
        name: float(
            np.mean(odmd_bench.percent_error(ex.depth, dbox.predict(ex, config=config, selection=selection)))
        )
        for name, ex in odmd_bench.load_split(split, "odms-detection", data_dir).items()
    }


@pytest.mark.usefixtures("dbox_depths_made_once")
def test_shipped_p_z_weights_give_the_odms_numbers_docs_dbox_states(
    paper_data_dir: Path, tmp_path: Path, dbox_scores: Callable[..., dict[str, float]]
) -> None:
    """p-z on the ODMS-detection val sets (its selection sets).

    Run by default on that benchmark through the CLI, and its per-set selection (docs/dbox.md states both).
    """
    scores = dbox_scores(paper_data_dir, tmp_path, "odms-detection", "val")
    stated = {"normal": 12.51, "perturb": 19.53, "robot": 9.68, "driving": 26.99, "all": 17.18}
    # stated to two decimals; the two kernels differ in the last bits, so not compared rounded
    assert set(scores) == set(stated) and all(abs(scores[k] - stated[k]) < 0.0051 for k in stated), scores
    per_set = _odms_means(paper_data_dir, "val", "p-z", "per-set")
    stated = {"normal": 9.81, "perturb": 17.80, "robot": 8.28, "driving": 23.37}
    assert all(abs(per_set[k] - stated[k]) < 0.0051 for k in stated), per_set


@pytest.mark.usefixtures("dbox_depths_made_once")
@pytest.mark.parametrize(
    ("config", "overall", "per_set"),
    [
        (
            "ns-z",
            {"normal": 14.99, "perturb": 27.63, "robot": 15.13, "driving": 39.81},
            {"normal": 8.82, "perturb": 27.63, "robot": 10.28, "driving": 36.61},
        ),
        (
            "abs-z",
            {"normal": 21.24, "perturb": 23.45, "robot": 18.69, "driving": 54.42},
            {"normal": 20.50, "perturb": 22.22, "robot": 16.44, "driving": 53.12},
        ),
    ],
)
def test_shipped_ns_z_and_abs_z_weights_give_the_val_numbers_docs_dbox_states(
    paper_data_dir: Path, config: str, overall: dict[str, float], per_set: dict[str, float]
) -> None:
    """docs/dbox.md's val rows of ns-z and abs-z, both selections (the sets their files were chosen on)."""
    got = {selection: _odms_means(paper_data_dir, "val", config, selection) for selection in dbox.SELECTIONS}
    # stated to two decimals; the two kernels differ in the last bits, so not compared rounded
    assert all(abs(got["overall"][k] - overall[k]) < 0.0051 for k in overall), got["overall"]
    assert all(abs(got["per-set"][k] - per_set[k]) < 0.0051 for k in per_set), got["per-set"]


@pytest.mark.usefixtures("dbox_depths_made_once")
@pytest.mark.parametrize(
    ("config", "stated", "paper_all"),
    [
        ("p-z", {"normal": 10.19, "perturb": 17.91, "robot": 12.95, "driving": 26.30, "all": 16.83}, 17.1),
        ("ns-z", {"normal": 8.78, "perturb": 27.24, "robot": 33.94, "driving": 37.38, "all": 26.84}, 29.3),
        ("abs-z", {"normal": 19.32, "perturb": 22.80, "robot": 19.80, "driving": 54.32, "all": 29.06}, 30.1),
    ],
)
def test_shipped_per_set_z_weights_meet_the_papers_table_2_row_on_test(
    paper_data_dir: Path, config: str, stated: dict[str, float], paper_all: float
) -> None:
    """docs/dbox.md's per-set test rows of the z configurations, at most the paper's Table 2 All."""
    got = _odms_means(paper_data_dir, "test", config, "per-set")
    got["all"] = float(np.mean(list(got.values())))
    assert all(abs(got[k] - stated[k]) < 0.0051 for k in stated), got
    assert got["all"] <= paper_all, got


@pytest.mark.usefixtures("dbox_depths_made_once")
def test_p_z_per_set_misses_the_papers_robot_and_driving_means_in_the_tail_only(paper_data_dir: Path) -> None:
    """docs/dbox.md's comparison with the paper's Detailed ODMS Results (supplementary).

    The shipped per-set p-z files miss the paper's Robot and Driving means (11.45, 24.84),
    but their median is below the paper's on Normal, Perturb and Driving and within 0.11 of
    it on Robot: the gap is a tail of over-estimates (errors above 100 %), most of them on
    examples whose Z_n / L lies below the 5th percentile of the p-z training stream (1.03).
    """
    paper_median = {"normal": 8.17, "perturb": 15.25, "robot": 6.29, "driving": 18.99}
    stated = {  # median, max, examples over 100 %
        "normal": (6.45, 119.58, 3),
        "perturb": (13.38, 271.58, 9),
        "robot": (6.40, 922.55, 36),
        "driving": (17.79, 484.52, 15),
    }
    for name, ex in odmd_bench.load_split("test", "odms-detection", paper_data_dir).items():
        depth = dbox.predict(ex, config="p-z", selection="per-set")
        err = odmd_bench.percent_error(ex.depth, depth)
        median, top, over = stated[name]
        # The stated numbers are the shipped predictions'; predicting again here agrees to
        # float32 rounding, which depends on the kernel (Driving's max: 484.5153 plain,
        # 484.5144 with oneDNN, 484.52 shipped): the max gets a relative tolerance.
        assert abs(float(np.median(err)) - median) < 0.0051, name
        assert abs(float(err.max()) - top) < 1e-4 * top, name
        assert int(np.count_nonzero(err > 100)) == over and np.all(depth[err > 100] > ex.depth[err > 100])
        assert float(np.median(err)) < paper_median[name] + (0.12 if name == "robot" else 0.0), name
        if name == "robot":  # 27 of the 36 lie below the training stream's 5th percentile of Z_n / L
            low = ex.depth / np.linalg.norm(ex.camera[:, 0, :] - ex.camera[:, -1, :], axis=1) < 1.03
            assert int(np.count_nonzero(low & (err > 100))) == 27 and int(np.count_nonzero(low)) == 1247
            assert abs(np.sort(err)[-10:].sum() / err.sum() - 0.124) < 0.001  # the ten largest: 12 %


@pytest.mark.usefixtures("dbox_depths_made_once")
def test_the_p_z_robot_val_tail_is_made_of_sequences_that_start_with_wrong_boxes(
    paper_data_dir: Path,
) -> None:
    """docs/dbox.md's account of the p-z Robot tail, on val.

    The ODMS-detection Robot val examples whose box width halves from one observation to
    the next (boxes of something else at the start) carry the tail.
    """
    ex = odmd_bench.load("val", "robot", "odms-detection", paper_data_dir)
    err = odmd_bench.percent_error(ex.depth, dbox.predict(ex, config="p-z"))
    w = ex.boxes[:, :, 2]
    ratio = w[:, 1:] / w[:, :-1]
    wrong = ratio.min(axis=1) < 0.5
    assert int(wrong.sum()) == 21 and sorted(set(np.argmin(ratio[wrong], axis=1).tolist())) == [0, 1, 2, 3, 4]
    assert abs(float(err[wrong].mean()) - 141.0) < 0.05 and abs(float(err[~wrong].mean()) - 8.1) < 0.05
    assert abs(float(err[wrong].sum() / err.sum()) - 0.17) < 0.005
    assert int(np.count_nonzero(err > 100)) == 9 and bool(np.all(wrong[err > 100]))


def test_p_z_on_odmd_data_runs_the_weights_selected_on_odmd_val(
    paper_data_dir: Path,
    v1_data_dir: Path,
    tmp_path: Path,
    dbox_scores: Callable[..., dict[str, float]],
) -> None:
    """``--config p-z`` on ODMD data runs ``selected-on-odmd-v1/dbox_p-z.pt`` (docs/dbox.md's rows).

    Its selection set, odmd-v1 val, gives the val row of its record; odmd-paper test gives
    the leaderboard's row (pinned to 4 decimals, 5e-4: the two kernels differ in the last
    bits). On ODMS data the same name still runs the ODMS-selected file.
    """
    odmd_file = dbox.WEIGHTS_DIR / "selected-on-odmd-v1" / "dbox_p-z.pt"
    record = json.loads(odmd_file.with_suffix(".json").read_text())
    assert record["val_benchmark"] == "odmd-v1" and record["config"]["name"] == "p-z"
    val = dbox_scores(v1_data_dir, tmp_path / "val", "odmd-v1", "val", "--config", "p-z")
    assert all(abs(val[k] - record["val_mean_percent_error"][k]) < 1e-3 for k in val), val
    stated = {"normal": 13.51, "camera": 14.13, "object": 15.51, "robot": 22.23, "all": 16.35}
    assert all(abs(val[k] - stated[k]) < 0.0051 for k in stated), val
    test = dbox_scores(paper_data_dir, tmp_path / "test", "odmd-paper", "test", "--config", "p-z")
    pinned = {"normal": 13.8802, "camera": 14.1350, "object": 15.5958, "robot": 21.2447, "all": 16.2139}
    assert set(test) == set(pinned) and all(abs(test[k] - pinned[k]) < 5e-4 for k in pinned), test
    # docs/dbox.md's comparison row: the ODMS-selected file on the same sets, by --weights
    odms = dbox_scores(
        paper_data_dir, tmp_path / "odms", "odmd-paper", "test", "--weights", str(dbox.weights_path("p-z"))
    )
    stated = {"normal": 18.96, "camera": 23.19, "object": 20.75, "robot": 26.56, "all": 22.37}
    assert all(abs(odms[k] - stated[k]) < 0.0051 for k in stated), odms
    for benchmark, split, data, weights in (
        ("odmd-paper", "test", paper_data_dir, "selected-on-odmd-v1/dbox_p-z.pt"),
        ("odmd-v1", "val", v1_data_dir, "selected-on-odmd-v1/dbox_p-z.pt"),
        ("odms-detection", "val", paper_data_dir, "dbox_p-z.pt"),
    ):
        ex = odmd_bench.load(split, "robot", benchmark, data)
        assert dbox.provenance(ex, config="p-z")["weights"] == weights, benchmark


def test_p_z_per_set_on_odmd_data_runs_the_files_selected_on_each_odmd_val_set(
    paper_data_dir: Path,
    v1_data_dir: Path,
    tmp_path: Path,
    dbox_scores: Callable[..., dict[str, float]],
) -> None:
    """``--config p-z --selection per-set`` on ODMD data: ``selected-on-odmd-v1/dbox_p-z.<set>.pt``.

    Each file gives on its own set of odmd-v1 val what its record states (the selection);
    odmd-paper test gives the leaderboard's row (docs/dbox.md), pinned to 4 decimals.
    """
    folder = dbox.WEIGHTS_DIR / "selected-on-odmd-v1"
    val = dbox_scores(
        v1_data_dir, tmp_path / "val", "odmd-v1", "val", "--config", "p-z", "--selection", "per-set"
    )
    for name in ("normal", "camera", "object", "robot"):
        record = json.loads((folder / f"dbox_p-z.{name}.json").read_text())
        assert record["selection"] == {"kind": "per-set", "on": name, "run_on": name}, record["selection"]
        assert record["val_benchmark"] == "odmd-v1"
        assert abs(val[name] - record["val_mean_percent_error"][name]) < 1e-3, (name, val)
    stated = {"normal": 13.18, "camera": 12.94, "object": 15.35, "robot": 21.24, "all": 15.68}
    assert all(abs(val[k] - stated[k]) < 0.0051 for k in stated), val
    test = dbox_scores(
        paper_data_dir, tmp_path / "test", "odmd-paper", "test", "--config", "p-z", "--selection", "per-set"
    )
    pinned = {"normal": 13.5033, "camera": 13.2145, "object": 15.3559, "robot": 19.7652, "all": 15.4597}
    assert set(test) == set(pinned) and all(abs(test[k] - pinned[k]) < 5e-4 for k in pinned), test
    assert test["all"] <= 15.6, test  # the paper's DBox_p^z (Table 1), the issue's bound
    # per set it is never worse on val than the one network selected overall (its rule)
    overall = json.loads((folder / "dbox_p-z.json").read_text())["val_mean_percent_error"]
    assert all(val[k] <= overall[k] + 1e-6 for k in stated), (val, overall)


@pytest.mark.parametrize(
    ("config", "stated"),
    [
        ("ns-z", {"normal": 33.68, "camera": 37.34, "object": 44.40, "robot": 58.34, "all": 43.44}),
        ("abs-z", {"normal": 9.64, "camera": 9.67, "object": 10.49, "robot": 18.56, "all": 12.09}),
    ],
)
def test_ns_z_and_abs_z_by_name_on_odmd_data_give_the_rows_docs_dbox_states(
    paper_data_dir: Path,
    tmp_path: Path,
    dbox_scores: Callable[..., dict[str, float]],
    config: str,
    stated: dict[str, float],
) -> None:
    """``--config ns-z`` / ``abs-z`` on ``odmd-paper`` test: docs/dbox.md's rows (ODMS-selected files)."""
    got = dbox_scores(paper_data_dir, tmp_path, "odmd-paper", "test", "--config", config)
    assert set(got) == set(stated)
    assert all(abs(got[k] - stated[k]) < 0.0051 for k in stated), got


def test_shipped_p_weights_give_the_numbers_the_readme_states(
    shipped_p_on_paper_test: dict[str, float],
) -> None:
    """The README and the leaderboard quote these rounded to two decimals (1.78 / 2.56 / 2.60 / 11.47, 4.60).

    Pinned to four decimals with a tolerance of 5e-4: the two kernel paths (oneDNN, plain
    torch) differ by about 1e-5 here, and normal lies 4e-5 above a rounding boundary, so
    comparing rounded values could fail on a CPU whose last bits differ.
    """
    pinned = {"normal": 1.7750, "camera": 2.5641, "object": 2.6039, "robot": 11.4713, "all": 4.6036}
    got = shipped_p_on_paper_test
    assert set(got) == set(pinned)
    assert all(abs(got[k] - pinned[k]) < 5e-4 for k in pinned), got


def test_shipped_ns_weights_give_the_numbers_docs_dbox_states(
    shipped_ns_on_paper_test: dict[str, float], shipped_p_on_paper_test: dict[str, float]
) -> None:
    """docs/dbox.md and the leaderboard: ns on odmd-paper test, 0.32 / 4.06 / 6.05 / 14.68, All 6.28.

    Within 10 % of the paper's DBox_NS (5.8), and the paper's qualitative finding, checked
    against the shipped p on the same sets: ns is better on Normal and worse on both
    perturbed sets.
    """
    got = shipped_ns_on_paper_test
    pinned = {"normal": 0.3217, "camera": 4.0597, "object": 6.0506, "robot": 14.6770, "all": 6.2773}
    assert set(got) == set(pinned) and all(abs(got[k] - pinned[k]) < 5e-4 for k in pinned), got
    assert got["all"] <= 5.8 * 1.1, got
    p = shipped_p_on_paper_test
    assert got["normal"] < p["normal"] and got["camera"] > p["camera"] and got["object"] > p["object"]


def test_shipped_abs_weights_give_the_numbers_docs_dbox_states(
    paper_data_dir: Path,
    tmp_path: Path,
    dbox_scores: Callable[..., dict[str, float]],
    shipped_p_on_paper_test: dict[str, float],
    shipped_ns_on_paper_test: dict[str, float],
) -> None:
    """docs/dbox.md and the leaderboard: abs on odmd-paper test, 1.16 / 2.17 / 1.90 / 14.75, All 4.99.

    Within 10 % of the paper's DBox_Abs (4.55), and the paper's findings against the shipped
    p and ns: abs (f_Abs) is the best of the three on the perturbed sets (camera, object),
    and the worst on Robot.
    """
    got = dbox_scores(paper_data_dir, tmp_path, "odmd-paper", "test", "--config", "abs")
    pinned = {"normal": 1.1564, "camera": 2.1725, "object": 1.8971, "robot": 14.7533, "all": 4.9948}
    assert set(got) == set(pinned) and all(abs(got[k] - pinned[k]) < 5e-4 for k in pinned), got
    assert got["all"] <= 4.55 * 1.1, got
    p = shipped_p_on_paper_test
    assert got["camera"] < p["camera"] and got["object"] < p["object"] and got["robot"] > p["robot"]
    ns = shipped_ns_on_paper_test
    assert got["robot"] > ns["robot"] and got["camera"] < ns["camera"] and got["object"] < ns["object"], (
        got,
        ns,
    )


def test_shipped_p_weights_meet_the_issue_bound(shipped_p_on_paper_test: dict[str, float]) -> None:
    """The paper's DBox_p after 100K iterations: 2.2 / 3.0 / 3.0 / 11.7, All 5.0."""
    bound = {"normal": 2.2, "camera": 3.0, "object": 3.0, "robot": 11.7, "all": 5.0}
    means = shipped_p_on_paper_test
    assert {k: means[k] <= bound[k] for k in bound} == dict.fromkeys(bound, True), means


# --- imports ---------------------------------------------------------------------------


def test_the_package_and_the_evaluator_never_import_torch() -> None:
    code = (
        "import sys; import odmd_bench, odmd_bench.evaluation.scoring, odmd_bench.evaluation.metrics, odmd_bench.cli.main, "
        "odmd_bench_baselines.dbox; assert 'torch' not in sys.modules, 'torch was imported'"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=REPO)


def test_a_new_run_never_replaces_weights_and_a_damaged_state_is_refused(tmp_path: Path) -> None:
    opts = {"device": "cpu", "val_every": 5, "val_sets": _tiny_val(), "batch_size": 16, "progress": None}
    held = tmp_path / "held"
    held.mkdir()
    (held / "dbox_p.pt").write_bytes(b"someone's weights")
    with pytest.raises(UsageError, match=r"already holds weights or a log \(dbox_p.pt\)"):
        train("p", 5, held, **opts)  # type: ignore[arg-type]
    assert (held / "dbox_p.pt").read_bytes() == b"someone's weights"
    with pytest.raises(_Interrupt):
        train("p", 10, tmp_path / "run", on_step=_stop_at(7), **opts)  # type: ignore[arg-type]
    state = tmp_path / "run" / "last.pt"
    good = state.read_bytes()
    for bad in (5, {"settings": [1]}, {**torch.load(state, weights_only=True), "best": "{not json"}):
        torch.save(bad, state)
        with pytest.raises(DataError, match="training state|damaged since it was saved") as info:
            train("p", 10, tmp_path / "run", resume=True, **opts)  # type: ignore[arg-type]
        assert "weights_only` set to `False`" not in info.value.render()
    state.write_bytes(good)
    altered = torch.load(state, weights_only=True)
    altered["model"]["W"][0, 0] += 1e-3  # what one flipped bit in a tensor does: torch loads it
    torch.save(altered, state)
    with pytest.raises(DataError, match="damaged since it was saved"):
        train("p", 10, tmp_path / "run", resume=True, **opts)  # type: ignore[arg-type]
    state.write_bytes(good)
    train("p", 10, tmp_path / "run", resume=True, **opts)  # type: ignore[arg-type]


def test_a_record_cannot_change_the_formulation_of_its_weights(tmp_path: Path) -> None:
    ex = odmd_bench.generate(40, "odmd", "both", rng=5)
    shipped = dbox.predict(ex, config="abs")
    src = dbox.weights_path("abs")
    copy = tmp_path / "dbox_abs.pt"
    copy.write_bytes(src.read_bytes())
    # A copy without its record is still the shipped abs network, known by its hash.
    np.testing.assert_array_equal(dbox.predict(ex, weights=copy), shipped)
    record = json.loads(src.with_suffix(".json").read_text())
    for formulation, words in (
        ("rel", "configuration abs trains formulation abs"),
        ("bogus", "not one of rel, abs"),
    ):
        record["config"]["formulation"] = formulation
        copy.with_suffix(".json").write_text(json.dumps(record))
        with pytest.raises(DataError, match="does not fit its weights") as info:
            dbox.predict(ex, weights=copy)
        assert words in info.value.render()
    record["config"] = {"name": "p", "formulation": "rel"}  # a consistent record of another configuration
    copy.with_suffix(".json").write_text(json.dumps(record))
    with pytest.raises(DataError, match="these are the shipped abs weights, of formulation abs"):
        dbox.predict(ex, weights=copy)
    assert dbox.predict_report(ex, config="abs")[1]["formulation"] == "abs"


@pytest.mark.slow
def test_two_runs_on_a_loaded_machine_train_the_same_weights(tmp_path: Path) -> None:
    """Issue 38's check: one command run twice, each in a fresh process, while other processes keep every core busy.

    With the kernel chosen by timing, two of six such runs trained different weights.
    """
    worker = Path(__file__).with_name("dbox_worker.py")
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(os.cpu_count() or 2)]
    try:
        weights = []
        for name in ("a", "b"):
            out = tmp_path / name
            args = ["train-dbox", "--config", "p", "--steps", "20", "--val-every", "10", "--seed", "3"]
            subprocess.run(
                [sys.executable, str(worker), *args, "--out", str(out)],
                check=True,
                timeout=900,
                capture_output=True,
            )
            weights.append(_weights(out / "dbox_p.pt"))
            assert json.loads((out / "dbox_p.json").read_text())["cpu_kernels"] == "plain"
    finally:
        for p in busy:
            p.kill()
            p.wait()
    assert weights[0].keys() == weights[1].keys()
    assert all(torch.equal(weights[0][k], weights[1][k]) for k in weights[0])


def test_the_shipped_weights_hold_each_checkpoint_once() -> None:
    """Two shipped names for one checkpoint keep one file; the other's record names it."""
    files = sorted(dbox.WEIGHTS_DIR.rglob("*.pt"))
    digests = [(p.parent, hashlib.sha256(p.read_bytes()).hexdigest()) for p in files]
    assert len(set(digests)) == len(digests), "byte-identical weight files in one folder"
    kept_once = [
        r
        for r in dbox.WEIGHTS_DIR.rglob("dbox_*.json")
        if json.loads(r.read_text()).get(weights_module.SAME_AS)
    ]
    assert kept_once  # ns-z's perturb checkpoint is its overall one; abs-z's perturb is its normal one
    for record in kept_once:
        path = record.with_suffix(".pt")
        assert not path.exists() and weights_module.stored_at(path).is_file()
        _, sha = dbox.verify_weights(path, require_record=True)  # checked against its own record
        assert sha == json.loads(record.read_text())["weights_sha256"]
        config = path.name.removeprefix("dbox_").split(".")[0]
        assert path.name.split(".")[1] in dbox.per_set_names(dbox.weights_path(config), config)


def test_a_record_naming_other_bytes_is_refused(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A same_weights_as that names another checkpoint fails its own record's hash."""
    shipped = tmp_path / "weights"
    shutil.copytree(dbox.WEIGHTS_DIR, shipped)
    monkeypatch.setattr(weights_module, "WEIGHTS_DIR", shipped)
    record = shipped / "dbox_ns-z.perturb.json"
    doc = json.loads(record.read_text())
    record.write_text(json.dumps(dict(doc, same_weights_as="dbox_ns-z.robot.pt")))
    with pytest.raises(DataError, match="do not match its record"):
        dbox.verify_weights(shipped / "dbox_ns-z.perturb.pt", require_record=True)
    # outside the shipped folders a record never stands for a missing file
    (tmp_path / "mine.json").write_text(json.dumps({**doc, "same_weights_as": "dbox_ns-z.pt"}))
    with pytest.raises(DataError, match="DBox weights not found"):
        dbox.verify_weights(tmp_path / "mine.pt")


def test_shared_depths_are_the_computed_ones_and_each_content_is_computed_once(
    tmp_path_factory: pytest.TempPathFactory, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``dbox_depths_shared`` (tests/conftest.py) gives what ``predict_depth`` gives, bit for bit.

    Each network, input, formulation and chunk is computed once; met again, it is read back
    from the run's folder; another input is computed, one with the same scale (the same
    camera, other boxes) too; what the real call refuses is refused.
    """
    from conftest import dbox_depths_shared
    from odmd_bench_baselines.dbox import formulations

    ex = _examples(40, 271828)
    nets = [DBox(generator=torch.Generator().manual_seed(s)) for s in (271, 828)]
    cpu = torch.device("cpu")
    cases = [(net, form, chunk) for net in nets for form in ("rel", "abs") for chunk in (4096, 7)]
    want = [predict_depth(net, ex, form, cpu, chunk).tobytes() for net, form, chunk in cases]
    assert len(set(want)) == len(cases)
    real, calls = formulations.predict_depth, []

    def counted(*args: object, **kwargs: object) -> np.ndarray:
        calls.append(args)
        return real(*args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(formulations, "predict_depth", counted)
    with dbox_depths_shared(tmp_path_factory):
        for _ in range(2):
            got = [formulations.predict_depth(net, ex, form, cpu, chunk) for net, form, chunk in cases]
            assert all(g.dtype == np.float64 for g in got) and [g.tobytes() for g in got] == want
        assert len(calls) == len(cases)
        again = formulations.predict_depth(nets[0], _examples(40, 271829), "rel", cpu)
        assert len(calls) == len(cases) + 1 and again.tobytes() != want[0]
        moved = Examples(boxes=ex.boxes * 1.01, detected=ex.detected, camera=ex.camera, depth=ex.depth)
        got = formulations.predict_depth(nets[0], moved, "rel", cpu)
        assert len(calls) == len(cases) + 2 and got.tobytes() == real(nets[0], moved, "rel", cpu).tobytes()
        hand = _hand_example()
        still = Examples(
            boxes=hand.boxes, detected=hand.detected, camera=np.zeros_like(hand.camera), depth=hand.depth
        )
        with pytest.raises(DataError, match="camera motion"):
            formulations.predict_depth(nets[0], still, "rel", cpu)
    assert formulations.predict_depth is counted
