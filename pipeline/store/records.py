"""The store's own tables (beside the metric tables): study rollouts and designs, controller tuning,
quality gates and policy checks; their columns and DDL. No metric module is imported here, so the
stages that write studies (`sweep`) do not depend on the metrics' code."""

from __future__ import annotations

# Studies (`sweep`): one row per rollout job, stored once per (study, job_key) whatever retried it.
# The balance-loss event (metrics.fall_intervention) and left/right timing (metrics.gait_symmetry)
# columns came later: a store from before gets them added (NULL in its old rows).
SWEEP_EVENT_DDL = {
    "event": "VARCHAR", "onset_s": "DOUBLE", "human_fall_s": "DOUBLE", "robot_fall_s": "DOUBLE",
    "before_onset": "BOOLEAN", "detected": "BOOLEAN", "caught": "BOOLEAN", "latency_s": "DOUBLE",
    "pelvis_drop_at_lock_m": "DOUBLE", "max_pelvis_drop_m": "DOUBLE", "max_harness_force_n": "DOUBLE",
    "false_alarm": "BOOLEAN", "walk_s": "DOUBLE", "stance_l_s": "DOUBLE", "stance_r_s": "DOUBLE",
    "swing_l_s": "DOUBLE", "swing_r_s": "DOUBLE", "stance_ratio_lr": "DOUBLE", "swing_ratio_lr": "DOUBLE",
    "stride_time_cv_pct": "DOUBLE"}
SWEEP_COLUMNS = ["study", "job_key", "subject", "variant", "condition", "gains_hash", "scenario", "seed",
                 "params_hash", "mean_abs_ex_cm", "mean_abs_ey_cm", "force_rms_n", "fell",
                 "gait_speed_mps", "stride_length_m", "n_strides", "n_samples", *SWEEP_EVENT_DDL, "wall_s"]
SWEEP_DDL = ("study VARCHAR NOT NULL, job_key VARCHAR NOT NULL, subject VARCHAR, variant VARCHAR, "
             "condition VARCHAR, gains_hash VARCHAR, scenario VARCHAR, seed BIGINT, params_hash VARCHAR, "
             "mean_abs_ex_cm DOUBLE, mean_abs_ey_cm DOUBLE, force_rms_n DOUBLE, fell BOOLEAN, "
             "gait_speed_mps DOUBLE, stride_length_m DOUBLE, n_strides BIGINT, n_samples BIGINT, "
             "wall_s DOUBLE, run_id BIGINT, PRIMARY KEY (study, job_key)")
# Per-subject controller tuning (`tune`): a new version per (subject, variant, controller) when the
# tuned result changes (data/tuning/<subject>/<variant>/<controller>.json).
TUNING_COLUMNS = ["subject", "variant", "controller", "method", "n_trials", "seed", "generic_gains",
                  "tuned_gains", "search_best_objective", "generic_mean", "generic_ci95", "generic_falls",
                  "tuned_mean", "tuned_ci95", "tuned_falls", "n_heldout", "search_rollouts", "search_falls"]
TUNING_DDL = ("version_id BIGINT NOT NULL, subject VARCHAR, variant VARCHAR, controller VARCHAR, "
              "method VARCHAR, n_trials BIGINT, seed BIGINT, generic_gains VARCHAR, tuned_gains VARCHAR, "
              "search_best_objective DOUBLE, generic_mean DOUBLE, generic_ci95 DOUBLE, generic_falls BIGINT, "
              "tuned_mean DOUBLE, tuned_ci95 DOUBLE, tuned_falls BIGINT, n_heldout BIGINT, "
              "content_hash VARCHAR, run_id BIGINT, created_at TIMESTAMP, search_rollouts BIGINT, "
              "search_falls BIGINT")
# The responsiveness study's design (`pipeline.stages.sweep.sensitivity_jobs`): which (factor, level) cells
# each of its jobs stands in, `twin` when the job's robot is the twin's. Each study's latest design only
# (its rows in sweep_results keep every job ever stored).
DESIGN_COLUMNS = ["study", "job_key", "factor", "level", "twin"]
DESIGN_DDL = ("study VARCHAR NOT NULL, job_key VARCHAR NOT NULL, factor VARCHAR NOT NULL, "
              "level DOUBLE NOT NULL, twin BOOLEAN, PRIMARY KEY (study, job_key, factor, level)")
QUALITY_DDL = ('run_id BIGINT NOT NULL, subject VARCHAR NOT NULL, stage VARCHAR, "check" VARCHAR, '
               "value DOUBLE, warn_above DOUBLE, fail_above DOUBLE, status VARCHAR, note VARCHAR, "
               "cause VARCHAR")
# evaluate-policy's checks (`evaluation.json` of each policy folder): one row per check with its
# measured value and the closed interval [low, high] it must lie in (NULL: open side; value, low,
# high and unit NULL for an evaluation from before `check_rows`) and the walks per condition the
# evaluation ran (`evaluate_policy.n_seeds`, or `transfer.gate_seeds` for a transfer gate's: a pass
# over 2 walks says less than one over 10); a new version per (subject, variant) when its rows change.
POLICY_CHECK_COLUMNS = ["subject", "variant", "check", "passed", "value", "low", "high", "unit", "walks"]
POLICY_CHECKS_DDL = ('version_id BIGINT NOT NULL, subject VARCHAR NOT NULL, variant VARCHAR NOT NULL, '
                     '"check" VARCHAR NOT NULL, passed BOOLEAN, value DOUBLE, low DOUBLE, high DOUBLE, '
                     "unit VARCHAR, content_hash VARCHAR, run_id BIGINT, created_at TIMESTAMP, walks INTEGER")
