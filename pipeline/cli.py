"""Command line: `python -m pipeline <command>`; each command parses params, calls the library
and writes or prints its outputs. Any `GaitloopError`, and any error of the system (`OSError`: disk
full, permission denied, ...), ends the run with one line on stderr (`error: <message>`, `error: <what>
(<file>)`) and exit status 2; Ctrl-C with `error: interrupted (<command>)` and exit status 130."""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from ingest.errors import GaitloopError
from ingest.subject import UP_AXIS_CHOICES
from pipeline.bench import SECTIONS
from pipeline.params import check_params, load_params
from pipeline.paths import (
    BENCH_REPORT,
    METRICS_ROOT,
    PARAMS_FILE,
    POLICIES_ROOT,
    PROCESSED_ROOT,
    REPORTS_ROOT,
    SWEEPS_ROOT,
    TUNED_GAINS,
    TUNING_REPORT,
    UNIVERSAL_DIR,
)
from pipeline.stages.outputs import json_text, write_json

if TYPE_CHECKING:
    import pandas

EXIT_ERROR = 2
EXIT_INTERRUPTED = 130  # 128 + SIGINT, as a shell reports a job ended by Ctrl-C


def cmd_check_params(args: argparse.Namespace) -> int:
    params = check_params(args.params)
    print(f"{params.path}: every section valid", file=sys.stderr)
    return 0


def cmd_ingest(args: argparse.Namespace) -> int:
    from pipeline.stages.ingest import run_ingest

    folder = run_ingest(args.subject, load_params(args.params), args.out_root)
    print(f"wrote {folder}", file=sys.stderr)
    return 0


def cmd_events(args: argparse.Namespace) -> int:
    from ingest.process import IngestParams, process_trial
    from pipeline.commands.quicklook import file_trial, format_events, quicklook_subject

    p = load_params(args.params).section("ingest", IngestParams)
    if args.method:
        p = dataclasses.replace(p, events=dataclasses.replace(p.events, method=args.method))
    subject = quicklook_subject(args.file, args.subject, args.up_axis, args.markerset)
    trial = file_trial(args.file, args.grf, subject)
    print(format_events(process_trial(trial, subject.markerset, p).events, args.format))
    return 0


def _sections(text: str) -> tuple[str, ...]:
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = sorted(set(names) - set(SECTIONS))
    if unknown or not names:
        raise argparse.ArgumentTypeError(f"unknown section(s) {', '.join(unknown) or '(none)'}; "
                                         f"known: {', '.join(SECTIONS)}")
    return names


def cmd_bench(args: argparse.Namespace) -> int:
    from pipeline.bench.suite import run_bench

    result = run_bench(load_params(args.params), args.repeat, args.only or SECTIONS)
    if args.only and args.out.exists():  # refresh those sections, keep the others' last numbers
        result = {**json.loads(args.out.read_text()), **result}
        result["meets_targets"] = all(v["meets_targets"] for v in result.values() if isinstance(v, dict))
    write_json(args.out, result)
    print(json_text(result), end="")
    return 0


def cmd_run(args: argparse.Namespace) -> int:
    """`dvc repro` of `args.targets`, its stages joining one local Ray head (unless RAY_ADDRESS names
    a cluster already), `dvc.lock` rewritten through libyaml (`pipeline.commands.repro`): what
    `make run` calls."""
    import os
    import subprocess
    from contextlib import ExitStack

    from sim.rollout.cluster import RAY_ADDRESS, local_head

    params = check_params(args.params)  # every section, before any stage runs
    cmd = [sys.executable, "-m", "pipeline.commands.repro", *args.targets]
    if os.environ.get(RAY_ADDRESS):
        return subprocess.run(cmd).returncode
    with ExitStack() as stack:
        try:
            env = stack.enter_context(local_head(params.ray.num_cpus, Path.cwd()))
        except (OSError, RuntimeError) as exc:  # no shared head: every stage starts its own Ray
            print(f"warning: {exc}; each stage starts its own Ray", file=sys.stderr)
            env = {}
        return subprocess.run(cmd, env={**os.environ, **env}).returncode


