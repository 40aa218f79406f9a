"""The Gymnasium / PettingZoo environments: API checkers, determinism, step rules, and the
learned policy moving in the environment exactly as the ``learned`` planner plans."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
pytest.importorskip("pettingzoo")

from gymnasium.utils.env_checker import check_env  # noqa: E402
from pettingzoo.test import parallel_api_test  # noqa: E402

from warerover_phys.envs import (  # noqa: E402
    EnvConfig,
    GridMAPF,
    Instance,
    LearnedDriver,
    MAPFGymEnv,
    parallel_env,
)
from warerover_phys.movingai import read_map, read_scen  # noqa: E402
from warerover_phys.planning.learned import learned_oneshot  # noqa: E402
from warerover_phys.planning.oneshot import grid_graph  # noqa: E402
from warerover_phys.planning.policy import NUM_CHANNELS  # noqa: E402
from warerover_phys.validate import validate_states  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data"
MAP = DATA / "random-32-32-10.map"
SCEN = DATA / "random-32-32-10-random-1.scen"


def small() -> Instance:
    obstacles = np.zeros((7, 8), dtype=bool)
    obstacles[2, 1:6] = True
    obstacles[5, 3] = True
    return Instance(obstacles, name="small")


def test_gymnasium_check_env():
    check_env(MAPFGymEnv(small(), num_agents=4, max_steps=30, render_mode="rgb_array"))
    check_env(MAPFGymEnv(small(), num_agents=3, others="wait", max_steps=20),
              skip_render_check=True)


def test_pettingzoo_parallel_api_test():
    parallel_api_test(parallel_env(small(), num_agents=5, max_steps=40), num_cycles=60)
    parallel_api_test(parallel_env(small(), num_agents=5, max_steps=40, lifelong=True),
                      num_cycles=60)


def test_registered_with_gymnasium():
    from warerover_phys.envs.single import register

    register()
    env = gym.make("warerover/MAPF-v0", instance=small(), num_agents=2, max_steps=10)
    obs, _ = env.reset(seed=3)
    assert obs.shape == (NUM_CHANNELS, 11, 11)


def _episode(seed: int, lifelong: bool):
    env = parallel_env(small(), num_agents=6, max_steps=50, lifelong=lifelong)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(99)
    record = [np.stack(list(obs.values()))]
    while env.agents:
        acts = {a: int(rng.integers(5)) for a in env.agents}
        obs, rew, term, trunc, info = env.step(acts)
        record.append(np.stack(list(obs.values())))
        record.append(np.array(list(rew.values())))
    return record


@pytest.mark.parametrize("lifelong", [False, True])
def test_same_seed_same_episode(lifelong):
    a, b = _episode(5, lifelong), _episode(5, lifelong)
    assert len(a) == len(b)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    c = _episode(6, lifelong)
    assert len(a) != len(c) or not all(np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_reset_without_seed_continues_the_generator():
    env, env2 = parallel_env(small(), num_agents=3), parallel_env(small(), num_agents=3)
    seen = []
    for e in (env, env2):
        e.reset(seed=1)
        seen.append([e.core.pos.copy() for _ in range(4) if e.reset() is not None])
    assert all(np.array_equal(x, y) for x, y in zip(*seen, strict=True))
    assert len({tuple(p) for p in seen[0]}) > 1  # later resets draw new starts


def core_at(starts, goals, obstacles=None):
    obstacles = np.zeros((3, 4), dtype=bool) if obstacles is None else obstacles
    core = GridMAPF(Instance(obstacles, tuple(starts), tuple(goals)),
                    EnvConfig(num_agents=len(starts)))
    core.reset(np.random.default_rng(0))
    return core


def test_step_rules_swap_vertex_follow_obstacle():
    # swap: (1,0) <-> (1,1) -> both wait and are blocked
    core = core_at([(1, 0), (1, 1)], [(1, 1), (1, 0)])
    _, rew, blocked, *_ = core.step(np.array([4, 3]))
    assert core.paths() == [(1, 0), (1, 1)] and blocked.all()
    assert np.allclose(rew, -0.01 - 0.05)
    # two agents into one cell -> both wait
    core = core_at([(0, 1), (2, 1)], [(0, 0), (0, 0)])
    core.step(np.array([2, 1]))
    assert core.paths() == [(0, 1), (2, 1)]
    # following is allowed; a move into a cell whose agent stays is cancelled (chain)
    core = core_at([(0, 0), (0, 1), (1, 0), (1, 1)], [(0, 3)] * 1 + [(0, 2), (2, 0), (2, 1)])
    core.step(np.array([4, 4, 4, 0]))
    assert core.paths() == [(0, 1), (0, 2), (1, 0), (1, 1)]
    # off the grid and onto an obstacle: cancelled
    obstacles = np.zeros((3, 4), dtype=bool)
    obstacles[0, 1] = True
    core = core_at([(0, 0)], [(2, 3)], obstacles)
    _, _, blocked, *_ = core.step(np.array([1]))
    assert blocked[0] and core.paths() == [(0, 0)]
    core.step(np.array([4]))
    assert core.paths() == [(0, 0)]


def test_goal_rewards_and_termination():
    core = core_at([(0, 0)], [(0, 1)])
    _, rew, _, term, _ = core.step(np.array([4]))
    assert rew[0] == pytest.approx(1.0) and term
    core = core_at([(0, 0), (2, 3)], [(0, 0), (2, 2)])
    _, rew, _, term, _ = core.step(np.array([2, 0]))
    assert rew[0] == pytest.approx(-1.0 - 0.01) and not term


def test_observation_channels():
    obstacles = np.zeros((5, 5), dtype=bool)
    obstacles[2, 3] = True
    core = GridMAPF(Instance(obstacles, ((2, 2), (2, 1)), ((0, 2), (2, 1))),
                    EnvConfig(num_agents=2, fov_radius=2))
    obs = core.reset(np.random.default_rng(0))
    o = obs[0]
    assert o.shape == (4, 5, 5)
    assert o[0, 2, 3] == 1 and o[0, 0, 0] == 0  # obstacle right of the agent
    assert o[0, :, 4].sum() == 0 and obs[1][0, :, 0].all()  # off-grid column for agent 1
    assert o[1, 2, 1] == 1 and o[1].sum() == 1  # the other agent, not itself
    assert o[2, 0, 2] == 1 and o[2].sum() == 1  # goal two rows up
    assert o[3, 1, 2] == pytest.approx(-0.5) and o[3, 2, 2] == 0 and o[3, 2, 3] == 1


def test_scenario_layout_and_movingai_instances():
    core = GridMAPF(Instance.from_scenario(ROOT / "layouts" / "paper_homogeneous.yaml"),
                    EnvConfig(num_agents=10))
    assert core.reset(np.random.default_rng(1)).shape == (10, NUM_CHANNELS, 11, 11)
    inst = Instance.from_movingai(MAP, SCEN, num_agents=20)
    assert len(inst.starts) == 20
    with pytest.raises(ValueError, match="num_agents"):
        EnvConfig(num_agents=0)
    with pytest.raises(ValueError, match="fixes 20 agents"):
        GridMAPF(inst, EnvConfig(num_agents=5))


@pytest.mark.parametrize("agents,seed", [(30, 0), (60, 3)])
def test_env_episode_with_learned_policy_equals_learned_planner(agents, seed):
    """The same instance and seed: the environment driven by the learned policy and shield
    moves every agent exactly as ``learned_oneshot`` plans; both are valid."""
    import time

    inst = Instance.from_movingai(MAP, SCEN, num_agents=agents)
    env = parallel_env(inst, num_agents=agents, max_steps=2000)
    env.reset(seed=seed)
    driver = LearnedDriver(env.core, seed=seed)
    driver.reset()
    traj = [env.core.paths()]
    while env.agents:
        acts = driver.actions()
        _, _, _, _, infos = env.step(dict(zip(env.possible_agents, acts.tolist(), strict=True)))
        assert not any(i["blocked"] for i in infos.values())  # the shield left no conflict
        traj.append(env.core.paths())
    assert all(env.core.on_goal())
    m = read_map(MAP)
    scen = read_scen(SCEN)[:agents]
    paths, _ = learned_oneshot(grid_graph(m.obstacles), [a.start for a in scen],
                               [a.goal for a in scen], time.monotonic() + 120, seed=seed)
    assert paths is not None
    planned = [[p[t] for p in paths] for t in range(len(paths[0]))]
    assert planned == traj
    cols = m.cols
    states = {i: [(r * cols + c,) * 2 for r, c in p] for i, p in enumerate(paths)}
    assert validate_states(states, m.obstacles) == []


@pytest.mark.parametrize("module", ["warerover_phys.envs", "warerover_phys.envs.parallel",
                                    "warerover_phys.envs.single",
                                    "warerover_phys.planning.policy"])
def test_docstring_examples(module):
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0
