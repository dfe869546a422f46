-- latest_<table> of each registered metric table (metrics.tables.REGISTRY): its rows of the
-- groups in latest_versions
CREATE OR REPLACE VIEW latest_$table AS
SELECT r.*
FROM result_$table r
JOIN latest_versions USING (version_id)
