"""Building plug-in classes (``package.module:ClassName``) so that any failure of the user's
code while it is built or called (an exception, a result of the wrong kind, an assignment
the world cannot take) is a one-line :class:`~.errors.ScenarioError` naming the field, the
plug-in and the tick, not a traceback.

>>> class Broken:
...     def __init__(self, spec):
...         raise RuntimeError("no licence")
>>> build_plugin(Broken, None, "planner.name", "my:Broken")
Traceback (most recent call last):
...
warerover_phys.errors.ScenarioError: <scenario>: planner.name: plugin constructor raised RuntimeError: no licence (got 'my:Broken')
"""

from __future__ import annotations

from typing import Any

from .errors import ScenarioError, WareroverError

__all__ = ["build_plugin", "Guarded"]


def _first_line(err: BaseException) -> str:
    text = str(err).strip()
    return f"{type(err).__name__}: {text.splitlines()[0]}" if text else type(err).__name__


class Guarded:
    """A plug-in instance whose ``plan`` / ``assign`` calls are checked: an exception it
    raises, or a result of the wrong kind, is a :class:`ScenarioError` naming the field, the
    plug-in and the tick. Every other attribute is the plug-in's own."""

    def __init__(self, obj: Any, field: str, name: str) -> None:
        self._obj, self._field, self._name = obj, field, name

    def __getattr__(self, attr: str) -> Any:
        return getattr(self._obj, attr)

    def _error(self, msg: str) -> ScenarioError:
        return ScenarioError(msg, field=self._field, value=self._name)

    def _call(self, method: str, tick: Any, *args: Any) -> Any:
        try:
            return getattr(self._obj, method)(*args)
        except ScenarioError:
            raise
        except Exception as err:  # noqa: BLE001 - the plug-in's bug, one line for the user
            raise self._error(f"plugin {method}() raised {_first_line(err)} at tick "
                              f"{tick}") from err     # chained: sweeps keep its traceback

    def plan(self, request: Any) -> Any:
        from .planning.base import PlanResult

        out = self._call("plan", request.tick, request)
        if not isinstance(out, PlanResult):
            raise self._error(f"plugin plan() must return a PlanResult (got "
                              f"{type(out).__name__} at tick {request.tick})")
        return out

    def assign(self, world: Any, rng: Any) -> list:
        out = self._call("assign", world.tick, world, rng)
        try:
            items = list(out)
        except TypeError:
            raise self._error(f"plugin assign() must return a list of Assignment (got "
                              f"{type(out).__name__} at tick {world.tick})") from None
        self._check_assignments(world, items)
        return items

    def _check_assignments(self, world: Any, items: list) -> None:
        from .schedulers.base import Assignment
        from .world import AgvState, OrderStatus

        agvs, shelves = set(), set()
        orders: set[int] = set()
        for i, a in enumerate(items):
            where = f"plugin assign() item {i} at tick {world.tick}"
            if not isinstance(a, Assignment):
                raise self._error(f"{where}: expected an Assignment (got {type(a).__name__})")
            if not (isinstance(a.agv, int) and 0 <= a.agv < len(world.agvs)) or a.agv in agvs \
                    or world.agvs[a.agv].state != AgvState.IDLE:
                raise self._error(f"{where}: AGV {a.agv!r} is not an idle AGV of the fleet "
                                  "(or is given twice)")
            if not (isinstance(a.shelf, int) and 0 <= a.shelf < len(world.layout.shelves)) \
                    or a.shelf in shelves or a.shelf in world.shelf_busy:
                raise self._error(f"{where}: shelf {a.shelf!r} is not a free shelf (or is "
                                  "given twice)")
            skus = set(world.layout.shelves[a.shelf].skus)
            for oid in a.orders:
                if oid in orders or world.status.get(oid) != OrderStatus.PENDING:
                    raise self._error(f"{where}: order {oid!r} is not pending (or is given "
                                      "twice)")
                if world.orders[oid].sku not in skus:
                    raise self._error(f"{where}: shelf {a.shelf} does not hold the SKU of "
                                      f"order {oid}")
                orders.add(oid)
            agvs.add(a.agv)
            shelves.add(a.shelf)


def build_plugin(cls: type, spec: Any, field: str, name: str) -> Any:
    """``cls(spec)`` wrapped in :class:`Guarded`; an exception the constructor raises
    becomes a :class:`ScenarioError`."""
    try:
        return Guarded(cls(spec), field, name)
    except ScenarioError:
        raise
    except WareroverError as err:
        raise ScenarioError(f"plugin constructor failed: {err}", field=field,
                            value=name) from None
    except Exception as err:  # noqa: BLE001 - the plug-in's own bug, reported as bad input
        first = str(err).strip().splitlines()[0] if str(err).strip() else ""
        raise ScenarioError(f"plugin constructor raised {type(err).__name__}"
                            + (f": {first}" if first else ""), field=field,
                            value=name) from None
