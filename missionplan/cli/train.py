"""`missionplan train`: reproduce the neural policy's weights by imitation of the expert (learn/training.py),
write them and a training report beside them, and print how well the network agrees with the expert."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from missionplan.base.atomic import probe_writable
from missionplan.bridge.limits import SEED_MAX, check_integer

from ..maps.gridmap import MapError
from .parsing import runs


@dataclass(frozen=True)
class TrainRequest:
    """`train`: the weights file to write, the seed, the number of training maps, DAgger or not, the worker
    processes, and whether to show progress."""

    out: Path
    seed: int
    maps: int | None
    no_dagger: bool
    workers: int
    quiet: bool


def register(sub: Any) -> None:
    """Add `train`."""
    train = sub.add_parser("train", help="train the neural policy by imitation of the expert and write its weights")
    train.add_argument("--out", required=True, type=Path, help="weights file to write (a training report goes beside it, .json)")
    train.add_argument("--seed", type=int, default=0, help="seed of the training maps, the split and the network")
    train.add_argument("--maps", type=int, default=None, help="number of training maps")
    train.add_argument("--no-dagger", action="store_true", help="skip the DAgger rounds")
    train.add_argument("--workers", type=int, default=2, help="processes playing the expert demonstrations")
    train.add_argument("--quiet", action="store_true", help="no progress bars")
    train.set_defaults(handler=runs(TrainRequest, cmd_train))


def cmd_train(request: TrainRequest) -> int:
    import json

    from missionplan.base.atomic import write_text_atomic
    from ..learn.network import save_weights
    from ..learn.training import DEFAULT_MAPS, train_policy

    check_integer(request.seed, "--seed", 0, SEED_MAX, error=MapError)
    if request.maps is not None:
        check_integer(request.maps, "--maps", 4, 100_000, what="a number of training maps", error=MapError)
    check_integer(request.workers, "--workers", 1, 256, what="a number of processes", error=MapError)
    if not request.out.parent.is_dir():
        raise MapError(f"--out {request.out}: folder {request.out.parent} does not exist")
    try:
        probe_writable(request.out.parent)  # before minutes of training, not after
    except OSError as err:
        raise MapError(f"--out {request.out}: cannot write files in {request.out.parent} ({err.strerror})") from None
    net, report = train_policy(seed=request.seed, num_maps=request.maps or DEFAULT_MAPS, dagger=not request.no_dagger,
                               workers=request.workers, progress=not request.quiet and sys.stderr.isatty())
    save_weights(net, request.out)
    report_path = request.out.with_suffix(".json")
    write_text_atomic(report_path, json.dumps(report, indent=1) + "\n")
    final = report["final"]
    print(f"{report['parameters']} parameters; {final['samples']['clean']} samples after augmentation and cleaning "
          f"({final['samples']['raw']} recorded)")
    print(f"accuracy against the expert: train {final['train_accuracy']:.2f} %, validation "
          f"{final['validation_accuracy']:.2f} %, test {final['test_accuracy']:.2f} %")
    print("test confusion (rows: expert up/right/down/left, columns: network):")
    for row in final["test_confusion"]:
        print("  " + " ".join(f"{value:>7}" for value in row))
    print(f"wrote {request.out} and {report_path}")
    return 0
