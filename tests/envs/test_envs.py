"""The Gymnasium / PettingZoo environments: API checkers, determinism, step rules, and the
learned policy moving in the environment exactly as the ``learned`` planner plans."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from longcases import slow_after

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
from warerover_phys.planning.learned.planner import learned_oneshot  # noqa: E402
from warerover_phys.planning.learned.policy import NUM_CHANNELS  # noqa: E402
from warerover_phys.planning.oneshot.core import grid_graph  # noqa: E402
from warerover_phys.problems.movingai import read_map, read_scen  # noqa: E402
from warerover_phys.validate import validate_states  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
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


@pytest.mark.parametrize("agents,seed", slow_after(1, [(30, 0), (60, 3)]))
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
                                    "warerover_phys.planning.learned.policy"])
def test_docstring_examples(module):
    import doctest
    import importlib

    result = doctest.testmod(importlib.import_module(module))
    assert result.attempted > 0 and result.failed == 0


# ----------------------------------------------------------------------------- executors
# The same environments on a real executor (issue 19): the rules choose the intended next
# cells, the executor's report decides what happened. Kept small: 8 agents, few steps.


def test_physics_check_env_and_parallel_api_test():
    check_env(MAPFGymEnv(small(), num_agents=8, max_steps=20, executor="physics"),
              skip_render_check=True)
    check_env(MAPFGymEnv(small(), num_agents=8, others="wait", max_steps=20,
                         executor="physics"), skip_render_check=True)
    parallel_api_test(parallel_env(small(), num_agents=8, max_steps=20, executor="physics"),
                      num_cycles=25)


def _physics_episode(seed: int, steps: int = 30):
    env = parallel_env(small(), num_agents=8, max_steps=steps, executor="physics")
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(7)
    record = [np.stack(list(obs.values()))]
    states = [env.core.states()]
    while env.agents:
        acts = {a: int(rng.integers(5)) for a in env.agents}
        obs, rew, term, trunc, info = env.step(acts)
        record += [np.stack(list(obs.values())), np.array(list(rew.values())),
                   np.array([[i["blocked"], i["in_transit"], i["on_goal"]]
                             for i in info.values()])]
        states.append(env.core.states())
        assert env.core.report is not None and env.core.report.states == states[-1]
    return record, states, env


def test_physics_same_seed_same_episode():
    (a, sa, _), (b, sb, _) = _physics_episode(5), _physics_episode(5)
    assert sa == sb and len(a) == len(b)
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    _, sc, _ = _physics_episode(6)
    assert sc != sa


def test_physics_moves_are_executed_safely_and_never_faster_than_a_cell_per_step():
    _, states, env = _physics_episode(3, steps=60)
    core = env.core
    cols = core.cols
    traj = {i: [s[i] for s in states] for i in range(core.num_agents)}
    conflicts = [c for c in validate_states(traj, ~core.free) if c.kind != "move"]
    assert conflicts == []
    assert core.collisions == 0
    moves = transit = 0
    for seq in traj.values():
        for (a0, b0), (a1, b1) in zip(seq, seq[1:], strict=False):
            for u, v in ((a0, a1), (b0, b1), (a0, b1)):  # at most one cell per step
                (ru, cu), (rv, cv) = divmod(u, cols), divmod(v, cols)
                assert abs(ru - rv) + abs(cu - cv) <= 1
            assert a1 in (a0, b0)  # it stands, or leaves, the cell it stood on / moved to
            if a0 == b0 and a1 == b1 != a0:
                raise AssertionError("a 1 m/s AGV crossed a 1 m cell within one 1 s step")
            moves += a1 != a0
            transit += a1 != b1
    assert moves > 10 and transit > 10  # the agents did move, and moves take > 1 step


def test_physics_in_transit_actions_wait_and_rotations_are_cancelled():
    obstacles = np.zeros((3, 4), dtype=bool)
    inst = Instance(obstacles, ((1, 0),), ((1, 3),))
    env = parallel_env(inst, num_agents=1, max_steps=20, executor="physics")
    env.reset(seed=0)
    _, _, _, _, info = env.step({"agv_0": 4})  # right: it starts, 1 m takes over 1 s
    assert info["agv_0"]["in_transit"] and env.core.states()[0] == (4, 5)
    assert env.core.paths() == [(1, 0)]  # observed at the cell it leaves
    for _ in range(3):  # left: ignored while in transit (1 m from rest at 1 m/s^2: 2 s)
        _, _, _, _, info = env.step({"agv_0": 3})
        assert not info["agv_0"]["blocked"]
        if env.core.states()[0] == (5, 5):
            break
        assert env.core.states()[0] == (4, 5) and env.core.paths() == [(1, 0)]
    assert env.core.states()[0] == (5, 5) and env.core.paths() == [(1, 1)]
    # Four agents turning a 2x2 block: the grid rules allow it, a real executor cannot.
    starts, goals = ((0, 0), (0, 1), (1, 1), (1, 0)), ((0, 1), (1, 1), (1, 0), (0, 0))
    turn = np.array([4, 2, 3, 1])
    grid = GridMAPF(Instance(obstacles, starts, goals), EnvConfig(num_agents=4))
    grid.reset(np.random.default_rng(0))
    grid.step(turn)
    assert grid.paths() == list(goals)
    phys = GridMAPF(Instance(obstacles, starts, goals),
                    EnvConfig(num_agents=4, executor="physics"))
    phys.reset(np.random.default_rng(0))
    _, _, blocked, _, _ = phys.step(turn)
    assert phys.paths() == list(starts) and blocked.all()
    # An open chain is allowed (following): the executor starts each agent once the one
    # ahead has left its cell; the others wait (blocked) and ask again.
    chain = np.array([4, 2, 3, 2])
    _, _, blocked, _, _ = phys.step(chain)
    assert blocked.tolist() == [True, True, True, False]
    assert phys.states()[3] == (4, 8)
    want = [1, 5, 4, 8]
    for _ in range(16):
        if phys.states() == {i: (v, v) for i, v in enumerate(want)}:
            break
        phys.step(np.where(phys.pos == want, 0, chain))
    assert phys.states() == {i: (v, v) for i, v in enumerate(want)}


@pytest.mark.parametrize("rotations", [False, True])
def test_grid_executor_through_the_protocol_matches_the_rules(rotations):
    """The registry's grid executor, driven through the Executor Protocol, moves (and, with
    rotations, turns: no poses, so a turn takes one step) every agent exactly as the
    built-in rules (no cycle of moves happens in these episodes)."""
    def run(executor):
        env = parallel_env(small(), num_agents=6, max_steps=40, executor=executor,
                           rotations=rotations)
        env.reset(seed=2)
        if rotations:
            env.core.heading[:] = 0  # a real executor's bodies start facing east
        rng = np.random.default_rng(11)
        k = env.core.num_actions
        out = [(env.core.paths(), env.core.heading.tolist())]
        while env.agents:
            env.step({a: int(rng.integers(k)) for a in env.agents})
            out.append((env.core.paths(), env.core.heading.tolist()))
        return out

    assert run("grid") == run("warerover_phys.executors.grid:GridExecutor")


def test_executor_option_errors():
    with pytest.raises(ValueError, match="executor"):
        EnvConfig(executor="")
    from warerover_phys.errors import ScenarioError

    with pytest.raises(ScenarioError, match="unknown executor"):
        GridMAPF(small(), EnvConfig(num_agents=2, executor="nosuch"))
    from warerover_phys.config import ExecutorSpec

    core = GridMAPF(small(), EnvConfig(num_agents=2, executor=ExecutorSpec(name="physics")))
    core.reset(np.random.default_rng(0))
    assert core.executor.name == "physics"


def test_env_episode_with_learned_policy_equals_cli_solve(tmp_path):
    """``warerover solve --planner learned --seed S --out PLAN`` writes exactly the
    configurations the environment goes through when the learned driver (seed S) steps it."""
    from typer.testing import CliRunner

    from warerover_phys.cli import app

    agents, seed = 25, 4
    plan = tmp_path / "plan.txt"
    r = CliRunner().invoke(app, ["solve", str(MAP), str(SCEN), "--agents", str(agents),
                                 "--planner", "learned", "--seed", str(seed), "--out",
                                 str(plan)])
    assert r.exit_code == 0, r.output
    lines = plan.read_text().split("solution=\n", 1)[1].split()
    solved = [[(int(y), int(x)) for x, y in
               (c.split(",") for c in line.split(":", 1)[1].strip("(),").split("),("))]
              for line in lines]
    env = parallel_env(Instance.from_movingai(MAP, SCEN, num_agents=agents),
                       num_agents=agents, max_steps=2000)
    env.reset(seed=seed)
    driver = LearnedDriver(env.core, seed=seed)
    driver.reset()
    traj = [env.core.paths()]
    while env.agents:
        env.step(dict(zip(env.possible_agents, driver.actions().tolist(), strict=True)))
        traj.append(env.core.paths())
    assert traj == solved


# ----------------------------------------------------------------------------- rotations


def test_rotations_check_env_and_parallel_api_test():
    env = MAPFGymEnv(small(), num_agents=4, max_steps=30, rotations=True)
    assert env.action_space.n == 4 and env.observation_space.shape == (NUM_CHANNELS + 1, 11, 11)
    check_env(env, skip_render_check=True)
    check_env(MAPFGymEnv(small(), num_agents=3, others="wait", max_steps=20, rotations=True),
              skip_render_check=True)
    parallel_api_test(parallel_env(small(), num_agents=5, max_steps=40, rotations=True),
                      num_cycles=60)


def _rotation_episode(seed: int, agents: int = 6, steps: int = 80):
    env = parallel_env(small(), num_agents=agents, max_steps=steps, rotations=True,
                       lifelong=True)
    env.reset(seed=seed)
    core = env.core
    rng = np.random.default_rng(seed + 100)
    states, heads = [core.pos.copy()], [core.heading.copy()]
    blocked_any = False
    while env.agents:
        acts = rng.choice(4, size=agents, p=[0.1, 0.6, 0.15, 0.15])
        before, h0 = core.pos.copy(), core.heading.copy()
        _, _, _, _, infos = env.step(dict(zip(env.possible_agents, acts.tolist(), strict=True)))
        blocked = np.array([infos[a]["blocked"] for a in env.possible_agents])
        blocked_any |= bool(blocked.any())
        moved = core.pos != before
        assert not (moved & (acts != 1)).any()  # only forward moves
        assert ((core.heading - h0) % 4 == np.array([0, 0, 3, 1])[acts]).all()
        assert (blocked == ((acts == 1) & ~moved)).all()
        states.append(core.pos.copy())
        heads.append(core.heading.copy())
    return np.array(states), np.array(heads), blocked_any, core


@pytest.mark.parametrize("seed", [0, 1])
def test_rotations_pass_the_validators_heading_checks(seed):
    from warerover_phys.validate import validate_headings

    states, heads, blocked_any, core = _rotation_episode(seed)
    traj = {i: [(int(v), int(v)) for v in states[:, i]] for i in range(states.shape[1])}
    assert validate_states(traj, ~core.free) == []
    headings = {i: heads[:, i].tolist() for i in range(heads.shape[1])}
    assert validate_headings(traj, headings, core.cols,
                             turn_ticks={i: (1, 2) for i in headings}) == []
    assert (states[1:] != states[:-1]).sum() > 20 and blocked_any  # it moved, some blocked
    again = _rotation_episode(seed)
    assert np.array_equal(again[0], states) and np.array_equal(again[1], heads)


def test_rotation_actions_and_heading_channel():
    from warerover_phys.envs.core import rotation_actions

    core = GridMAPF(Instance(np.zeros((3, 4), dtype=bool), ((1, 1),), ((1, 3),)),
                    EnvConfig(num_agents=1, fov_radius=1, rotations=True))
    obs = core.reset(np.random.default_rng(0))
    core.heading[:] = 3  # north
    obs = core.observe()
    assert obs.shape == (1, 5, 3, 3) and obs[0, 4, 0, 1] == 1 and obs[0, 4].sum() == 1
    assert rotation_actions(np.array([4]), core.heading).tolist() == [3]  # east: turn right
    _, rew, blocked, _, _ = core.step(np.array([3]))
    assert core.heading.tolist() == [0] and not blocked[0] and core.paths() == [(1, 1)]
    core.step(np.array([1]))
    assert core.paths() == [(1, 2)]
    assert rotation_actions(np.array([0, 4, 1, 3, 2]), np.array([0, 0, 0, 0, 0])).tolist() \
        == [0, 1, 2, 3, 3]
    with pytest.raises(ValueError, match="actions in 0..3"):
        core.step(np.array([4]))
    from warerover_phys.config import AgvTypeSpec

    with pytest.raises(ValueError, match="differential drive"):
        EnvConfig(rotations=True, executor="physics", agv_type=AgvTypeSpec(drive="omni"))
    with pytest.raises(ValueError, match="sweeps beyond its cell"):
        GridMAPF(small(), EnvConfig(rotations=True, executor="physics",
                                    agv_type=AgvTypeSpec(body_m=(1.0, 1.0))))


def test_rotations_from_the_scenario(tmp_path):
    import yaml

    src = yaml.safe_load((ROOT / "layouts" / "paper_homogeneous.yaml").read_text())
    name = src.get("planner", "pibt")
    src["planner"] = {**(name if isinstance(name, dict) else {"name": name}), "rotations": True}
    if isinstance(src.get("layout"), str):
        src["layout"] = str(ROOT / "layouts" / src["layout"])
    path = tmp_path / "rot.yaml"
    path.write_text(yaml.safe_dump(src))
    inst = Instance.from_scenario(path)
    assert inst.rotations
    env = MAPFGymEnv(inst, num_agents=6, max_steps=15)
    assert env.action_space.n == 4
    obs, _ = env.reset(seed=0)
    for _ in range(15):  # the others follow the learned policy through rotation actions
        obs, _, term, trunc, _ = env.step(1)
        assert obs.shape == (NUM_CHANNELS + 1, 11, 11)
        if term or trunc:
            break


# ------------------------------------------------------------------- rotations on physics
# Turn actions on a real executor: a turn is a committed plan that stands on its cell and
# changes its heading; the body turns at the motion model's rate and the report's body
# angle says when the turn is over (until then the agent is ``turning``: its actions wait).


def test_physics_rotations_check_env_and_parallel_api_test():
    check_env(MAPFGymEnv(small(), num_agents=6, max_steps=15, rotations=True,
                         executor="physics"), skip_render_check=True)
    check_env(MAPFGymEnv(small(), num_agents=4, others="wait", max_steps=15, rotations=True,
                         executor="physics"), skip_render_check=True)
    parallel_api_test(parallel_env(small(), num_agents=6, max_steps=20, rotations=True,
                                   executor="physics"), num_cycles=25)


def _physics_rotation_episode(seed: int, agv_type=None, agents: int = 5, steps: int = 25):
    env = parallel_env(small(), num_agents=agents, max_steps=steps, rotations=True,
                       executor="physics", agv_type=agv_type, lifelong=True)
    obs, _ = env.reset(seed=seed)
    core = env.core
    rng = np.random.default_rng(seed + 100)
    states, heads = [core.states()], [core.heading.tolist()]
    record = [np.stack(list(obs.values()))]
    while env.agents:
        acts = rng.choice(4, size=agents, p=[0.1, 0.5, 0.2, 0.2])
        busy, h0 = core.busy(), core.heading.copy()
        obs, rew, _, _, infos = env.step(dict(zip(env.possible_agents, acts.tolist(),
                                                  strict=True)))
        assert core.report.states == core.states()  # the executor's report decides
        turning = np.array([infos[a]["turning"] for a in env.possible_agents])
        assert (turning == core.turning()).all()
        # An idle agent asked to turn turns (at once or over steps); a busy one ignores it.
        asked = ~busy & (acts >= 2)
        want = (h0 + np.array([0, 0, -1, 1])[acts]) % 4
        assert (core.turn_to[asked] == want[asked]).all()
        assert (core.heading[busy & ~turning] == core.turn_to[busy & ~turning]).all()
        record += [np.stack(list(obs.values())), np.array(list(rew.values())), turning]
        states.append(core.states())
        heads.append(core.heading.tolist())
    return states, heads, record, core


@pytest.mark.parametrize("turn_rate", [2.5, 0.5])
def test_physics_rotations_are_executed_validated_and_deterministic(turn_rate):
    """Random rotation actions on physics (a quarter turn in 0.63 s: one step; at 0.5
    rad/s: 3.14 s, four steps): the reported states pass the validator with the motion
    model's turn ticks, nobody collides, and the same seed gives the same episode."""
    from warerover_phys.config import AgvTypeSpec
    from warerover_phys.planning.rotation import agent_turn_ticks
    from warerover_phys.validate import validate_headings

    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0, max_turn_rate_radps=turn_rate)
    states, heads, record, core = _physics_rotation_episode(3, spec)
    n = core.num_agents
    traj = {i: [s[i] for s in states] for i in range(n)}
    headings = {i: [h[i] for h in heads] for i in range(n)}
    assert [c for c in validate_states(traj, ~core.free) if c.kind != "move"] == []
    q = agent_turn_ticks(spec, 1.0)
    assert q == ((1, 2) if turn_rate == 2.5 else (4, 7))
    assert validate_headings(traj, headings, core.cols, turn_ticks=dict.fromkeys(traj, q)) \
        == []
    assert core.collisions == 0
    turns = sum(a != b for h in headings.values() for a, b in zip(h, h[1:], strict=False))
    moves = sum(a[0] != b[0] for t in traj.values() for a, b in zip(t, t[1:], strict=False))
    assert turns > 5 and moves > 5
    again = _physics_rotation_episode(3, spec)
    assert again[0] == states and again[1] == heads
    assert all(np.array_equal(x, y) for x, y in zip(again[2], record, strict=True))
    assert _physics_rotation_episode(4, spec)[0] != states


