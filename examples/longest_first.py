"""Longest first: prioritized space-time A* that plans the AGVs with the longest way to go
first (or the shortest, with ``longest_first: false``), reusing the built-in
:class:`~warerover_phys.planning.AStarPlanner` for the searches.

A planner plug-in (``plan(request) -> PlanResult``):

    planner: {name: "examples.longest_first:LongestFirstAStar",
              params: {max_expansions: 20000, longest_first: true}}

Run ``python -m examples.longest_first`` to check it and run one episode with it.
"""

from __future__ import annotations

from dataclasses import replace

from pydantic import BaseModel, ConfigDict, Field

from warerover_phys.planning import AStarPlanner, PlanRequest, PlanResult

__all__ = ["LongestFirstAStar"]


class LongestFirstAStar:
    name = "longest-first-astar"
    replans_all = False
    """Called only for the AGVs that need a new path."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid", frozen=True)  # misspelt keys are errors

        max_expansions: int = Field(20_000, ge=1)
        """Node budget of one AGV's search; past it the AGV waits and retries."""
        longest_first: bool = True
        """Plan the AGV with the longest static distance (in ticks) first."""

    def __init__(self, spec, params: Params) -> None:  # the scenario's PlannerSpec
        self.params = params
        self.astar = AStarPlanner(max_expansions=params.max_expansions)

    def plan(self, request: PlanRequest) -> PlanResult:
        sign = -1 if self.params.longest_first else 1

        def ticks_to_go(agent) -> int:
            graph = request.graphs.get(agent.k, agent.loaded, agent.shelf)
            return graph.distance(graph.cell(agent.start), graph.cell(agent.goal)) \
                * agent.ticks_per_move

        # AStarPlanner plans in (priority, agv) order: keep the loop's priority (AGVs that
        # failed to get a plan go first) and break its ties by the distance. The request
        # itself stays untouched.
        agents = [replace(a, priority=(*a.priority, sign * ticks_to_go(a)))
                  for a in request.agents]
        return self.astar.plan(replace(request, agents=agents))


def main() -> None:
    from warerover_phys import load_scenario, run_episode
    from warerover_phys.testing import check_planner

    print(check_planner(LongestFirstAStar))
    scenario = load_scenario("layouts/paper_homogeneous.yaml", [
        ("planner.name", "examples.longest_first:LongestFirstAStar")])
    metrics = run_episode(scenario, seed=1).metrics
    print({k: metrics[k] for k in ("success_rate", "throughput", "ticks")})


if __name__ == "__main__":
    main()
