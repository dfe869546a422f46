"""gaitloop ingest: mocap files in, canonical trials, gait events, steady strides and cycles out."""

from ingest.canonical import load_trial
from ingest.errors import GaitloopError, IngestError, ManifestError, SubjectError
from ingest.manifest import Manifest
from ingest.opensim_export import export_trial
from ingest.process import IngestParams, ProcessedTrial, SubjectTables, process_subject, process_trial
from ingest.similarity import scaled_static, scaled_subject, scaled_tables
from ingest.static import StaticTrial, read_static_trial
from ingest.subject import Subject, load_subject
from ingest.trial import Trial
from ingest.trial_file import read_trials, write_trials

__all__ = [
    "GaitloopError",
    "IngestError",
    "IngestParams",
    "Manifest",
    "ManifestError",
    "ProcessedTrial",
    "StaticTrial",
    "Subject",
    "SubjectError",
    "SubjectTables",
    "Trial",
    "export_trial",
    "load_subject",
    "load_trial",
    "process_subject",
    "process_trial",
    "read_static_trial",
    "read_trials",
    "scaled_static",
    "scaled_subject",
    "scaled_tables",
    "write_trials",
]
