"""Slow grid: the ideal grid executor, except that AGVs move only on every N-th tick. On the
ticks in between the whole fleet waits, and every AGV with plan left falls one more tick
behind it (``StepReport.behind``), so the plans keep their relative timing.

An executor plug-in built by delegating to :class:`~warerover_phys.executors.GridExecutor`:

    executor: {name: "examples.slow_grid:SlowGrid", params: {every_n_ticks: 3}}

Run ``python -m examples.slow_grid`` to check it and run one episode with it.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from warerover_phys.executors import ExecutorSetup, GridExecutor, StepReport, TickView

__all__ = ["SlowGrid"]


class SlowGrid:
    name = "slow-grid"

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid", frozen=True)  # misspelt keys are errors

        every_n_ticks: int = Field(2, ge=1)
        """AGVs move on ticks 0, N, 2N, ...; 1 = the plain grid executor."""

    def __init__(self, spec, params: Params) -> None:  # the scenario's ExecutorSpec
        self.grid = GridExecutor(spec)
        self.every = params.every_n_ticks

    def bind(self, setup: ExecutorSetup) -> None:
        self.grid.bind(setup)
        self.paused = 0

    def step(self, view: TickView) -> StepReport:
        if view.tick % self.every == 0:
            return self.grid.step(view)
        self.paused += 1
        report = StepReport(states=dict(self.grid.pos))  # everyone stays where it is
        for agv in report.states:
            path = view.plans.get(agv)
            if path is not None and path.end_tick > view.tick - view.behind[agv]:
                report.behind[agv] = view.behind[agv] + 1
                report.replan.append(agv)
        return report

    def remaining(self, agv: int) -> list[tuple[int, int]]:
        return self.grid.remaining(agv)

    def stop_short(self, agv: int, cells: frozenset[int], view: TickView) -> tuple[bool, bool]:
        return self.grid.stop_short(agv, cells, view)

    def summary(self) -> dict[str, Any]:
        return {**self.grid.summary(), "slow_grid_paused_ticks": self.paused}

    def trajectory(self) -> None:
        return self.grid.trajectory()


def main() -> None:
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.testing import check_executor

    print(check_executor(SlowGrid))
    scenario = load_scenario("layouts/paper_homogeneous.yaml", [
        ("executor.name", "examples.slow_grid:SlowGrid"),
        ("executor.params", {"every_n_ticks": 2})])
    metrics = run_episode(scenario, seed=1).metrics
    print({k: metrics[k] for k in ("success_rate", "throughput", "ticks", "collisions")})


if __name__ == "__main__":
    main()
