"""Suite-wide settings: the hypothesis profiles, and the skipped tests named in the summary.

**Hypothesis profiles** (one place; a test's own ``@settings`` overrides only what it names):

- ``ci`` (chosen where the ``CI`` environment variable is set, as CI services do):
  derandomized (the same examples on every run, so a red CI run reproduces anywhere and a
  green one is not luck), no example database, no deadline, and
  :data:`CI_MAX_EXAMPLES` examples for a test that states no count of its own;
- ``dev`` (elsewhere): random examples, kept in the local example database (a failure is
  replayed first on the next run), :data:`DEV_MAX_EXAMPLES` for a test that states no count.

``HYPOTHESIS_PROFILE=ci`` or ``=dev`` picks one explicitly (``make test`` locally, then, is
``dev``; ``.ci/run`` exports ``CI=true``). A test that states ``max_examples`` keeps that
count under both profiles (derandomized in CI all the same). Counts from 30 to 120 are
ordinary budgets near the profile's; every count outside that range says why on the line
above it: few where an example runs an episode or a planner on a floor, many where an
example is one cheap call over a wide input space (a parser, a kernel, a distance).

**Slow cases.** Besides ``@pytest.mark.slow`` on a test, the cases listed in
``tests/slow_cases.txt`` (``tests/longcases.py``) are marked slow at collection.

**Skips.** The terminal summary names every skipped test with its reason (xdist folds
``-rs`` lines by location, which hides which tests were left out). Under ``CI`` a skip is a
failure (CI runs everything: a missing browser, binary or extra must turn it red, not
leave it green with fewer tests), except for the reasons in :data:`OPTIONAL_IN_CI`.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

pytest_plugins = ["pytester"]  # tests/test_ci_policy.py runs this file on small suites

CI_MAX_EXAMPLES = 50
DEV_MAX_EXAMPLES = 100

# Both from hypothesis's "default" profile: hypothesis loads its own "ci" profile at import
# where CI is set, and a profile registered then would inherit that one's settings.
_BASE = settings.get_profile("default")
settings.register_profile(
    "ci", _BASE, max_examples=CI_MAX_EXAMPLES, derandomize=True, database=None,
    deadline=None, print_blob=True, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile(
    "dev", _BASE, max_examples=DEV_MAX_EXAMPLES, derandomize=False, deadline=None,
    suppress_health_check=[HealthCheck.too_slow])


OPTIONAL_IN_CI = re.compile(r"\btorch\b")
"""Skip reasons CI accepts: the PyTorch training tests need the ``[train]`` extra, which CI
does not install (they are named in the summary)."""


def in_ci(env=os.environ) -> bool:
    """Whether ``CI`` is set to something other than a false word."""
    return env.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def profile_name(env=os.environ) -> str:
    """``HYPOTHESIS_PROFILE`` if set, else ``ci`` under :func:`in_ci`, else ``dev``."""
    return env.get("HYPOTHESIS_PROFILE") or ("ci" if in_ci(env) else "dev")


settings.load_profile(profile_name())


def pytest_report_header(config) -> str:
    return f"hypothesis profile: {profile_name()}; CI: {in_ci()} (skips fail)" if in_ci() \
        else f"hypothesis profile: {profile_name()}"


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """The cases listed in ``tests/slow_cases.txt`` join the slow set (before ``-m``
    selects: this hook runs first)."""
    if not Path(__file__).with_name("longcases.py").exists():
        return  # this file run alone on a small suite (tests/test_ci_policy.py)
    from longcases import mark_slow_cases, slow_cases

    mark_slow_cases(items, slow_cases())


def _skip_reason(rep) -> str:
    reason = rep.longrepr[2] if isinstance(rep.longrepr, tuple) else str(rep.longrepr)
    return reason.removeprefix("Skipped: ")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    rep = outcome.get_result()
    if rep.skipped and not hasattr(rep, "wasxfail") and in_ci():
        reason = _skip_reason(rep)
        if not OPTIONAL_IN_CI.search(reason):
            rep.outcome = "failed"
            rep.longrepr = (f"skipped under CI ({reason}): CI runs every test; install what "
                            f"it needs (see .ci/run) or, for an optional extra, add its "
                            f"reason to OPTIONAL_IN_CI in tests/conftest.py")


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    """A whole module skipped at import (``pytest.importorskip`` at the top) fails its
    collection under ``CI``, as a test's skip fails the test."""
    outcome = yield
    rep = outcome.get_result()
    if rep.skipped and in_ci():
        reason = _skip_reason(rep)
        if not OPTIONAL_IN_CI.search(reason):
            rep.outcome = "failed"
            rep.longrepr = f"module skipped under CI ({reason}): CI runs every test"


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    skipped = terminalreporter.stats.get("skipped", [])
    if not skipped:
        return
    terminalreporter.section(f"{len(skipped)} skipped tests")
    for rep in sorted(skipped, key=lambda r: r.nodeid):
        terminalreporter.line(f"SKIPPED {rep.nodeid}: {_skip_reason(rep)}")
