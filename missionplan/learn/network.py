"""The neural policy: the 376 -> 280 -> 4 network, its weights file, and the planner's Policy.

The network (SPEC section 5, thesis ch. 3.3): one hidden layer of 280 ReLU units (with
dropout while training), then 4 outputs (Up, Right, Down, Left) through a softmax;
376*280 + 280 + 280*4 + 4 = 106,684 trainable parameters. One set of weights serves every
drone, and `NeuralPolicy.action_scores` runs one forward pass per step for all the drones
that ask: one matrix product per layer, in numpy. Planning and flying therefore need no
PyTorch; only training does (missionplan.learn.training builds and fits the same network
in torch and hands its weights over as `PolicyWeights`).

Weights file: an uncompressed numpy `.npz` archive of the four float32 arrays under torch's
`state_dict` names: `hidden.weight` (280, 376), `hidden.bias` (280,), `output.weight` (4, 280),
`output.bias` (4,) (about 430 kB). It is read with `allow_pickle=False`, so a weights file
cannot run code. The shipped one is `missionplan/learn/weights/policy.npz`;
`missionplan train` writes the same format whatever the file is named.
"""

from __future__ import annotations

import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from missionplan.base.atomic import atomic_path
from ..grid.world import CoverageWorld
from .features import STATE_SIZE, encode_states

HIDDEN_UNITS = 280
NUM_ACTIONS = 4
SHIPPED_WEIGHTS = Path(__file__).resolve().parent / "weights" / "policy.npz"
# The arrays of a weights file, by name (torch's state_dict keys), and their shapes.
WEIGHT_SHAPES: dict[str, tuple[int, ...]] = {
    "hidden.weight": (HIDDEN_UNITS, STATE_SIZE),
    "hidden.bias": (HIDDEN_UNITS,),
    "output.weight": (NUM_ACTIONS, HIDDEN_UNITS),
    "output.bias": (NUM_ACTIONS,),
}


@dataclass(frozen=True, eq=False)  # eq: arrays have no single truth value; compare .arrays() instead
class PolicyWeights:
    """The network's four float32 arrays, in torch's layout (a layer's weight is (outputs, inputs))."""

    hidden_weight: np.ndarray
    hidden_bias: np.ndarray
    output_weight: np.ndarray
    output_bias: np.ndarray
    # Contiguous (inputs, outputs) copies for x @ W: a few times faster than x @ W.T for the
    # 1-10 rows of a planning step (measured: 5 rows, 18 us against 77 us for the first layer).
    _hidden_t: np.ndarray = field(init=False, repr=False, compare=False)
    _output_t: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "_hidden_t", np.ascontiguousarray(self.hidden_weight.T))
        object.__setattr__(self, "_output_t", np.ascontiguousarray(self.output_weight.T))

    @staticmethod
    def from_arrays(arrays: dict[str, np.ndarray]) -> "PolicyWeights":
        """From arrays named as in a weights file (or a torch state_dict turned to numpy); checks every shape."""
        if set(arrays) != set(WEIGHT_SHAPES):
            raise ValueError(f"expected exactly the arrays {', '.join(WEIGHT_SHAPES)}")
        checked = {}
        for name, shape in WEIGHT_SHAPES.items():
            array = np.asarray(arrays[name])
            if array.shape != shape or not np.issubdtype(array.dtype, np.floating):
                raise ValueError(f"{name} is {array.dtype} {array.shape}, expected floats {shape}")
            if not np.all(np.isfinite(array)):
                raise ValueError(f"{name} holds a NaN or an infinity")
            checked[name] = np.ascontiguousarray(array, dtype=np.float32)
        return PolicyWeights(checked["hidden.weight"], checked["hidden.bias"],
                             checked["output.weight"], checked["output.bias"])

    def arrays(self) -> dict[str, np.ndarray]:
        """The arrays by their file names."""
        return {"hidden.weight": self.hidden_weight, "hidden.bias": self.hidden_bias,
                "output.weight": self.output_weight, "output.bias": self.output_bias}

    def parameter_count(self) -> int:
        return sum(array.size for array in self.arrays().values())

    def probabilities(self, states: np.ndarray) -> np.ndarray:
        """(n, 4) softmax outputs for a batch of encoded states: ReLU(x W1ᵀ + b1) W2ᵀ + b2, then softmax.

        float32 throughout, as torch computes it, so the shipped network decides as it did in torch.
        """
        x = np.asarray(states, dtype=np.float32)
        hidden = np.maximum(x @ self._hidden_t + self.hidden_bias, np.float32(0))
        logits = hidden @ self._output_t + self.output_bias
        exp = np.exp(logits - logits.max(axis=1, keepdims=True))  # shifted: no overflow, same softmax
        return exp / exp.sum(axis=1, keepdims=True)


def save_weights(weights: PolicyWeights, path: str | Path) -> None:
    """Write the weights atomically (a crash never leaves a truncated file)."""
    with atomic_path(Path(path)) as tmp, open(tmp, "wb") as handle:
        # A file object, not a name: np.savez would append ".npz" to a name that lacks it.
        np.savez(handle, **weights.arrays())


def load_weights(path: str | Path = SHIPPED_WEIGHTS) -> PolicyWeights:
    """The weights of `path`; ValueError with one line when the file is missing or not ours."""
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: no such weights file")
    try:
        if not zipfile.is_zipfile(path):
            raise ValueError("not an .npz archive")
        with np.load(path, allow_pickle=False) as archive:
            return PolicyWeights.from_arrays({name: archive[name] for name in archive.files})
    except Exception as error:  # numpy and zipfile raise many kinds; the user needs one line
        reason = str(error).splitlines()[0] if str(error) else type(error).__name__
        raise ValueError(f"{path}: not a missionplan policy weights file ({reason})") from None


class NeuralPolicy:
    """The planner's Policy backed by the network: scores are log-probabilities."""

    name = "nn"

    def __init__(self, weights: PolicyWeights | None = None) -> None:
        self.weights = weights if weights is not None else load_weights()

    def action_scores(self, world: CoverageWorld, drones: Sequence[int]) -> np.ndarray:
        if not drones:
            return np.zeros((0, NUM_ACTIONS))
        probabilities = self.weights.probabilities(encode_states(world, drones))
        return np.log(np.maximum(probabilities, 1e-12))
