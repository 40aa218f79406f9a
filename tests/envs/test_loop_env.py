"""The closed-loop environment (warerover_phys.envs.loop): PettingZoo's API test, the same
episode as ``warerover run`` when a step planner drives it, rules of a joint move."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("gymnasium")
pytest.importorskip("pettingzoo")

from hypothesis import given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402
from pettingzoo.test import parallel_api_test  # noqa: E402

from warerover_phys import load_scenario, run_episode  # noqa: E402
from warerover_phys.envs.loop import (  # noqa: E402
    PlannerDriver,
    WarehouseLoopEnv,
    resolve_moves,
)
from warerover_phys.sim import Simulation  # noqa: E402
from warerover_phys.validate import validate_states  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
HOMOGENEOUS = ROOT / "layouts" / "paper_homogeneous.yaml"


def scenario(planner: str = "learned", executor: str = "grid", orders: int = 6,
             max_ticks: int | None = None):
    sc = load_scenario(HOMOGENEOUS)
    update = {"planner": sc.planner.model_copy(update={"name": planner}),
              "executor": sc.executor.model_copy(update={"name": executor}),
              "orders": sc.orders.model_copy(update={
                  "oneshot": sc.orders.oneshot.model_copy(update={"count": orders})})}
    if max_ticks is not None:
        update["max_ticks"] = max_ticks
    return sc.model_copy(update=update)


def drive(env: WarehouseLoopEnv, seed: int, choose) -> tuple[dict, float, int]:
    env.reset(seed=seed)
    total, steps = 0.0, 0
    while env.agents:
        _, rewards, _, _, _ = env.step(choose())
        total += sum(rewards.values())
        steps += 1
    return env.paths(), total, steps


def floor_obstacles(env: WarehouseLoopEnv) -> np.ndarray:
    return ~env.sim.world.graphs.get(1, False).valid


@pytest.mark.parametrize(("planner", "seed"), [("learned", 0), ("pibt", 0), ("pibt", 3)])
def test_a_step_planner_driving_the_env_gives_the_episode_of_run(planner, seed):
    sc = scenario(planner)
    res = run_episode(sc, seed=seed)
    env = WarehouseLoopEnv(sc)
    paths, total, steps = drive(env, seed, PlannerDriver(env, planner).actions)
    assert res.metrics["success_rate"] == 1.0
    assert paths == {k: list(v) for k, v in res.actual.items()}
    assert env.sim.world.tick == res.metrics["ticks"] == steps
    assert validate_states(paths, floor_obstacles(env)) == []
    assert total > 0  # every order completed pays every agent


def test_the_learned_driver_gives_runs_episode_on_physics_too():
    sc = scenario("learned", "physics", orders=4)
    res = run_episode(sc, seed=1)
    env = WarehouseLoopEnv(sc)
    paths, _, _ = drive(env, 1, PlannerDriver(env, "learned").actions)
    assert paths == {k: list(v) for k, v in res.actual.items()}
    assert res.metrics["agv_contacts"] == 0


def test_parallel_api_test():
    parallel_api_test(WarehouseLoopEnv(scenario(max_ticks=30)), num_cycles=40)


def test_random_actions_same_seed_same_episode_and_valid():
    env = WarehouseLoopEnv(scenario(max_ticks=40))

    def episode(seed):
        rng = np.random.default_rng(seed)
        return drive(env, seed, lambda: {a: int(rng.integers(5)) for a in env.agents})

    a, b, c = episode(5), episode(5), episode(6)
    assert a == b
    assert a[0] != c[0]
    assert a[2] == 40  # nobody finishes 6 orders at random: truncated at max_ticks
    assert validate_states(a[0], floor_obstacles(env)) == []


def test_observations_and_infos_follow_the_loop():
    env = WarehouseLoopEnv(scenario())
    obs, infos = env.reset(seed=0)
    space = env.observation_space("agv_0")
    assert all(space.contains(o) for o in obs.values())
    req = env.request
    assert [a.agv for a in req.agents] == list(range(len(env.possible_agents)))
    for i, a in enumerate(req.agents):
        info = infos[f"agv_{i}"]
        assert info["goal"] == env.sim.world.graphs.get(1, False).cell(a.goal)
        assert info["hold"] == a.hold
        # the centre of the window is the AGV's own cell: never an obstacle for it
        r = env.config.fov_radius
        assert obs[f"agv_{i}"][0, r, r] == 0.0


def test_a_move_into_an_obstacle_or_a_held_agv_is_blocked():
    env = WarehouseLoopEnv(scenario())
    env.reset(seed=0)
    starts = [a.start for a in env.request.agents]
    g = env.sim.world.graphs.get(1, False)
    # an agent with a wall (or the map edge) next to it, asked to go there, stays blocked
    steps = {1: (-1, 0), 2: (1, 0), 3: (0, -1), 4: (0, 1)}
    for i, v in enumerate(starts):
        r, c = g.cell(v)
        for act, (dr, dc) in steps.items():
            rr, cc = r + dr, c + dc
            if not (0 <= rr < g.rows and 0 <= cc < g.cols) or not g.valid[rr, cc]:
                _, rewards, _, _, infos = env.step({f"agv_{i}": act})
                assert infos[f"agv_{i}"]["blocked"]
                assert env.sim.actual[i][-1] == (v, v)
                assert rewards[f"agv_{i}"] < 0
                return
    raise AssertionError("no AGV of paper_homogeneous starts beside a wall")


def test_larger_or_rotation_aware_fleets_are_refused():
    with pytest.raises(ValueError, match="1x1"):
        WarehouseLoopEnv(ROOT / "layouts" / "paper_heterogeneous.yaml")
    sc = scenario()
    sc = sc.model_copy(update={"planner": sc.planner.model_copy(update={"rotations": True})})
    with pytest.raises(ValueError, match="rotations"):
        WarehouseLoopEnv(sc)
    env = WarehouseLoopEnv(scenario())
    with pytest.raises(ValueError, match="step planner"):
        PlannerDriver(env, "astar")


def test_simulation_halves_must_alternate():
    sim = Simulation(scenario("pibt"), 0)
    req = sim.begin_tick()
    with pytest.raises(RuntimeError):
        sim.begin_tick()
    sim.finish_tick(sim.planner.plan(req))
    with pytest.raises(RuntimeError):
        sim.finish_tick(None)


# 200 examples: one cheap call per example over a wide input space
@settings(max_examples=200, deadline=None)
@given(st.integers(2, 8).flatmap(lambda n: st.tuples(
    st.lists(st.integers(0, 15), min_size=n, max_size=n, unique=True),
    st.lists(st.integers(0, 15), min_size=n, max_size=n))))
def test_resolve_moves_leaves_no_conflict(case):
    start, wanted = (np.array(x) for x in case)
    target = resolve_moves(start, wanted)
    # each agent goes where it asked or stays
    assert np.all((target == start) | (target == wanted))
    # no two agents on one cell
    assert len(set(target.tolist())) == len(target)
    # no swaps
    pos = {int(v): i for i, v in enumerate(start)}
    for i in range(len(start)):
        j = pos.get(int(target[i]))
        if j is not None and j != i:
            assert target[j] != start[i]
    # an agent whose wish conflicts with nobody's moves
    for i in range(len(start)):
        w = int(wanted[i])
        alone = sum(int(x) == w for x in wanted) == 1 and w not in pos
        if alone:
            assert target[i] == w