def cmd_reference(args: argparse.Namespace) -> int:
    from pipeline.stages.reference import run_reference

    doc = run_reference(args.subject, load_params(args.params), args.root or PROCESSED_ROOT,
                        args.reports or REPORTS_ROOT)
    print(f"{args.subject}: marker RMS {doc['marker_rms_m'] * 100:.2f} cm, "
          f"{doc['ik_frames_per_s']:.0f} IK frames/s, cycle {doc['cycle']['stride_length_m']:.3f} m at "
          f"{doc['cycle']['speed_mps']:.3f} m/s", file=sys.stderr)
    return 0


def cmd_tune_controllers(args: argparse.Namespace) -> int:
    from pipeline.commands.tune_controllers import run_tuning, write_gains

    params = check_params(args.params)
    doc = run_tuning(params, args.out)
    for name, res in doc["controllers"].items():
        print(f"{name}: J {res['initial_objective']:.4f} -> {res['objective']:.4f} in {res['n_evaluations']} "
              f"rollouts ({res['wall_s']:.0f} s): {res['gains']}", file=sys.stderr)
    write_gains(args.gains, doc, params)
    print(f"wrote {args.out} and {args.gains}", file=sys.stderr)
    return 0


def cmd_scale(args: argparse.Namespace) -> int:
    from pipeline.stages.scale import run_scale

    folder = run_scale(args.subject, load_params(args.params), args.root or PROCESSED_ROOT,
                       args.reports or REPORTS_ROOT)
    print(f"wrote {folder}", file=sys.stderr)
    return 0


def cmd_simulate(args: argparse.Namespace) -> int:
    from pipeline.stages.simulate import run_simulate

    params = load_params(args.params)
    if getattr(args, "human", "replay") == "policy":
        from pipeline.stages.simulate import run_simulate_policy

        doc = run_simulate_policy(args.subject, params, args.root or PROCESSED_ROOT,
                                  args.policy_root or POLICIES_ROOT)
        if "note" in doc:  # no trained policy: empty tables
            print(f"{args.subject} policy: {doc['note']}", file=sys.stderr)
        else:
            print(f"{args.subject} policy: falls {doc['falls']}, {doc['conditions']}", file=sys.stderr)
        return 0

    doc = run_simulate(args.subject, params, args.root or PROCESSED_ROOT, args.reports or REPORTS_ROOT)
    for cond, m in doc["conditions"].items():
        print(f"{args.subject} {cond}: mean |e_x| {m['mean_abs_e_x_cm']:.2f} cm, mean |e_y| "
              f"{m['mean_abs_e_y_cm']:.2f} cm, harness force RMS {m['harness_force_rms_n']:.1f} N, "
              f"falls {m['falls']}", file=sys.stderr)
    return 0


def cmd_train(args: argparse.Namespace) -> int:
    from pipeline.stages.train import run_train

    rec = run_train(args.subject, load_params(args.params), n_envs=args.n_envs,
                    threads=args.threads, steps=args.steps, resume=args.resume, max_wall_s=args.max_wall_s,
                    subprocess=True if args.subprocess else None, init_from=args.init_from, on_ray=args.ray,
                    variant=args.variant)
    print(f"{args.subject}: policy at {rec['steps']} steps, {rec['wall_s']:.0f} s of training in total",
          file=sys.stderr)
    return 0


def cmd_transfer(args: argparse.Namespace) -> int:
    from pipeline.stages.transfer import run_transfer

    rec = run_transfer(args.subject, load_params(args.params), args.root or PROCESSED_ROOT,
                       steps=args.steps, max_wall_s=args.max_wall_s,
                       universal_dir=args.universal or UNIVERSAL_DIR)
    verdict = "passed" if rec["pass"] else f"FAILED ({', '.join(rec['failed']) or 'no check required'})"
    source = rec["source"] + (f" (distance {rec['distance']})" if "distance" in rec else "")
    how = f"fine-tuned for {rec['steps']} steps" if rec["steps"] else "zero-shot"
    print(f"{args.subject}: from {source}, {how}, {rec['wall_s']:.0f} s; gate {verdict}", file=sys.stderr)
    return 0


