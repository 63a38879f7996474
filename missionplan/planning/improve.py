"""Anytime improvement of a finished plan (`plan --improve SECONDS`): local search on the zone split in a time budget.

The planner's plan comes first. Each round proposes one change, plans it whole (field_plan's attempt: zones,
paths, the clearance band, flight plans and sorties) and keeps it only when it covers every reachable target
and its objective is lower: the busiest drone's flight time, all its sorties together, for a plan with missions,
else the grid makespan (the busiest drone's moves); at an equal objective, fewer moves in all. So the plan
written is never worse than the planner's, and every candidate keeps the separation and clearance promises,
since it is made by the same stages.

The moves, in a fixed cycle (each a whole re-plan, so a round costs what a plan costs):
- balance: each zone's share of the targets scaled by (the fleet's mean time / its drone's time) ** step: the
  zones balanced on the time the drones fly, not on their cell counts. The step halves when the move is
  refused and starts again at 1 when one is kept;
- shift: a part of the busiest drone's share handed to its least busy neighbouring zone (zones whose target
  cells touch), half the share that would level the two, halving on refusal;
- reseed: the planner with another seed (where the zones' sampling starts, who makes way in a deadlock): a
  plan's makespan moves by a few percent with it (docs/neural-policy.md), and a whole fleet sweeping open
  ground in lanes, whose zones are redrawn block by block, has only this move.

A proposal that repeats one already planned (the same shares to four decimals and the same seed) is refused
without planning. What a round proposes depends only on the seed and on which earlier rounds were kept, so the
same seed and
the same number of rounds give the same plan (`rounds`); the time budget decides how many rounds fit, which
depends on the machine. A round is started only when the last one's duration still fits in what is left.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from functools import cached_property
from typing import Callable

import numpy as np

from missionplan.base.naming import Named

from ..grid.metrics import move_count
from ..mission.plan_improvement import Candidate, PlanImprovement
from .errors import PlanRequestError

MOVES = ("balance", "shift", "reseed")
MAX_BUDGET_S = 86_400.0  # a day: past that a budget is a typo
MIN_STEP = 1.0 / 16  # a balance step or shift fraction halved below this starts again from the top
RESEED_STRIDE = 7919  # another planner seed per reseed round: seed + k * stride, far from the user's next seeds


@dataclass
class Trial:
    """A plan made by one attempt and what the improvement reads of it."""

    plan: object  # field_plan.FieldPlan
    shares: np.ndarray | None  # each zone's share of the targets the plan was made with (None: the planner's own split)
    seed: int

    @cached_property
    def spans(self) -> np.ndarray:
        """drone_spans of the plan, read once: every proposal from this plan reads them."""
        return drone_spans(self.plan)

    def share_vector(self) -> np.ndarray:
        """The shares, the planner's own split read from its zones' sizes."""
        if self.shares is not None:
            return self.shares
        sizes = self.plan.result.zones.sizes().astype(float)  # type: ignore[attr-defined]
        return sizes / max(sizes.sum(), 1.0)


def check_budget(budget_s: float, rounds: int | None) -> None:
    """A budget of 0 to MAX_BUDGET_S seconds and, when given, at least one round."""
    if not (0.0 <= budget_s <= MAX_BUDGET_S):  # also refuses nan
        raise PlanRequestError(Named("{improve} {0:g}: outside 0 to {1:g} s", budget_s, MAX_BUDGET_S))
    if rounds is not None and rounds < 1:
        raise PlanRequestError(Named("{improve_rounds} {0}: at least 1", rounds))


def objective_name(plan: object) -> str:
    """flight_s for a plan with missions, moves for a grid plan (planning/improve.py's docstring)."""
    return "flight_s" if getattr(plan, "plans", None) is not None else "moves"


def drone_spans(plan: object) -> np.ndarray:
    """Each drone's share of the objective: its flight time over all its sorties, or its grid moves."""
    if getattr(plan, "plans", None) is not None:
        return plan.plans.drone_flight_s()  # type: ignore[attr-defined]
    return np.array([move_count(np.asarray(path)) for path in plan.result.run.paths], dtype=float)  # type: ignore[attr-defined]


def score(plan: object, objective: str) -> tuple[float, float] | None:
    """(objective, total) of a plan, lower is better; None when it does not cover every reachable target (or has
    no missions where the first plan had)."""
    if not plan.result.run.success or objective_name(plan) != objective:  # type: ignore[attr-defined]
        return None
    spans = drone_spans(plan)
    return float(spans.max()), float(spans.sum())


def zone_neighbours(zone: np.ndarray) -> list[set[int]]:
    """For each drone, the drones whose zones' target cells touch its own (4-connected)."""
    count = int(zone.max()) + 1 if zone.size else 0
    touching: list[set[int]] = [set() for _ in range(count)]
    for a, b in ((zone[1:, :], zone[:-1, :]), (zone[:, 1:], zone[:, :-1])):
        pairs = (a >= 0) & (b >= 0) & (a != b)
        for i, j in set(zip(a[pairs].tolist(), b[pairs].tolist())):
            touching[i].add(j)
            touching[j].add(i)
    return touching


class ZoneSearch:
    """The cycle of moves and their step sizes (the module docstring)."""

    def __init__(self, seed: int, reseed_only: bool = False) -> None:
        self.seed = seed
        self.moves = ("reseed",) if reseed_only else MOVES
        self.round = 0
        self.balance_step = 1.0
        self.shift_fraction = 0.5
        self.reseeds = 0

    def propose(self, best: Trial) -> tuple[str, np.ndarray | None, int]:
        """(move, shares, planner seed) of the next candidate, from the best plan so far."""
        move = self.moves[self.round % len(self.moves)]
        self.round += 1
        spans = best.spans
        shares = best.share_vector()
        if move == "balance" and spans.min() > 0:
            scaled = shares * (spans.mean() / spans) ** self.balance_step
            return move, scaled / scaled.sum(), best.seed
        if move == "shift":
            busiest = int(np.argmax(spans))
            neighbours = zone_neighbours(best.plan.result.zones.zone)[busiest] or set(range(len(spans))) - {busiest}  # type: ignore[attr-defined]
            if neighbours:
                calmest = min(neighbours, key=lambda d: (spans[d], d))
                gap = (spans[busiest] - spans[calmest]) / max(spans[busiest], 1e-9)
                moved = shares[busiest] * gap * self.shift_fraction
                shifted = shares.copy()
                shifted[busiest] -= moved
                shifted[calmest] += moved
                return move, shifted / shifted.sum(), best.seed
        self.reseeds += 1  # the best plan's shares as they were: its own split stays the planner's (lanes redraw it)
        return "reseed", best.shares, self.seed + self.reseeds * RESEED_STRIDE

    def judged(self, move: str, kept: bool) -> None:
        """Step sizes: back to the top after a kept move, halved after a refused one."""
        if move == "balance":
            self.balance_step = 1.0 if kept or self.balance_step / 2 < MIN_STEP else self.balance_step / 2
        elif move == "shift":
            self.shift_fraction = 0.5 if kept or self.shift_fraction / 2 < MIN_STEP else self.shift_fraction / 2


def improve(first: object, first_shares: np.ndarray | None, attempt: Callable[[np.ndarray | None, int], object],
            budget_s: float, seed: int, rounds: int | None = None,
            clock: Callable[[], float] = time.perf_counter) -> tuple[object, PlanImprovement | None]:
    """The best plan found in `budget_s` seconds (and at most `rounds` candidates) from `first`, and what was tried.
    `attempt(shares, seed)` plans the whole field with those zone shares (None: the planner's own split) and
    planner seed; `first_shares` the shares `first` was made with (None: the planner's own split). A first plan
    that failed is returned as it is, with no record: there is no covering plan to be better than."""
    check_budget(budget_s, rounds)
    began = clock()
    objective = objective_name(first)
    first_score = score(first, objective)
    if first_score is None:
        return first, None
    best = Trial(first, None if first_shares is None else np.asarray(first_shares, dtype=float), seed)
    best_score = first_score
    # A whole fleet sweeping in lanes has its zones redrawn block by block, which shares would switch off.
    run = first.result.run  # type: ignore[attr-defined]
    search = ZoneSearch(seed, reseed_only=first_shares is None and run.lane_drones == len(run.paths))
    candidates: list[Candidate] = []
    tried = {_proposal_key(best.shares, seed)}
    last_round_s = 0.0
    while rounds is None or len(candidates) < rounds:
        started = clock()
        if started - began + last_round_s > budget_s:
            break
        move, new_shares, new_seed = search.propose(best)
        key = _proposal_key(new_shares, new_seed)
        if key in tried:  # the same zones and seed plan the same plan: refused without planning it
            search.judged(move, False)
            continue
        tried.add(key)
        plan = attempt(new_shares, new_seed)
        judged = score(plan, objective)
        kept = judged is not None and judged < best_score
        if kept:
            assert judged is not None
            best, best_score = Trial(plan, new_shares, new_seed), judged
        search.judged(move, kept)
        now = clock()
        last_round_s = now - started
        candidates.append(Candidate(round(now - began, 2), move, None if judged is None else round(judged[0], 1), kept))
    record = PlanImprovement(budget_s, rounds, objective, round(first_score[0], 1), round(best_score[0], 1),
                             round(clock() - began, 2), tuple(candidates))
    return best.plan, record


def _proposal_key(shares: np.ndarray | None, seed: int) -> tuple[bytes | None, int]:
    """What makes two proposals the same plan: the shares to four decimals, and the seed."""
    return (None if shares is None else np.round(shares, 4).tobytes(), seed)

