"""From recorded demonstrations to the train / validation / test sets (SPEC section 5).

1. Augment x8: each (state, action) pair in its 8 symmetric versions (features.augment).
2. Clean: identical states are merged; a state recorded with different actions keeps its
   most frequent action, and is dropped when two actions tie for most frequent.
3. Split 75 / 15 / 10 by recorded pair, not by row: the 8 symmetric versions of one
   recorded pair always land in the same split, and a state seen more than once goes
   where it was first seen. So no test state, nor a rotation of it, was trained on:
   the test accuracy is a held-out number, not a memory test.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .features import NUM_SYMMETRIES, augment

SPLIT_FRACTIONS = (0.75, 0.15, 0.10)


@dataclass
class Split:
    states: np.ndarray  # (n, 376) int8
    actions: np.ndarray  # (n,) int64

    def __len__(self) -> int:
        return len(self.actions)


@dataclass
class Dataset:
    train: Split
    validation: Split
    test: Split
    stats: dict[str, int] = field(default_factory=dict)


def _row_keys(states: np.ndarray) -> np.ndarray:
    """One opaque, comparable key per row, so np.unique can find identical states fast."""
    rows = np.ascontiguousarray(states, dtype=np.int8)
    return rows.view(np.dtype((np.void, rows.shape[1]))).ravel()


def build_dataset(states: np.ndarray, actions: np.ndarray, seed: int = 0) -> Dataset:
    """Augment, clean and split recorded (state, action) pairs."""
    raw = len(actions)
    aug_states, aug_actions = augment(states.astype(np.int8), actions.astype(np.int64))
    # augment stacks the 8 symmetries as blocks of `raw` rows: row i comes from pair i % raw.
    origin = np.tile(np.arange(raw), NUM_SYMMETRIES)

    _, first, inverse = np.unique(_row_keys(aug_states), return_index=True, return_inverse=True)
    unique = len(first)
    votes = np.zeros((unique, 4), dtype=np.int64)
    np.add.at(votes, (inverse, aug_actions), 1)
    best = votes.max(axis=1)
    label = votes.argmax(axis=1)
    conflicting = (votes > 0).sum(axis=1) > 1
    tied = (votes == best[:, None]).sum(axis=1) > 1
    keep = ~tied

    rng = np.random.default_rng(seed)
    order = rng.permutation(raw)
    split_of_pair = np.empty(raw, dtype=np.int64)
    cut1 = int(round(SPLIT_FRACTIONS[0] * raw))
    cut2 = int(round((SPLIT_FRACTIONS[0] + SPLIT_FRACTIONS[1]) * raw))
    split_of_pair[order[:cut1]], split_of_pair[order[cut1:cut2]], split_of_pair[order[cut2:]] = 0, 1, 2
    split_of_state = split_of_pair[origin[first]]

    kept_states = aug_states[first]
    parts = []
    for which in range(3):
        rows = np.flatnonzero(keep & (split_of_state == which))
        rows = rows[rng.permutation(len(rows))]
        parts.append(Split(kept_states[rows], label[rows]))
    stats = {"raw": raw, "augmented": len(aug_actions), "unique": unique,
             "conflicting": int(conflicting.sum()), "dropped_ties": int(tied.sum()),
             "clean": int(keep.sum()), "train": len(parts[0]), "validation": len(parts[1]), "test": len(parts[2])}
    return Dataset(parts[0], parts[1], parts[2], stats)