def test_physics_turn_takes_the_motion_models_time():
    """One agent: a quarter turn at 0.5 rad/s keeps it ``turning`` for exactly
    ``turn_ticks`` steps (its actions then wait); it then moves along its new heading."""
    from warerover_phys.config import AgvTypeSpec
    from warerover_phys.planning.rotation import turn_ticks

    spec = AgvTypeSpec(body_m=(0.7, 0.7), max_speed_mps=1.0, max_turn_rate_radps=0.5)
    q = turn_ticks(spec, 1.0, 1)
    core = GridMAPF(Instance(np.zeros((3, 4), dtype=bool), ((1, 1),), ((2, 1),)),
                    EnvConfig(num_agents=1, rotations=True, executor="physics",
                              agv_type=spec))
    core.reset(np.random.default_rng(0))
    assert core.heading.tolist() == [0]  # the executor starts bodies facing east
    core.step(np.array([3]))  # turn right: towards south
    steps = 1
    while core.turning()[0]:
        assert core.heading.tolist() == [0] and core.turn_to.tolist() == [1]
        core.step(np.array([2]))  # ignored while turning
        steps += 1
    assert steps == q and core.heading.tolist() == [1]
    assert abs(core.report.poses[0, 2] - np.pi / 2) < 1e-6
    for _ in range(4):
        _, _, blocked, term, _ = core.step(np.array([1]))  # forward: south
        assert not blocked[0]
        if term:
            break
    assert term and core.paths() == [(2, 1)] and core.heading.tolist() == [1]
