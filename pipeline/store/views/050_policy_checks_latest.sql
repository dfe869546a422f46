-- the newest evaluation of each subject's policy and cohort variant, one row per check
CREATE OR REPLACE VIEW policy_checks_latest AS
SELECT c.* EXCLUDE (content_hash)
FROM policy_checks c
WHERE c.version_id = (SELECT max(d.version_id) FROM policy_checks d WHERE d.subject = c.subject
    AND d.variant = c.variant)
ORDER BY subject, variant, "check"
