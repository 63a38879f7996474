"""Training the neural policy by imitation of the expert, with an optional DAgger pass.

`train_policy` is the whole job behind `missionplan train`:

1. demonstrations: the expert covers the training maps alone (missionplan.learn.trainmaps),
   every decision recorded (missionplan.learn.demos);
2. dataset: x8 augmentation, cleaning, 75 / 15 / 10 split (missionplan.learn.dataset);
3. fit: mini-batch Adam on the categorical cross-entropy, early stopping on the
   validation loss (the best epoch's weights are kept);
4. DAgger (beyond the thesis): the trained network covers the same maps, the expert labels
   every state the network reaches, the new pairs join the data and the network is trained
   again from scratch. Both networks then cover held-out maps; the DAgger one is kept only
   if it needs fewer moves than the first one.

Everything is seeded, and torch runs single-threaded per process, so the same seed gives
the same weights.

This module owns the torch side of the network: `PolicyNet`, the trainable 376 -> 280 -> 4
module, and `to_weights`, which hands a trained one over as the numpy `PolicyWeights` that
planning runs and `save_weights` writes (missionplan.learn.network). PyTorch is needed here
and nowhere else, so it is an extra: `pip install 'missionplan[train]'`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from tqdm import tqdm

from ..maps.gridmap import GridMap, MapError

try:
    import torch
    from torch import nn
except ModuleNotFoundError as missing:
    if missing.name != "torch":
        raise
    # MapError: the CLI prints it as one line and exits 2, as for any other unusable request.
    raise MapError("training needs PyTorch, which is not installed: pip install 'missionplan[train]'") from None

from ..grid.expert import ExpertPolicy
from ..grid.planner import Planner, Policy
from ..grid.world import CoverageWorld
from .dataset import Dataset, Split, build_dataset
from .demos import Demonstrations, collect
from .features import STATE_SIZE
from .network import HIDDEN_UNITS, NUM_ACTIONS, NeuralPolicy, PolicyWeights
from .trainmaps import training_maps

DEFAULT_SEED = 0
DEFAULT_MAPS = 60
EVAL_MAPS = 12
EVAL_SEED_OFFSET = 1000  # held-out maps come from a different seed than the training maps
BATCH_SIZE = 512
LEARNING_RATE = 2e-3
MAX_EPOCHS = 40
PATIENCE = 4  # epochs without a better validation loss before stopping
DAGGER_EXPERT_SHARE = 0.5  # DAgger's beta: the expert still takes half of the decisions
DROPOUT = 0.2


class PolicyNet(nn.Module):
    """376 -> 280 ReLU (dropout) -> 4 logits; softmax is applied by the loss or by `probabilities`.

    The layer names are the weights file's array names (hidden.weight, ...): see `to_weights`.
    """

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


def to_weights(net: PolicyNet) -> PolicyWeights:
    """The trained network's weights as planning uses and saves them (copies, bit for bit)."""
    return PolicyWeights.from_arrays({name: tensor.detach().cpu().numpy().copy()
                                      for name, tensor in net.state_dict().items()})


@dataclass
class FitResult:
    net: PolicyNet
    epochs: int
    best_epoch: int
    seconds: float
    history: list[dict[str, float]]


def fit(dataset: Dataset, seed: int = DEFAULT_SEED, progress: bool = True,
        max_epochs: int = MAX_EPOCHS, desc: str = "training") -> FitResult:
    """Train a fresh PolicyNet on dataset.train, early-stopping on dataset.validation."""
    torch.manual_seed(seed)
    rng = np.random.default_rng(seed)
    net = PolicyNet()
    optimiser = torch.optim.Adam(net.parameters(), lr=LEARNING_RATE)
    loss_fn = nn.CrossEntropyLoss()
    x_train = torch.from_numpy(dataset.train.states.astype(np.float32))
    y_train = torch.from_numpy(dataset.train.actions.astype(np.int64))
    x_val = torch.from_numpy(dataset.validation.states.astype(np.float32))
    y_val = torch.from_numpy(dataset.validation.actions.astype(np.int64))

    started = time.perf_counter()
    best_loss, best_epoch, best_state = float("inf"), 0, None
    history: list[dict[str, float]] = []
    bar = tqdm(range(1, max_epochs + 1), desc=desc, unit="epoch", disable=not progress, leave=False)
    for epoch in bar:
        net.train()
        order = torch.from_numpy(rng.permutation(len(y_train)))
        total = 0.0
        for begin in range(0, len(order), BATCH_SIZE):
            batch = order[begin: begin + BATCH_SIZE]
            optimiser.zero_grad()
            loss = loss_fn(net(x_train[batch]), y_train[batch])
            loss.backward()
            optimiser.step()
            total += loss.item() * len(batch)
        net.eval()
        with torch.inference_mode():
            val_logits = net(x_val)
            val_loss = float(loss_fn(val_logits, y_val))
            val_acc = float((val_logits.argmax(dim=1) == y_val).float().mean())
        history.append({"epoch": epoch, "train_loss": total / len(order), "val_loss": val_loss, "val_acc": val_acc})
        bar.set_postfix(val_loss=f"{val_loss:.3f}", val_acc=f"{100 * val_acc:.1f}%")
        if val_loss < best_loss:
            best_loss, best_epoch = val_loss, epoch
            best_state = {k: v.clone() for k, v in net.state_dict().items()}
        elif epoch - best_epoch >= PATIENCE:
            break
    bar.close()
    assert best_state is not None
    net.load_state_dict(best_state)
    net.eval()
    return FitResult(net, len(history), best_epoch, time.perf_counter() - started, history)


