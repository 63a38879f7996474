"""The neural policy: the 376 -> 280 -> 4 network, its weights file, and the planner's Policy.

The network (SPEC section 5, thesis ch. 3.3): one hidden layer of 280 ReLU units with
dropout while training, then 4 outputs (Up, Right, Down, Left) through a softmax;
376*280 + 280 + 280*4 + 4 = 106,684 trainable parameters. One set of weights serves every
drone, and `NeuralPolicy.action_scores` runs one forward pass per step for all the drones
that ask.

Weights file: a torch `state_dict` saved with `torch.save` (about 430 kB). The shipped
one is `missionplan/learn/weights/policy.pt`; `missionplan train` writes the same format.
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import numpy as np
import torch
from torch import nn

from bridge.atomic import atomic_path
from ..grid.world import CoverageWorld
from .features import STATE_SIZE, encode_states

HIDDEN_UNITS = 280
NUM_ACTIONS = 4
DROPOUT = 0.2
SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights" / "policy.pt"


class PolicyNet(nn.Module):
    """376 -> 280 ReLU (dropout) -> 4 logits; softmax is applied by the loss or by `probabilities`."""

    def __init__(self, dropout: float = DROPOUT) -> None:
        super().__init__()
        self.hidden = nn.Linear(STATE_SIZE, HIDDEN_UNITS)
        self.dropout = nn.Dropout(dropout)
        self.output = nn.Linear(HIDDEN_UNITS, NUM_ACTIONS)

    def forward(self, states: torch.Tensor) -> torch.Tensor:
        return self.output(self.dropout(torch.relu(self.hidden(states))))

    def probabilities(self, states: np.ndarray) -> np.ndarray:
        """(n, 4) softmax outputs for a batch of encoded states, in inference mode."""
        self.eval()
        with torch.inference_mode():
            logits = self(torch.from_numpy(np.ascontiguousarray(states, dtype=np.float32)))
            return torch.softmax(logits, dim=1).numpy()


def count_parameters(net: nn.Module) -> int:
    return sum(p.numel() for p in net.parameters() if p.requires_grad)


def save_weights(net: PolicyNet, path: str | Path) -> None:
    """Write the weights atomically (a crash never leaves a truncated file)."""
    with atomic_path(Path(path)) as tmp:
        torch.save(net.state_dict(), tmp)


def load_weights(path: str | Path = SHIPPED_WEIGHTS) -> PolicyNet:
    """A PolicyNet with the weights of `path`; ValueError with one line when the file is not ours."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such weights file")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
        net = PolicyNet()
        net.load_state_dict(state)
    except Exception as error:  # torch raises many kinds; the user needs one line
        raise ValueError(f"{path}: not a missionplan policy weights file ({type(error).__name__})") from None
    net.eval()
    return net


class NeuralPolicy:
    """The planner's Policy backed by the network: scores are log-probabilities."""

    name = "nn"

    def __init__(self, net: PolicyNet | None = None) -> None:
        self.net = net if net is not None else load_weights()
        self.net.eval()
        # A step's batch is a few rows: waking a second thread costs more than the product
        # (measured: Leonardo x 5 plans in 0.47 s on one thread, 1.0 s on two).
        torch.set_num_threads(1)

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        if not drones:
            return np.zeros((0, NUM_ACTIONS))
        probabilities = self.net.probabilities(encode_states(world, drones))
        return np.log(np.maximum(probabilities, 1e-12))
