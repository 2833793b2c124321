"""City scale: batch derivation on Dask (:mod:`.batch`) and 3D Tiles output (:mod:`.tileset`).

``batch`` orchestrates; its workers call the same engine ``derive`` the CLI calls and write
their own outputs (ARCHITECTURE.md).
"""

from .batch import BATCH_FILE, STATS_COLUMNS, BatchResult, batch, plan_chunks
from .tileset import tileset_problems, write_tileset

__all__ = ["BATCH_FILE", "STATS_COLUMNS", "BatchResult", "batch", "plan_chunks",
           "tileset_problems", "write_tileset"]