def cmd_adopt_universal(args: argparse.Namespace) -> int:
    from pipeline.commands.adoption import append_record, evaluate_checkpoint
    from pipeline.paths import REPO_ROOT
    from sim.learn.pool import UniversalParams
    from sim.learn.universal import shown_path

    params = load_params(args.params)
    subjects = args.subjects or list(params.section("universal", UniversalParams).subjects)
    universal = args.universal or UNIVERSAL_DIR
    doc = evaluate_checkpoint(params, universal, subjects, root=args.root or PROCESSED_ROOT,
                              policy_root=args.policy_root or POLICIES_ROOT, progress=not args.json)
    if not args.no_record:  # no path of this machine in the record
        where = shown_path(str(universal.resolve()), REPO_ROOT)
        against = (f" --policy-root {shown_path(str(args.policy_root.resolve()), REPO_ROOT)}"
                   if args.policy_root else "")
        how = (f"python -m pipeline adopt-universal {' '.join(args.subjects)}".rstrip() + against
               + f" (the checkpoint in {where})")
        append_record(universal, doc, how)
    print(json_text(doc), end="")
    return 0


def cmd_evaluate_policy(args: argparse.Namespace) -> int:
    from pipeline.runs.evaluate_policy import evaluate_policy

    root = args.policy_root or POLICIES_ROOT  # another policy's SPM figure goes beside it, not into reports/
    doc = evaluate_policy(args.subject, load_params(args.params), policy_root=root,
                          reports=args.policy_root or REPORTS_ROOT, progress=not args.json,
                          variant=args.variant)
    if args.out:
        write_json(args.out, doc)
    print(json_text(doc), end="")
    return 0


def cmd_render(args: argparse.Namespace) -> int:
    from pipeline.commands.render import run_render

    path = run_render(args.subject, args.condition, load_params(args.params), args.root or PROCESSED_ROOT,
                      args.reports or REPORTS_ROOT, args.seed, args.bout, args.scenario)
    print(f"wrote {path}", file=sys.stderr)
    return 0


def cmd_export(args: argparse.Namespace) -> int:
    from pipeline.commands.export import run_export

    scenario = None if args.scenario == "replay" else args.scenario
    folder = run_export(args.subject, load_params(args.params), args.out, scenario,
                        tuple(args.condition) if args.condition else None, args.walks,
                        args.root or PROCESSED_ROOT)
    print(f"wrote {folder}", file=sys.stderr)
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from pipeline.stages.sweep import check_failed, job_label, run_sweep

    root = args.root or SWEEPS_ROOT
    summary = run_sweep(load_params(args.params), root, study=args.study)
    for f in summary["failed"]:
        print(f"failed: {job_label(f)}: {f['error']}", file=sys.stderr)
    for note in summary["notes"]:
        print(f"left out: {note}", file=sys.stderr)
    print(f"sweep {summary['study']}: {summary['ran']} ran, {summary['resumed']} resumed, "
          f"{len(summary['failed'])} failed of {summary['jobs']} jobs", file=sys.stderr)
    check_failed(summary, root)  # failed jobs: `error: ...`, exit 2 (dvc does not record the stage as done)
    return 0


def cmd_tune(args: argparse.Namespace) -> int:
    from pipeline.runs.tune import run_tune

    path = run_tune(args.subject, args.controller, check_params(args.params), variant=args.variant,
                    n_trials=args.n_trials)
    print(f"wrote {path}", file=sys.stderr)
    return 0


def cmd_metrics(args: argparse.Namespace) -> int:
    from pipeline.stages.metrics import run_metrics

    folder = run_metrics(args.subject, load_params(args.params), args.root, args.out_root)
    print(f"wrote {folder}", file=sys.stderr)
    return 0


def cmd_store(args: argparse.Namespace) -> int:
    from pipeline.stages.store import run_store

    report = run_store(load_params(args.params), args.root, args.db)
    print(f"store run {report.run_id}: {report.n_groups} groups, {len(report.new_versions)} new versions "
          f"in {report.seconds:.2f} s", file=sys.stderr)
    return 0


