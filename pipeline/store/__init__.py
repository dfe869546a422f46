"""The versioned results store: one DuckDB file (`data/results.duckdb`) kept across runs.

Every result row belongs to a version: one (subject, source, human_mode, condition) group's
(`metrics.groups.GROUP`) results at one point in time, with the sha256 of its content, the hash of
the params that made it, the code revision (`git rev-parse HEAD`, 'unknown' outside git) and the
creation time.

- A group whose content equals its latest version's content gets no new version: rerunning an
  unchanged pipeline adds nothing. Changed content gets a new version; an earlier version is never
  updated or deleted (content that returns to an older state is a new version, so "latest" is
  always what the last run computed).
- Readers never block a store run and a store run never changes what a reader sees: a run writes a
  copy of the store (`<store>.<pid>.tmp` beside it) and swaps it in (`os.replace`) once committed, so
  a reader (a notebook, any DuckDB client, `read_only=True`) keeps its snapshot until it reconnects,
  and a run killed midway leaves the store as it was (its temp file is deleted by the next run).
- One store run writes at a time: runs take `<store>.lock` (flock), and a DuckDB client holding the
  store itself open for writing is waited for too. A second writer retries for `busy_timeout_s`,
  then fails with `StoreError` "store is busy". Connections are always closed.

SPM tests belong to the group of their second sample (`*_b`: the simulated or the controller
condition); their curves and clusters to the test's version. Base tables are `result_<name>`, one per
metric table of `metrics.tables.REGISTRY` (its columns and types; `schema.py`).
`run_groups` records, for every store run, each group it stored and the version that group resolved
to; `latest_versions` (and every `latest_<name>` view) holds the groups of each subject's last run,
so a condition that a subject no longer has drops out of the latest views while its old versions
stay queryable. `quality` holds each subject's quality gates (`metrics.quality`) of every store run
(`quality_latest`: its last run's; each paper-table row carries its subject's worst status).
`policy_checks` holds `evaluate-policy`'s checks of each subject's policy and cohort variant, a new
version per (subject, variant) when they change (`policy_checks_latest`: the newest).
`paper_table1..3`, `phase_compliance`, `event_aligned`, `spm_clusters`,
`subject_summary` are described in README.md; `sensitivity` (the responsiveness study) in docs/robot.md.

Modules (imported by name: the package itself imports nothing, so a stage pulls in only what it uses):
`connection` (opening, the writer's lock, the copy swapped in), `records` (the store's own tables:
studies, tuning, quality, policy checks), `schema` (the metric tables' DDL and the views, read from
`views/*.sql`), `write` (`store_results`), `read` (`query`, `compare_views`).
"""
