"""``tests/slow_cases.txt`` (the cases moved to the slow set by their measured time) names
only tests that exist, each with a reason, and its cases are marked ``slow``."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from longcases import SLOW_CASES, mark_slow_cases, slow_cases

REPO = Path(__file__).resolve().parent.parent


def _functions(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)}


def test_every_listed_case_names_a_test_that_exists():
    cases = slow_cases()
    assert cases, "slow_cases.txt lists nothing"
    seen: dict[Path, set[str]] = {}
    for node, reason in cases.items():
        path, _, rest = node.partition("::")
        file = REPO / path
        assert file.is_file(), f"{node}: no file {path}"
        name = rest.split("[")[0].split("::")[-1]
        if file not in seen:
            seen[file] = _functions(file)
        assert name in seen[file], f"{node}: {path} has no test {name}"
        assert reason, node


@pytest.mark.parametrize("line", ["tests/x.py::test_a", "tests/x.py::test_a  #   ",
                                  "  # a reason without a node"])
def test_a_line_without_node_or_reason_is_refused(tmp_path, line):
    f = tmp_path / "slow_cases.txt"
    f.write_text(f"# a comment\n\n{line}\n", encoding="utf-8")
    with pytest.raises(ValueError, match="slow_cases.txt:3"):
        slow_cases(f)


def test_a_case_listed_twice_is_refused(tmp_path):
    f = tmp_path / "slow_cases.txt"
    f.write_text("tests/x.py::test_a[1 2]  # one\ntests/x.py::test_a[1 2]  # two\n")
    with pytest.raises(ValueError, match="listed twice"):
        slow_cases(f)


class _Item:
    def __init__(self, nodeid: str):
        self.nodeid = nodeid
        self.marks: list = []

    def add_marker(self, mark) -> None:
        self.marks.append(mark)


def test_listed_cases_and_only_they_are_marked_slow(tmp_path):
    f = tmp_path / "slow_cases.txt"
    f.write_text("tests/x.py::test_a[run zero]  # a case with a space in its id\n")
    items = [_Item("tests/x.py::test_a[run zero]"), _Item("tests/x.py::test_a[run fifo]"),
             _Item("tests/x.py::test_a")]
    assert mark_slow_cases(items, slow_cases(f)) == 1
    assert [m.name for m in items[0].marks] == ["slow"]
    assert items[1].marks == [] and items[2].marks == []


def test_the_shipped_list_is_the_one_read():
    assert SLOW_CASES == REPO / "tests" / "slow_cases.txt"