def format_frame(df: pandas.DataFrame, fmt: str) -> str:
    """A query result as an aligned table, CSV or a JSON list of records."""
    if fmt == "csv":
        return df.to_csv(index=False).rstrip("\n")
    if fmt == "json":
        return json.dumps(json.loads(df.to_json(orient="records", date_format="iso")), indent=2)
    return df.to_string(index=False) if not df.empty else f"(no rows; columns: {', '.join(df.columns)})"


def cmd_query(args: argparse.Namespace) -> int:
    from pipeline.store.connection import StoreParams
    from pipeline.store.read import query

    p = load_params(args.params).section("store", StoreParams)
    print(format_frame(query(args.db or p.path, args.sql, p.busy_timeout_s), args.format))
    return 0


def cmd_compare_stores(args: argparse.Namespace) -> int:
    from pipeline.store.read import compare_views

    doc = compare_views(args.before, args.after, rtol=args.rtol)
    for view, d in doc.items():
        verdict = "equal" if d["equal"] else "DIFFERENT"
        print(f"{view}: {verdict} ({d['rows_before']} / {d['rows_after']} rows, max relative difference "
              f"{d['max_relative_difference']:.1e})", file=sys.stderr)
    print(json_text(doc), end="")
    return 0 if all(d["equal"] for d in doc.values()) else 1


def cmd_add_subject(args: argparse.Namespace) -> int:
    from pipeline.commands.add_subject import NewTrial, Registry, add_subject

    registry = Registry(params_path=args.params)
    trials = [NewTrial.parse(t) for t in args.trial]
    path = add_subject(args.id, args.height_m, args.mass_kg, args.static, trials, markerset=args.markerset,
                       up_axis=args.up_axis, knee_flexion_sign=args.knee_flexion_sign, dataset=args.dataset,
                       round_trip_of=args.round_trip_of, origin=args.origin, policy=not args.no_policy,
                       registry=registry)
    lists = "subjects" if args.no_policy or args.round_trip_of else "subjects and transfer.subjects"
    print(f"wrote {path} and added {args.id!r} to {lists} in {args.params}; run `dvc repro`", file=sys.stderr)
    return 0


