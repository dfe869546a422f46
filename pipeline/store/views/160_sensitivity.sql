-- the responsiveness study per subject, variant, scenario, factor, level and controller: mean and
-- 95 % CI (Student t across walks, t95: n = 2..200, 1.96 beyond) of the walks' mean |e_x|, |e_y| (cm,
-- samples before an arm lock) and harness force RMS (N); falls (a human fall, an arm lock or an
-- unstable run), arm locks (the fall rule fired: deflection, drop) and human falls counted apart
CREATE OR REPLACE VIEW sensitivity AS
WITH r AS (
    SELECT d.factor, d.level, d.twin, s.*
    FROM sweep_results s
    JOIN sweep_current USING (study, job_key)
    JOIN sensitivity_design d USING (study, job_key)
), t AS (
    SELECT * FROM (VALUES $t95) v(n, t95)
), g AS (
    SELECT study, subject, variant, scenario, factor, level, condition, bool_and(twin) AS twin,
        count(*) AS n, sum(fell::INT) AS falls, count(robot_fall_s) AS arm_locks,
        count(human_fall_s) AS human_falls,
        avg(mean_abs_ex_cm) AS mean_abs_ex_cm, stddev_samp(mean_abs_ex_cm) AS sd_ex,
        avg(mean_abs_ey_cm) AS mean_abs_ey_cm, stddev_samp(mean_abs_ey_cm) AS sd_ey,
        avg(force_rms_n) AS force_rms_n, stddev_samp(force_rms_n) AS sd_f,
        avg(gait_speed_mps) AS gait_speed_mps
    FROM r
    GROUP BY ALL
)
SELECT g.study, g.subject, g.variant, g.scenario, g.factor, g.level, g.condition, g.twin, g.n,
    g.falls, g.arm_locks, g.human_falls,
    g.mean_abs_ex_cm, coalesce(t.t95, 1.96) * g.sd_ex / sqrt(g.n) AS mean_abs_ex_cm_ci95,
    g.mean_abs_ey_cm, coalesce(t.t95, 1.96) * g.sd_ey / sqrt(g.n) AS mean_abs_ey_cm_ci95,
    g.force_rms_n, coalesce(t.t95, 1.96) * g.sd_f / sqrt(g.n) AS force_rms_n_ci95, g.gait_speed_mps
FROM g
LEFT JOIN t ON t.n = g.n
ORDER BY g.study, g.subject, g.variant, g.scenario, g.factor, g.level, g.condition
