"""Optional libraries (benchmarks/records/optional.py): a missing one is refused naming the extra
that installs it; an installed one that is broken raises its own error, never "not installed"."""

import sys

import pytest

from benchmarks.records.optional import MissingExtra, require


def test_a_missing_library_names_its_extra():
    with pytest.raises(MissingExtra, match=r"a thing needs no_such_lib_xyz, which is not "
                                           r"installed: pip install 'rsfbench\[extra\]'"):
        require("no_such_lib_xyz", "extra", "a thing")


def test_a_broken_library_raises_its_own_error(tmp_path, monkeypatch):
    (tmp_path / "broken_lib_xyz").mkdir()
    (tmp_path / "broken_lib_xyz" / "__init__.py").write_text("import its_missing_part_xyz\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "broken_lib_xyz", raising=False)
    with pytest.raises(ModuleNotFoundError) as exc:
        require("broken_lib_xyz", "extra", "a thing")
    assert not isinstance(exc.value, MissingExtra) and exc.value.name == "its_missing_part_xyz"


def test_an_installed_library_is_returned():
    assert require("json", "extra", "a thing").__name__ == "json"
