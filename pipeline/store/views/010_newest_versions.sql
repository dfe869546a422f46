-- newest version of every group, whether or not the subject's last run still had it
CREATE OR REPLACE VIEW newest_versions AS
SELECT *
FROM versions v
WHERE version_id = (SELECT max(version_id) FROM versions w WHERE $same_group)
