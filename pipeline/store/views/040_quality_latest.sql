-- each subject's quality gates as of its last store run
CREATE OR REPLACE VIEW quality_latest AS
SELECT q.*
FROM quality q
WHERE q.run_id = (SELECT max(u.run_id) FROM quality u WHERE u.subject = q.subject)
ORDER BY subject, stage, "check"
