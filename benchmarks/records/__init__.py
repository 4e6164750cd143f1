"""Records: result files written whole and read back checked, where a measurement comes from
(commit, package versions, machine), and the Markdown tables of the reports. The lowest room:
it imports nothing else of :mod:`benchmarks`."""

from benchmarks._api import lazy_api

__getattr__, __dir__, __all__ = lazy_api(__name__, {
    "files": ("BadResultsFile", "atomic_write", "read_table", "read_json_record"),
    "provenance": ("git_commit", "version_line"),
    "report": ("markdown_table", "jsonable", "fmt"),
})
