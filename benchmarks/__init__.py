"""The accuracy-and-cost harness: limit-cycle metrics, studies, plots and the ``rsfbench`` CLI."""
