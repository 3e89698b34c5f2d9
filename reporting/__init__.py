"""Per-subject and per-dataset reports of the pipeline: figures (PNG) and self-contained HTML."""
from .dataset import dataset_summary, write_dataset_report
from .subject import write_subject_report

__all__ = ["dataset_summary", "write_dataset_report", "write_subject_report"]
