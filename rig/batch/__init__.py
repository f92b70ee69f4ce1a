"""Archives reprocessed on a Dask cluster (`slrig batch`): see docs/batch.md."""

from rig.batch.archive import ArchiveInput, find_inputs, input_digest, output_digest
from rig.batch.cluster import Cluster, DaskMissingError, connect, require_dask
from rig.batch.run import BatchSummary, memory_needed, reprocess_archive

__all__ = [
    "ArchiveInput",
    "BatchSummary",
    "Cluster",
    "DaskMissingError",
    "connect",
    "find_inputs",
    "input_digest",
    "memory_needed",
    "output_digest",
    "reprocess_archive",
    "require_dask",
]
