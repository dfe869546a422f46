"""Commands `metrics <subject>`, `store`, `query "SQL"` and `add-subject <id>`."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import pandas as pd

from pipeline.commands.add_subject import NewTrial, Registry, add_subject
from pipeline.params import load_params
from pipeline.paths import METRICS_ROOT, PROCESSED_ROOT, REPORTS_ROOT
from pipeline.stages.metrics import run_metrics
from pipeline.stages.report import run_report
from pipeline.stages.store import run_store
from pipeline.store import query


def cmd_metrics(args: argparse.Namespace) -> int:
    folder = run_metrics(args.subject, load_params(args.params), args.root, args.out_root)
    print(f"wrote {folder}", file=sys.stderr)
    return 0


def cmd_store(args: argparse.Namespace) -> int:
    report = run_store(load_params(args.params), args.root, args.db)
    print(f"store run {report.run_id}: {report.n_groups} groups, {len(report.new_versions)} new versions "
          f"in {report.seconds:.2f} s", file=sys.stderr)
    return 0


def format_frame(df: pd.DataFrame, fmt: str) -> str:
    """A query result as an aligned table, CSV or a JSON list of records."""
    if fmt == "csv":
        return df.to_csv(index=False).rstrip("\n")
    if fmt == "json":
        return json.dumps(json.loads(df.to_json(orient="records", date_format="iso")), indent=2)
    return df.to_string(index=False) if not df.empty else f"(no rows; columns: {', '.join(df.columns)})"


def cmd_query(args: argparse.Namespace) -> int:
    p = load_params(args.params).store.build()
    print(format_frame(query(args.db or p.path, args.sql, p.busy_timeout_s), args.format))
    return 0


def cmd_add_subject(args: argparse.Namespace) -> int:
    registry = Registry(params_path=args.params)
    trials = [NewTrial.parse(t) for t in args.trial]
    path = add_subject(args.id, args.height_m, args.mass_kg, args.static, trials, markerset=args.markerset,
                       up_axis=args.up_axis, knee_flexion_sign=args.knee_flexion_sign, dataset=args.dataset,
                       registry=registry)
    print(f"wrote {path} and added {args.id!r} to {args.params}; run `dvc repro`", file=sys.stderr)
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    params = load_params(args.params)
    p = params.store.build()
    all_subjects = list(params.subjects)
    subjects = [] if args.summary_only else (args.subjects or all_subjects)
    written = run_report(subjects, all_subjects, args.db or p.path, args.reports, not args.no_summary,
                         params.report.build(), p.busy_timeout_s)
    print("wrote " + ", ".join(str(w) for w in written), file=sys.stderr)
    return 0


def add_results_commands(commands: argparse._SubParsersAction) -> None:
    metrics = commands.add_parser("metrics", help="compute a subject's metric tables (Tables I-III, SPM)")
    metrics.add_argument("subject")
    metrics.add_argument("--root", type=Path, default=PROCESSED_ROOT,
                         help="inputs: <root>/<subject>/{real,sim}/ (default: %(default)s)")
    metrics.add_argument("--out-root", type=Path, default=METRICS_ROOT,
                         help="outputs: <out-root>/<subject>/ (default: %(default)s)")
    metrics.set_defaults(func=cmd_metrics)

    store = commands.add_parser("store", help="add every subject's metrics to the DuckDB results store")
    store.add_argument("--root", type=Path, default=METRICS_ROOT,
                       help="metric tables: <root>/<subject>/ (default: %(default)s)")
    store.add_argument("--db", type=Path, help="store file (default: params store.path)")
    store.set_defaults(func=cmd_store)

    q = commands.add_parser("query", help="run SQL on the results store (read-only)")
    q.add_argument("sql", help='e.g. "select * from paper_table2"')
    q.add_argument("--format", choices=("table", "csv", "json"), default="table")
    q.add_argument("--db", type=Path, help="store file (default: params store.path)")
    q.set_defaults(func=cmd_query)

    rep = commands.add_parser("report", help="write reports/<subject>/report.md, summary.md and index.html")
    rep.add_argument("subjects", nargs="*", help="subjects to report (default: all in params)")
    rep.add_argument("--summary-only", action="store_true", help="only reports/summary.md and index.html")
    rep.add_argument("--no-summary", action="store_true", help="only the per-subject reports")
    rep.add_argument("--reports", type=Path, default=REPORTS_ROOT, help="output root (default: reports)")
    rep.add_argument("--db", type=Path, help="store file (default: params store.path)")
    rep.set_defaults(func=cmd_report)

    add = commands.add_parser("add-subject", help="register a new subject from its raw files")
    add.add_argument("id", help="new subject id (lower case, digits, _ or -)")
    add.add_argument("--height-m", type=float, required=True)
    add.add_argument("--mass-kg", type=float, required=True)
    add.add_argument("--static", type=Path, required=True, help="static (scaling) marker file")
    add.add_argument("--trial", action="append", required=True, metavar="COND=MARKERS[,ANGLES[,GRF]]",
                     help="a walking trial: condition and marker file, optionally IK angles and GRF .mot")
    add.add_argument("--markerset", help="marker set in data/markersets/ (default: the one that fits)")
    add.add_argument("--up-axis", choices=("y", "z"), default="z")
    add.add_argument("--knee-flexion-sign", type=int, choices=(1, -1), default=1)
    add.add_argument("--dataset", help="dataset label (default: added:<id>)")
    add.set_defaults(func=cmd_add_subject)
