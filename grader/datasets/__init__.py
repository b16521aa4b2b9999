"""The lab dataset format: a folder with ``manifest.json`` (or ``.yaml``) and CSV files
whose header cells read ``name [unit]``. The contract: docs/reference/dataset-format.md."""

from grader.datasets.load import Dataset, Run, load, read_manifest, write_dataset
from grader.datasets.schema import ControllerSpec, Given, Manifest, RunSpec

__all__ = ["ControllerSpec", "Dataset", "Given", "Manifest", "Run", "RunSpec", "load", "read_manifest", "write_dataset"]
