"""Archives reprocessed on a Dask cluster (`slrig batch`): see docs/batch.md."""

from rig.batch.archive import ArchiveInput, find_inputs, input_digest, output_digest
from rig.batch.cluster import Cluster, DaskMissingError, connect, require_dask
from rig.batch.run import BatchSummary, memory_needed, reprocess_archive
from rig.lazy import face

# The names other packages use, each imported from its module when first read (rig.lazy.face).
_LAZY = {
    "accuracy_summary": "recognise",
    "describe_archive": "recognise",
    "evaluate_archive": "recognise",
    "labeller": "recognise",
}
__getattr__, __dir__ = face(__name__, _LAZY)

__all__ = [
    "ArchiveInput",
    "BatchSummary",
    "Cluster",
    "DaskMissingError",
    "accuracy_summary",
    "connect",
    "describe_archive",
    "evaluate_archive",
    "find_inputs",
    "input_digest",
    "labeller",
    "memory_needed",
    "output_digest",
    "reprocess_archive",
    "require_dask",
]
