"""Every data and report path of gaitloop, built here and nowhere else.

Layout, relative to the repository root (each root can be moved by a command's `--root`,
`--out-root` or `--reports` option, so the per-subject functions take the root they build under):

    params.yaml
    data/processed/<subject>/model/       human.xml, model.json (scale); reference.npz/.json (reference)
    data/processed/<subject>/real/        events, strides, cycles, robot; trials.npz, the processed trials
                                          the later stages read instead of the raw files (ingest)
    data/processed/<subject>/sim/         replay-human rollouts processed like the real trials (simulate)
    data/processed/<subject>/sim_policy/  policy-human rollouts (simulate --human policy)
    data/metrics/<subject>/               metrics.json, quality, provenance (metrics)
    data/metrics/<subject>/tables/        one parquet per metric table (metrics.tables.REGISTRY), as a set
    data/policies/<subject>/              the trained walking policy (train)
    data/policies/<subject>/cohort/<v>/   a cohort variant's fine-tuned policy (train --variant), committed
    data/sweeps/<study>/                  a study's rollout rows (sweep)
    data/tuning/<subject>/<variant>/      per-subject tuned controller gains (tune), committed
    data/exports/<subject>/<scenario>/    simulated trials as OpenSim files (export), not versioned
    data/paper/wang2025.yaml              the reference paper's published Tables I-III (report)
    data/results.duckdb                   the results store (params store.path; relative paths in params
                                          are taken from the repository root)
    reports/<subject>/                    figures, videos and report.md of one subject
    reports/                              bench.json, controller_tuning.json, summary.md, index.html

`ingest.manifest` and `ingest.subject` keep their own root for data/sources.yaml, data/raw and
data/subjects: ingest does not depend on the pipeline.
"""

from __future__ import annotations

from pathlib import Path

REPO_ROOT = Path(__file__).resolve().parent.parent
PARAMS_FILE = REPO_ROOT / "params.yaml"
DATA_ROOT = REPO_ROOT / "data"
PROCESSED_ROOT = DATA_ROOT / "processed"
METRICS_ROOT = DATA_ROOT / "metrics"
POLICIES_ROOT = DATA_ROOT / "policies"
UNIVERSAL_DIR = DATA_ROOT / "universal"  # the universal walking policy's one run (sim/learn/universal.py)
ADOPTION_FILE = "adoption.json"  # in UNIVERSAL_DIR: the adoption rule's evaluations (adopt-universal)
EXPORTS_ROOT = DATA_ROOT / "exports"      # `export`: simulated trials as OpenSim files (not versioned)
PAPER_FILE = DATA_ROOT / "paper" / "wang2025.yaml"
STORE_FILE = DATA_ROOT / "results.duckdb"
REPORTS_ROOT = REPO_ROOT / "reports"
BENCH_REPORT = REPORTS_ROOT / "bench.json"
TUNING_REPORT = REPORTS_ROOT / "controller_tuning.json"
SWEEPS_ROOT = DATA_ROOT / "sweeps"    # `sweep`: <study>/jobs/<job key>.parquet, results.parquet (DVC stage)
TUNING_ROOT = DATA_ROOT / "tuning"    # `tune`: <subject>/<variant>/<controller>.json (committed)
TUNED_GAINS = TUNING_ROOT / "controllers.yaml"  # `tune-controllers`: gains on top of params.yaml (committed)

HUMAN_XML = "human.xml"          # in model_dir: the scaled human (scale stage)
REFERENCE_NPZ = "reference.npz"  # in model_dir: the retargeted motion and cycle (reference stage)
REAL_TRIALS = "trials.npz"       # in real_dir: the processed trials (ingest stage)


def repo_path(path: str | Path) -> Path:
    """`path` as given when absolute, else relative to the repository root (paths in params.yaml)."""
    path = Path(path)
    return path if path.is_absolute() else REPO_ROOT / path


def repo_relative(path: Path) -> str:
    """`path` relative to the repository root when it lies inside it, else as given (for documents
    that name their files)."""
    return str(path.relative_to(REPO_ROOT)) if path.is_relative_to(REPO_ROOT) else str(path)


def sweep_dir(root: str | Path, study: str) -> Path:
    """`<root>/<study>` (root: data/sweeps): a study's job rows and their union."""
    return Path(root) / study


def tuning_file(root: str | Path, subject: str, variant: str, controller: str) -> Path:
    """`<root>/<subject>/<variant>/<controller>.json` (root: data/tuning): one tuning result."""
    return Path(root) / subject / variant / f"{controller}.json"


def subject_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>`: a subject's folder under any of the roots above."""
    return Path(root) / subject


def model_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>/model` (root: data/processed): scaled human and reference motion."""
    return subject_dir(root, subject) / "model"


def human_xml(root: str | Path, subject: str) -> Path:
    return model_dir(root, subject) / HUMAN_XML


def reference_npz(root: str | Path, subject: str) -> Path:
    return model_dir(root, subject) / REFERENCE_NPZ


def real_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>/real` (root: data/processed): the ingested real trials."""
    return subject_dir(root, subject) / "real"


def real_trials(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>/real/trials.npz` (root: data/processed): the processed trials
    (`ingest.trial_file`)."""
    return real_dir(root, subject) / REAL_TRIALS


def sim_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>/sim` (root: data/processed): replay-human rollouts."""
    return subject_dir(root, subject) / "sim"


def sim_policy_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>/sim_policy` (root: data/processed): policy-human rollouts."""
    return subject_dir(root, subject) / "sim_policy"


def metrics_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>` (root: data/metrics): a subject's metrics, quality gates and provenance."""
    return subject_dir(root, subject)


def metric_tables_dir(root: str | Path, subject: str) -> Path:
    """`<root>/<subject>/tables` (root: data/metrics): a subject's metric tables, one parquet each
    (`metrics.tables.REGISTRY`); the metrics stage replaces the folder as a set."""
    return metrics_dir(root, subject) / "tables"


def policy_dir(root: str | Path, subject: str, variant: str = "healthy") -> Path:
    """`<root>/<subject>` (root: data/policies): a subject's trained policy; a cohort variant's
    fine-tuned one in `<root>/<subject>/cohort/<variant>` (`healthy` is the subject's own)."""
    own = subject_dir(root, subject)
    return own if variant == "healthy" else own / "cohort" / variant


def report_dir(reports: str | Path, subject: str) -> Path:
    """`<reports>/<subject>` (reports: reports/): a subject's figures, videos and report."""
    return subject_dir(reports, subject)
