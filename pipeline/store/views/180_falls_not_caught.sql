-- every event the unsupported person fell after (falls_free) that a controller did not catch,
-- with why (the first that applies): no event (the human fell, or the arm locked, before the
-- onset), the simulation went unstable (`fell` without a fall or lock time, sim.rollout.batch),
-- no lock within the detection window, or the pelvis already past the caught drop at the lock
CREATE OR REPLACE VIEW falls_not_caught AS
$events_free
SELECT e.subject, e.variant, e.event, e.condition, e.scenario, e.seed, e.onset_s, e.human_fall_s,
    e.robot_fall_s, e.latency_s, e.pelvis_drop_at_lock_m,
    CASE WHEN e.before_onset AND e.human_fall_s < e.onset_s THEN 'fell_before_onset'
        WHEN e.before_onset THEN 'locked_before_onset'
        WHEN e.fell AND e.human_fall_s IS NULL AND e.robot_fall_s IS NULL THEN 'unstable'
        WHEN NOT coalesce(e.detected, FALSE) THEN 'not_detected'
        ELSE 'dropped' END AS reason
FROM ev e
JOIN unsupported u USING (subject, variant, scenario, event, seed)
WHERE e.condition <> 'free' AND u.falls_free AND NOT coalesce(e.caught, FALSE)
ORDER BY e.subject, e.variant, e.event, e.condition, e.scenario, e.seed
