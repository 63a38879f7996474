"""A drone launched in a walled-in courtyard: covers it, then is parked and costs nothing.

Costs are counted, not timed: once a drone's free region has nothing unexplored left, the
planner must not call find_goal for it again (nor ask the policy), however long the others
take. Regions are 4-connected free cells, as drones fly.
"""

import numpy as np
import pytest
from scipy import ndimage

import missionplan.grid.planner as planner_module
from missionplan.grid.expert import ExpertPolicy
from missionplan.grid.pathfinding import FlightSearch, find_goal
from missionplan.grid.planner import Planner
from missionplan.grid.world import HOVER, CoverageWorld, reachable_targets
from missionplan.grid.zones import split_zones
from missionplan.maps.gridmap import GridMap
from replay_check import replay

ROWS, COLS = 20, 44
COURTYARD = (slice(6, 14), slice(26, 36))  # 8 x 10 target cells behind walls 2 cells thick
SEALED = (slice(6, 14), slice(4, 10))  # a second courtyard that no drone launches in
POCKET_LAUNCH = (9, 30)
STREET_LAUNCHES = [(1, 12), (17, 20)]


def courtyard_city(sealed: bool = False) -> GridMap:
    """Open streets (targets) around a building block with a closed courtyard (targets);
    with `sealed`, a second block whose courtyard nobody can reach."""
    obstacle = np.zeros((ROWS, COLS), dtype=bool)
    obstacle[4:16, 24:38] = True
    obstacle[COURTYARD] = False
    if sealed:
        obstacle[4:16, 2:12] = True
        obstacle[SEALED] = False
    return GridMap("courtyard", obstacle, ~obstacle, [])


def plan(gmap: GridMap, starts: list, monkeypatch: pytest.MonkeyPatch, zone_method: str = "geodesic",
         balance: bool = True):
    """Plan with the expert, counting find_goal calls per drone start cell and whether the courtyard was done."""
    zones = split_zones(reachable_targets(gmap, starts), gmap.free, starts, zone_method, balance=balance)
    world = CoverageWorld(gmap, starts, zones.zone)
    calls: list[tuple[tuple[int, int], bool]] = []  # (start of the search, courtyard already covered)
    real = planner_module.find_goal

    def counting(search, start, *args, **kwargs):
        calls.append((tuple(start), not world.unexplored[COURTYARD].any()))
        return real(search, start, *args, **kwargs)

    monkeypatch.setattr(planner_module, "find_goal", counting)
    planner = Planner(world, ExpertPolicy(), seed=0)
    return world, planner.run(), calls


def in_courtyard(cell) -> bool:
    return COURTYARD[0].start <= cell[0] < COURTYARD[0].stop and COURTYARD[1].start <= cell[1] < COURTYARD[1].stop


def courtyard_done_at(world: CoverageWorld, run) -> int:
    """First step after which every courtyard cell has been photographed (replayed from the paths)."""
    explored = ~world.reachable
    for t in range(run.paths.shape[1]):
        for r, c in run.paths[:, t]:
            explored[max(r - 4, 0): r + 5, max(c - 4, 0): c + 5] = True
        if explored[COURTYARD].all():
            return t
    raise AssertionError("the courtyard was never covered")


def check_parked(world: CoverageWorld, run, calls, pocket: int) -> None:
    done = courtyard_done_at(world, run)
    assert done < run.steps - 10  # the street drones still have work long after: parking matters
    # Not a single goal search for the pocket drone once its courtyard is covered ...
    assert not [start for start, covered in calls if covered and in_courtyard(start)]
    # ... it never moves again, and every later decision of it is "idle".
    assert (run.paths[pocket, done:] == run.paths[pocket, done]).all()
    assert (run.idle_decisions[done:] >= 1).all()
    assert (run.policy_decisions[done:] + run.pathfinder_decisions[done:] <= world.num_drones - 1).all()


def test_a_drone_launched_in_a_courtyard_covers_it_then_parks_for_free(monkeypatch):
    gmap = courtyard_city()
    starts = STREET_LAUNCHES + [POCKET_LAUNCH]
    world, run, calls = plan(gmap, starts, monkeypatch)
    assert run.success, run.failure
    assert run.metrics["coverage"] == pytest.approx(100.0)
    assert world.num_targets == int((~gmap.obstacle).sum())  # the courtyard has a drone: all reachable
    checked = replay({"grid": gmap.rows_text(), "paths": run.paths.tolist()})
    assert checked["problems"] == []
    assert checked["coverage"] == pytest.approx(100.0)
    check_parked(world, run, calls, pocket=2)
    assert any(not in_courtyard(start) for start, _ in calls)  # the street drones still plan paths


def test_a_pocket_drone_and_a_courtyard_nobody_reaches(monkeypatch):
    gmap = courtyard_city(sealed=True)
    starts = [POCKET_LAUNCH] + STREET_LAUNCHES  # the pocket drone first: it comes first every step too
    world, run, calls = plan(gmap, starts, monkeypatch)
    assert run.success, run.failure
    sealed_cells = SEALED[0].stop - SEALED[0].start
    sealed_cells *= SEALED[1].stop - SEALED[1].start
    assert len(world.unreachable_cells) == sealed_cells
    assert run.metrics["coverage"] == pytest.approx(100.0)  # of the reachable targets
    checked = replay({"grid": gmap.rows_text(), "paths": run.paths.tolist()})
    assert checked["problems"] == []
    assert checked["unreachable"] == sealed_cells
    assert checked["coverage"] == pytest.approx(100.0)
    check_parked(world, run, calls, pocket=0)


