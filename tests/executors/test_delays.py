"""Random delays (``executor.delays``, executors/delays.py): a delay of ``k`` ticks holds
its AGV for exactly ``k`` ticks of physics steps whatever the clock's rounding, and the
executor starts exactly the delays that whole-tick arithmetic on its draws prescribes."""

from __future__ import annotations

import copy

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_reorder import REPO, plan40  # noqa: F401  (the fixture)

from warerover_phys.config import ExecutorSpec
from warerover_phys.executors.delays import delay_draws, held


@settings(max_examples=80, deadline=None)
@given(st.sampled_from([0.02, 0.01, 0.05, 0.1]), st.integers(1, 5000), st.integers(1, 10))
def test_a_delay_holds_its_agv_for_whole_ticks_on_the_summed_clock(dt, start_tick, k):
    """On a clock summed step by step, as the executor's is, a delay of ``k`` ticks that
    starts on a tick holds exactly the ``k x steps_per_tick`` steps that follow, and is
    over on the step that starts the tick it ends."""
    tick_s = 1.0
    steps = round(tick_s / dt)
    t = 0.0
    for _ in range(start_tick * steps):
        t += dt
    until = t + k * tick_s
    n_held = 0
    for _ in range((k + 2) * steps):
        n_held += bool(held(until, t, dt))
        t += dt
    assert n_held == k * steps


def test_the_executor_starts_the_delays_whole_ticks_prescribe(plan40):  # noqa: F811
    """Every delay the executor starts, and no other, is the one a replay of its draws
    with tick counts (a delay of ``k`` ticks from tick ``j`` is over at tick ``j + k``)
    starts. Exact time comparisons on the summed clock started about 5% fewer."""
    from warerover_phys.execute import parse_delays
    from warerover_phys.gap.ideal_plan import plan_from_file
    from warerover_phys.gap.open_loop import execute_timed

    plan, _ = plan_from_file(str(REPO / "tests" / "data" / "random-32-32-10.map"),
                             str(plan40), None)
    d = parse_delays("bernoulli:0.3")
    spec = ExecutorSpec(name="physics", delays=d, trajectory_hz=1.0)
    n = plan.num_agents
    seen: set[tuple[int, int]] = set()
    box: dict = {}

    def spy(tick, ex):
        if "rng" not in box:
            box["rng"] = copy.deepcopy(ex.follow.rng)
        box["ticks"] = tick
        for a, until in enumerate(ex.state.delayed_until.tolist()):
            if until > 0:
                seen.add((a, round(until / ex.state.tick_s)))

    execute_timed(plan, spec, seed=5, before_tick=spy)
    rng, ends = box["rng"], np.zeros(n, dtype=int)
    want: set[tuple[int, int]] = set()
    for j in range(box["ticks"]):  # the ticks drawn before the last look
        events, k = delay_draws(rng, d, n)
        start = events & (ends <= j)
        ends[start] = j + k[start]
        want |= {(a, j + int(k[a])) for a in np.flatnonzero(start).tolist()}
    assert len(want) > 200 and seen == want
