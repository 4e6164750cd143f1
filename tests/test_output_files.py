"""A user's files are never replaced nor deleted, and a failed write leaves no half file
(:mod:`benchmarks.records.files`): the ledger of what rsfbench wrote, ``--overwrite``, a run's
inputs, and the commands that write through them (observe, invert's files, simulate --save)."""

import errno
import json

import pandas as pd
import pytest

from benchmarks.cli.main import main
from benchmarks.records import files as F
from benchmarks.records.files import (LEDGER, OutputExists, claim_outputs, remove_own,
                                      write_output, write_table, writing)


@pytest.fixture(autouse=True)
def fresh_run():
    F.begin_run()
    yield
    F.begin_run()


def test_a_new_file_is_written_and_joins_the_ledger(tmp_path):
    path = write_output(tmp_path / "a.json", '{"x": 1}')
    assert json.loads(path.read_text()) == {"x": 1}
    ledger = json.loads((tmp_path / LEDGER).read_text())
    assert set(ledger) == {"a.json"} and len(ledger["a.json"]["sha256"]) == 64
    assert F.written() == [str(path.resolve())]


def test_a_file_of_the_user_s_is_refused_and_kept(tmp_path):
    mine = tmp_path / "events.csv"
    mine.write_text("t,Fs\n0,1\n")
    with pytest.raises(OutputExists, match="events.csv exists and is not a file rsfbench wrote"):
        write_table(pd.DataFrame({"a": [1]}), mine)
    assert mine.read_text() == "t,Fs\n0,1\n"
    assert not list(tmp_path.glob(".rsfbench-tmp-*"))


def test_rsfbench_s_own_unchanged_file_is_replaced_by_a_later_run(tmp_path):
    write_output(tmp_path / "a.txt", "first")
    F.begin_run()                                    # another run, later
    write_output(tmp_path / "a.txt", "second")
    assert (tmp_path / "a.txt").read_text() == "second"


def test_a_file_rsfbench_wrote_and_the_user_changed_is_theirs(tmp_path):
    write_output(tmp_path / "apparatus.toml", "mass = 1\n")
    (tmp_path / "apparatus.toml").write_text("mass = 2  # edited by hand\n")
    F.begin_run()
    with pytest.raises(OutputExists):
        write_output(tmp_path / "apparatus.toml", "mass = 3\n")
    assert not remove_own(tmp_path / "apparatus.toml")          # nor deleted
    assert (tmp_path / "apparatus.toml").read_text() == "mass = 2  # edited by hand\n"


def test_writers_into_one_directory_at_once_keep_each_other_s_entries(tmp_path):
    """The ledger is read, changed and written under its lock; its lock file is hidden and
    never a step's output."""
    from concurrent.futures import ThreadPoolExecutor

    from benchmarks.pipeline.manifest import snapshot
    names = [f"f{i:03d}.txt" for i in range(96)]
    with ThreadPoolExecutor(8) as pool:
        list(pool.map(lambda name: write_output(tmp_path / name, name), names))
    assert sorted(json.loads((tmp_path / LEDGER).read_text())) == names
    assert sorted(snapshot(tmp_path)) == names
    assert all(p.name.startswith(".") for p in tmp_path.iterdir() if p.name not in names)


def test_remove_own_deletes_only_rsfbench_s_unchanged_file(tmp_path):
    write_output(tmp_path / "curves.csv", "x\n1\n")
    (tmp_path / "user.csv").write_text("x\n1\n")                 # same content, not in the ledger
    assert not remove_own(tmp_path / "user.csv") and (tmp_path / "user.csv").exists()
    assert remove_own(tmp_path / "curves.csv") and not (tmp_path / "curves.csv").exists()
    assert "curves.csv" not in json.loads((tmp_path / LEDGER).read_text())


def test_overwrite_replaces_a_user_s_file_but_never_an_input(tmp_path):
    mine, source = tmp_path / "events.csv", tmp_path / "run.csv"
    mine.write_text("old")
    source.write_text("data")
    F.note_input(source)
    F.allow_overwrite(True)
    write_output(mine, "new")
    assert mine.read_text() == "new"
    with pytest.raises(OutputExists, match="is an input of this run"):
        write_output(source, "clobbered")
    assert source.read_text() == "data"


def test_a_write_that_fails_leaves_the_old_file_and_no_temporary(tmp_path):
    write_output(tmp_path / "t.csv", "old")
    with pytest.raises(RuntimeError):
        with writing(tmp_path / "t.csv") as tmp:
            tmp.write_text("half of the new")
            raise RuntimeError("killed half-way")
    assert (tmp_path / "t.csv").read_text() == "old"
    assert not list(tmp_path.glob(".rsfbench-tmp-*"))


def test_a_full_disk_names_the_file_and_leaves_nothing_half(tmp_path):
    with pytest.raises(OSError) as err:
        with writing(tmp_path / "observe.png") as tmp:
            tmp.write_bytes(b"\x89PNG")
            raise OSError(errno.ENOSPC, "No space left on device")
    assert err.value.errno == errno.ENOSPC and err.value.filename == str(tmp_path / "observe.png")
    assert "observe.png" in str(err.value)
    assert not (tmp_path / "observe.png").exists()
    assert not list(tmp_path.glob(".rsfbench-tmp-*"))


def test_claim_refuses_before_any_work(tmp_path):
    (tmp_path / "b.csv").write_text("x")
    claim_outputs([tmp_path / "a.csv"])                            # free: fine
    with pytest.raises(OutputExists, match="b.csv"):
        claim_outputs([tmp_path / "a.csv", tmp_path / "b.csv"])


