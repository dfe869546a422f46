-- a study's rollouts per subject, variant, condition and scenario: mean over seeds
CREATE OR REPLACE VIEW sweep_summary AS
SELECT study, subject, variant, condition, scenario,
    coalesce(event, 'none') AS event, count(*) AS n_runs, sum(fell::INT) AS falls,
    avg(mean_abs_ex_cm) AS mean_abs_ex_cm, avg(mean_abs_ey_cm) AS mean_abs_ey_cm,
    avg(force_rms_n) AS force_rms_n, avg(gait_speed_mps) AS gait_speed_mps,
    avg(stride_length_m) AS stride_length_m
FROM sweep_results
JOIN sweep_current USING (study, job_key)
GROUP BY ALL
ORDER BY study, subject, variant, scenario, event, condition
