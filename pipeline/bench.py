"""Command `bench`: ingest throughput on the bundled real recordings.

Each measured run is `load_trial` (sha256 check, read, canonical frame) + `process_trial` (gap
fill, filter, events, strides, cycles) with a fresh manifest, so the file hash is paid as in a
real run. One untimed warm-up, then the best of `repeat` runs (`time.perf_counter`).
"""

from __future__ import annotations

import time

from ingest.canonical import load_trial
from ingest.manifest import Manifest
from ingest.process import IngestParams, process_trial
from ingest.subject import Subject, TrialSpec, load_subject

TARGETS = {"camargo_trial_s": 0.2}


def time_trials(subject: Subject, trials: tuple[TrialSpec, ...], manifest: Manifest, p: IngestParams,
                repeat: int) -> tuple[float, int]:
    """Best wall time (s) to ingest `trials` of `subject`, and their total number of frames."""

    def once() -> int:
        fresh = Manifest(manifest.sources, manifest.mirror, manifest.cache)
        return sum(process_trial(load_trial(subject, spec, fresh), subject.markerset, p).trial.n_frames
                   for spec in trials)

    n_frames = once()
    best = float("inf")
    for _ in range(repeat):
        start = time.perf_counter()
        once()
        best = min(best, time.perf_counter() - start)
    return best, n_frames


def run_bench(p: IngestParams, repeat: int = 5) -> dict:
    """Timings of the Camargo trial and of all OpenCap subject-4 trials, against `TARGETS`."""
    manifest = Manifest.load()
    camargo, opencap = load_subject("camargo"), load_subject("opencap4")
    cam_s, cam_frames = time_trials(camargo, camargo.trials[:1], manifest, p, repeat)
    oc_s, oc_frames = time_trials(opencap, opencap.trials, manifest, p, repeat)
    result = {
        "camargo_trial_s": round(cam_s, 4),
        "camargo_frames": cam_frames,
        "camargo_frames_per_s": round(cam_frames / cam_s),
        "opencap4_trials": len(opencap.trials),
        "opencap4_s": round(oc_s, 4),
        "opencap4_frames": oc_frames,
        "opencap4_frames_per_s": round(oc_frames / oc_s),
        "repeat": repeat,
        "targets": TARGETS,
    }
    result["meets_targets"] = all(result[k] <= v for k, v in TARGETS.items())
    return result
