"""The Robot Runners start kit's output fields of a lifelong run, as functions of what the
run recorded: when each robot took each task, when it did each errand, how many timesteps
ran. :func:`warerover_phys.problems.robotrunners.output_json` writes them.

Which version of the start kit each field follows (``MAPF-Competition/Start-Kit``,
``src/CompetitionSystem.cpp`` ``BaseSystem::simulate`` and ``saveResults``,
``src/TaskManager.cpp``; the 2023 kit's ``InfAssignSystem`` / ``TaskAssignSystem``):

- ``sumOfCost`` (both): the sum over robots of :func:`goal_held_ticks`, the timesteps at
  whose start a robot held a task (the kit adds one per robot per timestep while its goal
  list is not empty). With 2023 ``roundrobin`` every robot always holds a task, so it is
  robots x timesteps.
- ``makespan`` (both): the largest of those counts (not the timesteps run).
- ``numTaskFinished`` (both): tasks whose last errand was reached, the final timestep's
  moves included.
- ``events``: 2023 files, per robot a list of ``[task, timestep, "assigned"|"finished"]``
  (:func:`events_2023`); 2024 and later, one ``[timestep, robot, task, errands done]`` per
  errand reached, errands done counting from 1 (:func:`events_2024`; assignments are in
  ``actualSchedule``).
- ``tasks``: 2023, ``[task, row, col]`` of each task assigned; 2024 and later, ``[task,
  timestep revealed, [row1, col1, row2, col2, ...]]`` of each task revealed
  (:func:`tasks_field`).
- ``actualSchedule`` (the 2024 kit's; kept for 2023 runs too): per robot ``"t:task"``
  items joined by commas, ``t`` the timestep at which the assignment took effect, one
  after the timestep it was made (the kit records it after the move).

Timesteps: ``t`` is the state after ``t`` moves; a task taken at ``t`` is held during the
move from ``t`` to ``t + 1``; an errand reached by that move is done at ``t + 1``.

>>> goal_held_ticks([[(0, 7), (4, 9)], []], {7: 4}, 10)
[10, 0]
>>> events_2024([(0, 0, 7, 0), (4, 0, 7, 1)])
[[4, 0, 7, 1]]
>>> events_2023([(0, 0, 7, 0), (4, 0, 7, 1)], {7: 1}, 2)
[[[7, 0, 'assigned'], [7, 4, 'finished']], []]
>>> schedule_strings([[(0, 7), (4, 9)]])
['1:7,5:9']
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

__all__ = ["goal_held_ticks", "cost_fields", "events_2023", "events_2024", "tasks_field",
           "schedule_strings", "finish_ticks"]

Event = tuple[int, int, int, int]
"""(timestep, robot, task, errands done): 0 when the robot takes the task."""


def finish_ticks(events: Iterable[Event], errands: Mapping[int, int]) -> dict[int, int]:
    """Task -> the timestep its last errand was done (``errands``: task -> errand count)."""
    return {k: t for t, _, k, done in events if done and done == errands[k]}


def goal_held_ticks(schedule: Sequence[Sequence[tuple[int, int]]],
                    finished_at: Mapping[int, int], ticks: int) -> list[int]:
    """Per robot, the timesteps (of ``0 .. ticks - 1``) at whose start it held a task:
    each task from the timestep it was taken to the one it was finished (``finished_at``),
    or to ``ticks`` if it was not."""
    return [sum(min(finished_at.get(k, ticks), ticks) - t for t, k in taken)
            for taken in schedule]


def cost_fields(held: Sequence[int]) -> dict[str, int]:
    """``sumOfCost`` and ``makespan`` from the per-robot goal-held counts."""
    return {"sumOfCost": int(sum(held)), "makespan": int(max(held, default=0))}


def events_2024(events: Iterable[Event]) -> list[list[int]]:
    """``[timestep, robot, task, errands done]`` per errand done (2024 and later)."""
    return [[t, i, k, done] for t, i, k, done in events if done]


def events_2023(events: Iterable[Event], errands: Mapping[int, int],
                robots: int) -> list[list[list]]:
    """Per robot, ``[task, timestep, "assigned"]`` when it took a task and ``[task,
    timestep, "finished"]`` when it did the task's last errand (the 2023 kit)."""
    out: list[list[list]] = [[] for _ in range(robots)]
    for t, i, k, done in events:
        if done == 0:
            out[i].append([k, t, "assigned"])
        elif done == errands[k]:
            out[i].append([k, t, "finished"])
    return out


def tasks_field(releases: Mapping[int, int], cells: Mapping[int, Sequence[int]], cols: int,
                *, version_2023: bool) -> list[list]:
    """The ``tasks`` field: task ids in order with their errands' cells (``cells``: task ->
    linearised errand cells); 2023 ``[task, row, col, ...]``, later ``[task, revealed,
    [row, col, ...]]``."""
    out: list[list] = []
    for k in sorted(releases):
        flat: list[int] = []
        for e in cells[k]:
            flat += [e // cols, e % cols]
        out.append([k, *flat] if version_2023 else [k, releases[k], flat])
    return out


def schedule_strings(schedule: Sequence[Sequence[tuple[int, int]]]) -> list[str]:
    """``actualSchedule``: per robot ``"t:task"`` items joined by commas, ``t`` one after
    the timestep the task was taken (when the kit records it)."""
    return [",".join(f"{t + 1}:{k}" for t, k in taken) for taken in schedule]
