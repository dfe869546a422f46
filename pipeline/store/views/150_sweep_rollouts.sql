-- every rollout of the studies' current jobs once (a job in two studies is the same rollout)
-- (a robot moved away from the twin in the responsiveness study is not the twin: left out)
CREATE OR REPLACE VIEW sweep_rollouts AS
SELECT DISTINCT ON (job_key) r.* EXCLUDE (study, run_id)
FROM sweep_results r
JOIN sweep_current c USING (study, job_key)
WHERE (r.study, r.job_key) NOT IN (SELECT (study, job_key) FROM sensitivity_design WHERE NOT twin)
ORDER BY job_key, study
