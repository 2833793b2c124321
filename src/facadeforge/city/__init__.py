"""City scale: batch derivation on Dask (:mod:`.batch`), 3D Tiles output (:mod:`.tileset`),
textured mass models enhanced (:mod:`.enhance`; a city of them through ``batch``'s machinery:
:mod:`.enhance_batch`).

``batch`` orchestrates; its workers call the same engine ``derive`` the CLI calls and write
their own outputs (ARCHITECTURE.md).
"""

from .batch import BATCH_FILE, STATS_COLUMNS, BatchResult, batch, plan_chunks
from .tileset import tileset_problems, write_tileset

__all__ = ["BATCH_FILE", "STATS_COLUMNS", "BatchResult", "batch", "plan_chunks",
           "tileset_problems", "write_tileset"]
