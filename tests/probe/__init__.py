"""The reliability probe: the harness used as a new user and a hostile one would use it.

:mod:`probe.harness` runs a case and names what it observed, :mod:`probe.cases` and
:mod:`probe.families` are the catalogue, ``test_reliability.py`` runs every case (the slow ones
under ``make test-slow``). ``pytest tests/probe -m 'slow or not slow' --probe-report DIR`` also
writes the table of kinds and outcomes (``reliability.csv``, ``reliability.md``): the ``probe``
study of ``rsfbench study probe``."""
