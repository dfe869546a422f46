-- the latest tuned gains per subject, variant and controller, beside the generic ones
-- search_status: 'no signal' when every search rollout fell (each trial scored the fall penalty,
-- so the tuned gains are the first trial's, the generic ones; pipeline.runs.tune.search_falls)
CREATE OR REPLACE VIEW tuning_comparison AS
SELECT t.* EXCLUDE (content_hash, run_id), CASE
    WHEN t.search_rollouts > 0 AND t.search_falls = t.search_rollouts THEN 'no signal'
    WHEN t.search_rollouts IS NULL THEN 'unknown' ELSE 'ok' END AS search_status
FROM tuned_gains t
WHERE t.version_id = (SELECT max(u.version_id) FROM tuned_gains u WHERE u.subject = t.subject
    AND u.variant = t.variant AND u.controller = t.controller)
ORDER BY subject, variant, controller