def evaluate(net: PolicyNet, split: Split) -> tuple[float, np.ndarray]:
    """Accuracy against the expert's labels and the 4 x 4 confusion matrix (row: expert, column: network)."""
    if len(split) == 0:
        return float("nan"), np.zeros((4, 4), dtype=np.int64)
    predicted = net.probabilities(split.states.astype(np.float32)).argmax(axis=1)
    confusion = np.zeros((4, 4), dtype=np.int64)
    np.add.at(confusion, (split.actions, predicted), 1)
    return float((predicted == split.actions).mean()), confusion


def coverage_moves(maps: list[GridMap], make_policy: Callable[[], Policy]) -> list[float]:
    """Moves / floor of single-drone coverage of each map (lower is better; inf if it failed)."""
    ratios = []
    for gmap in maps:
        world = CoverageWorld(gmap, [gmap.launch[0]])
        run = Planner(world, make_policy()).run()
        floor = max(world.num_targets / 9, 1.0)
        ratios.append(float(run.metrics["MMN"]) / floor if run.success else float("inf"))
    return ratios


def _accuracy_report(net: PolicyNet, dataset: Dataset) -> dict[str, Any]:
    report: dict[str, Any] = {}
    for name in ("train", "validation", "test"):
        accuracy, confusion = evaluate(net, getattr(dataset, name))
        report[f"{name}_accuracy"] = round(100 * accuracy, 2)
        if name == "test":
            report["test_confusion"] = confusion.tolist()
    return report


def train_policy(seed: int = DEFAULT_SEED, num_maps: int = DEFAULT_MAPS, dagger: bool = True,
                 workers: int = 2, progress: bool = True,
                 log: Callable[[str], None] = print) -> tuple[PolicyWeights, dict[str, Any]]:
    """The whole training job; returns the weights to ship (`save_weights` writes them) and a JSON-able report."""
    torch.set_num_threads(1)  # repeatable: the same seed gives the same weights on any machine
    maps = training_maps(seed, num_maps)
    eval_maps = training_maps(seed + EVAL_SEED_OFFSET, EVAL_MAPS)

    began = time.perf_counter()
    demos, expert_runs = collect(maps, workers=workers, progress=progress, desc="expert demonstrations")
    demo_seconds = time.perf_counter() - began
    log(f"demonstrations: {len(demos)} pairs from {len(maps)} maps in {demo_seconds:.1f} s")
    dataset = build_dataset(demos.states, demos.actions, seed)
    log(f"dataset: {dataset.stats['augmented']} after x8 augmentation, {dataset.stats['clean']} after cleaning "
        f"({dataset.stats['train']} / {dataset.stats['validation']} / {dataset.stats['test']})")
    first = fit(dataset, seed, progress, desc="training")
    first_report = _accuracy_report(first.net, dataset)
    log(f"trained in {first.seconds:.1f} s ({first.epochs} epochs, best {first.best_epoch}): "
        f"test accuracy {first_report['test_accuracy']:.2f} %")

    report: dict[str, Any] = {
        "seed": seed, "maps": len(maps), "parameters": count_parameters(first.net),
        "samples": dataset.stats, "demonstration_s": round(demo_seconds, 1),
        "training_s": round(first.seconds, 1), "epochs": first.epochs, "best_epoch": first.best_epoch,
        **first_report,
        "expert_moves_per_floor_train_maps": round(float(np.mean([r.moves / max(r.floor, 1) for r in expert_runs])), 3),
    }
    chosen, chosen_dataset = first.net, dataset
    if dagger:
        first_weights = to_weights(first.net)  # the network as it drives (numpy), here and in the workers
        began = time.perf_counter()
        extra, _ = collect(maps, weights=first_weights, workers=workers, expert_share=DAGGER_EXPERT_SHARE,
                           progress=progress, desc="DAgger (network drives)")
        dagger_collect_s = time.perf_counter() - began
        merged = Demonstrations.concatenate([demos, extra])
        dagger_dataset = build_dataset(merged.states, merged.actions, seed)
        second = fit(dagger_dataset, seed, progress, desc="training (DAgger)")
        second_report = _accuracy_report(second.net, dagger_dataset)
        log(f"DAgger: {len(extra)} states labelled by the expert in {dagger_collect_s:.1f} s; "
            f"retrained in {second.seconds:.1f} s, test accuracy {second_report['test_accuracy']:.2f} %")

        expert_eval = coverage_moves(eval_maps, ExpertPolicy)
        second_weights = to_weights(second.net)
        first_eval = coverage_moves(eval_maps, lambda: NeuralPolicy(first_weights))
        second_eval = coverage_moves(eval_maps, lambda: NeuralPolicy(second_weights))
        means = {name: round(float(np.mean(values)), 3) for name, values in
                 (("expert", expert_eval), ("nn", first_eval), ("nn_dagger", second_eval))}
        keep = means["nn_dagger"] < means["nn"]
        log(f"held-out maps, single drone, moves / floor: expert {means['expert']}, network {means['nn']}, "
            f"network after DAgger {means['nn_dagger']} -> {'keep DAgger' if keep else 'keep the first network'}")
        report["dagger"] = {"states": len(extra), "collect_s": round(dagger_collect_s, 1),
                            "training_s": round(second.seconds, 1), "epochs": second.epochs,
                            "samples": dagger_dataset.stats, **second_report,
                            "heldout_moves_per_floor": means, "kept": keep}
        if keep:
            chosen, chosen_dataset = second.net, dagger_dataset
        report["dagger"]["expert_share"] = DAGGER_EXPERT_SHARE
    report["final"] = _accuracy_report(chosen, chosen_dataset)
    report["final"]["samples"] = chosen_dataset.stats
    return to_weights(chosen), report