@pytest.mark.parametrize("pocket_launch, street_launches", [
    (POCKET_LAUNCH, STREET_LAUNCHES),
    ((7, 27), [(1, 40), (17, 40)]),  # every zone straddles the wall: each drone used to wait on the others
])
def test_straight_line_zones_that_straddle_the_courtyard_wall_still_finish(monkeypatch, pocket_launch,
                                                                           street_launches):
    """The thesis's straight-line Voronoi zones (unbalanced) give street cells to the pocket drone
    and courtyard cells to street drones: a drone's zone is done once the part it can fly to is,
    and nobody waits on a drone that can never come."""
    gmap = courtyard_city()
    starts = street_launches + [pocket_launch]
    pocket = len(starts) - 1
    world, run, calls = plan(gmap, starts, monkeypatch, zone_method="euclidean", balance=False)
    zone = split_zones(reachable_targets(gmap, starts), gmap.free, starts, "euclidean").zone
    regions, _ = ndimage.label(gmap.free)
    outside = regions != regions[pocket_launch]
    assert (zone[outside] == pocket).any() and (zone[~outside] != pocket).any()  # both ways across the wall
    assert run.success, run.failure
    assert run.metrics["coverage"] == pytest.approx(100.0)
    check_parked(world, run, calls, pocket=pocket)


@pytest.mark.parametrize("method", ["geodesic", "euclidean"])
def test_balanced_zones_share_each_region_among_the_drones_launched_in_it(method):
    """Balancing with a drone in the courtyard: the courtyard is that drone's alone, and the
    streets are split evenly among the street drones (an equal share of the whole map for the
    pocket drone would leave them uneven)."""
    gmap = courtyard_city()
    starts = STREET_LAUNCHES + [(1, 30), POCKET_LAUNCH]  # three street drones, then the pocket's
    targets = reachable_targets(gmap, starts)
    zones = split_zones(targets, gmap.free, starts, method, balance=True)
    regions, _ = ndimage.label(gmap.free)
    courtyard = regions == regions[POCKET_LAUNCH]
    assert (zones.zone[courtyard & targets] == 3).all() and not (zones.zone[~courtyard] == 3).any()
    street_sizes = np.bincount(zones.zone[targets & ~courtyard], minlength=4)[:3]
    assert street_sizes.max() / street_sizes.min() - 1 <= 0.1, street_sizes
    shares = np.array([0.4, 0.2, 0.2, 0.2])  # shares are renormalised within each region
    weighted = split_zones(targets, gmap.free, starts, method, balance=True, shares=shares)
    assert (weighted.zone[courtyard & targets] == 3).all()
    sizes = np.bincount(weighted.zone[targets & ~courtyard], minlength=4)[:3]
    assert abs(sizes[0] / sizes.sum() - 0.5) <= 0.05, sizes


def test_region_counts_follow_every_photo():
    gmap = courtyard_city(sealed=True)
    starts = STREET_LAUNCHES + [POCKET_LAUNCH]
    zone = split_zones(reachable_targets(gmap, starts), gmap.free, starts, "euclidean").zone
    world = CoverageWorld(gmap, starts, zone)
    assert world.num_regions == 2 and world.drone_region.tolist() == [0, 0, 1]
    rng = np.random.default_rng(1)
    for _ in range(60):
        world.step(rng.integers(HOVER, 4, size=3))
        left = world.unexplored
        for region in range(world.num_regions):
            here = left & (world.region_of == region)
            expected = [int((here & (world.zone_of == k)).sum()) for k in range(3)]
            assert world.region_zone_remaining[region, :3].tolist() == expected
            assert world.region_zone_remaining[region].sum() == here.sum()
        for k in range(3):
            sees = left & (world.region_of == world.drone_region[k])
            if not world.zone_done(k):
                sees &= world.zone_of == k
            assert world.seen_in_region(k) == int(sees.sum())
        assert world.region_done().tolist() == [
            not (left & (world.region_of == world.drone_region[k])).any() for k in range(3)]


def test_find_goal_keeps_to_the_start_region():
    free = np.ones((9, 20), dtype=bool)
    free[:, 8] = False  # a wall from edge to edge: two regions
    search = FlightSearch(free)
    seen = np.zeros_like(free)
    seen[4, 10] = True  # 2 cells away as the crow flies, but on the other side
    assert find_goal(search, (4, 6), seen, []) is None
    seen[0, 0] = True
    # A drone beyond the wall is nearer by Manhattan distance, but can never get to (0, 0).
    rival = np.array([[0, 9]])
    assert find_goal(search, (8, 7), seen, [], rivals=rival, rival_backlog=np.array([0.0])) == (0, 0)
    assert find_goal(search, (8, 7), seen, [], rivals=np.array([[0, 1]]), rival_backlog=np.array([0.0])) is None
