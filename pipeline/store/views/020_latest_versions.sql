-- the groups of each subject's last store run, each at the version that run resolved it to
CREATE OR REPLACE VIEW latest_versions AS
SELECT v.*
FROM versions v
JOIN run_groups g USING (version_id)
WHERE g.run_id = (SELECT max(h.run_id) FROM run_groups h WHERE h.subject = g.subject)
