"""The suite's own policy (``tests/conftest.py``): under ``CI`` a skipped test fails
unless its reason is an optional extra (torch), every skip is named in the summary, and the
hypothesis profile is ``ci`` (derandomized) there and ``dev`` elsewhere. Each case runs the
real conftest on a small suite in a fresh pytest process."""

from __future__ import annotations

from pathlib import Path

import pytest
from conftest import CI_MAX_EXAMPLES, DEV_MAX_EXAMPLES, profile_name
from hypothesis import settings

CONFTEST = Path(__file__).with_name("conftest.py").read_text()

SUITE = '''
import pytest

def test_runs():
    assert True

def test_needs_a_browser():
    pytest.skip("chromium is not installed (apt-get install chromium)")

def test_needs_torch():
    pytest.importorskip("torch_not_here_either", reason="needs torch (the [train] extra)")

@pytest.mark.skipif(True, reason="lacam3 binary not built")
def test_needs_a_binary():
    pass
'''


@pytest.fixture
def suite(pytester):
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_suite=SUITE)
    return pytester


def run(pytester, monkeypatch, ci: str | None, *args: str):
    monkeypatch.delenv("HYPOTHESIS_PROFILE", raising=False)
    if ci is None:
        monkeypatch.delenv("CI", raising=False)
    else:
        monkeypatch.setenv("CI", ci)
    return pytester.runpytest_subprocess("-p", "no:randomly", "-p", "no:cacheprovider", *args)


def test_under_ci_a_skip_fails_but_an_optional_extra_does_not(suite, monkeypatch):
    res = run(suite, monkeypatch, "true")
    res.assert_outcomes(passed=1, failed=1, errors=1, skipped=1)  # a skipif: at setup
    out = res.stdout.str()
    assert "skipped under CI (chromium is not installed" in out
    assert "skipped under CI (lacam3 binary not built)" in out
    assert "SKIPPED test_suite.py::test_needs_torch: needs torch (the [train] extra)" in out
    assert "hypothesis profile: ci" in out


@pytest.mark.parametrize("ci", [None] + [pytest.param(v, marks=pytest.mark.slow)  # make test-all
                                 for v in ("false", "0")])
def test_elsewhere_skips_stay_skips_and_are_named(suite, monkeypatch, ci):
    res = run(suite, monkeypatch, ci)
    res.assert_outcomes(passed=1, skipped=3)
    out = res.stdout.str()
    assert "3 skipped tests" in out
    for name in ("test_needs_a_browser", "test_needs_torch", "test_needs_a_binary"):
        assert f"SKIPPED test_suite.py::{name}: " in out
    assert "hypothesis profile: dev" in out


def test_under_ci_a_module_skipped_at_import_fails_its_collection(pytester, monkeypatch):
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_extra='import pytest\npytest.importorskip("no_such_module_x")\n'
                                   'def test_a():\n    pass\n')
    res = run(pytester, monkeypatch, "true")
    assert res.ret != 0
    assert "module skipped under CI" in res.stdout.str()
    res = run(pytester, monkeypatch, None)
    res.assert_outcomes(skipped=1)


DRAWS = '''
from pathlib import Path
from hypothesis import given, settings, strategies as st

@settings(max_examples=7)
@given(st.integers(0, 10**9))
def test_draws(x):
    with Path("draws.txt").open("a") as f:
        f.write(f"{x}\\n")
'''


def draws(pytester, monkeypatch, ci: str | None) -> list[int]:
    path = pytester.path / "draws.txt"
    path.unlink(missing_ok=True)
    run(pytester, monkeypatch, ci).assert_outcomes(passed=1)
    return [int(v) for v in path.read_text().split()]


def test_the_ci_profile_is_derandomized_even_where_a_test_states_its_count(pytester,
                                                                          monkeypatch):
    """A test with its own ``@settings(max_examples=...)`` inherits the profile's
    derandomization: two CI runs draw the same examples, two dev runs differ."""
    pytester.makeconftest(CONFTEST)
    pytester.makepyfile(test_draws=DRAWS)
    first, second = draws(pytester, monkeypatch, "true"), draws(pytester, monkeypatch, "true")
    assert first == second and len(first) == 7
    dev = [draws(pytester, monkeypatch, None) for _ in range(2)]
    assert dev[0] != dev[1]


def test_profiles_are_chosen_by_ci():
    assert profile_name({}) == "dev"
    assert profile_name({"CI": "true"}) == profile_name({"CI": "1"}) == "ci"
    assert profile_name({"CI": "false"}) == profile_name({"CI": ""}) == "dev"
    assert profile_name({"CI": "true", "HYPOTHESIS_PROFILE": "dev"}) == "dev"
    ci, dev = settings.get_profile("ci"), settings.get_profile("dev")
    assert ci.derandomize and ci.database is None and ci.max_examples == CI_MAX_EXAMPLES
    assert not dev.derandomize and dev.max_examples == DEV_MAX_EXAMPLES > CI_MAX_EXAMPLES
    assert ci.deadline is None and dev.deadline is None
