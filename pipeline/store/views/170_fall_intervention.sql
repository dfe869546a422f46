-- balance loss x controller x variant: was it caught? (metrics.fall_intervention)
CREATE OR REPLACE VIEW fall_intervention AS
$events_free
SELECT e.subject, e.variant, e.event, e.condition, count(*) AS rollouts,
    count(*) FILTER (WHERE e.before_onset) AS fell_before_onset,
    count(*) FILTER (WHERE NOT e.before_onset) AS events,
    count(*) FILTER (WHERE NOT e.before_onset AND u.falls_free) AS events_falling_free,
    count(*) FILTER (WHERE NOT e.before_onset AND e.human_fall_s IS NOT NULL) AS human_falls,
    avg(e.detected::INT) FILTER (WHERE NOT e.before_onset) AS detection_rate,
    avg(e.detected::INT) FILTER (WHERE NOT e.before_onset AND u.falls_free) AS detection_rate_falling,
    avg(e.caught::INT) FILTER (WHERE NOT e.before_onset AND u.falls_free) AS caught_rate_falling,
    avg(e.latency_s) FILTER (WHERE e.detected) AS latency_s,
    avg(e.pelvis_drop_at_lock_m) FILTER (WHERE e.detected) AS pelvis_drop_at_lock_m,
    max(e.pelvis_drop_at_lock_m) FILTER (WHERE e.detected) AS worst_drop_at_lock_m,
    avg(e.max_harness_force_n) FILTER (WHERE NOT e.before_onset) AS max_harness_force_n,
    max(e.max_harness_force_n) FILTER (WHERE NOT e.before_onset) AS peak_harness_force_n
FROM ev e
LEFT JOIN unsupported u USING (subject, variant, scenario, event, seed)
GROUP BY ALL
ORDER BY e.subject, e.variant, e.event, e.condition
