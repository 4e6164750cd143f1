"""The documentation site builds without a warning (a broken link, a reference Sphinx cannot
find, a docstring it cannot read), and no page a user reads names the project's internal issue
numbers."""

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"
#: "issue 14", "Issue 6's", "the issue's targets": the tracker's words, not a user's
#: a page autosummary wrote at an earlier build for a name since gone (git-ignored api/)
STALE = "benchmarks.gone.rst"
INTERNAL = re.compile(r"\b[Ii]ssues? \d+|\bthe issue's\b|\bthis issue\b")


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    """The site built once (about a minute: autosummary documents every public name), over
    the page of a name an earlier build documented and no ``__all__`` has any more."""
    html = tmp_path_factory.mktemp("site") / "html"
    (DOCS / "api").mkdir(exist_ok=True)
    (DOCS / "api" / STALE).write_text("benchmarks.gone\n===============\n")
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b",
                          "html", str(DOCS), str(html)],
                         capture_output=True, text=True, cwd=ROOT)
    return run, html


@pytest.mark.needs("sphinx", "myst_parser", "furo")
def test_the_site_builds_without_a_warning(site):
    run, html = site
    assert run.returncode == 0, run.stderr[-3000:]
    assert (html / "reference.html").exists()
    assert not (DOCS / "api" / STALE).exists()         # written afresh, not left in no toctree


@pytest.mark.needs("sphinx", "myst_parser", "furo")
def test_the_reference_documents_every_public_name(site):
    # each package's page links a page per name of its __all__, and that page documents the
    # name itself, not a module of the same name
    import runpy
    run, html = site
    public_api = runpy.run_path(str(DOCS / "conf.py"))["public_api"]()
    missing = []
    for package, names in public_api.items():
        index = (html / "api" / f"{package}.html").read_text(encoding="utf-8")
        for name in names:
            page = html / "api" / f"{package}.{name}.html"
            if (f'href="{package}.{name}.html"' not in index or not page.exists()
                    or f'id="{package}.{name}"' not in page.read_text(encoding="utf-8")):
                missing.append(f"{package}.{name}")
    assert missing == []


@pytest.mark.needs("sphinx", "myst_parser", "furo")
def test_a_broken_link_fails_the_build(tmp_path):
    # the check itself can fail: a copy of the site with one link to a page that is not there
    site = tmp_path / "docs"
    site.mkdir()
    (site / "conf.py").write_text((DOCS / "conf.py").read_text())
    (site / "index.md").write_text("# Home\n\nSee [the missing page](missing.md).\n")
    run = subprocess.run([sys.executable, "-m", "sphinx", "-W", "-q", "-b", "html", str(site),
                          str(tmp_path / "html")], capture_output=True, text=True, cwd=ROOT)
    assert run.returncode != 0 and "missing" in run.stderr


def test_every_page_is_in_the_site():
    index = (DOCS / "index.md").read_text(encoding="utf-8")
    pages = {p.stem for p in DOCS.glob("*.md")} - {"index"}
    assert pages == set(re.findall(r"^([\w-]+)$", index, re.M))


@pytest.mark.parametrize("page", sorted(p.name for p in DOCS.glob("*.md")))
def test_no_page_names_an_internal_issue(page):
    lines = (DOCS / page).read_text(encoding="utf-8").splitlines()
    assert [f"{i}: {line}" for i, line in enumerate(lines, 1) if INTERNAL.search(line)] == []


@pytest.mark.parametrize("name", sorted(p.name for p in (DOCS / "examples").glob("*.to*")))
def test_every_example_file_loads(name):
    # the problem files as `rsfbench simulate --problem` reads them, the column file as
    # `rsfbench observe --columns` does
    from benchmarks.lab.observe_recording import read_column_file
    from problems import SpringSlider, load_problem
    path = DOCS / "examples" / name
    if name == "columns.toml":
        columns, apparatus = read_column_file(path)
        assert set(columns) == {"time", "shear_force"} and apparatus["normal_force"] > 0
    else:
        assert isinstance(load_problem(path), SpringSlider)
