"""The order the test processes take the work units in (tests/conftest.py) names real units."""

from __future__ import annotations

from pathlib import Path

from conftest import LONGEST_FIRST, work_unit

ROOT = Path(__file__).resolve().parents[1]


def test_every_unit_named_first_exists_once():
    assert len(set(LONGEST_FIRST)) == len(LONGEST_FIRST)
    for unit in LONGEST_FIRST:
        file, _, test = unit.partition("::")
        assert (ROOT / file).is_file(), unit
        assert work_unit(unit) == unit, f"{unit} is not a whole unit (a file, or one docs page)"
        if "[" in test:  # a docs page of test_readme.py
            assert (ROOT / "docs" / test[test.index("[") + 1 : -1]).is_file(), unit
        elif test:
            assert f"def {test}(" in (ROOT / file).read_text(), unit


def test_a_file_is_one_unit_and_each_docs_page_its_own():
    assert work_unit("tests/test_planning.py::test_a[x]") == "tests/test_planning.py"
    a = "tests/test_readme.py::test_page[a.md]"
    assert work_unit(a) == a != work_unit(a.replace("[a.md]", "[b.md]"))
