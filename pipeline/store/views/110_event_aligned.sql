-- the event_traces table: one row per time step around each commanded event
CREATE OR REPLACE VIEW event_aligned AS
SELECT subject, human_mode, condition, scenario, event, t_s,
    n_runs, ex_cm_mean, ex_cm_ci95, ey_cm_mean, ey_cm_ci95, force_n_mean, force_n_ci95, version_id
FROM latest_event_traces
ORDER BY subject, scenario, event, condition, t_s
