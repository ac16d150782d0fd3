"""DBox's training step captured in a CUDA graph (``train-dbox --cuda-graph``).

At a batch of 512 the network is small for a GPU: a step is a few hundred short kernels,
and the time goes to launching them from Python, not to computing. A CUDA graph records
the step once (forward pass, L1 loss, backward pass, fused Adam) and replays it with one
launch; only the batch (copied into the graph's input) and the learning rate (a tensor on
the device, filled before each replay) change from step to step.

Capturing needs a few steps run first (PyTorch allocates its workspaces and the
optimizer's state in them). Those warm-up steps change the weights and the optimizer's
state, so both are copied before and written back, in place, after: the run continues
from exactly the state it had, as if the warm-up had not happened. The same logic runs
without capture (``capture=False``), which lets the CPU tests check it.

One process, float32 and CUDA only: DDP's gradient hooks and autocast are not captured
here.
"""

from __future__ import annotations

import torch

#: Steps run before the capture (PyTorch's guidance: a few, on a side stream).
WARMUP_STEPS = 3


class GraphedStep:
    """One training step of ``net`` with ``optimizer`` (Adam, fused), replayed from a graph.

    Args:
        net: the module whose output is compared with the target (the model, or its
            precision wrapper).
        optimizer: the run's Adam; its learning rates become tensors on the device and
            it is made capturable.
        x, y: a batch of the shapes every step has (input (B, n, 7), target (B,)); it
            is used for the warm-up only.
        capture: record a CUDA graph (on CUDA); False runs the same step eagerly on the
            static buffers (for tests of the warm-up's undoing).
    """

    def __init__(
        self,
        net: torch.nn.Module,
        optimizer: torch.optim.Optimizer,
        x: torch.Tensor,
        y: torch.Tensor,
        capture: bool,
    ) -> None:
        self.net = net
        self.optimizer = optimizer
        self.x = x.detach().clone()
        self.y = y.detach().clone()
        dev = x.device
        self.lrs = []
        for group in optimizer.param_groups:
            lr = torch.tensor(float(group["lr"]), dtype=torch.float32, device=dev)
            group["lr"] = lr
            group["capturable"] = True
            self.lrs.append(lr)
        params = [p for group in optimizer.param_groups for p in group["params"]]
        kept = [p.detach().clone() for p in params]
        fresh = not optimizer.state
        state = {} if fresh else {p: {k: v.clone() for k, v in optimizer.state[p].items()} for p in params}
        if capture:
            side = torch.cuda.Stream(dev)
            side.wait_stream(torch.cuda.current_stream(dev))
            with torch.cuda.stream(side):
                for _ in range(WARMUP_STEPS):
                    self._step()
            torch.cuda.current_stream(dev).wait_stream(side)
        else:
            for _ in range(WARMUP_STEPS):
                self._step()
        with torch.no_grad():  # the warm-up undone, in place (the graph reads these tensors)
            for p, k in zip(params, kept, strict=True):
                p.copy_(k)
            for p in params:
                for name, value in optimizer.state[p].items():
                    if fresh:
                        value.zero_()  # Adam's initial state: no step, zero moments
                    else:
                        value.copy_(state[p][name])
        optimizer.zero_grad(set_to_none=True)
        self.graph: torch.cuda.CUDAGraph | None = None
        if capture:
            self.graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(self.graph):
                self.loss = self._step(zero=False)

    def _step(self, zero: bool = True) -> torch.Tensor:
        if zero:
            self.optimizer.zero_grad(set_to_none=True)
        loss = (self.net(self.x) - self.y).abs().mean()
        loss.backward()
        self.optimizer.step()
        return loss.detach()

    def step(self, x: torch.Tensor, y: torch.Tensor, lr: float) -> torch.Tensor:
        """Train on (x, y) at learning rate ``lr``; the batch's loss (a tensor, not read)."""
        self.x.copy_(x)
        self.y.copy_(y)
        for t in self.lrs:
            t.fill_(lr)
        if self.graph is None:
            return self._step()
        self.graph.replay()
        return self.loss.clone()  # the next replay overwrites the graph's own


def plain_optimizer_state(optimizer: torch.optim.Optimizer) -> dict[str, object]:
    """``optimizer.state_dict()`` with float learning rates and not capturable (for ``last.pt``).

    A run resumed without ``--cuda-graph`` then gets the usual optimizer back.
    """
    state = optimizer.state_dict()
    for group in state["param_groups"]:
        if isinstance(group.get("lr"), torch.Tensor):
            group["lr"] = float(group["lr"])
        group["capturable"] = False
    return state


__all__ = ["WARMUP_STEPS", "GraphedStep", "plain_optimizer_state"]