def cmd_report(args: argparse.Namespace) -> int:
    from pipeline.runs.studies import report_params
    from pipeline.stages.report import run_report
    from pipeline.store.connection import StoreParams

    params = load_params(args.params)
    p = params.section("store", StoreParams)
    all_subjects = list(params.subjects)
    subjects = [] if args.summary_only else (args.subjects or all_subjects)
    written = run_report(subjects, all_subjects, args.db or p.path, args.reports, not args.no_summary,
                         report_params(params), p.busy_timeout_s)
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

    cmp = commands.add_parser("compare-stores", help="are two results stores' paper tables, SPM clusters and "
                              "harness table equal? (exit 1 when not)")
    cmp.add_argument("before", type=Path)
    cmp.add_argument("after", type=Path)
    cmp.add_argument("--rtol", type=float, default=1e-9, help="relative tolerance (default: %(default)s)")
    cmp.set_defaults(func=cmd_compare_stores)

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
    add.add_argument("--static", type=Path, required=True, help="static (scaling) marker file, or 'auto': "
                     "the quiet standing before a walk in the trials (checked to be quiet standing), or "
                     "'none': no standing, scaled from the walking trials")
    add.add_argument("--trial", action="append", required=True,
                     metavar="COND=MARKERS[,ANGLES[,GRF[,ROBOT_LOG]]]",
                     help="a walking trial: condition and marker file, optionally IK angles and GRF .mot "
                     "and, for a robot-assisted trial (condition = the controller), the robot log .csv")
    add.add_argument("--origin", metavar="URL", help="public http(s) folder the new files can be downloaded "
                     "from (their manifest origin); default: tracked by DVC only (dvc push)")
    add.add_argument("--round-trip-of", metavar="SUBJECT", help="these files are SUBJECT's simulated trials "
                     "exported by `export` and read back: label the subject as a round trip")
    add.add_argument("--markerset", help="marker set: a name in data/markersets/ or a YAML file (default: "
                     "the shipped set that fits the files)")
    add.add_argument("--up-axis", choices=("x", "y", "z", "auto"), default="auto",
                     help="the files' up axis (default: auto, detected from pelvis and foot markers)")
    add.add_argument("--knee-flexion-sign", type=int, choices=(1, -1), default=1)
    add.add_argument("--dataset", help="dataset label (default: added:<id>)")
    add.add_argument("--no-policy", action="store_true", help="replay rows only: do not add the subject to "
                     "transfer.subjects (default: `dvc repro` transfers the universal walking policy to it)")
    add.set_defaults(func=cmd_add_subject)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m pipeline", description=__doc__.split(";")[0])
    parser.add_argument("--params", type=Path, default=PARAMS_FILE, help="params file (default: %(default)s)")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    check = commands.add_parser("check-params", help="validate every section of the params file (the stages "
                                "each validate only the sections they read)")
    check.set_defaults(func=cmd_check_params)

    ingest = commands.add_parser("ingest", help="process a subject's trials into events/strides/cycles")
    ingest.add_argument("subject", help="subject id (data/subjects/<id>.yaml)")
    ingest.add_argument("--out-root", type=Path, default=PROCESSED_ROOT,
                        help="outputs go to <out-root>/<subject>/real/ (default: %(default)s)")
    ingest.set_defaults(func=cmd_ingest)

    events = commands.add_parser("events", help="print the gait events of one marker file")
    events.add_argument("file", type=Path, help="marker file (.trc, .c3d or .csv)")
    events.add_argument("--grf", type=Path, help="OpenSim ground reaction file (.mot) for force events")
    events.add_argument("--method", choices=("kinematic", "force", "auto"),
                        help="event source (default: params ingest.events.method)")
    events.add_argument("--format", choices=("csv", "table", "json"), default="csv")
    events.add_argument("--subject", help="take the file format and marker set from this subject")
    events.add_argument("--up-axis", choices=UP_AXIS_CHOICES,
                        help="the file's up axis (default: the subject's, else auto: detected from pelvis "
                        "and foot markers, as add-subject does)")
    events.add_argument("--markerset", help="marker set: a name in data/markersets/ or a YAML file "
                        "(default: the shipped set that fits the file)")
    events.set_defaults(func=cmd_events)

    bench = commands.add_parser("bench", help="time ingest, IK, human, store and rollouts on the real data")
    bench.add_argument("--out", type=Path, default=BENCH_REPORT)
    bench.add_argument("--repeat", type=int, default=5, help="timed runs, best kept (default: 5)")
    bench.add_argument("--only", type=_sections, help=f"comma-separated sections to run (default: all of "
                       f"{', '.join(SECTIONS)})")
    bench.set_defaults(func=cmd_bench)

    run = commands.add_parser("run", help="dvc repro TARGETS, every stage on one local Ray head, the lock "
                              "written by libyaml (make run)")
    run.add_argument("targets", nargs="*", default=["summary", "report"],
                     help="stages (default: summary report, i.e. all but bench)")
    run.set_defaults(func=cmd_run)

    scale = commands.add_parser("scale", help="build a subject's scaled 27-DoF human from its static trial")
    scale.add_argument("subject", help="subject id (data/subjects/<id>.yaml)")
    scale.add_argument("--root", type=Path, help="model goes to <root>/<subject>/model/ "
                       "(default: data/processed)")
    scale.add_argument("--reports", type=Path, help="picture goes to <reports>/<subject>/model.png "
                       "(default: reports)")
    scale.set_defaults(func=cmd_scale)

    reference = commands.add_parser("reference", help="retarget a subject's walking onto its scaled human")
    reference.add_argument("subject", help="subject id (data/subjects/<id>.yaml)")
    reference.add_argument("--root", type=Path, help="model folder root: <root>/<subject>/model/ "
                           "(default: data/processed)")
    reference.add_argument("--reports", type=Path, help="figure goes to <reports>/<subject>/retarget.png "
                           "(default: reports)")
    reference.set_defaults(func=cmd_reference)

    tune_c = commands.add_parser("tune-controllers", help="tune every follow-me controller the same way "
                                 "on a synthetic walk (robot.tuning)")
    tune_c.add_argument("--out", type=Path, default=TUNING_REPORT)
    tune_c.add_argument("--gains", type=Path, default=TUNED_GAINS,
                        help="tuned-gains file to write the searched gains to, read on top of params.yaml "
                             "robot.controllers (default: data/tuning/controllers.yaml)")
    tune_c.set_defaults(func=cmd_tune_controllers)

    simulate = commands.add_parser("simulate", help="replay-human rollouts (free, pid, adaptive) of a "
                                   "subject's straight bouts, processed like the real trials")
    simulate.add_argument("subject", help="subject id (data/subjects/<id>.yaml)")
    simulate.add_argument("--root", type=Path, help="<root>/<subject>/{model,real} in, sim/ out "
                          "(default: data/processed)")
    simulate.add_argument("--reports", type=Path, help="figure to <reports>/<subject>/ "
                          "(default: reports)")
    simulate.add_argument("--human", choices=("replay", "policy"), default="replay",
                          help="replay: kinematic replay (default); policy: the trained walking policy, "
                          "written to <root>/<subject>/sim_policy/")
    simulate.add_argument("--policy-root", type=Path, help="policies folder holding <subject>/ for "
                          "--human policy (default: data/policies)")
    simulate.set_defaults(func=cmd_simulate)

    train = commands.add_parser("train", help="train the subject's walking policy (PPO + AMP)")
    train.add_argument("subject")
    train.add_argument("--n-envs", type=int, help="parallel environments (default: params train.n_envs)")
    train.add_argument("--threads", type=int, help="torch threads (default: params train.threads)")
    train.add_argument("--steps", type=int, help="total env steps (default: params train.total_steps)")
    train.add_argument("--resume", action="store_true", help="continue from data/policies/<subject>/")
    train.add_argument("--max-wall-s", type=float, help="stop (with a checkpoint) after this long")
    train.add_argument("--subprocess", action="store_true", help="one process per environment")
    train.add_argument("--init-from", metavar="SUBJECT",
                       help="start from SUBJECT's trained policy (transfer) instead of from scratch")
    train.add_argument("--ray", action="store_true", help="run as one Ray job: on this machine, or on a node "
                       "of the RAY_ADDRESS cluster (the policy folder comes back when it succeeded)")
    train.add_argument("--variant", default="healthy", help="fine-tune a cohort variant (params cohort) from "
                       "the subject's own policy into data/policies/<subject>/cohort/<variant>/")
    train.set_defaults(func=cmd_train)

    transfer = commands.add_parser("transfer", help="a policy for a subject without one: the universal "
                                   "or nearest committed policy, gated, fine-tuned (params transfer)")
    transfer.add_argument("subject")
    transfer.add_argument("--steps", type=int, help="env steps (default: params transfer.steps)")
    transfer.add_argument("--max-wall-s", type=float, help="fine-tuning time limit (default: params "
                          "transfer.max_wall_s)")
    transfer.add_argument("--root", type=Path, help="<root>/<subject>/{model,real} in "
                          "(default: data/processed)")
    transfer.add_argument("--universal", type=Path, help="the universal checkpoint's folder, e.g. a copy of "
                          "the one adopt-universal judged (default: data/universal)")
    transfer.set_defaults(func=cmd_transfer)

    adopt = commands.add_parser("adopt-universal", help="the adoption rule on the universal run's "
                                "checkpoint on every bundled body (docs/policies.md)")
    adopt.add_argument("subjects", nargs="*", help="bodies to judge (default: params universal.subjects)")
    adopt.add_argument("--universal", type=Path, help="the checkpoint's folder (default: data/universal)")
    adopt.add_argument("--root", type=Path, help="<root>/<subject>/{model,real} in (default: data/processed)")
    adopt.add_argument("--policy-root", type=Path, help="policies folder holding the committed policies "
                       "compared against and the run's source evaluation (default: data/policies)")
    adopt.add_argument("--no-record", action="store_true", help="do not append to <folder>/adoption.json")
    adopt.add_argument("--json", action="store_true", help="JSON only on stdout (no progress bar)")
    adopt.set_defaults(func=cmd_adopt_universal)

    evaluate = commands.add_parser("evaluate-policy", help="issue-6 checks of the trained walking policy")
    evaluate.add_argument("subject")
    evaluate.add_argument("--json", action="store_true", help="JSON only on stdout (no progress bar)")
    evaluate.add_argument("--out", type=Path, help="also write the JSON here")
    evaluate.add_argument("--policy-root", type=Path, help="policies folder holding <subject>/ "
                          "(default: data/policies; e.g. data/candidates/stop_gamma098)")
    evaluate.add_argument("--variant", default="healthy", help="a cohort variant's policy (params cohort; "
                          "default: healthy, the subject's own)")
    evaluate.set_defaults(func=cmd_evaluate_policy)

    render = commands.add_parser("render", help="mp4 of one replay or scenario rollout (offscreen MuJoCo)")
    render.add_argument("subject")
    render.add_argument("condition", help="free or a controller name in robot.controllers")
    render.add_argument("--seed", type=int, default=0)
    render.add_argument("--bout", type=int, default=0, help="straight bout index (default: 0)")
    render.add_argument("--scenario", help="the policy human walking this scenario (params scenarios) "
                        "instead of a replay bout")
    render.add_argument("--root", type=Path, help="default: data/processed")
    render.add_argument("--reports", type=Path, help="video to <reports>/<subject>/ (default: reports)")
    render.set_defaults(func=cmd_render)

    export = commands.add_parser("export", help="simulated trials as OpenSim files (.trc, .mot, GRF, "
                                 "robot log)")
    export.add_argument("subject")
    export.add_argument("--source", choices=("sim",), default="sim",
                        help="simulated trials (recorded ones are files already)")
    export.add_argument("--scenario", default="walk_10m", help="a scenario of params (policy human), or "
                        "'replay' for the replay human's straight bouts (default: walk_10m)")
    export.add_argument("--condition", action="append", help="free or a controller (repeatable; default: "
                        "rollout.conditions)")
    export.add_argument("--walks", type=int, help="walks (seeds) per condition (default: as in simulate)")
    export.add_argument("--out", type=Path, help="default: data/exports/<subject>/<scenario>/")
    export.add_argument("--root", type=Path, help="default: data/processed")
    export.set_defaults(func=cmd_export)

    sweep = commands.add_parser("sweep", help="run the study of params `sweep` on Ray (resumable; "
                                "RAY_ADDRESS: on that cluster)")
    sweep.add_argument("--root", type=Path, help="default: data/sweeps")
    sweep.add_argument("--study", help="params sweep.study (default), fall_intervention.study or "
                       "sensitivity.study")
    sweep.set_defaults(func=cmd_sweep)

    tune = commands.add_parser("tune", help="tune a controller's gains for one subject on the policy-human "
                               "scenarios (Optuna through Ray Tune)")
    tune.add_argument("subject")
    tune.add_argument("--controller", required=True, help="a controller of robot.controllers with a "
                      "tune.search space")
    tune.add_argument("--variant", default="healthy", help="cohort variant (default: healthy, the subject's "
                      "own policy)")
    tune.add_argument("--n-trials", type=int, help="default: params tune.n_trials")
    tune.set_defaults(func=cmd_tune)

    add_results_commands(commands)
    return parser


def system_error_text(exc: OSError) -> str:
    """`<what> (<file>)` of an error of the system: `No space left on device (data/results.duckdb)`."""
    files = [str(f) for f in (exc.filename, exc.filename2) if f is not None]
    what = exc.strerror or str(exc)
    return f"{what} ({' -> '.join(files)})" if files else what


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except GaitloopError as exc:
        problem, status = str(exc), EXIT_ERROR
    except KeyboardInterrupt:
        problem, status = f"interrupted (python -m pipeline {' '.join(argv)})", EXIT_INTERRUPTED
    except OSError as exc:  # disk full, permissions, a file that vanished: what and which file
        problem, status = system_error_text(exc), EXIT_ERROR
    print(f"error: {' '.join(problem.split())}", file=sys.stderr)
    return status
