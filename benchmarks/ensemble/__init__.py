"""Ensembles: one problem and one algorithm at many points, as one table.

::

    from benchmarks.ensemble import ensemble, grid, read_store
    table = ensemble(window("W2", "slip", t_end=40.0), Rodas5P(rtol=1e-4, atol=1e-4),
                     grid(b=np.arange(0.0084, 0.01045, 1e-4), lc=np.geomspace(3e-8, 3e-6, 21)),
                     store="W2_sweep")
    again = read_store("W2_sweep")     # the verified chunks only; not pandas.read_parquet(DIR)

:mod:`~benchmarks.ensemble.points` (the points), :mod:`~benchmarks.ensemble.rows` (solves →
rows, compiled batches for the own methods), :mod:`~benchmarks.ensemble.store` (Parquet chunks
listed with their hashes, and their one reader), :mod:`~benchmarks.ensemble.run` (chunks on
threads, processes or Dask).
"""

from benchmarks.ensemble.points import MAX_POINTS, check_points, grid, point_problems
from benchmarks.ensemble.rows import RESULT_COLUMNS, batch_rows, point_rows
from benchmarks.ensemble.run import CHUNK_SIZE, Chunk, ensemble, run_chunk
from benchmarks.ensemble.store import (
                                       BadChunkWarning,
                                       ChunkStore,
                                       IncompleteStoreWarning,
                                       StoreBusy,
                                       StrayFileWarning,
                                       read_store,
)

__all__ = ["ensemble", "grid", "check_points", "point_problems", "batch_rows", "point_rows",
           "run_chunk", "Chunk", "ChunkStore", "read_store", "BadChunkWarning",
           "StrayFileWarning", "IncompleteStoreWarning", "StoreBusy", "RESULT_COLUMNS",
           "CHUNK_SIZE", "MAX_POINTS"]
