"""The README quotes results/ through generated blocks (benchmarks/pipeline/readme.py): the committed
README must match the committed results, and the blocks must render what their sources say."""

import pandas as pd
import pytest

from benchmarks.pipeline import readme


def _locked() -> bool:
    """Is every package of requirements.lock installed at its locked version?"""
    import importlib.metadata
    for line in (readme.ROOT / "requirements.lock").read_text().splitlines():
        name, sep, version = line.strip().partition("==")
        if sep and not line.startswith("#"):
            try:
                if importlib.metadata.version(name) != version:
                    return False
            except importlib.metadata.PackageNotFoundError:
                return False
    return True


def test_committed_readme_matches_committed_results(monkeypatch):
    # in another environment than the lock's (pip install . without extras, newer releases) the
    # blocks' labels are judged with the versions they were made with, not those installed
    monkeypatch.setattr(readme, "RECORDED_VERSIONS", not _locked())
    stale = readme.refresh_pages(check=True)
    assert stale == [], f"generated blocks out of date (run `rsfbench readme`): {stale}"


def _root(tmp_path):
    (tmp_path / "results").mkdir()
    (tmp_path / "results" / "x.md").write_text(
        "Intro 1.5 s.\n\n| a | b |\n|---|---|\n| 1 | 2 |\n\ntext\n\n| c |\n|---|\n| 3 |\n")
    return tmp_path


def test_blocks_render_a_file_or_one_of_its_tables(tmp_path):
    root = _root(tmp_path)
    text = ("# T\n<!-- rsfbench: results/x.md table 2 -->\nold\nlines\n<!-- /rsfbench -->\n"
            "keep 7\n<!-- rsfbench: results/x.md -->\n<!-- /rsfbench -->\n")
    out = readme.fill(text, root)
    assert out.startswith("# T\n<!-- rsfbench: results/x.md table 2 -->\n| c |\n|---|\n| 3 |\n"
                          "<!-- /rsfbench -->\nkeep 7\n")
    assert "Intro 1.5 s.\n\n| a | b |" in out and "old" not in out
    assert readme.fill(out, root) == out                      # idempotent
    (root / "README.md").write_text(text)
    assert readme.refresh(root / "README.md", check=True) == ["results/x.md table 2",
                                                              "results/x.md"]
    assert (root / "README.md").read_text() == text           # check does not write
    readme.refresh(root / "README.md")
    assert (root / "README.md").read_text() == out


def test_a_whole_file_s_headings_sit_under_the_page_s(tmp_path):
    root = _root(tmp_path)
    (root / "results" / "h.md").write_text("# Title\n\ntext\n\n```sh\n# a comment\n```\n"
                                           "## Part\n")
    out = readme.fill("<!-- rsfbench: results/h.md -->\n<!-- /rsfbench -->\n", root)
    assert "\n## Title\n\ntext\n\n```sh\n# a comment\n```\n### Part\n" in out


@pytest.mark.parametrize("source, error", [("results/x.md table 3", ValueError),
                                           ("results/nope.md", FileNotFoundError),
                                           ("a guess", ValueError)])
def test_bad_block_sources_say_what_is_wrong(tmp_path, source, error):
    with pytest.raises(error, match="x.md|nope.md|a guess"):
        readme.render(source, _root(tmp_path))


def test_recommendation_bullets_follow_the_study(tmp_path):
    # two problems; Rodas5P is faster but reaches 1e-6 on both only at its tighter setting;
    # ETD2 never reaches 1e-3 on problem q
    rows = [("p", "Rodas5P", 1e-4, 0.001, 5e-4), ("q", "Rodas5P", 1e-4, 0.002, 2e-4),
            ("p", "Rodas5P", 1e-7, 0.004, 4e-7), ("q", "Rodas5P", 1e-7, 0.005, 9e-7),
            ("p", "ETD2", 1e-5, 0.010, 1e-4), ("q", "ETD2", 1e-5, 0.010, 2e-3)]
    df = pd.DataFrame(rows, columns=["problem", "integrator", "setting", "wall_s",
                                     "err_recurrence"]).assign(rhs_tier="numba",
                                                               retcode="Success")
    (tmp_path / "results").mkdir()
    df[df.problem == "p"].to_csv(tmp_path / "results" / "wp_quick.csv", index=False)
    df[df.problem == "q"].to_csv(tmp_path / "results" / "wp_external.csv", index=False)
    text = readme.recommendation(tmp_path)
    assert text == (
        "* **for recurrence intervals to 10⁻³, use `Rodas5P`** at rtol = atol = 0.0001: worst "
        "error 0.0005, 3 ms for the 2 problems;\n"
        "* **for recurrence intervals to 10⁻⁶, use `Rodas5P`** at rtol = atol = 1e-07: worst "
        "error 9e-07, 9 ms for the 2 problems.")


def test_a_block_says_which_run_it_comes_from_and_whether_it_is_stale(tmp_path):
    """The committed manifest names the study and commit; a block is stale exactly when the
    study's inputs (the machine aside) differ from those of that run."""
    from benchmarks.pipeline import manifest as M
    from benchmarks.pipeline.plan import study_inputs, study_named
    line = readme.origin("results/windows.md")
    record = M.read_manifest(readme.ROOT / "results")["windows"]
    assert f"the study `windows` at commit `{record['git_commit']}`" in line
    now = study_inputs(study_named("windows"), readme.ROOT / "results")
    same, _ = M.reusable(record, {**now, "machine": record["inputs"].get("machine")},
                         readme.ROOT / "results")
    assert ("**Stale**" not in line) == same
    assert readme.origin("results/x.md", _root(tmp_path)) == ""       # no manifest: no line
