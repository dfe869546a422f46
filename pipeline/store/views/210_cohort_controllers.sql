-- cohort x controller: following, harness force, and the gait change versus the same variant free
CREATE OR REPLACE VIEW cohort_controllers AS
WITH normal AS (
    SELECT * FROM sweep_rollouts WHERE coalesce(event, 'none') = 'none'
), free AS (
    SELECT subject, variant, scenario, avg(gait_speed_mps) AS free_speed,
        avg(stride_length_m) AS free_stride, avg(stride_time_cv_pct) AS free_cv,
        $walk_status AS free_status
    FROM normal
    WHERE condition = 'free'
    GROUP BY ALL
)
SELECT n.subject, n.variant, n.condition, n.scenario, count(*) AS walks, sum(n.fell::INT) AS falls,
    avg(n.mean_abs_ex_cm) AS mean_abs_ex_cm, avg(n.mean_abs_ey_cm) AS mean_abs_ey_cm,
    avg(n.force_rms_n) AS force_rms_n,
    100 * (avg(n.gait_speed_mps) / any_value(f.free_speed) - 1) AS speed_change_pct,
    100 * (avg(n.stride_length_m) / any_value(f.free_stride) - 1) AS stride_change_pct,
    avg(n.stride_time_cv_pct) - any_value(f.free_cv) AS cv_change_pct,
    any_value(f.free_status) AS free_status
FROM normal n
LEFT JOIN free f USING (subject, variant, scenario)
WHERE n.condition <> 'free'
GROUP BY ALL
ORDER BY n.subject, n.scenario, n.variant, n.condition
