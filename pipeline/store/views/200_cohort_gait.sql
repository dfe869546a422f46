-- each variant's gait signature walking free without events (metrics.gait_symmetry)
-- distinct_walks (_walk_summary.sql); the SD across walks needs two distinct ones
CREATE OR REPLACE VIEW cohort_gait AS
SELECT subject, variant, scenario, count(*) AS walks,
    count(DISTINCT $walk_summary) AS distinct_walks, sum(fell::INT) AS falls,
    avg(gait_speed_mps) AS gait_speed_mps, CASE
    WHEN count(DISTINCT $walk_summary) > 1 THEN stddev_samp(gait_speed_mps) END AS gait_speed_sd,
    avg(stride_length_m) AS stride_length_m, avg(stance_ratio_lr) AS stance_ratio_lr,
    avg(swing_ratio_lr) AS swing_ratio_lr, avg(stride_time_cv_pct) AS stride_time_cv_pct,
    sum(n_strides) AS strides, $walk_status AS status
FROM sweep_rollouts
WHERE coalesce(event, 'none') = 'none' AND condition = 'free'
GROUP BY ALL
ORDER BY subject, scenario, variant