# --- the commands ----------------------------------------------------------------------------

def _simulate(*extra):
    return main(["simulate", "--preset", "paper-example", "--t-end", "0.5", *extra])


def test_simulate_save_refuses_a_user_s_file_then_overwrite_replaces_it(tmp_path, capsys):
    run = tmp_path / "run.csv"
    run.write_text("my recording\n")
    assert _simulate("--save", str(run)) == 2
    assert "run.csv exists and is not a file rsfbench wrote" in capsys.readouterr().err
    assert run.read_text() == "my recording\n"
    assert _simulate("--save", str(run), "--overwrite") == 0
    assert pd.read_csv(run).columns[0] == "t"
    assert _simulate("--save", str(run)) == 0                    # its own file: replaced


def test_observe_keeps_a_recording_named_like_its_output_and_a_user_s_figure(tmp_path, capsys):
    """observe's files are refused where a user's file has the name: a recording called
    events.csv in --out, an observe.png of their own; nothing is read, written or deleted."""
    out = tmp_path / "obs"
    out.mkdir()
    (out / "events.csv").write_text("my events\n")
    (out / "observe.png").write_bytes(b"my figure")
    recording = tmp_path / "r.csv"
    recording.write_text("t,Fs\n0,1\n1,2\n")
    status = main(["observe", str(recording), "--column", "time=t", "--column",
                   "shear_force=Fs", "--out", str(out)])
    assert status == 2
    assert "events.csv exists and is not a file rsfbench wrote" in capsys.readouterr().err
    assert (out / "events.csv").read_text() == "my events\n"
    assert (out / "observe.png").read_bytes() == b"my figure"
    assert sorted(p.name for p in out.iterdir()) == ["events.csv", "observe.png"]


def test_observe_never_writes_over_its_own_input(tmp_path, capsys):
    recording = tmp_path / "events.csv"
    recording.write_text("t,Fs\n0,1\n1,2\n")
    status = main(["observe", str(recording), "--column", "time=t", "--column",
                   "shear_force=Fs", "--out", str(tmp_path), "--overwrite"])
    assert status == 2 and "is an input of this run" in capsys.readouterr().err
    assert recording.read_text() == "t,Fs\n0,1\n1,2\n"


def test_every_command_that_writes_files_offers_overwrite():
    from benchmarks.cli.args import GUARDED_COMMANDS
    from benchmarks.cli.main import build_parser
    import argparse

    def commands(parser, seen):
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for name, sub in action.choices.items():
                    seen[name] = sub
                    commands(sub, seen)
        return seen
    found = commands(build_parser(), {})
    for name in GUARDED_COMMANDS:
        assert "--overwrite" in found[name]._option_string_actions, name


def test_a_study_s_committed_files_are_its_own_and_a_user_s_edit_is_not(tmp_path):
    """A results directory's manifest lists each study's files with their sha256: those are
    rsfbench's (a fresh clone has no ledger), an edited one is not."""
    import hashlib
    out = tmp_path / "results"
    out.mkdir()
    (out / "compare_paper_example.csv").write_text("a\n1\n")
    digest = hashlib.sha256(b"a\n1\n").hexdigest()
    from benchmarks.pipeline import manifest as M
    M.write_manifest(out, {"compare": M.make_record(
        "compare", "quick", {}, {"compare_paper_example.csv": digest}, 0.0)})
    assert F.is_own(out / "compare_paper_example.csv")
    (out / "compare_paper_example.csv").write_text("a\n2\n")            # edited by hand
    assert not F.is_own(out / "compare_paper_example.csv")
    from benchmarks.pipeline.reproduce import _refuse_foreign_files
    from benchmarks.studies.compare import STUDY
    _refuse_foreign_files(STUDY, out)           # a results store: the rerun restores its record
    write_output(out / "compare_paper_example.csv", "a\n1\n")
    (out / "compare_paper_example.md").write_text("my notes\n")  # not a record: the user's
    F.begin_run()
    with pytest.raises(OutputExists, match="compare_paper_example.md"):
        _refuse_foreign_files(STUDY, out)
    mine = tmp_path / "mine"          # a folder of the user's with a file named manifest.json
    mine.mkdir()
    (mine / "manifest.json").write_text('{"name": "my web app"}')
    (mine / "compare_paper_example.csv").write_text("mine\n")
    with pytest.raises(OutputExists, match="compare_paper_example.csv"):
        _refuse_foreign_files(STUDY, mine)


def test_study_refuses_a_user_s_report_in_a_folder_that_is_no_results_store(tmp_path, capsys):
    (tmp_path / "REPORT.md").write_text("MY REPORT - precious\n")
    assert main(["study", "integrators", "--out", str(tmp_path)]) == 2
    assert "REPORT.md exists and is not a file rsfbench wrote" in capsys.readouterr().err
    assert (tmp_path / "REPORT.md").read_text() == "MY REPORT - precious\n"


@pytest.mark.parametrize("argv, name", [
    (["convergence", "--problem", "paper-example"], "convergence_paper-example_slip.png"),
    (["convergence", "--fixed-steps"], "convergence_fixed_steps.png"),
    (["work-precision", "--problems", "W2", "--t-end", "2", "--integrators", "Rodas5P"],
     "wp_quick_W2_slip.png"),
])
def test_the_studies_commands_refuse_a_user_s_figure_before_the_work(tmp_path, capsys, argv,
                                                                     name):
    """They refused it only after the work (18 s to 146 s), their other files written."""
    (tmp_path / name).write_text("mine")
    assert main([*argv, "--out", str(tmp_path)]) == 2
    assert f"{name} exists and is not a file rsfbench wrote" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]
