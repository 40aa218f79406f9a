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
count under both profiles: each says why where it departs from the profile's count (an
example that runs physics costs seconds; a parser check costs microseconds).

**Skips.** The terminal summary names every skipped test with its reason (xdist folds
``-rs`` lines by location, which hides which tests were left out).
"""

from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

CI_MAX_EXAMPLES = 50
DEV_MAX_EXAMPLES = 100

settings.register_profile(
    "ci", max_examples=CI_MAX_EXAMPLES, derandomize=True, database=None, deadline=None,
    print_blob=True, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile(
    "dev", max_examples=DEV_MAX_EXAMPLES, deadline=None,
    suppress_health_check=[HealthCheck.too_slow])


def profile_name(env: os._Environ | dict = os.environ) -> str:
    """``HYPOTHESIS_PROFILE`` if set, else ``ci`` where ``CI`` is set (and not false), else
    ``dev``."""
    chosen = env.get("HYPOTHESIS_PROFILE")
    if chosen:
        return chosen
    return "ci" if env.get("CI", "").lower() not in ("", "0", "false", "no") else "dev"


settings.load_profile(profile_name())


def pytest_report_header(config) -> str:
    return f"hypothesis profile: {profile_name()}"


def pytest_terminal_summary(terminalreporter, exitstatus, config) -> None:
    skipped = terminalreporter.stats.get("skipped", [])
    if not skipped:
        return
    terminalreporter.section(f"{len(skipped)} skipped tests")
    for rep in sorted(skipped, key=lambda r: r.nodeid):
        reason = rep.longrepr[2] if isinstance(rep.longrepr, tuple) else str(rep.longrepr)
        terminalreporter.line(f"SKIPPED {rep.nodeid}: {reason.removeprefix('Skipped: ')}")
