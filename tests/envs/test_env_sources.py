"""The environments take a grid as ``loop_env`` does (issue 31): an ``Instance``, a
scenario YAML path (or a loaded scenario), a MovingAI ``.map`` path;
``gymnasium.make("warerover/MAPF-v0", scenario=PATH)`` works; and the package has no
import circle (the optional-dependency helper lives in ``envs/deps.py``)."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

gym = pytest.importorskip("gymnasium")
pytest.importorskip("pettingzoo")

from gymnasium.utils.env_checker import check_env  # noqa: E402
from pettingzoo.test import parallel_api_test  # noqa: E402

from warerover_phys.config import load_scenario  # noqa: E402
from warerover_phys.envs import Instance, MAPFGymEnv, parallel_env  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "layouts" / "paper_homogeneous.yaml"
MAP = ROOT / "tests" / "data" / "random-32-32-10.map"


def _same_grid(instance: Instance, path: Path) -> None:
    expected = Instance.from_movingai(path) if path.suffix == ".map" else \
        Instance.from_scenario(path)
    assert np.array_equal(instance.obstacles, expected.obstacles)


@pytest.mark.parametrize("source", [SCENARIO, MAP, str(SCENARIO), str(MAP)])
def test_gym_env_takes_a_path(source):
    env = MAPFGymEnv(source, num_agents=3)
    _same_grid(env.core.instance, Path(source))
    obs, _ = env.reset(seed=0)
    assert obs.shape == env.observation_space.shape
    check_env(env, skip_render_check=True)


@pytest.mark.parametrize("source", [SCENARIO, MAP])
def test_parallel_env_takes_a_path(source):
    env = parallel_env(source, num_agents=3)
    _same_grid(env.core.instance, Path(source))
    parallel_api_test(env, num_cycles=20)


def test_a_loaded_scenario_and_an_instance_are_taken_too():
    sc = load_scenario(SCENARIO)
    assert np.array_equal(MAPFGymEnv(sc, num_agents=2).core.instance.obstacles,
                          Instance.from_scenario(SCENARIO).obstacles)
    inst = Instance(np.zeros((5, 5), dtype=bool))
    assert parallel_env(inst, num_agents=2).core.instance is inst
    with pytest.raises(TypeError, match="Instance"):
        MAPFGymEnv(42)
    with pytest.raises(TypeError, match="one of them"):
        MAPFGymEnv(inst, scenario=SCENARIO)


def test_gymnasium_make_with_a_scenario_path():
    from warerover_phys.envs.single import register

    register()
    env = gym.make("warerover/MAPF-v0", scenario=str(SCENARIO), num_agents=2)
    obs, _ = env.reset(seed=1)
    _same_grid(env.unwrapped.core.instance, SCENARIO)
    obs2, *_ = env.step(env.action_space.sample())
    assert obs2.shape == obs.shape


def test_envs_modules_do_not_import_the_package_init():
    """``loop``, ``parallel`` and ``single`` are imported by ``envs/__init__``; none of them
    imports from it (``from . import ...`` or ``from warerover_phys.envs import ...``)."""
    folder = ROOT / "warerover_phys" / "envs"
    for path in folder.glob("*.py"):
        if path.name == "__init__.py":
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                assert not (node.level == 1 and node.module is None), path.name
                assert node.module != "warerover_phys.envs", path.name


@pytest.mark.parametrize("module", ["single", "parallel", "loop"])
def test_each_envs_module_imports_first_in_a_fresh_interpreter(module):
    proc = subprocess.run([sys.executable, "-c", f"import warerover_phys.envs.{module}"],
                          cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
