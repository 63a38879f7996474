"""report.json `improve`: what the anytime improvement (`plan --improve SECONDS`, planning/improve.py) tried and kept.

A block of the plan record of its own: the budget, what was measured (the busiest drone's flight time for a
plan with missions, else the grid makespan in moves), the first plan's value and the kept one's, and one entry
per candidate plan, in the order they were judged, with the time it was judged at: the makespan against time.
An older missionplan reading the plan ignores the block; the plan it describes flies as any other.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

JSON = dict[str, Any]

OBJECTIVES = {"flight_s": "busiest drone", "moves": "makespan"}  # objective -> how a summary names it
UNITS = {"flight_s": "s", "moves": "moves"}


@dataclass(frozen=True)
class Candidate:
    """One plan the improvement made and judged: `value` None when it did not cover every reachable target."""

    at_s: float  # seconds since the improvement began, when the candidate was judged
    move: str  # balance, shift or reseed (planning/improve.py)
    value: float | None
    kept: bool

    def to_json(self) -> JSON:
        return {"at_s": self.at_s, "move": self.move, "value": self.value, "kept": self.kept}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> Candidate:
        value = doc.get("value")
        return cls(float(doc["at_s"]), str(doc["move"]), None if value is None else float(value), bool(doc["kept"]))


@dataclass(frozen=True)
class PlanImprovement:
    """report.json `improve`; `rounds` the candidates judged (the cap asked, when one was, in `rounds_asked`)."""

    budget_s: float
    rounds_asked: int | None
    objective: str  # a key of OBJECTIVES
    first: float  # the planner's plan
    kept: float  # the plan written: never more than `first`
    seconds: float  # spent improving
    candidates: tuple[Candidate, ...]

    @property
    def rounds(self) -> int:
        return len(self.candidates)

    @property
    def kept_round(self) -> int:
        """1-based round of the plan written, 0 for the planner's own."""
        kept = [i for i, c in enumerate(self.candidates, 1) if c.kept]
        return kept[-1] if kept else 0

    def to_json(self) -> JSON:
        return {"budget_s": self.budget_s, "rounds_asked": self.rounds_asked, "objective": self.objective,
                "first": self.first, "kept": self.kept, "seconds": self.seconds,
                "candidates": [c.to_json() for c in self.candidates]}

    @classmethod
    def from_json(cls, doc: Mapping[str, Any]) -> PlanImprovement:
        objective = str(doc["objective"])
        if objective not in OBJECTIVES:
            raise ValueError(f"improve objective {objective!r} is none of {', '.join(OBJECTIVES)}")
        asked = doc.get("rounds_asked")
        return cls(float(doc["budget_s"]), None if asked is None else int(asked), objective, float(doc["first"]),
                   float(doc["kept"]), float(doc["seconds"]),
                   tuple(Candidate.from_json(c) for c in doc["candidates"]))

    def summary(self) -> str:
        """`improve: 9 plans in 28.4 s (budget 30 s); busiest drone 812 s -> 774 s (-4.7 %), kept plan 6 (shift)`."""
        unit, name = UNITS[self.objective], OBJECTIVES[self.objective]
        text = (f"improve: {self.rounds} plan{'s' if self.rounds != 1 else ''} in {self.seconds:.1f} s "
                f"(budget {self.budget_s:g} s{'' if self.rounds_asked is None else f', {self.rounds_asked} rounds'}); "
                f"{name} {self.first:.0f} {unit} -> {self.kept:.0f} {unit}")
        if self.first > 0:
            text += f" ({100 * (self.kept / self.first - 1):+.1f} %)"
        round_kept = self.kept_round
        return text + (f", kept plan {round_kept} ({self.candidates[round_kept - 1].move})" if round_kept
                       else ", kept the first plan")
