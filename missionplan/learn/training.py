"""Training the neural policy by imitation of the expert, then DAgger rounds.

`train_policy` is the whole job behind `missionplan train`:

1. demonstrations: the expert covers the training maps alone (missionplan.learn.trainmaps),
   every decision recorded (missionplan.learn.demos);
2. dataset: x8 augmentation, cleaning, 75 / 15 / 10 split (missionplan.learn.dataset);
3. fit: mini-batch Adam on the categorical cross-entropy, early stopping on the
   validation loss (the best epoch's weights are kept);
4. DAgger (beyond the thesis), in DAGGER_ROUNDS rounds: the latest network drives fleets on
   the training maps (one drone per TARGETS_PER_DRONE targets, on balanced zones, so it meets
   zone borders and other drones as when planning) with the expert taking a share of the
   decisions that halves every round; the expert labels every state reached, all pairs so far
   train a fresh network. Every network, the first included, then covers held-out maps (the
   small ones alone, larger cities with a fleet of six); the one with the fewest moves per
   floor ships.

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
from ..grid.planner import Policy
from .dataset import Dataset, Split, build_dataset
from .demos import Demonstrations, collect, play_map
from .features import STATE_SIZE
from .network import HIDDEN_UNITS, NUM_ACTIONS, NeuralPolicy, PolicyWeights
from .trainmaps import heldout_cities, training_maps

DEFAULT_SEED = 0
DEFAULT_MAPS = 100
EVAL_MAPS = 12
HELDOUT_CITIES = 6  # larger cities, covered by a fleet of HELDOUT_FLEET
HELDOUT_FLEET = 6
EVAL_SEED_OFFSET = 1000  # held-out maps come from a different seed than the training maps
BATCH_SIZE = 512
LEARNING_RATE = 2e-3
MAX_EPOCHS = 40
PATIENCE = 4  # epochs without a better validation loss before stopping
DAGGER_EXPERT_SHARE = 0.5  # DAgger's beta in the first round: the expert still takes half of the decisions
DAGGER_ROUNDS = 7  # each round halves the expert's share
DAGGER_MAX_FLEET = 6
TARGETS_PER_DRONE = 400  # a DAgger map gets one drone per this many targets, up to DAGGER_MAX_FLEET
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


def dagger_fleets(maps: list[GridMap]) -> list[int]:
    """Drones per map in the DAgger rounds: one per TARGETS_PER_DRONE targets, 1..DAGGER_MAX_FLEET,
    so the network also meets zone borders and other drones, as it does when planning."""
    return [int(np.clip(gmap.target.sum() // TARGETS_PER_DRONE, 1, DAGGER_MAX_FLEET)) for gmap in maps]


def coverage_moves(maps: list[GridMap], make_policy: Callable[[], Policy],
                   fleets: list[int] | None = None) -> list[float]:
    """MMN / floor of covering each map (lower is better; inf if it failed): one drone each, or `fleets`."""
    fleets = [1] * len(maps) if fleets is None else fleets
    ratios = []
    for gmap, uavs in zip(maps, fleets):
        _, run = play_map(gmap, make_policy(), 0.0, uavs, record=False)
        ratios.append(run.moves / max(run.floor, 1.0) if run.success else float("inf"))
    return ratios


def _accuracy_report(net: PolicyNet, dataset: Dataset) -> dict[str, Any]:
    report: dict[str, Any] = {}
    for name in ("train", "validation", "test"):
        accuracy, confusion = evaluate(net, getattr(dataset, name))
        report[f"{name}_accuracy"] = round(100 * accuracy, 2)
        if name == "test":
            report["test_confusion"] = confusion.tolist()
    return report


def _dagger(maps: list[GridMap], eval_maps: list[GridMap], demos: Demonstrations, first: PolicyNet,
            first_dataset: Dataset, seed: int, workers: int, progress: bool,
            log: Callable[[str], None]) -> tuple[PolicyNet, Dataset, dict[str, Any]]:
    """DAgger rounds: the latest network drives fleets on the training maps, the expert labels every
    state it reaches, all pairs so far train a fresh network. Every network is scored on the held-out
    maps (one drone and fleets); the best one is kept, the first network included."""
    fleets = dagger_fleets(maps)
    cities = heldout_cities(seed + EVAL_SEED_OFFSET, HELDOUT_CITIES)

    def held_out(make_policy: Callable[[], Policy]) -> float:
        moves = (coverage_moves(eval_maps, make_policy)
                 + coverage_moves(cities, make_policy, [HELDOUT_FLEET] * len(cities)))
        return round(float(np.mean(moves)), 3)

    expert_score = held_out(ExpertPolicy)
    weights = to_weights(first)
    best_score = first_score = held_out(lambda: NeuralPolicy(weights))
    best, best_dataset, best_round = first, first_dataset, 0
    log(f"held-out maps, moves / floor: expert {expert_score}, network {best_score}")
    rounds: list[dict[str, Any]] = []
    data = demos
    for round_number in range(1, DAGGER_ROUNDS + 1):
        share = DAGGER_EXPERT_SHARE ** round_number
        began = time.perf_counter()
        extra, _ = collect(maps, weights=weights, workers=workers, expert_share=share, fleets=fleets,
                           progress=progress, desc=f"DAgger round {round_number} (network drives)")
        collect_s = time.perf_counter() - began
        data = Demonstrations.concatenate([data, extra])
        dataset = build_dataset(data.states, data.actions, seed)
        fitted = fit(dataset, seed, progress, desc=f"training (DAgger round {round_number})")
        weights = to_weights(fitted.net)
        score = held_out(lambda: NeuralPolicy(weights))
        log(f"DAgger round {round_number}: {len(extra)} states labelled by the expert in {collect_s:.1f} s "
            f"(expert share {share}); retrained in {fitted.seconds:.1f} s; held-out moves / floor {score}")
        rounds.append({"states": len(extra), "expert_share": share, "collect_s": round(collect_s, 1),
                       "training_s": round(fitted.seconds, 1), "epochs": fitted.epochs,
                       "samples": dataset.stats, "heldout_moves_per_floor": score,
                       **_accuracy_report(fitted.net, dataset)})
        if score < best_score:
            best, best_dataset, best_score, best_round = fitted.net, dataset, score, round_number
    log(f"kept the network of {'DAgger round ' + str(best_round) if best_round else 'the first training'} "
        f"(held-out moves / floor {best_score}, expert {expert_score})")
    summary = {"rounds": rounds, "fleets": {"max": DAGGER_MAX_FLEET, "targets_per_drone": TARGETS_PER_DRONE},
               "heldout_expert_moves_per_floor": expert_score, "heldout_network_moves_per_floor": first_score,
               "kept_round": best_round}
    return best, best_dataset, summary


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
        chosen, chosen_dataset, report["dagger"] = _dagger(maps, eval_maps, demos, first.net, dataset, seed, workers,
                                                           progress, log)
    report["final"] = _accuracy_report(chosen, chosen_dataset)
    report["final"]["samples"] = chosen_dataset.stats
    return to_weights(chosen), report
