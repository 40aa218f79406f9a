"""Command-line options of ``warerover execute``: the executor spec, ``--set`` options,
``--reorder``, the robot model, ``--delays``."""

from __future__ import annotations

from typing import Any

from ..config import AgvTypeSpec, DelaySpec, ExecutorSpec
from ..errors import ScenarioError, WareroverError


def executor_spec(name: str, *, dt_s: float = 0.02, delays: DelaySpec | None = None,
                  trajectory_hz: float = 10.0, params: dict | None = None,
                  options: dict[str, Any] | None = None,
                  source: str = "--set") -> ExecutorSpec:
    """The executor section of an execution: ``name`` and the command line's own settings,
    plus ``options`` (other :class:`~warerover_phys.config.ExecutorSpec` fields, by name),
    validated by the schema; a bad one raises :class:`ScenarioError` naming ``source``'s
    field and value."""
    from pydantic import ValidationError

    options = dict(options or {})
    own = {"name", "params", "dt_s", "delays", "trajectory_hz"} & set(options)
    if own:
        key = sorted(own)[0]
        raise ScenarioError("set it with its own option (--executor, --dt-s, --delays)",
                            file="<command line>", field=f"{source} executor.{key}",
                            value=options[key])
    try:
        return ExecutorSpec(name=name, params=params or {}, dt_s=dt_s,
                            delays=delays or DelaySpec(), trajectory_hz=trajectory_hz,
                            **options)
    except ValidationError as err:
        e = err.errors()[0]
        loc = ".".join(str(p) for p in e["loc"])
        msg = "unknown executor option" if e["type"] == "extra_forbidden" else e["msg"]
        raise ScenarioError(msg.removeprefix("Value error, "), file="<command line>",
                            field=f"{source} executor.{loc}" if loc else source,
                            value=e.get("input")) from None


def executor_options(texts: list[str] | None) -> dict[str, Any]:
    """``["no_slip=true", "executor.comm_latency_s=0.2"]`` (``--set`` of ``warerover
    execute``; the ``executor.`` prefix is optional; values are YAML) as a dict."""
    from ..config import parse_override

    out: dict[str, Any] = {}
    for text in texts or []:
        try:
            key, value = parse_override(text)
        except ScenarioError as err:
            raise err.with_file("<command line>") from None
        key = key.removeprefix("executor.")
        if not key or "." in key:
            raise ScenarioError("expected an executor field: --set FIELD=VALUE (e.g. "
                                "no_slip=true)", file="<command line>", field="--set",
                                value=text)
        out[key] = value
    return out


REORDER_MODES = ("none", "greedy", "milp")


def check_reorder(mode: str) -> str:
    """``--reorder`` (``executor.reorder``): one of :data:`REORDER_MODES`, else a
    :class:`~warerover_phys.errors.WareroverError` naming the option and the value."""
    if mode not in REORDER_MODES:
        raise WareroverError(f"--reorder must be none, greedy or milp (got {mode!r})")
    return mode


def robot_model(options: dict[str, Any], types: list[AgvTypeSpec]
                ) -> tuple[dict[str, Any], list[AgvTypeSpec]]:
    """``--set robot=diffdrive`` of ``warerover execute`` (a key of ``options`` from
    :func:`executor_options`): the executor options and AGV types with the preset of a
    scenario's ``robot: diffdrive`` (:func:`~warerover_phys.config.diffdrive_preset`:
    ``no_slip`` on, wheel limits for differential-drive types that give none); ``robot``
    is taken out of the options. ``default`` or no ``robot``: unchanged."""
    from pydantic import ValidationError

    from ..config import diffdrive_preset

    options = dict(options)
    robot = options.pop("robot", "default")
    if robot == "default":
        return options, types
    if robot != "diffdrive":
        raise ScenarioError("expected default or diffdrive", file="<command line>",
                            field="--set robot", value=robot)
    if options.get("no_slip") is False:
        raise ScenarioError("robot=diffdrive drives without side slip; no_slip=false "
                            "contradicts it", file="<command line>", field="--set no_slip",
                            value=False)
    unique = {t: f"t{k}" for k, t in enumerate(dict.fromkeys(types))}  # (frozen: hashable)
    raw = diffdrive_preset({"fleet": {"types": {name: t.model_dump(exclude_none=True)
                                                for t, name in unique.items()}}})
    try:
        made = {k: AgvTypeSpec.model_validate(v) for k, v in raw["fleet"]["types"].items()}
    except ValidationError as err:
        raise ScenarioError(err.errors()[0]["msg"], file="<command line>",
                            field="--set robot") from None
    return {**options, "no_slip": True}, [made[unique[t]] for t in types]


def parse_delays(text: str | None) -> DelaySpec:
    """``MODEL:PROB[:MIN_TICKS:MAX_TICKS]`` (``bernoulli:0.05:1:10``) as a DelaySpec."""
    if not text:
        return DelaySpec()
    from pydantic import ValidationError

    parts = text.split(":")
    keys = ["model", "prob", "min_ticks", "max_ticks"]
    if len(parts) not in (2, 4) or parts[0] not in ("none", "bernoulli", "poisson"):
        raise WareroverError(f"--delays: expected MODEL:PROB[:MIN_TICKS:MAX_TICKS] with MODEL "
                             f"bernoulli or poisson (got {text!r})")
    values: dict[str, object] = {"model": parts[0]}
    for key, part, kind in zip(keys[1:], parts[1:], (float, int, int), strict=False):
        try:  # the command line gives text: numbers are read here, ranges checked below
            values[key] = kind(part)
        except ValueError:
            what = "a number" if kind is float else "a whole number of ticks"
            raise WareroverError(f"--delays: {key}: expected {what} (got {part!r} in "
                                 f"{text!r})") from None
    try:
        return DelaySpec.model_validate(values)
    except ValidationError as err:
        e = err.errors()[0]
        where = e["loc"][0] if e["loc"] else "MIN_TICKS:MAX_TICKS"
        raise WareroverError(f"--delays: {where}: {e['msg']} (got {text!r})") from None
